"""The pure parts of `navgw fleet`: finding recordings, engine agreement, the table, the CLI's
messages. The Dask runs are in test_fleet_cluster.py."""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from drivers.errors import InputError
from gateway.fleet import recordings as fleet_recordings
from gateway.fleet.agreement import attitude_agreement
from gateway.fleet.recordings import find_recordings, read_manifest
from gateway.fleet.rows import FleetRow, error_row
from gateway.fleet.table import read_rows, schema, write_parquet
from gateway.readback.frame_decoder import DecodeStats
from gateway.readback.run_series import MessageSeries, RunSeries
from sim_bus import scenarios

T0 = 1_700_000_000.0


def write_pair(directory: Path, number: int, t_first: float, t_last: float) -> str:
    """A recorder pair whose CAN log spans ``t_first``..``t_last`` (two frames)."""
    stem = f"navgw-{number:06d}-20231114T2213{number:02d}Z"
    lines = [f"({t:.6f}) can0 0CFF1080#0E800A80F5BF00F2\n" for t in (t_first, t_last)]
    (directory / f"{stem}.imu.log").write_text("".join(lines))
    (directory / f"{stem}.gnss.nmea").write_text("")
    return stem


def test_rotated_pairs_that_follow_on_are_one_recording(tmp_path: Path) -> None:
    s1 = write_pair(tmp_path, 1, T0, T0 + 100.0)
    s2 = write_pair(tmp_path, 2, T0 + 100.005, T0 + 200.0)  # rotated: 5 ms on
    s3 = write_pair(tmp_path, 3, T0 + 260.0, T0 + 300.0)  # a restart a minute later
    s5 = write_pair(tmp_path, 5, T0 + 300.001, T0 + 400.0)  # pair 4 deleted (keep_files)
    found = find_recordings([tmp_path])
    assert [r.name for r in found] == [str(tmp_path / s) for s in (s1, s3, s5)]
    assert found[0].can_logs == (tmp_path / f"{s1}.imu.log", tmp_path / f"{s2}.imu.log")
    assert found[0].nmea_logs == (tmp_path / f"{s1}.gnss.nmea", tmp_path / f"{s2}.gnss.nmea")
    assert found[0].config is None and len(found[1].can_logs) == 1


def test_a_pair_missing_its_partner_is_still_a_recording(tmp_path: Path) -> None:
    stem = write_pair(tmp_path, 1, T0, T0 + 1.0)
    (tmp_path / f"{stem}.gnss.nmea").unlink()
    (found,) = find_recordings([tmp_path])
    assert found.nmea_logs == (tmp_path / f"{stem}.gnss.nmea",)  # the task reports it missing


def test_sim_run_directories_and_their_config(tmp_path: Path) -> None:
    assert (fleet_recordings.SIM_CAN_LOG, fleet_recordings.SIM_NMEA_LOG) == (
        scenarios.IMU_LOG, scenarios.GNSS_LOG,
    )  # fmt: skip
    assert fleet_recordings.SIM_CONFIG == scenarios.CONFIG_FILE
    for name in ("b", "a"):
        (tmp_path / name).mkdir()
        for file in ("imu.log", "gnss.nmea"):
            (tmp_path / name / file).write_text("")
    (tmp_path / "a" / "navgw.toml").write_text("")
    a, b = find_recordings([tmp_path])
    assert (a.name, b.name) == (str(tmp_path / "a"), str(tmp_path / "b"))
    assert a.config == tmp_path / "a" / "navgw.toml" and b.config is None


def test_a_manifest_lists_recordings_relative_to_itself(tmp_path: Path) -> None:
    manifest = tmp_path / "m.toml"
    manifest.write_text(
        '[[recording]]\ncan = ["x/1.imu.log", "x/2.imu.log"]\nnmea = "x/1.gnss.nmea"\n'
        '[[recording]]\nname = "t7"\ncan = "y.log"\nnmea = "y.nmea"\nconfig = "t7.toml"\n'
    )
    first, second = read_manifest(manifest)
    assert first.name == str(tmp_path / "x/1.imu.log") and len(first.can_logs) == 2
    assert second.name == "t7" and second.config == tmp_path / "t7.toml"


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ('[[recording]]\ncan = "a"\nnmea = "b"\nspeed = 3\n', "recording 1: unknown key 'speed'"),
        ('[[recording]]\ncan = "a"\n', "recording 1: nmea: None; expected a path"),
        ('[[recording]]\ncan = []\nnmea = "b"\n', "recording 1: can: []; expected a path"),
        ('[vehicle]\nx = 1\n', "no [[recording]] tables only; expected [[recording]] tables"),
    ],
)  # fmt: skip
def test_a_bad_manifest_says_where_and_what_was_expected(
    tmp_path: Path, text: str, message: str
) -> None:
    (tmp_path / "m.toml").write_text(text)
    with pytest.raises(InputError, match=None) as err:
        read_manifest(tmp_path / "m.toml")
    assert str(err.value).startswith(f"{tmp_path / 'm.toml'}: ") and message in str(err.value)


def test_no_recording_is_an_error_naming_the_path(tmp_path: Path) -> None:
    for path in (tmp_path, tmp_path / "missing"):
        with pytest.raises(InputError, match="expected a manifest"):
            find_recordings([path])


def run_of(t: np.ndarray, roll: np.ndarray, pitch: np.ndarray, yaw: np.ndarray) -> RunSeries:
    series = MessageSeries(127257, list(t))
    series.signals.update(ROLL=list(roll), PITCH=list(pitch), YAW=list(yaw))
    return RunSeries(Path("x"), 0x1C, t[0], t[-1], {"ATTITUDE": series}, DecodeStats())


def test_engine_agreement_is_the_rms_difference_with_heading_wrapped() -> None:
    t = T0 + np.arange(0.0, 10.0, 0.02)
    zero = np.zeros_like(t)
    yaw = np.deg2rad(179.5) * np.ones_like(t)
    a = run_of(t, zero, zero, yaw)
    b = run_of(t, zero + np.deg2rad(0.3), zero - np.deg2rad(0.4), np.deg2rad(-179.5) + zero)
    agreement = attitude_agreement(a, b)
    assert agreement.roll_rms_diff_deg == pytest.approx(0.3)
    assert agreement.pitch_rms_diff_deg == pytest.approx(0.4)
    assert agreement.heading_rms_diff_deg == pytest.approx(1.0)  # across +-180, not 359


def test_engine_agreement_skips_what_one_engine_did_not_send() -> None:
    t = T0 + np.arange(0.0, 10.0, 0.02)
    zero = np.zeros_like(t)
    b_roll = np.where((t > T0 + 4) & (t < T0 + 6), np.nan, np.deg2rad(1.0))
    a_roll = np.deg2rad(1.0 + 2.0 * (t >= T0 + 5))
    a = run_of(t, a_roll, zero, zero)
    agreement = attitude_agreement(a, run_of(t, b_roll, zero, zero))
    assert agreement.roll_rms_diff_deg == pytest.approx(2.0 * math.sqrt(200 / 400), rel=0.02)
    assert math.isnan(attitude_agreement(a, run_of(t, zero + np.nan, zero, zero)).roll_rms_diff_deg)


def test_a_table_of_error_rows_keeps_its_types(tmp_path: Path) -> None:
    rows = [error_row("r1", "observer", 2, "r1/imu.log: no IMU sample")]
    write_parquet(rows, tmp_path / "t.parquet")
    assert read_rows(tmp_path / "t.parquet") == rows
    import pyarrow.parquet as pq

    assert pq.read_schema(tmp_path / "t.parquet").field("imu_lost").type == "int64"
    assert schema().names == [f for f in FleetRow.__dataclass_fields__]


def navgw(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "gateway.cli.main", "fleet", *args],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip


def test_bad_input_exits_2_with_a_message_and_no_traceback(tmp_path: Path) -> None:
    done = navgw(str(tmp_path / "nowhere"), "--out", str(tmp_path / "t.parquet"))
    assert done.returncode == 2 and "Traceback" not in done.stderr
    assert done.stderr.startswith(f"navgw fleet: {tmp_path / 'nowhere'}: not found; expected")
    (tmp_path / "bad.toml").write_text("[estimator]\nengine = 'kalman'\n")
    done = navgw(str(tmp_path), "--out", "t.parquet", "--config", str(tmp_path / "bad.toml"))
    assert done.returncode == 2 and "Traceback" not in done.stderr and "engine" in done.stderr
