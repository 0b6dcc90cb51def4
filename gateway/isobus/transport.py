"""J1939-21 / ISO 11783-3 broadcast transport (BAM) receive, as a pure reassembler.

A parameter group of 9 to 1785 bytes is broadcast as a TP.CM (PGN 60416) with control byte 32
(BAM, to global): its size, its number of packets and its PGN; then TP.DT (PGN 60160) packets
1, 2, ... of 7 bytes each from the same source (the last one padded). navgw needs it for the
Commanded Address (PGN 65240, 9 bytes).

Per J1939-21, a receiver drops a message whose next packet comes more than T1 = 750 ms after
the last (a dead sender leaves no half message behind), and a new announce from a source
replaces the message that source had not finished. Here a packet out of sequence drops the
message too (a lost packet would else shift the payload). One message per source at a time,
as J1939-21 allows one BAM per sender. The clock is the caller's ``now``: an unfinished
message is dropped when its source's next frame comes too late.

Destination-specific transfers (RTS/CTS, to one node) are not taken: no PGN that navgw reacts
to comes that way. Malformed frames (short, a size out of range, a packet count that does not
match the size) are counted and logged at a limited rate, never raised.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

import cantools

import dbc
from dbc.fast_decode import LittleEndianDecoder
from drivers.log_limit import LogLimiter
from gateway.isobus.j1939 import GLOBAL_ADDRESS, FrameId, Pgn

log = logging.getLogger(__name__)

T1_S = 0.75  # J1939-21: most time between two packets of one message
BAM_CONTROL = 32
PACKET_BYTES = 7
MIN_SIZE = 9  # shorter groups travel in one frame
MAX_SIZE = 1785  # 255 packets of 7 bytes
FRAME_BYTES = 8


@dataclass(frozen=True, slots=True)
class BamMessage:
    """A reassembled broadcast parameter group."""

    pgn: int
    source: int
    data: bytes


@dataclass(slots=True)
class _Session:
    pgn: int
    size: int
    packets: int
    last_t: float
    data: bytearray = field(default_factory=bytearray)

    @property
    def next_packet(self) -> int:
        return len(self.data) // PACKET_BYTES + 1


@dataclass
class TransportStats:
    """Counts of what the reassembler saw."""

    completed: int = 0
    dropped: int = 0  # unfinished messages: timed out, replaced, or a packet out of sequence
    malformed: int = 0  # frames that cannot be read: skipped


class BamReceiver:
    """Feed it every TP.CM and TP.DT frame (not our echo); it returns each complete BAM."""

    def __init__(self, database: cantools.database.can.Database | None = None) -> None:
        db = database or dbc.load(dbc.OUTPUT_DBC)
        self._cm = LittleEndianDecoder(db.get_message_by_name("TP_CM"))
        self._dt = LittleEndianDecoder(db.get_message_by_name("TP_DT"))
        self._sessions: dict[int, _Session] = {}  # source address: message being received
        self._log = LogLimiter(log)
        self.stats = TransportStats()

    def on_frame(self, frame_id: FrameId, data: bytes, now: float) -> BamMessage | None:
        """Take one TP.CM or TP.DT frame; a complete message when this packet ends one."""
        if frame_id.destination != GLOBAL_ADDRESS:
            return None  # connection mode, to one node: not taken (see the module docstring)
        if len(data) < FRAME_BYTES:
            self._malformed(frame_id, now, f"{len(data)} bytes, expected {FRAME_BYTES}")
            return None
        if frame_id.pgn == Pgn.TP_CONNECTION_MANAGEMENT:
            self._announce(frame_id, data, now)
            return None
        if frame_id.pgn == Pgn.TP_DATA_TRANSFER:
            return self._packet(frame_id.source, data, now)
        return None

    def _announce(self, frame_id: FrameId, data: bytes, now: float) -> None:
        cm = self._cm.decode(data[:FRAME_BYTES])
        if cm["CONTROL"] != BAM_CONTROL:
            return  # an abort, an end of message or a CTS of another node's transfer
        size, packets = int(cm["MESSAGE_SIZE"]), int(cm["PACKETS"])
        if not MIN_SIZE <= size <= MAX_SIZE or packets != -(-size // PACKET_BYTES):
            self._malformed(
                frame_id, now,
                f"BAM of {size} bytes in {packets} packets, expected {MIN_SIZE}-{MAX_SIZE} "
                f"bytes in ceil(size / {PACKET_BYTES}) packets",
            )  # fmt: skip
            return
        source = frame_id.source
        if self._sessions.pop(source, None) is not None:
            self.stats.dropped += 1  # J1939-21: a new announce replaces the unfinished one
        self._sessions[source] = _Session(int(cm["PGN"]), size, packets, now)

    def _packet(self, source: int, data: bytes, now: float) -> BamMessage | None:
        session = self._sessions.get(source)
        if session is None:
            return None  # no announce seen (or already dropped): nothing to add it to
        dt = self._dt.decode(data[:FRAME_BYTES])
        late = now - session.last_t > T1_S
        if late or dt["SEQUENCE_NUMBER"] != session.next_packet:
            del self._sessions[source]
            self.stats.dropped += 1
            why = (
                f"{now - session.last_t:.3f} s after the last packet (T1 {T1_S} s)"
                if late
                else f"packet {dt['SEQUENCE_NUMBER']} where {session.next_packet} was due"
            )
            self._log.warning(
                now, f"transport: BAM of PGN {session.pgn} from 0x{source:02X} dropped: {why}",
                ("dropped", source),
            )  # fmt: skip
            return None
        session.data += data[1:FRAME_BYTES]
        session.last_t = now
        if session.next_packet <= session.packets:
            return None
        del self._sessions[source]
        self.stats.completed += 1
        return BamMessage(session.pgn, source, bytes(session.data[: session.size]))

    def _malformed(self, frame_id: FrameId, now: float, problem: str) -> None:
        self.stats.malformed += 1
        self._log.warning(
            now, f"transport: PGN {frame_id.pgn} from 0x{frame_id.source:02X} skipped: {problem}",
            ("malformed", frame_id.pgn),
        )  # fmt: skip
