"""BAM receive (J1939-21 broadcast transport): the pure reassembler, then on a virtual bus.

The frames are built by hand from J1939-21 (TP.CM control 32, size, packets, reserved 0xFF,
PGN; TP.DT sequence number and 7 bytes), and checked against the ``nmea2000`` package's own
reassembler, so the test shares no code with :mod:`gateway.isobus.transport`.
"""

from __future__ import annotations

import logging

import can
import pytest
from nmea2000._canboat import Reassembler

from gateway.isobus.j1939 import FrameId, Pgn, can_id
from gateway.isobus.transport import T1_S, BamMessage, BamReceiver

SOURCE = 0xF8
PAYLOAD = bytes(range(1, 10))  # 9 bytes: two packets, the second padded


def announce(size: int, pgn: int = Pgn.COMMANDED_ADDRESS, packets: int | None = None) -> bytes:
    n = -(-size // 7) if packets is None else packets
    return bytes([32, size & 0xFF, size >> 8, n, 0xFF]) + pgn.to_bytes(3, "little")


def packets(payload: bytes) -> list[bytes]:
    padded = payload + b"\xff" * 6
    return [bytes([k + 1]) + padded[7 * k : 7 * k + 7] for k in range(-(-len(payload) // 7))]


def cm_id(source: int = SOURCE, destination: int = 255) -> FrameId:
    return FrameId(7, Pgn.TP_CONNECTION_MANAGEMENT, source, destination)


def dt_id(source: int = SOURCE, destination: int = 255) -> FrameId:
    return FrameId(7, Pgn.TP_DATA_TRANSFER, source, destination)


def test_a_bam_is_reassembled_and_the_padding_cut() -> None:
    rx = BamReceiver()
    assert rx.on_frame(cm_id(), announce(len(PAYLOAD)), 0.0) is None
    first, second = packets(PAYLOAD)
    assert rx.on_frame(dt_id(), first, 0.05) is None
    assert rx.on_frame(dt_id(), second, 0.10) == BamMessage(Pgn.COMMANDED_ADDRESS, SOURCE, PAYLOAD)
    assert rx.stats.completed == 1 and rx.stats.dropped == rx.stats.malformed == 0
    # the same frames through the nmea2000 package's reassembler give the same payload
    theirs = Reassembler()
    out = [
        theirs.push(Pgn.TP_CONNECTION_MANAGEMENT, announce(len(PAYLOAD)), SOURCE),
        theirs.push(Pgn.TP_DATA_TRANSFER, first, SOURCE),
        theirs.push(Pgn.TP_DATA_TRANSFER, second, SOURCE),
    ]
    assert out[-1] == PAYLOAD


def test_a_long_bam_of_many_packets() -> None:
    rx = BamReceiver()
    payload = bytes(range(256)) * 4  # 1024 bytes, 147 packets
    rx.on_frame(cm_id(), announce(len(payload), pgn=0xFECA), 0.0)
    got = [rx.on_frame(dt_id(), p, 0.05 * k) for k, p in enumerate(packets(payload))]
    assert got[:-1] == [None] * 146
    assert got[-1] == BamMessage(0xFECA, SOURCE, payload)


@pytest.mark.parametrize("gap_s, complete", [(T1_S - 0.01, True), (T1_S + 0.01, False)])
def test_more_than_t1_between_packets_drops_the_message(gap_s: float, complete: bool) -> None:
    rx = BamReceiver()
    rx.on_frame(cm_id(), announce(len(PAYLOAD)), 0.0)
    first, second = packets(PAYLOAD)
    rx.on_frame(dt_id(), first, 0.1)
    message = rx.on_frame(dt_id(), second, 0.1 + gap_s)
    assert (message is not None) == complete
    assert rx.stats.dropped == (0 if complete else 1)
    assert rx.on_frame(dt_id(), second, 0.2 + gap_s) is None  # nothing left to add to


def test_a_packet_out_of_sequence_drops_the_message(caplog: pytest.LogCaptureFixture) -> None:
    rx = BamReceiver()
    payload = bytes(20)  # 3 packets
    rx.on_frame(cm_id(), announce(len(payload)), 0.0)
    one, _, three = packets(payload)
    rx.on_frame(dt_id(), one, 0.05)
    with caplog.at_level(logging.WARNING, logger="gateway.isobus.transport"):
        assert rx.on_frame(dt_id(), three, 0.10) is None
    assert rx.stats.dropped == 1 and rx.stats.completed == 0
    assert "packet 3 where 2 was due" in caplog.text


def test_a_new_announce_replaces_the_unfinished_message() -> None:
    rx = BamReceiver()
    rx.on_frame(cm_id(), announce(20), 0.0)
    rx.on_frame(dt_id(), packets(bytes(20))[0], 0.05)
    rx.on_frame(cm_id(), announce(len(PAYLOAD)), 0.1)
    out = [rx.on_frame(dt_id(), p, 0.15) for p in packets(PAYLOAD)]
    assert out[-1] == BamMessage(Pgn.COMMANDED_ADDRESS, SOURCE, PAYLOAD)
    assert rx.stats.dropped == 1


def test_two_sources_at_once_are_kept_apart() -> None:
    rx = BamReceiver()
    other = bytes(range(50, 59))
    rx.on_frame(cm_id(SOURCE), announce(9), 0.0)
    rx.on_frame(cm_id(0x33), announce(9), 0.0)
    (a1, a2), (b1, b2) = packets(PAYLOAD), packets(other)
    rx.on_frame(dt_id(SOURCE), a1, 0.01)
    rx.on_frame(dt_id(0x33), b1, 0.02)
    assert rx.on_frame(dt_id(0x33), b2, 0.03) == BamMessage(Pgn.COMMANDED_ADDRESS, 0x33, other)
    assert rx.on_frame(dt_id(SOURCE), a2, 0.04) == BamMessage(
        Pgn.COMMANDED_ADDRESS, SOURCE, PAYLOAD
    )


def test_malformed_frames_are_counted_logged_once_and_skipped(
    caplog: pytest.LogCaptureFixture,
) -> None:
    rx = BamReceiver()
    with caplog.at_level(logging.WARNING, logger="gateway.isobus.transport"):
        for k in range(50):
            assert rx.on_frame(cm_id(), bytes([32, 9, 0]), 0.01 * k) is None  # short
        assert rx.on_frame(cm_id(), announce(9, packets=3), 1.0) is None  # 9 bytes in 3?
        assert rx.on_frame(cm_id(), announce(8), 1.1) is None  # fits one frame: no BAM
        assert rx.on_frame(cm_id(), announce(1786, packets=255), 1.2) is None
        assert rx.on_frame(dt_id(), packets(PAYLOAD)[0], 1.3) is None  # no session opened
        rx.on_frame(cm_id(), announce(9, packets=3), 20.0)  # 10 s on: logged again
    assert rx.stats.malformed == 54
    lines = [r.getMessage() for r in caplog.records]
    assert len(lines) == 2, lines  # at most one per 10 s, with the count of the others
    assert "PGN 60416 from 0xF8 skipped: 3 bytes, expected 8" in lines[0]
    assert "BAM of 9 bytes in 3 packets" in lines[1] and "(52 more since" in lines[1]


def test_connection_mode_frames_to_one_node_are_not_taken() -> None:
    rx = BamReceiver()
    rts = bytes([16, 9, 0, 2, 0xFF]) + int(Pgn.COMMANDED_ADDRESS).to_bytes(3, "little")
    assert rx.on_frame(cm_id(destination=0x1C), rts, 0.0) is None
    assert rx.on_frame(dt_id(destination=0x1C), packets(PAYLOAD)[0], 0.01) is None
    assert rx.on_frame(cm_id(), rts, 0.02) is None  # an RTS can only be to one node: ignored
    assert rx.stats == type(rx.stats)()


def test_bam_on_a_virtual_bus() -> None:
    """Frames as a tool sends them on a bus (priority 7, to global), read back and fed in."""
    channel = "transport-bam"
    with (
        can.Bus(interface="virtual", channel=channel) as tool,
        can.Bus(interface="virtual", channel=channel) as gateway,
    ):
        tool.send(
            can.Message(
                arbitration_id=can_id(Pgn.TP_CONNECTION_MANAGEMENT, SOURCE, 7),
                data=announce(len(PAYLOAD)),
            )
        )
        for p in packets(PAYLOAD):
            tool.send(can.Message(arbitration_id=can_id(Pgn.TP_DATA_TRANSFER, SOURCE, 7), data=p))
        rx, out = BamReceiver(), []
        while (msg := gateway.recv(0.1)) is not None:
            out.append(rx.on_frame(FrameId.parse(msg.arbitration_id), bytes(msg.data), 0.0))
    assert out == [None, None, BamMessage(Pgn.COMMANDED_ADDRESS, SOURCE, PAYLOAD)]
