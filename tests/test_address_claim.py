"""Address claim on python-can ``virtual`` buses: our state machine against raw nodes.

The buses echo what we send (``receive_own_messages``, as udp_multicast and socketcan's
loopback do); as in the live service, received frames go through
:class:`~gateway.service.bus_links.EchoFilter` before the claimer. Echoes are marked as ours by the
virtual bus (``is_rx`` false) or, like udp_multicast's, look received (``marks_own=False``).

AgIsoStack++'s test/address_claim_tests.cpp scenarios covered: PartneredClaim (two nodes claim
two addresses and both hold them: test_two_nodes_on_two_addresses_both_hold_them) and
CannotClaim (every address held by lower NAMEs: cannot-claim from 254, silent:
test_no_address_free_sends_cannot_claim_and_stays_silent). Of core_network_management_tests.cpp:
NewExternalControlFunction and ControlFunctionAddressChange (another node's claim is tracked,
and a node that moves frees its old address: test_a_node_that_moves_frees_its_old_address);
CommandedAddress is in test_network_management.py.
"""

import heapq
import logging
import random
from collections.abc import Iterable, Iterator
from operator import attrgetter

import can
import pytest
from nmea2000 import NMEA2000Decoder, _canboat

from drivers.samples import GnssFix, ImuSample
from gateway.config.gateway_config import GatewayConfig
from gateway.estimation.solution import Mode, Solution
from gateway.fusion.fusion_core import FusionCore
from gateway.isobus.address_claim import (
    CONFLICT_HOLD_S,
    RECLAIM_INTERVAL_S,
    AddressClaimer,
    ClaimState,
    Name,
)
from gateway.isobus.j1939 import FrameId, IndustryGroup, Pgn, can_id
from gateway.isobus.n2k_encode import LoopStatus
from gateway.isobus.output_scheduler import OutputScheduler
from gateway.service.bus_links import EchoFilter, claim_filters
from tests.kinematics import T0_S, Motion, Segment, gnss_stream, imu_stream

NAME = Name(identity_number=123456, manufacturer_code=2046, ecu_instance=1, function_instance=2)
OURS = NAME.value()
STEP_S = 0.005


def claim_frame(source: int, name: int) -> can.Message:
    return can.Message(
        arbitration_id=can_id(Pgn.ADDRESS_CLAIM, source, 6),
        is_extended_id=True,
        data=name.to_bytes(8, "little"),
    )


def request_frame(source: int, destination: int) -> can.Message:
    return can.Message(
        arbitration_id=can_id(Pgn.ISO_REQUEST, source, 6, destination),
        is_extended_id=True,
        data=int(Pgn.ADDRESS_CLAIM).to_bytes(3, "little"),
    )


def frame_from(pgn: int, source: int, data: bytes = bytes(8)) -> can.Message:
    """Any frame of ``pgn`` from ``source`` (priority 2, as our attitude)."""
    return can.Message(arbitration_id=can_id(pgn, source, 2), is_extended_id=True, data=data)


def received(bus: can.BusABC, marks_own: bool) -> Iterator[can.Message]:
    """What ``bus`` has received; with ``marks_own`` false, our echoes look received too."""
    while (msg := bus.recv(0)) is not None:
        msg.is_rx = msg.is_rx or not marks_own
        yield msg


class Node:
    """Our claimer plus the output scheduler behind a virtual bus, driven by a test clock."""

    def __init__(
        self,
        channel: str,
        seed: int = 1,
        reserved: tuple[int, ...] = (),
        marks_own: bool = True,
        name: Name = NAME,
        rates: dict[Pgn, float] | None = None,
    ) -> None:
        # receive_own_messages: the bus echoes our frames, as udp_multicast does
        self.bus = can.Bus(interface="virtual", channel=channel, receive_own_messages=True)
        self.claimer = AddressClaimer(name, rng=random.Random(seed), reserved=reserved)
        self.scheduler = OutputScheduler(rates)
        self.echo = EchoFilter()
        self.marks_own = marks_own
        self.now = 1_700_000_000.0
        self.sent: list[can.Message] = []

    def send(self, frames: Iterable[can.Message]) -> None:
        for frame in frames:
            self.bus.send(frame)
            self.echo.sent(frame, self.now)
            self.sent.append(frame)

    def start(self) -> None:
        self.send(self.claimer.start(self.now))

    def on_frame(self, msg: can.Message) -> None:
        """A received frame that is not our echo."""
        self.send(self.claimer.on_frame(msg, self.now))

    def poll(self) -> None:
        """The timers, once per step."""
        self.send(self.claimer.poll(self.now))

    def run(self, seconds: float) -> None:
        for _ in range(round(seconds / STEP_S)):
            for msg in received(self.bus, self.marks_own):
                if not self.echo.is_echo(msg, self.now):
                    self.on_frame(msg)
            self.poll()
            if self.claimer.claimed:
                assert self.claimer.address is not None
                loop = LoopStatus(source_address=self.claimer.address, address_claimed=True)
                self.send(self.scheduler.frames(Solution(t=self.now, mode=Mode.ALIGNING), loop))
            self.now += STEP_S

    def claims(self) -> list[int]:
        """Source addresses of the claims we sent, in order."""
        return [
            FrameId.parse(f.arbitration_id).source
            for f in self.sent
            if FrameId.parse(f.arbitration_id).pgn == Pgn.ADDRESS_CLAIM
        ]


class Raw:
    """A competing node that only sends and reads raw frames."""

    def __init__(self, channel: str) -> None:
        self.bus = can.Bus(interface="virtual", channel=channel)

    def received(self) -> list[can.Message]:
        frames = []
        while (msg := self.bus.recv(0)) is not None:
            frames.append(msg)
        return frames


@pytest.fixture
def buses(request: pytest.FixtureRequest) -> Iterator[tuple[Node, Raw]]:
    channel = f"claim-{request.node.name}"
    node, raw = Node(channel), Raw(channel)
    yield node, raw
    node.bus.shutdown()
    raw.bus.shutdown()


def test_name_matches_canboats_iso_name() -> None:
    expected = _canboat.iso_name(
        2046,
        123456,
        device_function=145,
        device_class=60,
        device_instance=2 << 3 | 1,
        system_instance=0,
        industry_group=IndustryGroup.AGRICULTURE,
        arbitrary_address_capable=True,
    )
    assert expected == OURS
    assert OURS >> 60 & 0x7 == 2 and OURS >> 63 == 1


def test_name_function_and_class_are_named_by_canboats_tables() -> None:
    """Class 60 Navigation, function 145 Ownship Position (GNSS): not "Reserved"."""
    claim = claim_frame(0x1C, OURS)
    fields = {f.id: f.value for f in NMEA2000Decoder().decode(claim).fields}
    assert fields["deviceClass"] == "Navigation"
    assert fields["deviceFunction"] == "Ownship Position (GNSS)"
    assert fields["industryGroup"] == "Agriculture"
    assert fields["uniqueNumber"] == 123456


def test_alone_claims_preferred_and_sends_nothing_before(buses: tuple[Node, Raw]) -> None:
    node, raw = buses
    node.start()
    node.run(0.150)
    assert not node.claimer.claimed
    assert [FrameId.parse(f.arbitration_id).pgn for f in node.sent] == [
        Pgn.ISO_REQUEST,
        Pgn.ADDRESS_CLAIM,
    ][: len(node.sent)]
    node.run(0.5)
    assert node.claimer.claimed and node.claimer.address == 0x1C
    first_request = node.sent[0]
    assert FrameId.parse(first_request.arbitration_id) == FrameId(6, Pgn.ISO_REQUEST, 254, 255)
    assert node.claims() == [0x1C]  # own echo ignored: no re-claim
    pgns = [FrameId.parse(f.arbitration_id).pgn for f in node.sent]
    assert pgns[:2] == [Pgn.ISO_REQUEST, Pgn.ADDRESS_CLAIM]
    assert Pgn.ATTITUDE in pgns[2:]
    claim_time = node.sent[1].timestamp
    assert 0.0 <= claim_time - first_request.timestamp <= 0.153 + STEP_S
    assert min(f.timestamp for f in node.sent[2:]) >= claim_time + 0.25
    assert {FrameId.parse(f.arbitration_id).source for f in node.sent[2:]} == {0x1C}
    seen = raw.received()
    assert len(seen) == len(node.sent)


def test_contention_won_by_our_lower_name(buses: tuple[Node, Raw]) -> None:
    node, raw = buses
    node.start()
    node.run(0.6)
    raw.bus.send(claim_frame(0x1C, OURS + 1))
    node.run(0.1)
    assert node.claimer.claimed and node.claimer.address == 0x1C
    assert node.claims() == [0x1C, 0x1C]  # defended once


def assert_silent_until_claimed(node: Node, claim: can.Message) -> None:
    """After ``claim``, nothing but claims for 250 ms, then output from the claimed address."""
    source = FrameId.parse(claim.arbitration_id).source
    after = node.sent[node.sent.index(claim) + 1 :]
    output = [f for f in after if FrameId.parse(f.arbitration_id).pgn != Pgn.ADDRESS_CLAIM]
    assert output, "no output after the claim"
    assert min(f.timestamp for f in output) >= claim.timestamp + 0.25
    assert {FrameId.parse(f.arbitration_id).source for f in after} == {source}


def test_contention_lost_moves_to_the_self_configurable_range(buses: tuple[Node, Raw]) -> None:
    node, raw = buses
    node.start()
    node.run(0.2)  # claim sent, contention running
    assert node.claimer.state is ClaimState.CLAIMING
    raw.bus.send(claim_frame(0x1C, OURS - 1))
    node.run(0.01)
    assert not node.claimer.claimed and node.claimer.address == 128
    node.run(0.4)
    assert node.claimer.claimed and node.claimer.address == 128
    assert node.claims() == [0x1C, 128]
    assert_silent_until_claimed(node, node.sent[2])


def test_late_joiner_with_lower_name_takes_our_address(buses: tuple[Node, Raw]) -> None:
    node, raw = buses
    node.start()
    raw.bus.send(claim_frame(128, OURS + 5))  # someone already holds 128
    node.run(0.6)
    assert node.claimer.address == 0x1C and node.claimer.claimed
    lost_at = len(node.sent)
    raw.bus.send(claim_frame(0x1C, OURS - 1))
    node.run(0.01)
    assert not node.claimer.claimed and node.claimer.address == 129
    node.run(0.3)
    assert node.claimer.claimed and node.claimer.address == 129
    assert node.claims() == [0x1C, 129]
    assert_silent_until_claimed(node, node.sent[lost_at])


def test_requests_for_the_claim_are_answered(buses: tuple[Node, Raw]) -> None:
    node, raw = buses
    node.start()
    node.run(0.6)
    raw.received()
    for destination, answered in ((255, True), (0x1C, True), (0x40, False)):
        raw.bus.send(request_frame(0x40, destination))
        node.run(0.01)
        claims = [
            f for f in raw.received() if FrameId.parse(f.arbitration_id).pgn == Pgn.ADDRESS_CLAIM
        ]
        assert len(claims) == answered
        if answered:
            assert FrameId.parse(claims[0].arbitration_id).source == 0x1C
            assert int.from_bytes(claims[0].data, "little") == OURS


def test_no_address_free_sends_cannot_claim_and_stays_silent(buses: tuple[Node, Raw]) -> None:
    node, raw = buses
    node.start()
    for address in [0x1C, *range(128, 248)]:  # everyone answers our request with a lower NAME
        raw.bus.send(claim_frame(address, OURS - 1000 + address))
    node.run(0.6)
    assert node.claimer.state is ClaimState.FAILED
    assert node.claimer.address is None and not node.claimer.claimed
    assert node.claims() == [254]  # cannot claim, never a claim of an address in use
    assert int.from_bytes(node.sent[-1].data, "little") == OURS
    raw.received()
    raw.bus.send(request_frame(0x40, 255))
    node.run(0.05)
    replies = raw.received()
    assert [FrameId.parse(f.arbitration_id).source for f in replies] == [254]
    assert len(node.sent) == 3  # request, cannot-claim, cannot-claim answer


def test_preferred_held_by_lower_name_at_start_goes_straight_to_128(
    buses: tuple[Node, Raw],
) -> None:
    node, raw = buses
    node.start()
    raw.bus.send(claim_frame(0x1C, OURS - 1))
    node.run(0.6)
    assert node.claims() == [128]
    assert node.claimer.claimed and node.claimer.address == 128


def test_two_nodes_on_two_addresses_both_hold_them(buses: tuple[Node, Raw]) -> None:
    """AgIsoStack++ PartneredClaim: another node claims 0x1D next to our 0x1C; neither moves."""
    node, raw = buses
    node.start()
    raw.bus.send(claim_frame(0x1D, OURS - 1))  # a lower NAME, but another address
    node.run(0.6)
    raw.bus.send(request_frame(0x1D, 255))  # it asks for the claims: ours comes back
    node.run(0.05)
    assert node.claimer.claimed and node.claimer.address == 0x1C
    assert node.claims() == [0x1C, 0x1C]
    claims = [
        FrameId.parse(f.arbitration_id)
        for f in raw.received()
        if FrameId.parse(f.arbitration_id).pgn == Pgn.ADDRESS_CLAIM
    ]
    assert [c.source for c in claims] == [0x1C, 0x1C]


def test_a_node_that_moves_frees_its_old_address(buses: tuple[Node, Raw]) -> None:
    """AgIsoStack++ ControlFunctionAddressChange: a node at 128 claims 130 with the same NAME;
    when we then lose 0x1C, 128 is free again and ours."""
    node, raw = buses
    node.start()
    raw.bus.send(claim_frame(128, OURS + 7))
    node.run(0.6)
    raw.bus.send(claim_frame(130, OURS + 7))  # the same node, moved
    raw.bus.send(claim_frame(0x1C, OURS - 1))
    node.run(0.4)
    assert node.claimer.claimed and node.claimer.address == 128
    assert node.claims() == [0x1C, 128]


def test_after_losing_the_address_nothing_more_comes_from_it(buses: tuple[Node, Raw]) -> None:
    """Every frame after the loss, output included, has the new address; none the old."""
    node, raw = buses
    node.start()
    node.run(0.6)
    raw.received()
    raw.bus.send(claim_frame(0x1C, OURS - 1))
    node.run(1.0)
    seen = raw.received()
    assert {FrameId.parse(f.arbitration_id).source for f in seen} == {128}
    assert sum(FrameId.parse(f.arbitration_id).pgn == Pgn.ATTITUDE for f in seen) > 30


def test_random_delay_is_seeded_and_bounded() -> None:
    delays = []
    for seed in range(50):
        claimer = AddressClaimer(NAME, rng=random.Random(seed))
        claimer.start(0.0)
        t = 0.0
        while not claimer.poll(t):
            t += 0.0001
        delays.append(t)
    assert min(delays) >= 0.0 and max(delays) <= 0.1531
    assert len(set(delays)) > 20


def test_preferred_address_and_name_fields_are_validated() -> None:
    with pytest.raises(ValueError, match="254"):
        AddressClaimer(NAME, preferred_address=254)
    with pytest.raises(ValueError, match="IDENTITY_NUMBER"):
        Name(identity_number=1 << 21).value()


def test_a_reserved_address_is_never_taken_and_every_move_is_logged(
    caplog: pytest.LogCaptureFixture,
) -> None:
    """The IMU bridge sends from 0x80 without claiming it: losing 0x1C must not move us
    there (seen: two nodes sending from 0x80, and the gateway's move not logged)."""
    node, raw = Node("claim-reserved", reserved=(0x80,)), Raw("claim-reserved")
    try:
        node.start()
        node.run(0.6)
        with caplog.at_level(logging.WARNING, logger="gateway.isobus.address_claim"):
            raw.bus.send(claim_frame(0x1C, OURS - 1))
            node.run(0.4)
        assert node.claimer.claimed and node.claimer.address == 0x81
        assert node.claims() == [0x1C, 0x81]
        lost = f"0x1C held by NAME 0x{OURS - 1:016X} (lower than ours"
        text = [r.getMessage() for r in caplog.records]
        assert [t for t in text if lost in t and t.endswith("claiming 0x81")] == text, text
        caplog.clear()
        with caplog.at_level(logging.WARNING, logger="gateway.isobus.address_claim"):
            node.start()  # the ISOBUS reopened (interface down and up): claim again
            node.run(0.6)
        assert node.claimer.claimed and node.claimer.address == 0x81
        text = [r.getMessage() for r in caplog.records]  # 0x1C is taken, not 0x81
        assert len(text) == 1 and lost in text[0] and text[0].endswith("claiming 0x81"), text
    finally:
        node.bus.shutdown()
        raw.bus.shutdown()


@pytest.mark.parametrize("marks_own", [True, False], ids=["virtual", "udp-like"])
def test_our_own_echoes_are_no_conflict(marks_own: bool) -> None:
    """On a bus that echoes, our claim and output come back: not a clone, not a spoof."""
    channel = f"claim-echo-{marks_own}"
    node, raw = Node(channel, marks_own=marks_own), Raw(channel)
    try:
        node.start()
        node.run(1.0)
        raw.bus.send(request_frame(0x40, 255))  # our answer is echoed too
        node.run(0.1)
        assert node.claimer.claimed and node.claims() == [0x1C, 0x1C]
        assert node.claimer.name_conflicts == node.claimer.spoofed_frames == 0
        assert not node.claimer.conflict(node.now)
        assert node.echo.echoes >= len(node.sent) - 10  # all but the last step's
        assert len(node.sent) > 100
    finally:
        node.bus.shutdown()
        raw.bus.shutdown()


@pytest.mark.parametrize("source", [0x1C, 0x40, 254], ids=["our-address", "other", "cannot"])
def test_a_claim_with_our_name_is_a_clone_and_we_keep_our_address(
    buses: tuple[Node, Raw], source: int, caplog: pytest.LogCaptureFixture
) -> None:
    node, raw = buses
    node.start()
    node.run(0.6)
    with caplog.at_level(logging.WARNING, logger="gateway.isobus.address_claim"):
        raw.bus.send(claim_frame(source, OURS))
        node.run(0.1)
    conflict_at = node.now - 0.1
    assert node.claimer.name_conflicts == 1 and node.claimer.spoofed_frames == 0
    assert node.claimer.claimed and node.claimer.address == 0x1C
    assert node.claims() == [0x1C]  # neither moved nor re-claimed: equal NAMEs have no winner
    assert node.claimer.conflict(node.now)
    assert not node.claimer.conflict(conflict_at + CONFLICT_HOLD_S + STEP_S)
    [text] = [r.getMessage() for r in caplog.records]
    assert f"NAME 0x{OURS:016X}" in text and "same NAME" in text and "identity_number" in text


def test_a_contender_we_beat_may_send_until_it_has_read_our_claim(buses: tuple[Node, Raw]) -> None:
    """A claim for an address below 128 may be followed by output at once (J1939-81): those
    frames, sent before our defence reached the contender, are no spoof; later ones are."""
    node, raw = buses
    node.start()
    node.run(0.6)
    raw.bus.send(claim_frame(0x1C, OURS + 1))
    raw.bus.send(frame_from(Pgn.ATTITUDE, 0x1C))
    node.run(0.2)
    assert node.claims() == [0x1C, 0x1C]  # defended
    assert node.claimer.spoofed_frames == 0 and not node.claimer.conflict(node.now)
    node.run(0.1)
    raw.bus.send(frame_from(Pgn.ATTITUDE, 0x1C))  # still sending as us: a spoofer
    node.run(0.01)
    assert node.claimer.spoofed_frames == 1 and node.claimer.conflict(node.now)


def test_frames_from_the_address_we_left_are_not_ours_to_count(buses: tuple[Node, Raw]) -> None:
    node, raw = buses
    node.start()
    node.run(0.6)
    raw.bus.send(claim_frame(0x1C, OURS - 1))
    node.run(0.4)
    assert node.claimer.claimed and node.claimer.address == 128
    raw.bus.send(frame_from(Pgn.ATTITUDE, 0x1C))  # the winner's output: its address now
    node.run(0.01)
    assert node.claimer.spoofed_frames == node.claimer.name_conflicts == 0
    raw.bus.send(frame_from(Pgn.ATTITUDE, 128))
    node.run(0.01)
    assert node.claimer.spoofed_frames == 1


# --- the fusion core: NAVGW_STATUS while a clone or a spoofer is about -----------------------

MOTION = Motion([Segment(10.0), Segment(5.0, accel_mps2=0.6), Segment(25.0)])
# aligned at 1.5 m/s (12.5 s), then navigating once the course has the heading within
# 0.5 deg 1-sigma (about 2 s: the course at 1.5 m/s is 0.76 deg), on the default config
NAVIGATING_FROM_S = 15.0
CONFLICT_AT_S = 20.0


class Gateway:
    """The real FusionCore from the default config behind a virtual bus that echoes, fed exact
    motion in time order as replay does. Received frames pass the service's receive filters
    (following our address) and EchoFilter before the core, as in the live service."""

    def __init__(self, channel: str, marks_own: bool = True) -> None:
        self.bus = can.Bus(interface="virtual", channel=channel, receive_own_messages=True)
        self.bus.set_filters(claim_filters())
        self.core = FusionCore.from_config(GatewayConfig())
        self.echo = EchoFilter()
        self.marks_own = marks_own
        self.sent: list[can.Message] = []
        self._filtered: int | None = None
        self._inputs: Iterator[ImuSample | GnssFix] = heapq.merge(
            imu_stream(MOTION), gnss_stream(MOTION), key=attrgetter("t")
        )
        self.send(self.core.start(T0_S), T0_S)

    def run(self, until_s: float) -> None:
        """Feed the inputs up to motion time ``until_s``, each after the frames received."""
        for item in self._inputs:
            self.receive(item.t)
            self.send(self.core.on_input(item), item.t)
            if item.t >= T0_S + until_s:
                return

    def receive(self, now: float) -> None:
        for msg in received(self.bus, self.marks_own):
            if not self.echo.is_echo(msg, now):
                self.send(self.core.on_bus_frame(msg, now), now)

    def send(self, frames: Iterable[can.Message], now: float) -> None:
        for frame in frames:
            self.bus.send(frame)
            self.echo.sent(frame, now)
            self.sent.append(frame)
        if self.core.claimer.address != self._filtered:
            self._filtered = self.core.claimer.address
            self.bus.set_filters(claim_filters(self._filtered))

    def modes(self, from_s: float, to_s: float) -> set[Mode]:
        """NAVGW_STATUS byte 2 of the frames sent in [from_s, to_s) of motion time."""
        return {
            Mode(f.data[2])
            for f in self.sent
            if FrameId.parse(f.arbitration_id).pgn == Pgn.NAVGW_STATUS
            and T0_S + from_s <= f.timestamp < T0_S + to_s
        }


@pytest.fixture
def gateway(request: pytest.FixtureRequest) -> Iterator[tuple[Gateway, Raw]]:
    channel = f"gw-{request.node.name}"
    gw, raw = Gateway(channel, getattr(request, "param", True)), Raw(channel)
    yield gw, raw
    gw.bus.shutdown()
    raw.bus.shutdown()


@pytest.mark.parametrize("gateway", [True, False], ids=["virtual", "udp-like"], indirect=True)
def test_the_gateways_own_echoes_leave_status_navigating(gateway: tuple[Gateway, Raw]) -> None:
    gw, _ = gateway
    gw.run(MOTION.duration_s)
    gw.receive(T0_S + MOTION.duration_s + 0.01)
    assert gw.echo.echoes == len(gw.sent) > 10_000  # every frame came back, and was told ours
    assert gw.core.claimer.name_conflicts == gw.core.claimer.spoofed_frames == 0
    assert gw.modes(NAVIGATING_FROM_S, MOTION.duration_s) == {Mode.NAVIGATING}


def test_a_clone_claiming_our_name_makes_status_degraded_for_the_hold_time(
    gateway: tuple[Gateway, Raw], caplog: pytest.LogCaptureFixture
) -> None:
    gw, raw = gateway
    gw.run(CONFLICT_AT_S)
    ours = gw.core.claimer.name
    with caplog.at_level(logging.WARNING, logger="gateway.isobus.address_claim"):
        raw.bus.send(claim_frame(0x40, ours))  # a second unit flashed with our identity
        gw.run(CONFLICT_AT_S + 2.0)
        raw.bus.send(claim_frame(0x40, ours))  # it answers a request: within 10 s, not logged
        gw.run(MOTION.duration_s)
    claimer = gw.core.claimer
    assert claimer.name_conflicts == 2 and claimer.spoofed_frames == 0
    assert claimer.claimed and claimer.address == 0x1C
    [text] = [r.getMessage() for r in caplog.records]
    assert "from 0x40" in text and f"NAME 0x{ours:016X}" in text and "identity_number" in text
    held_to = CONFLICT_AT_S + 2.0 + CONFLICT_HOLD_S
    assert gw.modes(NAVIGATING_FROM_S, CONFLICT_AT_S) == {Mode.NAVIGATING}
    assert gw.modes(CONFLICT_AT_S + 0.1, held_to) == {Mode.DEGRADED}
    assert gw.modes(held_to + 0.1, MOTION.duration_s) == {Mode.NAVIGATING}


@pytest.mark.parametrize("pgn", [Pgn.ATTITUDE, Pgn.NAVGW_STATUS])
def test_frames_sent_as_us_by_another_node_make_status_degraded(
    gateway: tuple[Gateway, Raw], caplog: pytest.LogCaptureFixture, pgn: Pgn
) -> None:
    gw, raw = gateway
    gw.run(CONFLICT_AT_S - 1.0)
    raw.bus.send(frame_from(pgn, 0x40, bytes(range(8))))  # another node's own: not ours
    gw.run(CONFLICT_AT_S)
    assert gw.core.claimer.spoofed_frames == 0
    with caplog.at_level(logging.WARNING, logger="gateway.isobus.address_claim"):
        for _ in range(3):
            raw.bus.send(frame_from(pgn, 0x1C, bytes(range(8))))
            gw.run(gw.core.solution().t - T0_S + 0.5)
    claimer = gw.core.claimer
    assert claimer.spoofed_frames == 3 and claimer.name_conflicts == 0
    # ISO 11783-5: a violation is answered with our claim from 0x1C, at most once a second
    # against a flood: violations at 0, 0.5 and 1 s get claims at 0 and 1 s
    reclaims = [
        f for f in gw.sent
        if FrameId.parse(f.arbitration_id).pgn == Pgn.ADDRESS_CLAIM
        and f.timestamp - T0_S > CONFLICT_AT_S - 0.1
    ]  # fmt: skip
    assert [FrameId.parse(f.arbitration_id).source for f in reclaims] == [0x1C] * 2
    assert reclaims[1].timestamp - reclaims[0].timestamp >= RECLAIM_INTERVAL_S
    [text] = [r.getMessage() for r in caplog.records]
    assert f"PGN {int(pgn)} from our address 0x1C" in text and "DEGRADED" in text
    held_to = CONFLICT_AT_S + 1.0 + CONFLICT_HOLD_S
    gw.run(MOTION.duration_s)
    assert gw.modes(NAVIGATING_FROM_S, CONFLICT_AT_S) == {Mode.NAVIGATING}
    assert gw.modes(CONFLICT_AT_S + 0.1, held_to) == {Mode.DEGRADED}
    assert gw.modes(held_to + 0.1, MOTION.duration_s) == {Mode.NAVIGATING}
