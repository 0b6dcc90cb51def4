"""Bus load of a set of periodic frames on a classical CAN bus (ISOBUS: 250 kbit/s)."""

from __future__ import annotations

from collections.abc import Mapping

from gateway.isobus.fast_packet import frame_count
from gateway.isobus.j1939 import Pgn

ISOBUS_BIT_RATE = 250_000
SINGLE_FRAME_BYTES = 8
#: Extended data frame fields subject to bit stuffing, data excluded: SOF 1, id 11, SRR 1,
#: IDE 1, id 18, RTR 1, r1 r0 2, DLC 4, CRC 15.
_STUFFED_OVERHEAD_BITS = 54
#: Not stuffed: CRC delimiter 1, ACK 2, EOF 7, intermission 3.
_FIXED_OVERHEAD_BITS = 13


def frame_bits(data_bytes: int = 8, worst_case_stuffing: bool = True) -> int:
    """Bits an extended frame occupies on the bus, with worst-case stuffing (1 per 4 bits)."""
    stuffed = _STUFFED_OVERHEAD_BITS + 8 * data_bytes
    stuff_bits = (stuffed - 1) // 4 if worst_case_stuffing else 0
    return stuffed + stuff_bits + _FIXED_OVERHEAD_BITS


def frames_per_second(rates_hz: Mapping[Pgn, float], payload_bytes: Mapping[Pgn, int]) -> float:
    """Frames per second of the given PGN rates; payloads over 8 bytes go as fast packets."""
    return sum(
        rate * (1 if payload_bytes[pgn] <= SINGLE_FRAME_BYTES else frame_count(payload_bytes[pgn]))
        for pgn, rate in rates_hz.items()
    )


def bus_load(
    rates_hz: Mapping[Pgn, float],
    payload_bytes: Mapping[Pgn, int],
    bit_rate: int = ISOBUS_BIT_RATE,
    worst_case_stuffing: bool = True,
) -> float:
    """Fraction of the bus the frames take (every N2K frame has 8 data bytes)."""
    frame = frame_bits(SINGLE_FRAME_BYTES, worst_case_stuffing)
    bits = frames_per_second(rates_hz, payload_bytes) * frame
    return bits / bit_rate
