"""Network management on python-can ``virtual`` buses: requests, NAK, device information,
PGN list, heartbeat, commanded address. Every frame the gateway sends here is decoded by the
``nmea2000`` package (canboat's PGN database), not by our DBC.

A :class:`Device` is the claimer, the network manager and the output scheduler behind a bus
that echoes (as the live service runs them, echoes dropped by EchoFilter), driven by a test
clock; the last tests run the real :class:`~gateway.fusion.fusion_core.FusionCore`.

AgIsoStack++'s test/core_network_management_tests.cpp scenarios covered (with those of
test_address_claim.py): CommandedAddress (a BAM of PGN 65240 with our NAME and address 0x04
from a node at 0xF8 moves us to 0x04: test_commanded_address_by_bam_moves_us); the request
for the address claim answered (test_address_claim.py). Not covered: its partner and
internal-control-function bookkeeping (TestCreateAndDestroy*, SimilarControlFunctions,
InvalidatingControlFunctions: navgw keeps no partner list, only who holds which address)
and the bus load estimate (BusloadTest: gateway/isobus/bus_load.py has its own tests).
"""

from __future__ import annotations

import logging
from collections.abc import Iterator
from importlib import metadata

import can
import pytest
from nmea2000 import NMEA2000Decoder, NMEA2000Message

from gateway.isobus.address_claim import Name
from gateway.isobus.device_info import (
    HEARTBEAT_INTERVAL_S,
    MANUFACTURER_INFORMATION,
    ProductInfo,
)
from gateway.isobus.j1939 import FrameId, Pgn, can_id
from gateway.isobus.network import (
    NETWORK_TRANSMIT_PGNS,
    RECEIVE_PGNS,
    UNCLAIMED_RECHECK_S,
    NetworkManager,
)
from gateway.isobus.output_scheduler import DEFAULT_RATES_HZ
from tests.test_address_claim import Node

NAME = Name(identity_number=123456)
OURS = NAME.value()
VERSION = metadata.version("navgw")
STEP_S = 0.005
TOOL = 0x40  # the requesting node's address


def request(
    pgn: int, destination: int = 255, source: int = TOOL, data: bytes | None = None
) -> can.Message:
    """A request (PGN 59904) for ``pgn`` as a tool sends it."""
    return can.Message(
        arbitration_id=can_id(Pgn.ISO_REQUEST, source, 6, destination),
        data=int(pgn).to_bytes(3, "little") if data is None else data,
    )


def bam(pgn: int, payload: bytes, source: int = 0xF8) -> list[can.Message]:
    """A J1939-21 BAM of ``payload``: TP.CM (control 32) then TP.DT packets, priority 7."""
    n = -(-len(payload) // 7)
    cm = bytes([32, len(payload) & 0xFF, len(payload) >> 8, n, 0xFF]) + pgn.to_bytes(3, "little")
    padded = payload + b"\xff" * 6
    frames = [can.Message(arbitration_id=can_id(Pgn.TP_CONNECTION_MANAGEMENT, source, 7), data=cm)]
    frames += [
        can.Message(
            arbitration_id=can_id(Pgn.TP_DATA_TRANSFER, source, 7),
            data=bytes([k + 1]) + padded[7 * k : 7 * k + 7],
        )
        for k in range(n)
    ]
    return frames


def commanded(name: int, address: int) -> bytes:
    """The 9-byte Commanded Address payload (PGN 65240)."""
    return name.to_bytes(8, "little") + bytes([address])


class Device(Node):
    """:class:`~tests.test_address_claim.Node` (claimer and scheduler behind a virtual bus
    that echoes) with the network manager: requests, commanded address, heartbeat."""

    def __init__(self, channel: str, periodic_rates: dict[Pgn, float] | None = None) -> None:
        super().__init__(channel, name=NAME, rates=periodic_rates)
        product = ProductInfo(software_version=VERSION, serial_code="123456", model_version="B")
        self.network = NetworkManager(self.claimer, product, self.scheduler.rates_hz)
        self.fault = False

    def on_frame(self, msg: can.Message) -> None:
        super().on_frame(msg)
        self.send(self.network.on_frame(msg, self.now))

    def poll(self) -> None:
        super().poll()
        if self.now >= self.network.next_heartbeat_t:
            self.send(self.network.heartbeat(self.now, self.fault))

    def run(self, seconds: float, fault: bool = False) -> None:
        self.fault = fault
        super().run(seconds)

    def since(self, index: int, pgn: int | None = None) -> list[can.Message]:
        """Frames sent from ``self.sent[index]`` on (of ``pgn`` only, if given)."""
        return [
            f for f in self.sent[index:]
            if pgn is None or FrameId.parse(f.arbitration_id).pgn == pgn
        ]  # fmt: skip


class Tool:
    """Another node: sends raw frames, decodes what it receives with the nmea2000 package."""

    def __init__(self, channel: str) -> None:
        self.bus = can.Bus(interface="virtual", channel=channel)
        self.decoder = NMEA2000Decoder()

    def send(self, *frames: can.Message) -> None:
        for frame in frames:
            self.bus.send(frame)

    def decoded(self) -> list[NMEA2000Message]:
        """The complete messages received since the last call (fast packets joined)."""
        out = []
        while (msg := self.bus.recv(0)) is not None:
            message = self.decoder.decode(msg)
            if message is not None:
                out.append(message)
        return out


def fields(message: NMEA2000Message) -> dict[str, object]:
    return {f.id: f.value for f in message.fields}


def by_pgn(messages: list[NMEA2000Message], pgn: int) -> list[NMEA2000Message]:
    return [m for m in messages if pgn == m.PGN]


@pytest.fixture
def bus(request: pytest.FixtureRequest) -> Iterator[tuple[Device, Tool]]:
    channel = f"nm-{request.node.name}"
    device, tool = Device(channel), Tool(channel)
    device.send(device.claimer.start(device.now))
    device.run(0.6)  # claimed 0x1C
    assert device.claimer.claimed and device.claimer.address == 0x1C
    tool.decoded()
    yield device, tool
    device.bus.shutdown()
    tool.bus.shutdown()


@pytest.mark.parametrize("destination", [255, 0x1C], ids=["global", "to-us"])
def test_product_information_answers_a_request_with_our_version(
    bus: tuple[Device, Tool], destination: int
) -> None:
    device, tool = bus
    tool.send(request(Pgn.PRODUCT_INFORMATION, destination))
    device.run(0.01)
    [info] = by_pgn(tool.decoded(), Pgn.PRODUCT_INFORMATION)
    assert info.source == 0x1C
    assert fields(info) == {
        "nmea2000Version": 2.1,
        "productCode": 1,
        "modelId": "navgw GNSS/IMU gateway",
        "softwareVersionCode": VERSION,
        "modelVersion": "B",
        "modelSerialCode": "123456",
        "certificationLevel": None,  # not certified: not available
        "loadEquivalency": 1,
    }
    frames = device.since(0, Pgn.PRODUCT_INFORMATION)
    assert len(frames) == 20 and frames[0].data[1] == 134  # fast packet, 134 bytes


def test_configuration_information_answers_a_request(bus: tuple[Device, Tool]) -> None:
    device, tool = bus
    tool.send(request(Pgn.CONFIGURATION_INFORMATION))
    device.run(0.01)
    [info] = by_pgn(tool.decoded(), Pgn.CONFIGURATION_INFORMATION)
    assert fields(info) == {
        "installationDescription1": None,
        "installationDescription2": None,
        "manufacturerInformation": MANUFACTURER_INFORMATION,
    }


@pytest.mark.parametrize(
    "destination, answered_to", [(255, 255), (0x1C, TOOL)], ids=["global", "to-us"]
)
def test_pgn_lists_say_what_the_scheduler_sends_and_what_we_read(
    bus: tuple[Device, Tool], destination: int, answered_to: int
) -> None:
    device, tool = bus
    tool.send(request(Pgn.PGN_LIST, destination))
    device.run(0.01)
    transmit, receive = by_pgn(tool.decoded(), Pgn.PGN_LIST)
    lists = {}
    for message in (transmit, receive):
        assert message.destination == answered_to
        entries = message.get_list_field_size()
        listed = [message.get_list_field_by_id(i, "pgn").value for i in range(entries)]
        lists[fields(message)["functionCode"]] = listed
    expected = sorted({59392, 59904, 60928, 126464, 126993, 126996, 126998, *DEFAULT_RATES_HZ})
    assert lists["Transmit PGN list"] == expected
    assert lists["Receive PGN list"] == [59904, 60160, 60416, 60928, 65240]


def test_the_transmit_list_follows_the_configured_rates() -> None:
    channel = "nm-rates"
    rates = {Pgn.NAVGW_ACCEL_BIAS: 0.0, Pgn.VESSEL_HEADING: 0.0}
    device, tool = Device(channel, rates), Tool(channel)
    try:
        device.send(device.claimer.start(device.now))
        device.run(0.6)
        tool.decoded()
        tool.send(request(Pgn.PGN_LIST, 0x1C), request(Pgn.VESSEL_HEADING, 0x1C))
        device.run(0.01)
        messages = tool.decoded()
        transmit = by_pgn(messages, Pgn.PGN_LIST)[0]
        listed = {
            transmit.get_list_field_by_id(i, "pgn").value
            for i in range(transmit.get_list_field_size())
        }
        assert Pgn.VESSEL_HEADING not in listed and Pgn.NAVGW_ACCEL_BIAS not in listed
        assert Pgn.ATTITUDE in listed
        [nak] = by_pgn(messages, Pgn.ISO_ACKNOWLEDGEMENT)  # turned off: not sent, so NAK
        assert fields(nak)["pgn"] == Pgn.VESSEL_HEADING
    finally:
        device.bus.shutdown()
        tool.bus.shutdown()


def test_a_request_for_a_pgn_we_do_not_send_gets_a_nak_only_when_addressed_to_us(
    bus: tuple[Device, Tool],
) -> None:
    device, tool = bus
    unsupported = 130306  # wind data
    tool.send(request(unsupported, 255))
    device.run(0.01)
    assert by_pgn(tool.decoded(), Pgn.ISO_ACKNOWLEDGEMENT) == []  # never NAK a global request
    mark = len(device.sent)
    tool.send(request(unsupported, 0x1C))
    device.run(0.01)
    [nak] = by_pgn(tool.decoded(), Pgn.ISO_ACKNOWLEDGEMENT)
    assert fields(nak)["control"] == "NAK" and fields(nak)["pgn"] == unsupported
    assert fields(nak)["groupFunction"] is None  # 0xFF: not a group function
    [frame] = device.since(mark, Pgn.ISO_ACKNOWLEDGEMENT)
    assert FrameId.parse(frame.arbitration_id) == FrameId(6, Pgn.ISO_ACKNOWLEDGEMENT, 0x1C, 255)
    assert frame.data[4] == TOOL  # J1939-21: the address acknowledged
    assert bytes(frame.data[2:4]) == b"\xff\xff"
    assert device.network.naks == 1


@pytest.mark.parametrize("pgn", [Pgn.GNSS_POSITION_DATA, Pgn.ATTITUDE, Pgn.NAVGW_STATUS])
def test_a_request_for_a_periodic_pgn_is_answered_by_its_next_frame_not_a_nak(
    bus: tuple[Device, Tool], pgn: Pgn
) -> None:
    device, tool = bus
    mark = len(device.sent)
    tool.send(request(pgn, 0x1C))
    device.run(1.0 / DEFAULT_RATES_HZ[pgn] + STEP_S)
    assert device.since(mark, Pgn.ISO_ACKNOWLEDGEMENT) == []
    assert device.since(mark, pgn)  # within one period


def test_a_request_for_the_address_claim_gets_the_claim_only(bus: tuple[Device, Tool]) -> None:
    device, tool = bus
    mark = len(device.sent)
    tool.send(request(Pgn.ADDRESS_CLAIM, 0x1C))
    device.run(0.01)
    [claim] = device.since(mark, Pgn.ADDRESS_CLAIM)
    assert int.from_bytes(claim.data, "little") == OURS
    assert device.since(mark, Pgn.ISO_ACKNOWLEDGEMENT) == []


def test_requests_to_another_node_or_before_the_claim_get_nothing() -> None:
    channel = "nm-early"
    device, tool = Device(channel), Tool(channel)
    try:
        device.send(device.claimer.start(device.now))
        tool.send(request(Pgn.PRODUCT_INFORMATION), request(130306, 0x1C))
        device.run(0.1)  # claim not complete
        assert device.since(0, Pgn.PRODUCT_INFORMATION) == []
        assert device.since(0, Pgn.ISO_ACKNOWLEDGEMENT) == []
        device.run(0.5)
        mark = len(device.sent)
        tool.send(request(Pgn.PRODUCT_INFORMATION, 0x41), request(130306, 0x41))
        device.run(0.01)
        assert device.since(mark, Pgn.PRODUCT_INFORMATION) == []
        assert device.since(mark, Pgn.ISO_ACKNOWLEDGEMENT) == []
    finally:
        device.bus.shutdown()
        tool.bus.shutdown()


def test_short_requests_are_counted_logged_at_a_sane_rate_and_skipped(
    bus: tuple[Device, Tool], caplog: pytest.LogCaptureFixture
) -> None:
    device, tool = bus
    mark = len(device.sent)
    with caplog.at_level(logging.WARNING, logger="gateway.isobus.network"):
        for _ in range(100):
            tool.send(request(0, 0x1C, data=b"\x14\xf0"))
        device.run(0.02)
    assert device.network.malformed == 100
    assert [r.getMessage() for r in caplog.records] == [
        "network: request from 0x40 of 2 bytes skipped, expected 3"
    ]
    assert device.since(mark, Pgn.ISO_ACKNOWLEDGEMENT) == []
    assert device.claimer.claimed


def test_heartbeat_every_60_s_from_the_claim_with_a_sequence_counter() -> None:
    channel = "nm-heartbeat"
    device, tool = Device(channel), Tool(channel)
    try:
        device.send(device.claimer.start(device.now))
        start = device.now
        device.run(2 * HEARTBEAT_INTERVAL_S + 1.0)
        beats = device.since(0, Pgn.HEARTBEAT)
        claim_done = device.since(0, Pgn.ADDRESS_CLAIM)[0].timestamp + 0.25
        assert len(beats) == 3
        # looked at every 50 ms until the claim completes: the first at most that late
        assert claim_done <= beats[0].timestamp <= claim_done + UNCLAIMED_RECHECK_S + STEP_S
        offsets = [b.timestamp - beats[0].timestamp for b in beats]
        assert offsets == pytest.approx([0.0, 60.0, 120.0], abs=STEP_S)  # on the step clock
        assert beats[0].timestamp - start < 0.5
        decoded = [m for m in by_pgn(tool.decoded(), Pgn.HEARTBEAT)]
        assert [fields(m)["sequenceCounter"] for m in decoded] == [0, 1, 2]
        assert {fields(m)["dataTransmitOffset"] for m in decoded} == {60.0}
        assert {fields(m)["equipmentStatus"] for m in decoded} == {"Operational"}
        assert {fields(m)["controller1State"] for m in decoded} == {None}  # unknown to the core
        assert {m.priority for m in decoded} == {7}
        tool.send(request(Pgn.HEARTBEAT, 0x1C))  # on request, with the next counter
        device.run(0.01, fault=True)
        [asked] = by_pgn(tool.decoded(), Pgn.HEARTBEAT)
        assert fields(asked)["sequenceCounter"] == 3
        device.run(HEARTBEAT_INTERVAL_S, fault=True)
        [faulty] = by_pgn(tool.decoded(), Pgn.HEARTBEAT)
        assert fields(faulty)["equipmentStatus"] == "Fault"
    finally:
        device.bus.shutdown()
        tool.bus.shutdown()


def test_commanded_address_by_bam_moves_us(
    bus: tuple[Device, Tool], caplog: pytest.LogCaptureFixture
) -> None:
    """AgIsoStack++ CommandedAddress: a BAM from 0xF8 commands our NAME to 0x04."""
    device, tool = bus
    mark = len(device.sent)
    with caplog.at_level(logging.WARNING, logger="gateway.isobus.address_claim"):
        tool.send(*bam(Pgn.COMMANDED_ADDRESS, commanded(OURS, 0x04)))
        device.run(0.01)
    assert device.claimer.address == 0x04 and not device.claimer.claimed
    [claim] = device.since(mark, Pgn.ADDRESS_CLAIM)
    assert FrameId.parse(claim.arbitration_id).source == 0x04
    assert "0xF8 commands us from 0x1C to 0x04" in caplog.text
    device.run(0.5)
    assert device.claimer.claimed and device.claimer.address == 0x04
    after = device.since(device.sent.index(claim))
    assert {FrameId.parse(f.arbitration_id).source for f in after} == {0x04}  # none from 0x1C
    output = [f for f in after if FrameId.parse(f.arbitration_id).pgn != Pgn.ADDRESS_CLAIM]
    assert min(f.timestamp for f in output) >= claim.timestamp + 0.25
    tool.decoded()
    tool.send(request(Pgn.PRODUCT_INFORMATION, 0x04))
    device.run(0.01)
    [info] = by_pgn(tool.decoded(), Pgn.PRODUCT_INFORMATION)
    assert info.source == 0x04


def test_commanded_address_for_another_name_or_a_lower_names_address_is_not_followed(
    bus: tuple[Device, Tool], caplog: pytest.LogCaptureFixture
) -> None:
    device, tool = bus
    tool.send(*bam(Pgn.COMMANDED_ADDRESS, commanded(OURS + 1, 0x04)))  # another node's
    device.run(0.05)
    assert device.claimer.address == 0x1C and device.claimer.claimed
    lower = OURS - 1
    tool.send(can.Message(arbitration_id=can_id(Pgn.ADDRESS_CLAIM, 0x05, 6),
                          data=lower.to_bytes(8, "little")))  # fmt: skip
    with caplog.at_level(logging.WARNING, logger="gateway.isobus.address_claim"):
        tool.send(*bam(Pgn.COMMANDED_ADDRESS, commanded(OURS, 0x05)))
        device.run(0.05)
    assert device.claimer.address == 0x1C and device.claimer.claimed
    assert f"held by NAME 0x{lower:016X}, lower than ours; keeping 0x1C" in caplog.text


def test_a_short_commanded_address_is_counted_and_skipped(bus: tuple[Device, Tool]) -> None:
    device, tool = bus
    # a 9-byte BAM is the least a BAM carries; one announcing 9 bytes but of another PGN, and
    # a commanded address of 10 bytes (extra byte) still reads: only its first 9 count
    tool.send(*bam(Pgn.COMMANDED_ADDRESS, commanded(OURS, 0x06) + b"\x00"))
    device.run(0.05)
    assert device.claimer.address == 0x06
    assert device.network.malformed == 0
    assert device.network.transport.stats.completed == 1


def test_the_fusion_core_answers_requests_and_sends_the_heartbeat() -> None:
    """The real core from the default config, fed motion as replay does (test_address_claim's
    Gateway): requests reach the network through on_bus_frame, the heartbeat goes out from
    on_imu after the claim; NAME function and class as canboat names them."""
    from tests.test_address_claim import Gateway

    channel = "nm-core"
    gateway, tool = Gateway(channel), Tool(channel)
    try:
        gateway.run(5.0)
        messages = tool.decoded()
        [beat] = by_pgn(messages, Pgn.HEARTBEAT)
        claim = by_pgn(messages, Pgn.ADDRESS_CLAIM)[0]
        assert fields(claim)["deviceFunction"] == "Ownship Position (GNSS)"
        assert fields(claim)["deviceClass"] == "Navigation"
        assert fields(claim)["industryGroup"] == "Agriculture"
        after_claim = beat.timestamp - claim.timestamp
        assert after_claim.total_seconds() <= 0.25 + UNCLAIMED_RECHECK_S + 0.005
        tool.send(request(Pgn.PRODUCT_INFORMATION, 0x1C), request(130306, 0x1C))
        gateway.run(5.1)
        messages = tool.decoded()
        [info] = by_pgn(messages, Pgn.PRODUCT_INFORMATION)
        assert fields(info)["softwareVersionCode"] == VERSION
        assert fields(info)["modelSerialCode"] == "1"  # the default identity number
        [nak] = by_pgn(messages, Pgn.ISO_ACKNOWLEDGEMENT)
        assert fields(nak)["pgn"] == 130306
        assert Pgn.ATTITUDE in {m.PGN for m in messages}
    finally:
        gateway.bus.shutdown()
        tool.bus.shutdown()


def test_the_lists_of_network_pgns() -> None:
    assert sorted(NETWORK_TRANSMIT_PGNS) == [59392, 59904, 60928, 126464, 126993, 126996, 126998]
    assert sorted(RECEIVE_PGNS) == [59904, 60160, 60416, 60928, 65240]
