"""`navgw fleet` on Dask: a small fleet (tests/fleet_run.py) on a LocalCluster and on a real
`dask scheduler` with two `dask worker` processes; the rows against single-recording replays."""

from __future__ import annotations

import json
import math
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from distributed import Client

from gateway.config.gateway_config import Engine
from gateway.fleet.cluster import run_fleet
from gateway.fleet.recordings import find_recordings
from gateway.fleet.rows import FleetRow
from gateway.fleet.table import read_rows
from gateway.fleet.task import FleetJob
from gateway.offline.log_replay import ReplaySummary
from gateway.readback.run_series import RunSeries
from tests.fleet_run import STEM_1, Fleet, expected, make_fleet

#: (recording, engine) -> its single replay's summary and output read back.
Reference = dict[tuple[str, str], tuple[ReplaySummary, RunSeries]]
DASK = Path(sys.executable).parent / "dask"
START_TIMEOUT_S = 120.0  # a busy machine: worker processes import numpy, cantools, navgw


@pytest.fixture(scope="module")
def fleet(tmp_path_factory: pytest.TempPathFactory) -> Fleet:
    return make_fleet(tmp_path_factory.mktemp("fleet"))


@pytest.fixture(scope="module")
def reference(fleet: Fleet, tmp_path_factory: pytest.TempPathFactory) -> Reference:
    """(recording, engine) -> the single replay's (summary, output read back)."""
    out = tmp_path_factory.mktemp("reference")
    return {
        (name, engine.value): expected(fleet, name, engine, out / f"{i}-{engine.value}.log")
        for i, name in enumerate(fleet.originals)
        for engine in Engine
    }


def check_rows(rows: list[FleetRow], fleet: Fleet, reference: Reference, engines: set[str]) -> None:
    """Every recording once per engine; each good row as its single replay; the broken one an
    error row."""
    assert {(r.recording, r.engine) for r in rows} == {
        (name, e) for name in [*fleet.originals, fleet.broken] for e in engines
    }
    for row in rows:
        if row.recording == fleet.broken:
            assert row.error is not None and "no IMU sample" in row.error
            assert row.imu_samples is None and row.navigating_s is None
            continue
        assert row.error is None, row.error
        summary, run = reference[(row.recording, row.engine)]
        assert row.imu_samples == summary.stats.imu_samples > 20_000
        assert row.gnss_fixes == summary.stats.gnss_fixes > 1000
        assert row.frames_out == summary.stats.frames_out
        assert row.parts == (2 if row.recording.endswith(STEM_1) else 1)
        modes = run.labels("NAVGW_STATUS", "MODE")
        assert row.navigating_s is not None and row.navigating_s > 0
        assert ("NAVIGATING" in modes) and ("FAULT" not in modes) and row.fault_s == 0.0
        for axis in "XYZ":
            last = run.numbers("NAVGW_GYRO_BIAS", f"GYRO_BIAS_{axis}")[-1]
            assert getattr(row, f"gyro_bias_{axis.lower()}_dps") == pytest.approx(last)
            last = run.numbers("NAVGW_ACCEL_BIAS", f"ACCEL_BIAS_{axis}")[-1]
            assert getattr(row, f"accel_bias_{axis.lower()}_mps2") == pytest.approx(last)
        assert row.fix_rtk_fixed_share == 1.0 and row.temp_min_c is not None
        assert row.rate_attitude_hz == pytest.approx(50.0, rel=0.02)
        both = len(engines) == 2
        assert (row.heading_rms_diff_deg is not None) == both
        if both:
            assert row.roll_rms_diff_deg is not None and 0.0 < row.roll_rms_diff_deg < 5.0


def test_a_local_cluster_gives_the_rows_of_single_replays(
    fleet: Fleet, reference: Reference
) -> None:
    job = FleetJob((Engine.OBSERVER, Engine.EKF))
    result = run_fleet(find_recordings(fleet.paths), job, workers=2)
    assert result.workers == 2
    check_rows(result.rows, fleet, reference, {"observer", "ekf"})
    assert not math.isclose(result.wall_s, 0.0)


@pytest.fixture
def cluster(tmp_path: Path) -> Iterator[str]:
    """A `dask scheduler` and two `dask worker` processes on localhost, random free ports;
    yields the scheduler's address once both workers are connected; always torn down."""
    scheduler_file = tmp_path / "scheduler.json"
    common = ["--host", "127.0.0.1"]
    procs = [
        subprocess.Popen(
            [str(DASK), "scheduler", *common, "--port", "0", "--dashboard-address", ":0",
             "--scheduler-file", str(scheduler_file)],
            stdout=subprocess.DEVNULL, stderr=(tmp_path / "scheduler.err").open("w"),
        )
    ]  # fmt: skip
    try:
        deadline = time.monotonic() + START_TIMEOUT_S
        while not scheduler_file.exists() or not scheduler_file.read_text().strip():
            assert procs[0].poll() is None, (tmp_path / "scheduler.err").read_text()
            assert time.monotonic() < deadline, "dask scheduler did not start"
            time.sleep(0.1)
        address = json.loads(scheduler_file.read_text())["address"]
        for i in range(2):
            procs.append(
                subprocess.Popen(
                    [str(DASK), "worker", address, *common, "--nworkers", "1", "--nthreads",
                     "1", "--no-dashboard", "--name", f"w{i}"],
                    stdout=subprocess.DEVNULL, stderr=(tmp_path / f"worker{i}.err").open("w"),
                )
            )  # fmt: skip
        with Client(address, timeout=START_TIMEOUT_S) as client:
            client.wait_for_workers(2, timeout=START_TIMEOUT_S)
        yield address
    finally:
        for proc in reversed(procs):
            proc.send_signal(signal.SIGINT)
        for proc in reversed(procs):
            try:
                proc.wait(timeout=30)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()


def test_the_command_runs_unchanged_on_a_dask_scheduler_with_two_workers(
    fleet: Fleet, reference: Reference, cluster: str, tmp_path: Path
) -> None:
    out, logs = tmp_path / "fleet.parquet", tmp_path / "logs"
    done = subprocess.run(
        [sys.executable, "-m", "gateway.cli.main", "fleet", *map(str, fleet.paths), "--out",
         str(out), "--engine", "observer", "--scheduler", cluster, "--logs", str(logs)],
        capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert "on 2 workers" in done.stderr and "1 with errors" in done.stderr
    check_rows(read_rows(out), fleet, reference, {"observer"})
    assert len(list(logs.glob("*.observer.log"))) == 5  # the broken one's too
