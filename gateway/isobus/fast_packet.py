"""NMEA 2000 fast-packet fragmentation (payloads of 9 to 223 bytes in 8-byte frames).

Frame 0: ``seq << 5 | 0``, the payload length, then 6 payload bytes; frame n: ``seq << 5 | n``
and 7 payload bytes; the last frame is padded with 0xFF. ``seq`` is a 3-bit counter kept per
PGN and source address, so that a receiver can tell consecutive packets apart.
"""

from __future__ import annotations

FIRST_FRAME_BYTES = 6
NEXT_FRAME_BYTES = 7
MAX_PAYLOAD_BYTES = FIRST_FRAME_BYTES + 31 * NEXT_FRAME_BYTES  # 5-bit frame counter: 223
PAD = 0xFF
_PADDING = bytes([PAD]) * NEXT_FRAME_BYTES  # enough for any last frame
#: The first byte of frame ``n`` (1-31) of sequence ``seq``: ``_HEADER[seq][n]``.
_HEADER = tuple(tuple(bytes([seq << 5 | n]) for n in range(32)) for seq in range(8))


def frame_count(payload_length: int) -> int:
    """Number of frames a payload of ``payload_length`` bytes takes."""
    extra = max(0, payload_length - FIRST_FRAME_BYTES)
    return 1 + -(-extra // NEXT_FRAME_BYTES)


class FastPacketFragmenter:
    """Splits payloads into fast-packet frames, one sequence counter per (PGN, source)."""

    def __init__(self) -> None:
        self._seq: dict[tuple[int, int], int] = {}

    def fragment(self, pgn: int, source: int, payload: bytes) -> list[bytes]:
        """The 8-byte data fields of the frames carrying ``payload``; advances the counter."""
        if not 0 < len(payload) <= MAX_PAYLOAD_BYTES:
            raise ValueError(
                f"fast-packet payload of PGN {pgn} is {len(payload)} bytes, "
                f"expected 1-{MAX_PAYLOAD_BYTES}"
            )
        key = (pgn, source)
        seq = self._seq.get(key, 0)
        self._seq[key] = (seq + 1) & 0x7
        padded = payload + _PADDING  # every slice below is then 8 bytes with its header
        header = _HEADER[seq]
        frames = [bytes((seq << 5, len(payload))) + padded[:FIRST_FRAME_BYTES]]
        frames += [
            header[index] + padded[start : start + NEXT_FRAME_BYTES]
            for index, start in enumerate(
                range(FIRST_FRAME_BYTES, len(payload), NEXT_FRAME_BYTES), start=1
            )
        ]
        return frames
