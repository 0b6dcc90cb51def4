"""One generic path from physical values to frame bytes, through a DBC message.

The DBC carries everything the encoder needs: scale, offset, the valid range ``[min|max]``,
and the NMEA 2000 special values as value-table entries ``NOT_AVAILABLE`` (all ones; 0x7F..
for signed fields) and ``OUT_OF_RANGE`` (one less). Policy, applied to every signal alike:

- ``None`` (or NaN) is sent as ``NOT_AVAILABLE``: never a made-up zero.
- A value outside the valid range is sent as ``OUT_OF_RANGE`` (or ``NOT_AVAILABLE`` when the
  field has no out-of-range code, e.g. NAVGW_STATUS tilt sigma): it never wraps and is never
  clamped to a plausible-looking number.
- Signals named ``RESERVED*`` are sent as all ones and are not passed in.
- Signals named ``SIGMA*`` carry an accuracy, a 1-sigma: rounded up to the field's
  resolution, never to the nearest (a tilt sigma of 0.064 deg went out as 0.06, a better
  accuracy than the engine had; now 0.07). Other values round to the nearest, half to even.

The policy is :meth:`_Field.raw`; cantools' ``Message.encode`` packed the raw values until
issue 14 (6-20 us a frame). Now each message is compiled once, from the DBC alone, into a
small Python function (:func:`packer_source`): each signal's start bit, length, sign, scale
and raw limits become constants, the raw values are packed with shifts into one
little-endian integer, and the reserved bits are a constant. A value takes the inlined fast
path only when it is a number whose scaled value rounds into the signal's raw range; anything
else (None, NaN, infinities, out of range, a missing or malformed value) goes through
:meth:`_Field.raw` and the original checks, so every special value and every error is what it
was. tests/test_output_dbc.py proves the packers against cantools' encode and decode of the
same DBC. A message with big-endian, float or multiplexed signals is still packed by cantools.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from fractions import Fraction
from functools import cache
from typing import Any

from cantools.database.can import Message, Signal

NOT_AVAILABLE = "NOT_AVAILABLE"
OUT_OF_RANGE = "OUT_OF_RANGE"
RESERVED_PREFIX = "RESERVED"
SIGMA_PREFIX = "SIGMA"
#: Raw units a stated sigma may exceed a step and still be sent as that step: the float error
#: of (value - offset) / scale (0.07 / 0.01 is 7.000000000000001), not a rounding down.
ROUND_UP_SLACK = 1e-9

#: A physical value as the encoders hand it over (bools and IntEnums are ints).
Value = float | int | None


class EncodeError(ValueError):
    """A value the frame cannot carry at all (no special value to send instead)."""


@dataclass(frozen=True, slots=True)
class _Field:
    """One signal, compiled: raw limits and special raw values."""

    name: str
    scale: float
    offset: float
    raw_min: int
    raw_max: int
    not_available: int | None
    out_of_range: int | None
    round_up: bool  # a SIGMA* field: an accuracy, never sent smaller than it is

    @classmethod
    def of(cls, signal: Signal) -> _Field:
        choices = {str(name): int(raw) for raw, name in (signal.choices or {}).items()}
        scale, offset = float(signal.scale), float(signal.offset)
        lo = signal.minimum if signal.minimum is not None else _bit_min(signal)
        hi = signal.maximum if signal.maximum is not None else _bit_max(signal)
        field = cls(
            signal.name,
            scale,
            offset,
            math.ceil((lo - offset) / scale - 1e-9),
            math.floor((hi - offset) / scale + 1e-9),
            choices.get(NOT_AVAILABLE),
            choices.get(OUT_OF_RANGE),
            signal.name.startswith(SIGMA_PREFIX),
        )
        if field.raw_min < _bit_min(signal) or field.raw_max > _bit_max(signal):
            raise EncodeError(f"signal {signal.name}: range [{lo}|{hi}] exceeds its bits")
        return field

    def raw(self, value: Value) -> int:
        """The raw field value for a physical ``value``, by the policy above."""
        if value is None or (isinstance(value, float) and math.isnan(value)):
            return self._special(self.not_available, value)
        scaled = (value - self.offset) / self.scale
        if not math.isfinite(scaled):
            return self._special(self.out_of_range, value)
        raw = math.ceil(scaled - ROUND_UP_SLACK) if self.round_up else round(scaled)
        if self.raw_min <= raw <= self.raw_max:
            return raw
        return self._special(self.out_of_range, value)

    def _special(self, raw: int | None, value: Value) -> int:
        for candidate in (raw, self.not_available):
            if candidate is not None:
                return candidate
        raise EncodeError(f"signal {self.name} cannot carry {value!r} and has no special value")


def _bit_min(signal: Signal | _Slot) -> int:
    return -(1 << (signal.length - 1)) if signal.is_signed else 0


def _bit_max(signal: Signal | _Slot) -> int:
    return (1 << (signal.length - 1)) - 1 if signal.is_signed else (1 << signal.length) - 1


#: A compiled packer: the message's bytes from a mapping of signal name to physical value.
Packer = Callable[[Mapping[str, Value]], bytes]


@dataclass(frozen=True, slots=True)
class _Slot:
    """Where a signal's raw value goes in the message, read as one little-endian integer."""

    name: str
    start: int
    length: int
    is_signed: bool

    @property
    def mask(self) -> int:
        return (1 << self.length) - 1


class FrameCodec:
    """Encodes one DBC message from a mapping of signal name to physical value."""

    def __init__(self, message: Message) -> None:
        self.message = message
        self._fields = [_Field.of(s) for s in message.signals if not _reserved(s)]
        self._reserved = {s.name: (1 << s.length) - 1 for s in message.signals if _reserved(s)}
        if any(s.is_signed for s in message.signals if _reserved(s)):
            raise EncodeError(f"{message.name}: reserved signals must be unsigned")
        self._slots = slots = _slots(message, self._fields)
        # the reserved bits, all ones; bits of no signal stay 0 (as cantools' encode leaves them)
        self._base = sum(((1 << s.length) - 1) << s.start for s in message.signals if _reserved(s))
        self.source: str | None = None  # the packer's source; None: cantools packs
        self._pack: Packer = self._encode_checked
        if slots is not None:
            self.source = packer_source(
                message.name, message.length, self._base, self._compiled(slots)
            )
            namespace: dict[str, Any] = {"fallback": self._encode_checked}
            namespace.update({f"raw_{i}": field.raw for i, field in enumerate(self._fields)})
            exec(_code(self.source, message.name), namespace)
            self._pack = namespace["pack"]

    @property
    def signal_names(self) -> frozenset[str]:
        """The signals ``encode`` expects (every non-reserved one)."""
        return frozenset(f.name for f in self._fields)

    @property
    def packer(self) -> Packer:
        """The compiled ``encode``, for callers that skip the method call (the encoders)."""
        return self._pack

    def encode(self, values: Mapping[str, Value]) -> bytes:
        """The message's bytes; ``values`` must name every non-reserved signal."""
        return self._pack(values)

    def _encode_checked(self, values: Mapping[str, Value]) -> bytes:
        """The reference path, step by step: what the packer falls back to on any error, so
        that it raises what the codec always raised (a missing signal first, then the first
        value that cannot be sent)."""
        missing = self.signal_names - values.keys()
        if missing:
            raise EncodeError(f"{self.message.name}: no value for {sorted(missing)}")
        slots = self._slots
        if slots is None:
            raw = dict(self._reserved)
            raw.update({f.name: f.raw(values[f.name]) for f in self._fields})
            return bytes(self.message.encode(raw, scaling=False, strict=False))
        word = self._base
        for field in self._fields:
            slot = slots[field.name]
            word |= (field.raw(values[field.name]) & slot.mask) << slot.start
        return word.to_bytes(self.message.length, "little")

    def _compiled(self, slots: dict[str, _Slot]) -> list[_Compiled]:
        out = []
        for i, field in enumerate(self._fields):
            slot = slots[field.name]
            out.append(
                _Compiled(
                    name=field.name,
                    raw=f"raw_{i}",
                    not_available=field.not_available,
                    scaled=_scaled_expression(field),
                    above=_above(field.raw_min),
                    below=_below(field.raw_max),
                    start=slot.start,
                    mask=slot.mask if slot.is_signed else None,
                    inline=not field.round_up,
                )
            )
        return out


@dataclass(frozen=True, slots=True)
class _Compiled:
    """One signal as the generated code sees it."""

    name: str
    raw: str  # the name of its _Field.raw in the packer's namespace
    not_available: int | None  # the raw value _Field.raw gives None, if it has one
    scaled: str  # the expression of _Field.raw for the scaled value of ``v``
    above: float  # the fast path takes a scaled value in (above, below): it rounds into
    below: float  # [raw_min, raw_max], whatever the tie-breaking
    start: int
    mask: int | None  # two's complement mask of a signed field; None: unsigned
    inline: bool  # False: every value goes through _Field.raw (a SIGMA* field's rounding up)


def packer_source(name: str, length: int, base: int, fields: list[_Compiled]) -> str:
    """Python source of ``pack(values) -> bytes`` for one message (see the module docstring).

    Per field ``i``, the raw value is:

    - for None, the field's NOT_AVAILABLE value, as :meth:`_Field.raw` gives it;
    - for a number whose scaled value lies strictly between ``above`` and ``below``,
      ``round(scaled)``: such a value is finite and rounds (half to even, as
      :meth:`_Field.raw`) into the raw range, the case in which :meth:`_Field.raw` returns
      exactly that;
    - for anything else, ``raw_i(v)``: :meth:`_Field.raw` itself, which a field that is
      not ``inline`` (a ``SIGMA*`` one, rounded up; one a frame) takes for every value.

    Any exception (a missing signal, a value that is no number, a value the field cannot
    carry) reruns the message through ``fallback``, the codec's step-by-step reference path,
    which raises what the codec has always raised.
    """
    lines = [f"def pack(values):  # {name}", "    try:"]
    terms = [hex(base)] if base else []
    for i, f in enumerate(fields):
        lines.append(f"        v = values[{f.name!r}]")
        lines += _raw_lines(f"r{i}", f)
        term = f"r{i}" if f.mask is None else f"(r{i} & {f.mask:#x})"
        terms.append(f"{term} << {f.start}" if f.start else term)
    lines += [
        "    except (LookupError, TypeError, ValueError, ArithmeticError):",
        "        return fallback(values)",
        f"    return ({' | '.join(terms) or '0'}).to_bytes({length}, 'little')",
    ]
    return "\n".join(lines) + "\n"


def _raw_lines(r: str, f: _Compiled) -> list[str]:
    """The packer's lines that set ``r`` to the raw value of ``v`` for the field ``f``."""
    if not f.inline:
        return [f"        {r} = {f.raw}(v)"]
    in_range = f"{f.above!r} < (s := {f.scaled}) < {f.below!r}"
    if f.not_available is None:
        lines = [f"        if v is not None and {in_range}:"]
    else:
        lines = ["        if v is None:", f"            {r} = {f.not_available}"]
        lines.append(f"        elif {in_range}:")
    return [*lines, f"            {r} = round(s)", "        else:", f"            {r} = {f.raw}(v)"]


@cache
def _code(source: str, name: str) -> Any:
    """Compiled once per distinct source (address claims build a codec per claim)."""
    return compile(source, f"<packer {name}>", "exec")


def _scaled_expression(field: _Field) -> str:
    """``(v - offset) / scale`` as :meth:`_Field.raw` computes it; ``v - 0.0`` is ``v`` for
    every number (-0.0 included), so a zero offset is left out."""
    if field.offset == 0.0:
        return f"v / {field.scale!r}"
    return f"(v - {field.offset!r}) / {field.scale!r}"


@cache
def _above(raw_min: int) -> float:
    """The least float not below ``raw_min - 1/2``: a scaled value above it rounds to
    ``raw_min`` or more."""
    exact = Fraction(raw_min) - Fraction(1, 2)
    x = float(exact)
    while Fraction(x) < exact:
        x = math.nextafter(x, math.inf)
    return x


@cache
def _below(raw_max: int) -> float:
    """The greatest float not above ``raw_max + 1/2``: a scaled value below it rounds to
    ``raw_max`` or less."""
    exact = Fraction(raw_max) + Fraction(1, 2)
    x = float(exact)
    while Fraction(x) > exact:
        x = math.nextafter(x, -math.inf)
    return x


def _slots(message: Message, fields: list[_Field]) -> dict[str, _Slot] | None:
    """Every signal's place, or None if the message is not for a packer: big-endian, float,
    multiplexed or overlapping signals, or a special value that does not fit its field."""
    slots, used = {}, 0
    for s in message.signals:
        slot = _Slot(s.name, s.start, s.length, s.is_signed)
        bits = slot.mask << slot.start
        plain = s.byte_order == "little_endian" and not (s.is_float or s.is_multiplexer)
        if not plain or s.multiplexer_ids or bits & used or bits >> 8 * message.length:
            return None
        used |= bits
        slots[s.name] = slot
    for field in fields:
        slot = slots[field.name]
        for special in (field.not_available, field.out_of_range):
            if special is not None and not _bit_min(slot) <= special <= _bit_max(slot):
                return None
    return slots


def _reserved(signal: Signal) -> bool:
    return signal.name.startswith(RESERVED_PREFIX)
