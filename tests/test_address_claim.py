"""Address claim on python-can ``virtual`` buses: our state machine against raw nodes."""

import logging
import random

import can
import pytest
from nmea2000 import _canboat

from gateway.address_claim import AddressClaimer, ClaimState, Name
from gateway.j1939 import FrameId, IndustryGroup, Pgn, can_id
from gateway.n2k_encode import LoopStatus
from gateway.scheduler import OutputScheduler
from gateway.solution import Mode, Solution

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


class Node:
    """Our claimer plus the output scheduler behind a virtual bus, driven by a test clock."""

    def __init__(self, channel: str, seed: int = 1, reserved: tuple[int, ...] = ()) -> None:
        # receive_own_messages: the bus echoes our frames, as udp_multicast does
        self.bus = can.Bus(interface="virtual", channel=channel, receive_own_messages=True)
        self.claimer = AddressClaimer(NAME, rng=random.Random(seed), reserved=reserved)
        self.scheduler = OutputScheduler()
        self.now = 1_700_000_000.0
        self.sent: list[can.Message] = []

    def send(self, frames: list[can.Message]) -> None:
        for frame in frames:
            self.bus.send(frame)
            self.sent.append(frame)

    def start(self) -> None:
        self.send(self.claimer.start(self.now))

    def run(self, seconds: float) -> None:
        for _ in range(round(seconds / STEP_S)):
            while (msg := self.bus.recv(0)) is not None:
                self.send(self.claimer.on_frame(msg, self.now))
            self.send(self.claimer.poll(self.now))
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
def buses(request: pytest.FixtureRequest):
    channel = f"claim-{request.node.name}"
    node, raw = Node(channel), Raw(channel)
    yield node, raw
    node.bus.shutdown()
    raw.bus.shutdown()


def test_name_matches_canboats_iso_name() -> None:
    expected = _canboat.iso_name(
        2046,
        123456,
        device_function=23,
        device_class=0,
        device_instance=2 << 3 | 1,
        system_instance=0,
        industry_group=IndustryGroup.AGRICULTURE,
        arbitrary_address_capable=True,
    )
    assert expected == OURS
    assert OURS >> 60 & 0x7 == 2 and OURS >> 63 == 1


def test_alone_claims_preferred_and_sends_nothing_before(buses) -> None:
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


def test_contention_won_by_our_lower_name(buses) -> None:
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


def test_contention_lost_moves_to_the_self_configurable_range(buses) -> None:
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


def test_late_joiner_with_lower_name_takes_our_address(buses) -> None:
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


def test_requests_for_the_claim_are_answered(buses) -> None:
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


def test_no_address_free_sends_cannot_claim_and_stays_silent(buses) -> None:
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


def test_preferred_held_by_lower_name_at_start_goes_straight_to_128(buses) -> None:
    node, raw = buses
    node.start()
    raw.bus.send(claim_frame(0x1C, OURS - 1))
    node.run(0.6)
    assert node.claims() == [128]
    assert node.claimer.claimed and node.claimer.address == 128


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
        with caplog.at_level(logging.WARNING, logger="gateway.address_claim"):
            raw.bus.send(claim_frame(0x1C, OURS - 1))
            node.run(0.4)
        assert node.claimer.claimed and node.claimer.address == 0x81
        assert node.claims() == [0x1C, 0x81]
        text = [r.getMessage() for r in caplog.records]
        assert any("0x1C lost" in t and "claiming 0x81" in t for t in text), text
    finally:
        node.bus.shutdown()
        raw.bus.shutdown()
