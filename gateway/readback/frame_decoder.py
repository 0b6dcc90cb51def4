"""Any CAN frame, decoded by the output DBC: what navgw sends, network management, or not ours.

The layouts come from ``dbc/`` alone (:func:`dbc.load`): a frame matches its DBC message by
PGN, whatever its priority and source; a PDU1 frame (a request, an acknowledgement) sent to
an address the DBC does not list reads with the layout of the global one. The frames of a
fast-packet PGN (those whose id has a reassembled payload in the payloads DBC) are joined by
:class:`~gateway.readback.fast_packet_rx.FastPacketReceiver` and the payload is decoded.

Nothing here raises on a frame: one that is not in the DBC (another node's PGN, an 11-bit id,
an error frame) is counted ``unknown``; one that is but cannot be read (a wrong length, an
unknown multiplexer value, broken fast-packet framing) ``malformed``, with the reason kept.
Values are physical; a named value is its name (``"NAVIGATING"``), and the NMEA 2000 special
values ``NOT_AVAILABLE`` and ``OUT_OF_RANGE`` are ``None``: a reader never shows them as
numbers.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import can
import cantools
from cantools.database.can import Message
from cantools.database.errors import DecodeError

import dbc
from gateway.isobus.j1939 import GLOBAL_ADDRESS, PDU2_MIN_FORMAT, FrameId
from gateway.readback.fast_packet_rx import FastPacketReceiver, MalformedFrameError

#: A decoded signal: a number, the name of a named value, or None (not available).
Value = float | int | str | None
SPECIAL_VALUES = frozenset({"NOT_AVAILABLE", "OUT_OF_RANGE"})
_PS_SHIFT = 8  # the PDU specific byte (destination of a PDU1 frame) in a 29-bit id


@dataclass(frozen=True, slots=True)
class Decoded:
    """One message: the time of its (last) frame, its id's parts, DBC name and signals, and
    the bytes decoded (the frame's data, or a fast packet's payload)."""

    t: float
    frame_id: FrameId
    name: str
    signals: dict[str, Value]
    data: bytes


@dataclass
class DecodeStats:
    """What the decoder was given and what became of it."""

    frames: int = 0
    decoded: int = 0  # messages: a fast packet counts once, when complete
    unknown: int = 0
    malformed: int = 0
    last_problem: str = ""  # why the last malformed frame could not be read

    def malformed_frame(self, why: str) -> None:
        """Count one malformed frame and keep why."""
        self.malformed += 1
        self.last_problem = why


@dataclass
class OutputFrameDecoder:
    """``decode(msg)`` -> a :class:`Decoded`, or None (counted, or a fast-packet frame that
    does not end its packet)."""

    frames_db: cantools.database.can.Database = field(
        default_factory=lambda: dbc.load(dbc.OUTPUT_DBC)
    )
    payloads_db: cantools.database.can.Database = field(
        default_factory=lambda: dbc.load(dbc.OUTPUT_PAYLOADS_DBC)
    )
    stats: DecodeStats = field(default_factory=DecodeStats)
    fast_packets: FastPacketReceiver = field(default_factory=FastPacketReceiver)
    _messages: dict[int, tuple[Message, bool] | None] = field(default_factory=dict)

    def decode(self, msg: can.Message) -> Decoded | None:
        """The message ``msg`` completes, if any; never raises on the frame's content."""
        self.stats.frames += 1
        found = None
        if msg.is_extended_id and not msg.is_error_frame and not msg.is_remote_frame:
            found = self._lookup(msg.arbitration_id)
        if found is None:
            self.stats.unknown += 1
            return None
        message, fast_packet = found
        frame_id = FrameId.parse(msg.arbitration_id)
        data = bytes(msg.data)
        try:
            if fast_packet:
                payload = self.fast_packets.on_frame(frame_id.pgn, frame_id.source, data)
                if payload is None:
                    return None
                data = payload
            values = message.decode(data, decode_choices=True)
        except (DecodeError, MalformedFrameError) as exc:
            self.stats.malformed_frame(f"{message.name} from 0x{frame_id.source:02X}: {exc}")
            return None
        assert isinstance(values, dict)  # no container messages in these DBCs
        self.stats.decoded += 1
        return Decoded(float(msg.timestamp), frame_id, message.name, _physical(values), data)

    def _lookup(self, arbitration_id: int) -> tuple[Message, bool] | None:
        """The message to decode a frame of this id with, and whether it is a fast packet."""
        if arbitration_id not in self._messages:
            self._messages[arbitration_id] = self._find(arbitration_id)
        return self._messages[arbitration_id]

    def _find(self, arbitration_id: int) -> tuple[Message, bool] | None:
        candidates = [arbitration_id]
        if (arbitration_id >> 16) & 0xFF < PDU2_MIN_FORMAT:  # PDU1: try the global destination
            candidates.append(arbitration_id | GLOBAL_ADDRESS << _PS_SHIFT)
        for candidate in candidates:
            for db, fast_packet in ((self.payloads_db, True), (self.frames_db, False)):
                try:
                    return db.get_message_by_frame_id(candidate), fast_packet
                except KeyError:
                    continue
        return None


def _physical(values: Mapping[str, object]) -> dict[str, Value]:
    out: dict[str, Value] = {}
    for name, value in values.items():
        if isinstance(value, int | float):
            out[name] = value
        else:  # a NamedSignalValue
            text = str(value)
            out[name] = None if text in SPECIAL_VALUES else text
    return out
