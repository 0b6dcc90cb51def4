"""A fast decoder for frames whose signals are all little-endian (Intel), built from the DBC.

cantools' general decoder costs ~10 us a frame; the IMU bridge sends ~410 frames a second
and replay reads days of them. Each signal here is a shift and a mask of the payload read
as one little-endian integer, with the DBC's start bit, length, sign, scale and offset, so
the layout still comes from the DBC alone. Tests check it against cantools on every bit.

For the hottest frames, :meth:`LittleEndianDecoder.compile` goes further: it generates, from
the DBC, one Python function that reads the payload with :mod:`struct` in byte-aligned
little-endian words and returns just what the caller asked for, as a tuple (raw bits of a
signal, a table lookup on them, whether any or all of some signals are set), with no dict
and no loop: a few hundred nanoseconds a frame.
"""

from __future__ import annotations

import struct
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

#: struct codes of the byte-aligned little-endian words a compiled unpacker reads, by size.
_WORD_CODES = {1: "B", 2: "H", 4: "I", 8: "Q"}


@dataclass(frozen=True)
class Raw:
    """Output of a compiled unpacker: the raw bits of ``signal`` as an unsigned integer (no
    sign, scale or offset)."""

    signal: str


@dataclass(frozen=True)
class Lookup:
    """Output of a compiled unpacker: ``table[raw bits of signal]`` (``table`` has an entry for
    every raw value, e.g. from :meth:`LittleEndianDecoder.physical_table`)."""

    signal: str
    table: Sequence[Any]


@dataclass(frozen=True)
class AnyOf:
    """Output of a compiled unpacker, a bool: whether any of ``terms`` is true (a :class:`Raw`
    when its raw bits are not all zero, a :class:`Lookup` when its table, all bools, says so)."""

    terms: tuple[Raw | Lookup, ...]


@dataclass(frozen=True)
class AllOf:
    """Output of a compiled unpacker, a bool: whether every one of ``terms`` is true (as in
    :class:`AnyOf`)."""

    terms: tuple[Raw | Lookup, ...]


Output = Raw | Lookup | AnyOf | AllOf


@dataclass(frozen=True)
class _Field:
    name: str
    start: int
    length: int
    mask: int
    sign_bit: int
    scale: float
    offset: float
    integral: bool


class LittleEndianDecoder:
    """``decode(data) -> {signal: value}`` equal to cantools' ``decode(decode_choices=False)``."""

    def __init__(self, message: Any) -> None:
        fields = []
        for s in message.signals:
            if s.byte_order != "little_endian" or s.is_multiplexer or s.multiplexer_ids:
                raise ValueError(f"{message.name}.{s.name}: only plain little-endian signals")
            mask = (1 << s.length) - 1
            sign_bit = 1 << (s.length - 1) if s.is_signed else 0
            integral = s.scale == 1 and s.offset == 0
            fields.append(
                _Field(s.name, s.start, s.length, mask, sign_bit, s.scale, s.offset, integral)
            )
        self._by_name = {f.name: f for f in fields}
        self._fields = tuple(
            (f.name, f.start, f.mask, f.sign_bit, f.scale, f.offset, f.integral) for f in fields
        )
        self.name: str = message.name
        self.length: int = message.length

    def decode(self, data: bytes) -> dict[str, float | int]:
        """Physical values of every signal (raw integers where scale 1 and offset 0)."""
        word = int.from_bytes(data, "little")
        out: dict[str, float | int] = {}
        for name, start, mask, sign_bit, scale, offset, integral in self._fields:
            raw = (word >> start) & mask
            if raw & sign_bit:
                raw -= sign_bit << 1
            out[name] = raw if integral else raw * scale + offset
        return out

    def physical(self, signal: str, raw: int) -> float | int:
        """The value :meth:`decode` gives ``signal`` when its bits in the frame are ``raw``."""
        f = self._by_name[signal]
        if not 0 <= raw <= f.mask:
            raise ValueError(f"{self.name}.{signal}: raw value {raw} outside {f.length} bits")
        if raw & f.sign_bit:
            raw -= f.sign_bit << 1
        return raw if f.integral else raw * f.scale + f.offset

    def physical_table(self, signal: str) -> tuple[float | int, ...]:
        """:meth:`physical` of ``signal`` for every raw value, indexed by the raw value."""
        f = self._by_name[signal]
        signed = [raw - ((raw & f.sign_bit) << 1) for raw in range(f.mask + 1)]
        if f.integral:
            return tuple(signed)
        scale, offset = f.scale, f.offset
        return tuple(raw * scale + offset for raw in signed)

    def compile(self, outputs: Sequence[Output]) -> Callable[[bytes | bytearray], tuple[Any, ...]]:
        """A function of a payload of :attr:`length` bytes returning ``outputs``, in order.

        Generated from the DBC: the bytes that hold the signals asked for are read with one
        ``struct`` unpack as little-endian words (signals sharing a byte share a word; if some
        word is not 1, 2, 4 or 8 bytes, the whole payload is one integer), then each signal is
        a shift and a mask of its word. A payload of another length raises ``struct.error`` or
        ``ValueError``: the caller checks the length first.
        """
        leaves = [t for o in outputs for t in _leaves(o)]
        for o in outputs:
            if isinstance(o, AnyOf | AllOf) and not o.terms:
                raise ValueError(f"{self.name}: {type(o).__name__} of no term")
        for leaf in leaves:
            f = self._by_name.get(leaf.signal)
            if f is None:
                raise KeyError(f"{self.name} has no signal {leaf.signal}")
            if isinstance(leaf, Lookup) and len(leaf.table) != f.mask + 1:
                raise ValueError(f"{self.name}.{f.name}: a table of {len(leaf.table)} entries")
        for o in outputs:
            for t in o.terms if isinstance(o, AnyOf | AllOf) else ():
                if isinstance(t, Lookup) and not all(isinstance(v, bool) for v in t.table):
                    raise ValueError(f"{self.name}.{t.signal}: a table of bools is needed")
        used = [self._by_name[n] for n in dict.fromkeys(leaf.signal for leaf in leaves)]
        words, count, where = self._words(used)

        def bits(name: str) -> str:
            """Expression of the raw bits of ``name``."""
            f = self._by_name[name]
            word, shift, size = where[name]
            if not shift:
                return f"w{word}" if f.length == size else f"w{word} & {f.mask}"
            expr = f"w{word} >> {shift}"
            return expr if shift + f.length == size else f"({expr}) & {f.mask}"

        # A signal looked up more than once (its value, then a saturation test) is read once.
        looked_up = [leaf.signal for leaf in leaves if isinstance(leaf, Lookup)]
        twice = [n for n in dict.fromkeys(looked_up) if looked_up.count(n) > 1]
        shared = {n: f"s{k}" for k, n in enumerate(twice)}
        env: dict[str, Any] = {"_read": words}

        def term(t: Raw | Lookup, truth: bool = False) -> str:
            """Expression of ``t``; for ``truth``, one whose truth is the term's."""
            if isinstance(t, Raw):
                if not truth:
                    return bits(t.signal)
                word, shift, _ = where[t.signal]
                return f"w{word} & {self._by_name[t.signal].mask << shift}"
            table = next((k for k, v in env.items() if v is t.table), f"t{len(env)}")
            env[table] = t.table
            return f"{table}[{shared.get(t.signal) or bits(t.signal)}]"

        def merged(o: AnyOf | AllOf) -> str | None:
            """For Raw terms at the same bits of words of one size, one test: any of them is
            non-zero when the words OR-ed are there; all of them, if of 1 bit, when AND-ed."""
            if len(o.terms) < 2 or not all(isinstance(t, Raw) for t in o.terms):
                return None
            places = {(*where[t.signal][1:], self._by_name[t.signal].mask) for t in o.terms}
            if len(places) != 1:
                return None
            ((shift, _, mask),) = places
            if isinstance(o, AllOf) and mask != 1:
                return None
            words = (" | " if isinstance(o, AnyOf) else " & ").join(
                f"w{where[t.signal][0]}" for t in o.terms
            )
            return f"(({words}) & {mask << shift} != 0)"

        exprs = []
        for o in outputs:
            if isinstance(o, Raw | Lookup):
                exprs.append(term(o))
                continue
            fast = merged(o)
            if fast is not None:
                exprs.append(fast)
                continue
            joined = (" or " if isinstance(o, AnyOf) else " and ").join(
                term(t, truth=True) for t in o.terms
            )
            # bools from the tables, or some int from a Raw term: compared to 0, a bool
            raw = any(isinstance(t, Raw) for t in o.terms)
            exprs.append(f"({joined}) != 0" if raw else f"({joined})")
        source = "\n".join(
            [
                f"def unpack(data, {''.join(f'{k}={k}, ' for k in env)}):",
                f"    {''.join(f'w{k}, ' for k in range(count))}= _read(data)"
                if count
                else "    _read(data)",
                *(f"    {local} = {bits(n)}" for n, local in shared.items()),
                f"    return ({''.join(f'{e}, ' for e in exprs)})",
            ]
        )
        namespace = dict(env)
        exec(source, namespace)  # the source holds only integers and names made here
        unpack: Callable[[bytes | bytearray], tuple[Any, ...]] = namespace["unpack"]
        unpack.__doc__ = f"Compiled from {self.name} in the DBC:\n\n{source}"
        return unpack

    def _words(
        self, used: Sequence[_Field]
    ) -> tuple[
        Callable[[bytes | bytearray], tuple[int, ...]], int, dict[str, tuple[int, int, int]]
    ]:
        """The reader of the words holding the signals ``used``, how many words it returns, and
        where each signal lies: (word index, its start bit in the word, the word's bits)."""
        groups: list[list[int]] = []  # [first byte, last byte] of each word
        for first, last in sorted((f.start // 8, (f.start + f.length - 1) // 8) for f in used):
            if groups and first <= groups[-1][1]:
                groups[-1][1] = max(groups[-1][1], last)
            else:
                groups.append([first, last])
        if all(last - first + 1 in _WORD_CODES for first, last in groups):
            fmt, at = "<", 0
            for first, last in groups:
                fmt += "x" * (first - at) + _WORD_CODES[last - first + 1]
                at = last + 1
            fmt += "x" * (self.length - at)
            where = {}
            for f in used:
                k, (first, last) = next(
                    (k, g) for k, g in enumerate(groups) if g[0] <= f.start // 8 <= g[1]
                )
                where[f.name] = (k, f.start - 8 * first, 8 * (last - first + 1))
            return struct.Struct(fmt).unpack, len(groups), where
        length, name = self.length, self.name

        def read_whole(data: bytes | bytearray) -> tuple[int, ...]:
            if len(data) != length:
                raise ValueError(f"{name}: {len(data)} bytes, expected {length}")
            return (int.from_bytes(data, "little"),)

        return read_whole, 1, {f.name: (0, f.start, 8 * length) for f in used}


def _leaves(output: Output) -> tuple[Raw | Lookup, ...]:
    return output.terms if isinstance(output, AnyOf | AllOf) else (output,)
