"""ISO 11783-5 / J1939-81 address claim as a pure state machine (no I/O, no clock).

The service loop drives it with received frames and its own notion of time, and sends what
it returns::

    claimer = AddressClaimer(Name(identity_number=serial))
    send(claimer.start(now))
    for each received frame but our echo:  send(claimer.on_frame(frame, now))
    periodically:                          send(claimer.poll(now))
    output frames only while claimer.claimed, with source address claimer.address

Start-up: request for PGN 60928 (from 254 to 255), a random 0-153 ms wait (0.6 ms times a
random byte, as AgIsoStack++ does), claim of the preferred address, 250 ms contention, then
claimed. A competing claim for our address is won by the lower NAME: if ours is lower we
re-send our claim; if not we claim the lowest free address of the self-configurable range
128-247 (addresses claimed by others are tracked), or send cannot-claim from 254 and stop.
A Commanded Address (PGN 65240, reassembled by the caller) for our NAME moves us: we claim
the commanded address (ISO 11783-5), unless a node with a lower NAME holds it or it is
reserved (the claim could only lose, and send us to 128-247), and are silent for the 250 ms
of contention, as after any claim. After a move, nothing is sent from the old address: every
frame takes its source from :attr:`AddressClaimer.address` when it is built.
Addresses given as ``reserved`` (the IMU bridge's, which sends on the same bus without
claiming) are never taken. Requests for 60928 (global or to our address) are answered. Every
change of address is logged.

The caller drops the echo of our own frames before they reach :meth:`AddressClaimer.on_frame`
(the service's :class:`~gateway.service.bus_links.EchoFilter`; can-j1939 floods the bus by
treating its
echo as a contender). So a claim with our NAME that arrives is another node with the same
NAME: a cloned unit (two gateways with one identity number), which ISO 11783-5 does not
allow. A frame from our claimed address that is not a claim is another node sending from it:
a clone or a spoofer (not counted within 250 ms of our defending the address: a contender for
an address below 128 may send at once, until it has read our claim). Both are counted
(``name_conflicts``, ``spoofed_frames``), logged at most once per :data:`CONFLICT_LOG_S` each,
and make :meth:`AddressClaimer.conflict` true for :data:`CONFLICT_HOLD_S` after the last one.
We keep our address: equal NAMEs have no winner, and moving would not stop the other node
sending as us. The fusion core sends NAVGW_STATUS DEGRADED meanwhile (a controller cannot
tell our frames from the other's).
"""

from __future__ import annotations

import logging
import math
import random
from collections.abc import Collection
from dataclasses import dataclass
from enum import Enum, IntEnum

import can
import cantools

import dbc
from gateway.isobus.frame_codec import FrameCodec
from gateway.isobus.j1939 import (
    DEFAULT_MANUFACTURER_CODE,
    DEFAULT_SOURCE_ADDRESS,
    GLOBAL_ADDRESS,
    NETWORK_MANAGEMENT_PRIORITY,
    NULL_ADDRESS,
    FrameId,
    IndustryGroup,
    Pgn,
    can_id,
)

log = logging.getLogger(__name__)

SELF_CONFIGURABLE_ADDRESSES = range(128, 248)
CONTENTION_S = 0.25
DELAY_STEP_S = 0.0006  # random start-up wait: 0-255 steps, 0-153 ms
_PGN_BYTES = 3  # a requested PGN is 3 bytes, little-endian
CONFLICT_HOLD_S = 10.0  # conflict() stays true this long after the last NAME conflict or spoof
CONFLICT_LOG_S = 10.0  # at most one warning per kind of conflict this often
RECLAIM_INTERVAL_S = 1.0  # an address violation is answered with our claim this often at most


class DeviceClass(IntEnum):
    """NMEA 2000 device class (the NAME's vehicle system field; canboat DEVICE_CLASS)."""

    NAVIGATION = 60


class NameFunction(IntEnum):
    """NAME function codes: ISO 11783-1 / J1939 global ones (0-127) and the NMEA 2000 ones
    of class Navigation (128-255, canboat DEVICE_FUNCTION).

    navgw sends :attr:`OWNSHIP_POSITION_GNSS` in class Navigation. The global 23 (vehicle
    navigation) is right for J1939 but canboat and the ``nmea2000`` package read the function
    through the class and named class 0 / function 23 "Reserved". Of class 60's functions,
    145 "Ownship Position (GNSS)" is what navgw replaces on the bus (a GNSS receiver: its
    positions are what most consumers select it for, and displays list position sources by
    it); 140 "Ownship Attitude" would hide it from those lists, and 175 "Integrated Navigation
    System" from both. ``[isobus] device_function/device_class`` set another pair (e.g. 23/0
    on a bus that only ISO 11783 tools read).
    """

    OWNSHIP_POSITION_GNSS = 145  # class 60


class ClaimState(Enum):
    """Where the claim procedure is."""

    IDLE = "idle"  # start() not called yet
    WAITING = "waiting"  # request sent, random wait before the first claim
    CLAIMING = "claiming"  # claim sent, 250 ms contention running
    CLAIMED = "claimed"  # address held: output may be sent
    FAILED = "failed"  # no address free: cannot-claim sent, silent


@dataclass(frozen=True, slots=True)
class Name:
    """The 64-bit ISO 11783 NAME; its bit layout is the DBC message ADDRESS_CLAIM."""

    identity_number: int  # 21 bits, unique per unit (serial number)
    manufacturer_code: int = DEFAULT_MANUFACTURER_CODE  # 11 bits
    ecu_instance: int = 0  # 3 bits
    function_instance: int = 0  # 5 bits
    function: int = NameFunction.OWNSHIP_POSITION_GNSS  # 8 bits
    vehicle_system: int = DeviceClass.NAVIGATION  # 7 bits, NMEA 2000 device class
    vehicle_system_instance: int = 0  # 4 bits
    industry_group: IndustryGroup = IndustryGroup.AGRICULTURE
    arbitrary_address_capable: bool = True

    def payload(self, database: cantools.database.can.Database | None = None) -> bytes:
        """The 8 data bytes of an address claim (raises EncodeError if a field overflows)."""
        message = (database or dbc.load(dbc.OUTPUT_DBC)).get_message_by_name("ADDRESS_CLAIM")
        return FrameCodec(message).encode(
            {
                "IDENTITY_NUMBER": self.identity_number,
                "MANUFACTURER_CODE": self.manufacturer_code,
                "ECU_INSTANCE": self.ecu_instance,
                "FUNCTION_INSTANCE": self.function_instance,
                "FUNCTION": self.function,
                "SPARE": 0,
                "VEHICLE_SYSTEM": self.vehicle_system,
                "VEHICLE_SYSTEM_INSTANCE": self.vehicle_system_instance,
                "INDUSTRY_GROUP": self.industry_group,
                "ARBITRARY_ADDRESS_CAPABLE": self.arbitrary_address_capable,
            }
        )

    def value(self) -> int:
        """The NAME as the 64-bit number that decides contention (lower wins)."""
        return int.from_bytes(self.payload(), "little")


class AddressClaimer:
    """Claims and defends one source address; returns the frames to send."""

    def __init__(
        self,
        name: Name,
        preferred_address: int = DEFAULT_SOURCE_ADDRESS,
        rng: random.Random | None = None,
        reserved: Collection[int] = (),
    ) -> None:
        if not 0 <= preferred_address < NULL_ADDRESS:
            raise ValueError(f"preferred address {preferred_address} is not 0-253")
        self._name_bytes = name.payload()
        self._name = int.from_bytes(self._name_bytes, "little")
        self._arbitrary = name.arbitrary_address_capable
        self._preferred = preferred_address
        self._rng = rng or random.Random()
        self._others: dict[int, int] = {}  # address -> NAME of the node holding it
        self._reserved = frozenset(reserved)  # used on the bus by nodes that do not claim
        self._deadline = 0.0
        #: :meth:`poll` has nothing to do before this time (the deadline while waiting or
        #: claiming, else never): a caller per IMU sample compares instead of calling.
        self.timer_t = math.inf
        self._defended_until = -math.inf  # a contender we beat may send until it reads our claim
        self._conflict_at = -math.inf  # time of the last NAME conflict or spoofed frame
        self._reclaimed_at = -math.inf  # time of the last claim answering an address violation
        self._warned_at: dict[str, float] = {}  # kind of conflict -> time of its last warning
        self.state = ClaimState.IDLE
        self.address: int | None = None  # held or being claimed
        self.name_conflicts = 0  # claims with our NAME from another node
        self.spoofed_frames = 0  # frames from our claimed address that we did not send

    @property
    def claimed(self) -> bool:
        """True while the address is held and output may be sent from it."""
        return self.state is ClaimState.CLAIMED

    @property
    def name(self) -> int:
        """Our NAME as a 64-bit number."""
        return self._name

    def conflict(self, now: float) -> bool:
        """True within CONFLICT_HOLD_S of the last NAME conflict or spoofed frame: frames
        with our address may then not be ours."""
        return now - self._conflict_at < CONFLICT_HOLD_S

    def start(self, now: float) -> list[can.Message]:
        """Ask every node for its claim, then wait a random 0-153 ms before claiming."""
        self.state = ClaimState.WAITING
        self._deadline = self.timer_t = now + self._rng.randrange(256) * DELAY_STEP_S
        request = int(Pgn.ADDRESS_CLAIM).to_bytes(_PGN_BYTES, "little")
        return [_message(Pgn.ISO_REQUEST, NULL_ADDRESS, request, now)]

    def poll(self, now: float) -> list[can.Message]:
        """Advance the timers: send the first claim, or end the contention period."""
        if self.state is ClaimState.WAITING and now >= self._deadline:
            held_by = self._others.get(self._preferred)
            if self._preferred not in self._reserved and (held_by is None or held_by > self._name):
                return self._claim(self._preferred, now)
            return self._claim_free_or_give_up(self._preferred, now)
        if self.state is ClaimState.CLAIMING and now >= self._deadline:
            self.state = ClaimState.CLAIMED
            self.timer_t = math.inf
        return []

    def on_frame(self, msg: can.Message, now: float) -> list[can.Message]:
        """React to a received frame: track claims, defend our address, answer requests."""
        if not msg.is_extended_id:
            return []
        frame_id = FrameId.parse(msg.arbitration_id)
        if frame_id.pgn == Pgn.ADDRESS_CLAIM and len(msg.data) >= 8:
            return self._on_claim(frame_id.source, int.from_bytes(msg.data[:8], "little"), now)
        out: list[can.Message] = []
        if frame_id.source == self.address and self.claimed and now >= self._defended_until:
            out = self._on_spoofed(frame_id.pgn, now)
        if (
            frame_id.pgn == Pgn.ISO_REQUEST
            and len(msg.data) >= _PGN_BYTES
            and int.from_bytes(msg.data[:_PGN_BYTES], "little") == Pgn.ADDRESS_CLAIM
            and frame_id.destination in (GLOBAL_ADDRESS, self.address)
        ):
            return out + self._answer_request(now)
        return out

    def command(self, address: int, commander: int, now: float) -> list[can.Message]:
        """A Commanded Address for our NAME from ``commander``: claim ``address`` (see the
        module docstring); the claim, or nothing when the command is refused."""
        if self.state not in (ClaimState.CLAIMING, ClaimState.CLAIMED, ClaimState.FAILED):
            log.warning("address claim: commanded address before our claim ignored")
            return []
        held_by = self._others.get(address)
        refusal = None
        if not 0 <= address < NULL_ADDRESS:
            refusal = "not an address a node can claim"
        elif address in self._reserved:
            refusal = "reserved (used on the bus without a claim)"
        elif held_by is not None and held_by < self._name:
            refusal = f"held by NAME 0x{held_by:016X}, lower than ours"
        if refusal is not None:
            log.warning(
                "address claim: %s commands us to 0x%02X: %s; keeping %s",
                _address_text(commander), address, refusal, _address_text(self.address),
            )  # fmt: skip
            return []
        if address == self.address:
            return [self._claim_message(address, now)]
        log.warning(
            "address claim: %s commands us from %s to 0x%02X; claiming it",
            _address_text(commander), _address_text(self.address), address,
        )  # fmt: skip
        return self._claim(address, now)

    def _on_claim(self, source: int, name: int, now: float) -> list[can.Message]:
        if name == self._name:
            self._on_name_conflict(source, now)
            return []
        self._others = {a: n for a, n in self._others.items() if n != name}
        if source == NULL_ADDRESS:
            return []  # someone else's cannot-claim
        self._others[source] = name
        if source != self.address or self.state not in (ClaimState.CLAIMING, ClaimState.CLAIMED):
            return []
        if self._name < name:
            self._defended_until = now + CONTENTION_S
            return [self._claim_message(source, now)]  # we win: defend
        return self._claim_free_or_give_up(source, now)

    def _on_name_conflict(self, source: int, now: float) -> None:
        """Another node claims with our NAME: count, warn, mark the conflict."""
        self.name_conflicts += 1
        self._mark_conflict(
            "name", now,
            "address claim: another node claims from %s with our NAME 0x%016X: two units with "
            "the same NAME on the bus (a cloned unit); give each a unique [isobus] "
            "identity_number. Keeping %s; NAVGW_STATUS DEGRADED until %g s after the last "
            "conflict (%d in all)",
            _address_text(source), self._name, _address_text(self.address), CONFLICT_HOLD_S,
            self.name_conflicts,
        )  # fmt: skip

    def _on_spoofed(self, pgn: int, now: float) -> list[can.Message]:
        """A frame from our address that we did not send: count, warn, mark the conflict, and
        claim the address again (ISO 11783-5: an address violation is answered with an
        address claim), at most once per :data:`RECLAIM_INTERVAL_S` against a flood."""
        self.spoofed_frames += 1
        self._mark_conflict(
            "spoof", now,
            "address claim: a frame of PGN %d from our address %s that we did not send: "
            "another node sends as us (a cloned unit or a spoofer); NAVGW_STATUS DEGRADED "
            "until %g s after the last one (%d in all)",
            pgn, _address_text(self.address), CONFLICT_HOLD_S, self.spoofed_frames,
        )  # fmt: skip
        if now - self._reclaimed_at < RECLAIM_INTERVAL_S or self.address is None:
            return []
        self._reclaimed_at = now
        return [self._claim_message(self.address, now)]

    def _mark_conflict(self, kind: str, now: float, text: str, *args: object) -> None:
        """Start the hold of conflict(); warn at most once per CONFLICT_LOG_S per kind."""
        self._conflict_at = now
        if now - self._warned_at.get(kind, -math.inf) >= CONFLICT_LOG_S:
            self._warned_at[kind] = now
            log.warning(text, *args)

    def _answer_request(self, now: float) -> list[can.Message]:
        if self.state in (ClaimState.CLAIMING, ClaimState.CLAIMED) and self.address is not None:
            return [self._claim_message(self.address, now)]
        if self.state is ClaimState.FAILED:
            return [self._claim_message(NULL_ADDRESS, now)]
        return []

    def _claim_free_or_give_up(self, wanted: int, now: float) -> list[can.Message]:
        """Claim the first free self-configurable address instead of ``wanted`` (held by a
        lower NAME, or reserved), or send cannot-claim when none is free."""
        taken = self._others.keys() | self._reserved
        free = [a for a in SELF_CONFIGURABLE_ADDRESSES if a not in taken]
        if self._arbitrary and free:
            if self.address is not None:  # a first claim moves on quietly
                held_by = self._others.get(wanted)
                log.warning(
                    "address claim: 0x%02X %s; claiming 0x%02X",
                    wanted,
                    "reserved (used on the bus without a claim)" if held_by is None
                    else f"held by NAME 0x{held_by:016X} (lower than ours, 0x{self._name:016X})",
                    free[0],
                )  # fmt: skip
            return self._claim(free[0], now)
        log.warning(
            "address claim: no address free in %d-%d (in use: %s); sending cannot-claim and "
            "staying silent",
            SELF_CONFIGURABLE_ADDRESSES.start, SELF_CONFIGURABLE_ADDRESSES.stop - 1,
            ", ".join(f"0x{a:02X}" for a in sorted(taken)),
        )  # fmt: skip
        self.state = ClaimState.FAILED
        self.timer_t = math.inf
        self.address = None
        return [self._claim_message(NULL_ADDRESS, now)]  # cannot claim

    def _claim(self, address: int, now: float) -> list[can.Message]:
        self.state = ClaimState.CLAIMING
        self.address = address
        self._deadline = self.timer_t = now + CONTENTION_S
        return [self._claim_message(address, now)]

    def _claim_message(self, source: int, now: float) -> can.Message:
        return _message(Pgn.ADDRESS_CLAIM, source, self._name_bytes, now)


def _address_text(address: int | None) -> str:
    """``0x1C``, or what 254 and None mean."""
    if address == NULL_ADDRESS:
        return "254 (cannot claim)"
    return "no address" if address is None else f"0x{address:02X}"


def _message(pgn: Pgn, source: int, data: bytes, now: float) -> can.Message:
    """A network-management frame to the global address."""
    return can.Message(
        timestamp=now,
        arbitration_id=can_id(pgn, source, NETWORK_MANAGEMENT_PRIORITY, GLOBAL_ADDRESS),
        is_extended_id=True,
        data=data,
    )
