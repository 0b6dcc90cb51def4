"""One generic path from physical values to frame bytes, through a DBC message.

The DBC carries everything the encoder needs: scale, offset, the valid range ``[min|max]``,
and the NMEA 2000 special values as value-table entries ``NOT_AVAILABLE`` (all ones; 0x7F..
for signed fields) and ``OUT_OF_RANGE`` (one less). Policy, applied to every signal alike:

- ``None`` (or NaN) is sent as ``NOT_AVAILABLE``: never a made-up zero.
- A value outside the valid range is sent as ``OUT_OF_RANGE`` (or ``NOT_AVAILABLE`` when the
  field has no out-of-range code, e.g. NAVGW_STATUS tilt sigma): it never wraps and is never
  clamped to a plausible-looking number.
- Signals named ``RESERVED*`` are sent as all ones and are not passed in.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

from cantools.database.can import Message, Signal

NOT_AVAILABLE = "NOT_AVAILABLE"
OUT_OF_RANGE = "OUT_OF_RANGE"
RESERVED_PREFIX = "RESERVED"

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
        raw = round(scaled)
        if self.raw_min <= raw <= self.raw_max:
            return raw
        return self._special(self.out_of_range, value)

    def _special(self, raw: int | None, value: Value) -> int:
        for candidate in (raw, self.not_available):
            if candidate is not None:
                return candidate
        raise EncodeError(f"signal {self.name} cannot carry {value!r} and has no special value")


def _bit_min(signal: Signal) -> int:
    return -(1 << (signal.length - 1)) if signal.is_signed else 0


def _bit_max(signal: Signal) -> int:
    return (1 << (signal.length - 1)) - 1 if signal.is_signed else (1 << signal.length) - 1


class FrameCodec:
    """Encodes one DBC message from a mapping of signal name to physical value."""

    def __init__(self, message: Message) -> None:
        self.message = message
        self._fields = [_Field.of(s) for s in message.signals if not _reserved(s)]
        self._reserved = {s.name: (1 << s.length) - 1 for s in message.signals if _reserved(s)}
        if any(s.is_signed for s in message.signals if _reserved(s)):
            raise EncodeError(f"{message.name}: reserved signals must be unsigned")

    @property
    def signal_names(self) -> frozenset[str]:
        """The signals ``encode`` expects (every non-reserved one)."""
        return frozenset(f.name for f in self._fields)

    def encode(self, values: Mapping[str, Value]) -> bytes:
        """The message's bytes; ``values`` must name every non-reserved signal."""
        missing = self.signal_names - values.keys()
        if missing:
            raise EncodeError(f"{self.message.name}: no value for {sorted(missing)}")
        raw = dict(self._reserved)
        raw.update({f.name: f.raw(values[f.name]) for f in self._fields})
        return bytes(self.message.encode(raw, scaling=False, strict=False))


def _reserved(signal: Signal) -> bool:
    return signal.name.startswith(RESERVED_PREFIX)
