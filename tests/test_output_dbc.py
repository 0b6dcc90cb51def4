"""The output DBC describes SPEC 4, and ``cantools decode`` reads a candump of our output."""

import subprocess
import sys
from pathlib import Path

import pytest

import dbc
from gateway.estimation.solution import Mode, Solution
from gateway.isobus.j1939 import FrameId, Pgn
from gateway.isobus.n2k_encode import LAYOUTS, LoopStatus, OutputEncoder
from gateway.isobus.output_scheduler import DEFAULT_RATES_HZ, OutputScheduler

DB = dbc.load(dbc.OUTPUT_DBC)

EXPECTED = {  # name: (priority, PGN, cycle time ms)
    "ATTITUDE": (3, 127257, 20),
    "RATE_OF_TURN": (2, 127251, 20),
    "VESSEL_HEADING": (2, 127250, 100),
    "POSITION_RAPID_UPDATE": (2, 129025, 20),
    "COG_SOG_RAPID_UPDATE": (2, 129026, 100),
    "GNSS_POSITION_DATA_FP": (3, 129029, 100),
    "ADDRESS_CLAIM": (6, 60928, None),
    "ISO_REQUEST": (6, 59904, None),
    "NAVGW_GYRO_BIAS": (6, 0xFF20, 1000),
    "NAVGW_ACCEL_BIAS": (6, 0xFF21, 1000),
    "NAVGW_STATUS": (6, 0xFF22, 100),
}


@pytest.mark.parametrize("name", EXPECTED)
def test_every_spec_frame_is_a_j1939_pg_with_priority_pgn_and_cycle(name: str) -> None:
    message = DB.get_message_by_name(name)
    priority, pgn, cycle = EXPECTED[name]
    frame_id = FrameId.parse(message.frame_id)
    assert (frame_id.priority, frame_id.pgn) == (priority, pgn)
    assert message.protocol == "j1939"
    assert message.cycle_time == cycle
    assert message.comment
    if pgn in DEFAULT_RATES_HZ:
        assert cycle == round(1000 / DEFAULT_RATES_HZ[Pgn(pgn)])
        assert frame_id.source == 0x1C


def test_reassembled_129029_payload_has_its_own_placeholder_id() -> None:
    payload = DB.get_message_by_name("GNSS_POSITION_DATA")
    assert payload.length == 47
    assert payload.frame_id == 3 << 26 | (129029 | 1 << 17) << 8 | 0x1C  # extended data page
    assert payload.comment is not None
    assert "fast-packet" in payload.comment


def test_reassembled_payload_decodes_with_cantools() -> None:
    sol = Solution(t=1_700_000_000.5, mode=Mode.NAVIGATING, lat_deg=48.1, lon_deg=11.6, alt_m=520.0)
    payload = OutputEncoder().payload(Pgn.GNSS_POSITION_DATA, sol, LoopStatus(), 9)
    decoded = DB.get_message_by_name("GNSS_POSITION_DATA").decode(payload)
    assert isinstance(decoded, dict)  # a plain message, not a container
    assert decoded["SID"] == 9
    assert decoded["LATITUDE"] == pytest.approx(48.1, abs=1e-12)
    assert decoded["ALTITUDE"] == pytest.approx(520.0, abs=1e-6)
    assert str(decoded["METHOD"]) == "NOT_AVAILABLE"
    assert str(decoded["HDOP"]) == "NOT_AVAILABLE"


def test_every_encoded_message_is_in_the_dbc() -> None:
    names = {m.name for m in DB.messages}
    assert {layout.message for layout in LAYOUTS.values()} <= names


def test_cantools_decode_reads_a_candump_log_of_the_output(tmp_path: Path) -> None:
    sols = [
        Solution(
            t=1_700_000_000.0 + k / 100,
            mode=Mode.NAVIGATING,
            roll_rad=0.05,
            pitch_rad=-0.02,
            yaw_rad=1.5,
            yaw_rate_rps=0.01,
            lat_deg=52.5,
            lon_deg=13.4,
            vel_ned_mps=(1.0, 0.0, 0.0),
        )
        for k in range(100)
    ]
    scheduler = OutputScheduler()
    loop = LoopStatus(source_address=0x1C, address_claimed=True)
    lines = [
        f"({f.timestamp:.6f}) can0 {f.arbitration_id:08X}#{bytes(f.data).hex().upper()}"
        for s in sols
        for f in scheduler.frames(s, loop)
    ]
    result = subprocess.run(
        [sys.executable, "-m", "cantools", "decode", "--single-line", "-m", "0x03FFFF00"]
        + [str(dbc.path(dbc.OUTPUT_DBC))],
        input="\n".join(lines) + "\n",
        capture_output=True,
        text=True,
        timeout=60,
        check=True,
    )
    out = result.stdout.splitlines()
    assert len(out) == len(lines)
    by_name: dict[str, str] = {}
    for line in out:
        for name in EXPECTED:
            if f" {name}(" in line:
                by_name.setdefault(name, line)
    assert "YAW: 1.5 rad" in by_name["ATTITUDE"]
    assert "ROLL: 0.05 rad" in by_name["ATTITUDE"]
    assert "LATITUDE: 52.5 deg" in by_name["POSITION_RAPID_UPDATE"]
    assert "REFERENCE: TRUE" in by_name["VESSEL_HEADING"]
    assert "DEVIATION: NOT_AVAILABLE" in by_name["VESSEL_HEADING"]
    assert "SOG: 1.0 m/s" in by_name["COG_SOG_RAPID_UPDATE"]
    assert "FP_LENGTH: 47 B" in by_name["GNSS_POSITION_DATA_FP"]
    assert "INDUSTRY_CODE: AGRICULTURE" in by_name["NAVGW_STATUS"]
    assert "MODE: NAVIGATING" in by_name["NAVGW_STATUS"]
    assert "MANUFACTURER_CODE: 2046" in by_name["NAVGW_GYRO_BIAS"]
    assert not [line for line in out if "Unknown" in line or "error" in line.lower()]
