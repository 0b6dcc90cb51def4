"""NMEA 2000 fast-packet receive: the frames of one packet joined back into its payload.

The inverse of :class:`gateway.isobus.fast_packet.FastPacketFragmenter`, with its framing
constants: frame 0 is ``seq << 5 | 0``, the payload length and 6 bytes; frame n is
``seq << 5 | n`` and 7 bytes. One packet per (PGN, source) is open at a time, as the 3-bit
sequence counter is kept per PGN and source. A frame that does not continue the open packet
(another sequence, a frame skipped) drops it: a lost frame would else shift the payload.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from gateway.isobus.fast_packet import FIRST_FRAME_BYTES, MAX_PAYLOAD_BYTES

FRAME_BYTES = 8
_COUNTER_MASK = 0x1F


class MalformedFrameError(ValueError):
    """A frame that cannot belong to any fast packet (its size, a length out of range)."""


@dataclass(slots=True)
class _Packet:
    seq: int
    length: int
    next_frame: int = 1
    data: bytearray = field(default_factory=bytearray)


@dataclass
class FastPacketStats:
    """What the reassembler saw."""

    completed: int = 0
    dropped: int = 0  # packets left unfinished: a frame lost, or a new packet began


class FastPacketReceiver:
    """Feed it the frames of fast-packet PGNs; it returns each payload when its last frame
    arrives."""

    def __init__(self) -> None:
        self._open: dict[tuple[int, int], _Packet] = {}
        self.stats = FastPacketStats()

    def on_frame(self, pgn: int, source: int, data: bytes) -> bytes | None:
        """Take one frame of ``pgn`` from ``source``; the payload when this frame ends it.

        Raises :class:`MalformedFrameError` for a frame that no packet can have.
        """
        if len(data) != FRAME_BYTES:
            raise MalformedFrameError(f"a fast-packet frame of {len(data)} bytes, expected 8")
        key = (pgn, source)
        seq, counter = data[0] >> 5, data[0] & _COUNTER_MASK
        if counter == 0:
            self._first(key, seq, data)
            return None  # a payload of more than 6 bytes needs a next frame
        packet = self._open.get(key)
        if packet is None:
            return None  # the start of this packet was not seen (or it was dropped)
        if seq != packet.seq or counter != packet.next_frame:
            del self._open[key]
            self.stats.dropped += 1
            return None
        packet.data += data[1:]
        packet.next_frame += 1
        return self._complete(key, packet)

    def _first(self, key: tuple[int, int], seq: int, data: bytes) -> None:
        if self._open.pop(key, None) is not None:
            self.stats.dropped += 1
        length = data[1]
        if not FIRST_FRAME_BYTES < length <= MAX_PAYLOAD_BYTES:  # 6 bytes need no fast packet
            raise MalformedFrameError(
                f"a fast packet of {length} bytes, expected {FIRST_FRAME_BYTES + 1}-"
                f"{MAX_PAYLOAD_BYTES}"
            )
        self._open[key] = _Packet(seq, length, data=bytearray(data[2:]))

    def _complete(self, key: tuple[int, int], packet: _Packet) -> bytes | None:
        if len(packet.data) < packet.length:
            return None
        del self._open[key]
        self.stats.completed += 1
        return bytes(packet.data[: packet.length])
