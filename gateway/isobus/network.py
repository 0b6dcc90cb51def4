"""Network management beyond the address claim, pure (no I/O, no clock: fed ``now``).

The fusion core hands it every ISOBUS frame that is not our echo, after the
:class:`~gateway.isobus.address_claim.AddressClaimer` has seen it, and asks it for the
heartbeat when :attr:`NetworkManager.next_heartbeat_t` has come.

Requests (PGN 59904) are read when sent to the global address (255) or to the address we
hold (destination-specific); nothing is answered before the claim completes, nor while we
move (SPEC 4: nothing but claims before the address is held), and every answer comes from
the address held now. By requested PGN:

- 126996 Product Information, 126998 Configuration Information, 126464 PGN List, 126993
  Heartbeat: sent at once. 126464 is PDU1: it goes to the requester when the request was
  addressed to us (to global if the requester has no address), else to global.
- 60928: the address claim answers (it also does before the claim).
- A PGN the scheduler sends periodically: no answer of its own; its next periodic frame, at
  most one period later (1 s for the slowest default), is the answer. NAK would be wrong (we
  do send it), and J1939-21 keeps ACK for commands; AgIsoStack++ answers a request only
  through a handler registered for that PGN, and NAKs the rest, which would NAK these. An
  extra frame out of the grid would also break the fixed phase of the scheduler's output.
- Any other PGN: an ISO Acknowledgement (59392) NAK, to global, naming the requester and the
  PGN (J1939-21), when the request was addressed to us; a global request for it is ignored
  (J1939-21: never a NAK to a global request; every node would answer).

Heartbeat (126993): every :data:`~gateway.isobus.device_info.HEARTBEAT_INTERVAL_S` from the
claim on, the first as soon as the claim completes; equipment status FAULT while the caller
says so. The caller compares the time with :attr:`NetworkManager.next_heartbeat_t` (one
float comparison per IMU sample) and calls :meth:`NetworkManager.heartbeat` when it has
come.

Commanded Address (65240, 9 bytes, by BAM through :class:`~gateway.isobus.transport.
BamReceiver`): when the NAME in it is ours, the claimer claims the new address.

Malformed frames (a request shorter than 3 bytes, a commanded address shorter than 9, bad
transport frames) are counted in :attr:`NetworkManager.malformed` (and the transport's own
stats) and logged at a limited rate; none raises.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Collection

import can
import cantools

import dbc
from dbc.fast_decode import LittleEndianDecoder
from drivers.log_limit import LogLimiter
from gateway.isobus.address_claim import AddressClaimer
from gateway.isobus.device_info import (
    HEARTBEAT_INTERVAL_S,
    AckControl,
    DeviceInfoEncoder,
    PgnListFunction,
    ProductInfo,
)
from gateway.isobus.j1939 import GLOBAL_ADDRESS, NULL_ADDRESS, FrameId, Pgn
from gateway.isobus.transport import BamMessage, BamReceiver

log = logging.getLogger(__name__)

#: Network-management PGNs navgw sends (its own request for 60928 at start-up included).
NETWORK_TRANSMIT_PGNS = (
    Pgn.ISO_ACKNOWLEDGEMENT,
    Pgn.ISO_REQUEST,
    Pgn.ADDRESS_CLAIM,
    Pgn.PGN_LIST,
    Pgn.HEARTBEAT,
    Pgn.PRODUCT_INFORMATION,
    Pgn.CONFIGURATION_INFORMATION,
)
#: PGNs navgw reacts to (the transport PGNs carry the commanded address).
RECEIVE_PGNS = (
    Pgn.ISO_REQUEST,
    Pgn.TP_DATA_TRANSFER,
    Pgn.TP_CONNECTION_MANAGEMENT,
    Pgn.ADDRESS_CLAIM,
    Pgn.COMMANDED_ADDRESS,
)
#: While the address is not held, a due heartbeat is looked at again this much later (the
#: claim takes 250 ms).
UNCLAIMED_RECHECK_S = 0.05
_REQUEST_BYTES = 3


class NetworkManager:
    """Answers requests, sends the heartbeat, and takes commanded addresses for the claimer."""

    def __init__(
        self,
        claimer: AddressClaimer,
        product: ProductInfo,
        periodic: Collection[int],
        database: cantools.database.can.Database | None = None,
    ) -> None:
        self._claimer = claimer
        self._periodic = frozenset(int(p) for p in periodic)
        self._encoder = DeviceInfoEncoder(product, frames_db=database)
        self._transport = BamReceiver(database)
        self._request = LittleEndianDecoder(
            (database or dbc.load(dbc.OUTPUT_DBC)).get_message_by_name("ISO_REQUEST")
        )
        self._commanded = LittleEndianDecoder(
            dbc.load(dbc.OUTPUT_PAYLOADS_DBC).get_message_by_name("COMMANDED_ADDRESS")
        )
        self.transmit_pgns = tuple(sorted({*NETWORK_TRANSMIT_PGNS, *self._periodic}))
        self.receive_pgns = tuple(sorted(RECEIVE_PGNS))
        self.next_heartbeat_t = -math.inf  # the first one as soon as the claim completes
        self._heartbeats = 0
        self._fault = False  # the equipment status the caller last gave
        self._log = LogLimiter(log)
        self.malformed = 0  # requests and commanded addresses too short to read
        self.naks = 0

    @property
    def transport(self) -> BamReceiver:
        """The BAM reassembler (its stats count the transport's malformed frames)."""
        return self._transport

    def on_frame(self, msg: can.Message, now: float) -> list[can.Message]:
        """React to a received frame (not our echo): the answers to send now."""
        if not msg.is_extended_id:
            return []
        frame_id = FrameId.parse(msg.arbitration_id)
        pgn = frame_id.pgn
        if pgn == Pgn.ISO_REQUEST:
            return self._on_request(frame_id, bytes(msg.data), now)
        if pgn in (Pgn.TP_CONNECTION_MANAGEMENT, Pgn.TP_DATA_TRANSFER):
            message = self._transport.on_frame(frame_id, bytes(msg.data), now)
            if message is not None and message.pgn == Pgn.COMMANDED_ADDRESS:
                return self._on_commanded_address(message, now)
        return []

    def heartbeat(self, now: float, fault: bool) -> list[can.Message]:
        """The heartbeat due at :attr:`next_heartbeat_t` (call when ``now`` has reached it)."""
        self._fault = fault
        address = self._claimer.address
        if not self._claimer.claimed or address is None:
            self.next_heartbeat_t = now + UNCLAIMED_RECHECK_S
            return []
        due = self.next_heartbeat_t
        # on the 60 s grid from the first one; after a pause of the caller, anew from now
        late = not now - due < HEARTBEAT_INTERVAL_S
        self.next_heartbeat_t = (now if late else due) + HEARTBEAT_INTERVAL_S
        return self._heartbeat(address, now)

    def _heartbeat(self, source: int, now: float) -> list[can.Message]:
        frames = self._encoder.heartbeat(self._heartbeats, self._fault, source, now)
        self._heartbeats += 1
        return frames

    def _on_request(self, frame_id: FrameId, data: bytes, now: float) -> list[can.Message]:
        address = self._claimer.address
        if not self._claimer.claimed or address is None:
            return []
        addressed = frame_id.destination == address
        if not (addressed or frame_id.destination == GLOBAL_ADDRESS):
            return []  # for another node
        if len(data) < _REQUEST_BYTES:
            self.malformed += 1
            self._log.warning(
                now, f"network: request from 0x{frame_id.source:02X} of {len(data)} bytes "
                f"skipped, expected {_REQUEST_BYTES}", "request",
            )  # fmt: skip
            return []
        requested = int(self._request.decode(data[:_REQUEST_BYTES])["REQUESTED_PGN"])
        requester = frame_id.source
        reply_to = requester if addressed and requester != NULL_ADDRESS else GLOBAL_ADDRESS
        if requested == Pgn.PRODUCT_INFORMATION:
            return self._encoder.product_information(address, now)
        if requested == Pgn.CONFIGURATION_INFORMATION:
            return self._encoder.configuration_information(address, now)
        if requested == Pgn.PGN_LIST:
            return self._pgn_lists(address, reply_to, now)
        if requested == Pgn.HEARTBEAT:
            return self._heartbeat(address, now)
        if requested == Pgn.ADDRESS_CLAIM or requested in self._periodic or not addressed:
            return []  # the claimer answers; the periodic frame answers; no NAK to global
        self.naks += 1
        return self._encoder.acknowledgement(AckControl.NAK, requested, requester, address, now)

    def _pgn_lists(self, source: int, destination: int, now: float) -> list[can.Message]:
        """126464 twice: what we transmit, then what we receive."""
        encode = self._encoder.pgn_list
        return [
            *encode(PgnListFunction.TRANSMIT, self.transmit_pgns, source, now, destination),
            *encode(PgnListFunction.RECEIVE, self.receive_pgns, source, now, destination),
        ]

    def _on_commanded_address(self, message: BamMessage, now: float) -> list[can.Message]:
        if len(message.data) < self._commanded.length:
            self.malformed += 1
            self._log.warning(
                now, f"network: commanded address from 0x{message.source:02X} of "
                f"{len(message.data)} bytes skipped, expected {self._commanded.length}",
                "commanded",
            )  # fmt: skip
            return []
        fields = self._commanded.decode(message.data[: self._commanded.length])
        if fields["NAME"] != self._claimer.name:
            return []  # another node is commanded
        return self._claimer.command(int(fields["NEW_SOURCE_ADDRESS"]), message.source, now)
