"""The monitor's pure parts: fast-packet receive, the DBC decoder of any frame, the bus state
and its text, on a replayed run and on hand-made frames (other nodes, broken frames, silence)."""

from __future__ import annotations

from pathlib import Path

import can
import pytest

from drivers.logs.candump import read_candump
from gateway.isobus.address_claim import Name
from gateway.isobus.fast_packet import FastPacketFragmenter
from gateway.isobus.j1939 import IndustryGroup, Pgn, can_id
from gateway.monitor import panels
from gateway.monitor.bus_state import BusState
from gateway.readback.fast_packet_rx import FastPacketReceiver, MalformedFrameError
from gateway.readback.frame_decoder import OutputFrameDecoder
from tests.output_run import OutputRun, expected_text, make_output_run

GNSS = int(Pgn.GNSS_POSITION_DATA)
WIND_DATA = 130306  # NMEA 2000, not in our DBC


@pytest.fixture(scope="module")
def run(tmp_path_factory: pytest.TempPathFactory) -> OutputRun:
    return make_output_run(tmp_path_factory.mktemp("monitor-state"))


@pytest.fixture(scope="module")
def fed(run: OutputRun) -> BusState:
    state = BusState()
    for msg in read_candump(run.log):
        state.feed(msg)
    return state


def frame(pgn: int, source: int, data: bytes, t: float, priority: int = 6) -> can.Message:
    return can.Message(
        timestamp=t, arbitration_id=can_id(pgn, source, priority), data=data, is_extended_id=True
    )


# ------------------------------------------------------------------------ fast packets


def test_fragments_reassemble_per_source_interleaved_and_a_lost_frame_drops_the_packet() -> None:
    frag, rx = FastPacketFragmenter(), FastPacketReceiver()
    a, b = bytes(range(47)), bytes(range(100, 147))
    frames_a, frames_b = frag.fragment(GNSS, 0x1C, a), frag.fragment(GNSS, 0x80, b)
    out = []
    for fa, fb in zip(frames_a, frames_b, strict=True):  # two sources, frame by frame
        out += [rx.on_frame(GNSS, 0x1C, fa), rx.on_frame(GNSS, 0x80, fb)]
    assert [p for p in out if p is not None] == [a, b]
    assert rx.stats.completed == 2
    lossy = frag.fragment(GNSS, 0x1C, a)
    results = [rx.on_frame(GNSS, 0x1C, f) for i, f in enumerate(lossy) if i != 3]
    assert results == [None] * 6 and rx.stats.dropped == 1  # never a shifted payload
    assert rx.on_frame(GNSS, 0x1C, frag.fragment(GNSS, 0x1C, a)[0]) is None  # starts afresh
    with pytest.raises(MalformedFrameError, match="3 bytes, expected 8"):
        rx.on_frame(GNSS, 0x1C, b"\x00\x2f\x01")
    with pytest.raises(MalformedFrameError, match="a fast packet of 250 bytes, expected 7-223"):
        rx.on_frame(GNSS, 0x1C, bytes([0x20, 250, 0, 0, 0, 0, 0, 0]))


# --------------------------------------------------------------------------- decoder


def test_unknown_and_malformed_frames_are_counted_never_raised() -> None:
    decoder = OutputFrameDecoder()
    unknown = [
        can.Message(arbitration_id=0x123, data=b"\x01", is_extended_id=False),  # 11-bit
        frame(WIND_DATA, 0x30, bytes(8), 0.0),  # a PGN that is not in the DBC
        can.Message(arbitration_id=0x20000080, is_error_frame=True),
    ]
    malformed = [
        frame(Pgn.ATTITUDE, 0x1C, b"\x01\x02\x03", 0.0),  # 3 of 8 bytes
        frame(GNSS, 0x1C, b"\x00", 0.0),  # a fast-packet frame of 1 byte
        frame(GNSS, 0x1C, bytes([0x00, 3, 1, 2, 3, 255, 255, 255]), 0.0),  # 3-byte "packet"
    ]
    assert all(decoder.decode(m) is None for m in unknown + malformed)
    s = decoder.stats
    assert (s.frames, s.decoded, s.unknown, s.malformed) == (6, 0, 3, 3)
    assert s.last_problem == (
        "GNSS_POSITION_DATA from 0x1C: a fast packet of 3 bytes, expected 7-223"
    )


def test_a_request_to_any_address_reads_with_the_global_layout() -> None:
    decoded = OutputFrameDecoder().decode(
        can.Message(arbitration_id=0x18EA8533, data=b"\x00\xee\x00", is_extended_id=True)
    )
    assert decoded is not None and decoded.name == "ISO_REQUEST"
    assert decoded.signals == {"REQUESTED_PGN": 60928}
    assert (decoded.frame_id.source, decoded.frame_id.destination) == (0x33, 0x85)


# ---------------------------------------------------------------------------- state


def test_a_replayed_run_reads_as_a_person_would(fed: BusState, run: OutputRun) -> None:
    expected = expected_text(run.log)
    src = fed.current
    assert src is not None and src.address == 0x1C and src.is_navgw
    assert panels.mode_text(src) == "NAVIGATING"
    status = panels.status_text(src)
    assert "fix       RTK fixed" in status
    assert "health    IMU ok, GNSS ok, address claimed" in status
    assert "IMU lost  0 samples in the last second (most: 0)" in status
    assert expected["converged"] in panels.bias_text(src)
    # the last frames of the log, in display units
    assert expected["gyro"] in panels.bias_text(src)
    assert expected["latitude"] in panels.motion_text(src)
    # every SPEC 4 output at its configured rate, measured at the last frame
    assert fed.last_t is not None
    rates = {r.name: r for r in src.rates(fed.last_t)}
    for name, hz in (("ATTITUDE", 50), ("GNSS_POSITION_DATA", 10), ("NAVGW_GYRO_BIAS", 1)):
        assert rates[name].measured_hz == pytest.approx(hz, rel=0.03), name
        assert rates[name].verdict == "ok"
    assert ("attitude", "50.0", "50", "ok") in panels.rate_rows(src, fed.last_t)
    assert fed.first_t is not None
    heartbeats = 1 + int((fed.last_t - fed.first_t) // 60)  # at the claim, then every 60 s
    assert ("heartbeat", f"{heartbeats} received", "", "") in panels.rate_rows(src, fed.last_t)
    # sparklines: attitude every 0.25 s over 30 s, biases every second over 2 min
    assert len(src.sparks["roll"].values) == 120 and len(src.sparks["gyro x"].values) == 120
    assert f"{src.sparks['gyro x'].values[-1]:+.4f}" == expected["gyro x"]
    (claim,) = panels.claim_rows(fed)
    assert claim[:2] == ("0x1C", "navgw")
    assert claim[2].startswith("identity 1, manufacturer 2046, function 145 ownship position")
    assert fed.decoder.stats.unknown == fed.decoder.stats.malformed == 0
    assert fed.banner(fed.last_t + 0.5) == ""


def test_rates_are_judged_against_the_units_configured_ones(run: OutputRun) -> None:
    """``navgw monitor --config``: a unit configured for other rates than SPEC 4's (the log
    was made with the defaults) shows them, and what the log's rates mean against them."""
    configured = {
        int(Pgn.ATTITUDE): 0.0,
        int(Pgn.NAVGW_GYRO_BIAS): 2.0,
        int(Pgn.RATE_OF_TURN): 50.0,
    }
    state = BusState(configured_hz=configured)
    for msg in read_candump(run.log):
        state.feed(msg)
    src = state.current
    assert src is not None and state.last_t is not None
    rates = {r.name: r for r in src.rates(state.last_t)}
    assert (rates["ATTITUDE"].configured_hz, rates["ATTITUDE"].verdict) == (0.0, "high")
    assert (rates["NAVGW_GYRO_BIAS"].configured_hz, rates["NAVGW_GYRO_BIAS"].verdict) == (
        2.0,
        "low",
    )
    assert rates["RATE_OF_TURN"].verdict == "ok"
    assert rates["VESSEL_HEADING"].verdict == "high"  # 10 Hz on the bus, not configured here
    quiet = BusState(configured_hz=configured)
    quiet.feed(next(iter(read_candump(run.log))))
    (first,) = quiet.sources.values()
    assert {r.name: r.verdict for r in first.rates(state.last_t)}["ATTITUDE"] == "off"


def test_a_stopped_bus_and_a_silent_source_get_a_banner(fed: BusState) -> None:
    assert fed.last_t is not None
    assert fed.banner(fed.last_t + 3.25) == "NO FRAMES for 3.2 s"
    src = fed.current
    assert src is not None
    rates = {r.name: r for r in src.rates(fed.last_t + 10)}
    assert rates["ATTITUDE"].measured_hz == 0 and rates["ATTITUDE"].verdict == "missing"
    assert BusState().banner(0.0) == "no frames received yet"


def test_other_nodes_another_navgw_and_garbage_on_one_bus(fed: BusState, run: OutputRun) -> None:
    state = BusState()
    other = Name(identity_number=7, manufacturer_code=135, function=130, vehicle_system=25,
                 industry_group=IndustryGroup.MARINE, arbitrary_address_capable=False)  # fmt: skip
    second_navgw = Name(identity_number=2)
    t = 100.0
    state.feed(frame(Pgn.ADDRESS_CLAIM, 0x80, other.payload(), t))
    state.feed(frame(WIND_DATA, 0x80, bytes(8), t))  # a PGN the DBC does not know
    state.feed(frame(Pgn.ATTITUDE, 0x80, b"\x00", t))  # malformed
    state.feed(frame(Pgn.ADDRESS_CLAIM, 254, Name(identity_number=9).payload(), t))  # no room
    assert state.current is None and state.banner(t) == ""
    for i, msg in enumerate(read_candump(run.log)):  # navgw at 0x1C ...
        if i > 3000:
            break
        msg.timestamp = t + i * 1e-3
        state.feed(msg)
        if msg.arbitration_id & 0xFF == 0x1C:  # ... and a second one at 0x85, a NAME apart
            copy = can.Message(
                timestamp=msg.timestamp, arbitration_id=(msg.arbitration_id & ~0xFF) | 0x85,
                data=second_navgw.payload() if msg.arbitration_id >> 8 & 0xFFFF == 0xEEFF
                else msg.data, is_extended_id=True,
            )  # fmt: skip
            state.feed(copy)
    assert list(state.nav_sources) == [0x1C, 0x85]  # 0x80's attitude could not be read
    assert state.selected == 0x1C  # the first navgw
    rows = panels.claim_rows(state)
    assert [r[:2] for r in rows] == [
        ("0x1C", "navgw"), ("0x80", "other node"), ("0x85", "navgw"), ("0xFE", "cannot claim"),
    ]  # fmt: skip
    assert rows[1][2] == "identity 7, manufacturer 135, function 130, class 25, marine"
    assert rows[2][2].startswith("identity 2, ")
    state.select_next()
    assert state.selected == 0x85 and panels.mode_text(state.current) != "no status"
    assert panels.sources_text(state) == "sources: 0x1C navgw  [0x85 navgw]"
    s = state.decoder.stats
    assert (s.unknown, s.malformed) == (1, 1)
    assert "malformed 1" in panels.counters_text(state)
    assert "last malformed: ATTITUDE from 0x80: Wrong data size: 1 instead of 8" in (
        panels.counters_text(state)
    )
    state.select_next()  # back to the first
    assert state.selected == 0x1C
    # 0x1C falls silent while the others go on
    state.feed(frame(Pgn.ATTITUDE, 0x85, bytes(8), t + 10.0))
    assert state.banner(t + 10.5) == "source 0x1C silent for 7.5 s (other nodes still sending)"


def test_the_panels_of_an_idle_bus(tmp_path: Path) -> None:
    state = BusState()
    assert panels.mode_text(state.current) == "no status"
    assert panels.status_text(state.current) == "no NAVGW_STATUS from this source"
    assert panels.rate_rows(state.current, 0.0) == []
    assert panels.sources_text(state) == "no navigation source heard"
