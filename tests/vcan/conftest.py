"""Fixtures for tests on a real SocketCAN bus (vcan) with the real can-utils.

They run where SocketCAN and can-utils exist (CI runs them in the vcan VM of
shared/tools/vcan-vm/run.sh); elsewhere every test here is skipped with the reason.
"""

from __future__ import annotations

import dataclasses
import os
import shutil
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import can
import pytest

from gateway.config.gateway_config import load_config
from gateway.offline.log_replay import replay
from sim_bus.scenarios import SCENARIOS, generate

#: Set by .ci/run: a directory that ``python -m tests.vcan.conftest DIR`` filled on the host,
#: so the emulated guest need not simulate and replay (Python under TCG is ~10x slower).
PREPARED = "NAVGW_VCAN_PREPARED"

#: candump's socket receive buffer (-r), bytes: thousands of frames, so that a candump the
#: emulated guest leaves unscheduled for a while loses none (the default holds far fewer).
RCVBUF_BYTES = 4 * 1024 * 1024


#: Where the kernel lists its CAN receivers (one ``rcvlist_*`` file per kind of filter).
RCVLISTS = Path("/proc/net/can")
#: How long a candump may take to listen (the emulated guest starts one in well under 1 s).
LISTEN_TIMEOUT_S = 30.0


def candump_argv(channel: str, *options: str) -> list[str]:
    """``candump`` with ``options`` on ``channel``, with a socket buffer that loses nothing."""
    return ["candump", *options, "-r", str(RCVBUF_BYTES), channel]


def _raw_receivers(device: str) -> int:
    """CAN_RAW receivers the kernel lists for ``device`` ("any": bound to every interface)."""
    return sum(
        1
        for rcvlist in RCVLISTS.glob("rcvlist_*")
        for line in rcvlist.read_text().splitlines()
        if line.split()[:1] == [device] and line.endswith(" raw")
    )


def record_candump(channel: str, path: Path) -> subprocess.Popen[bytes]:
    """``candump -L`` of ``channel`` (candump's ``<device>[,<filters>]``) into ``path``,
    listening once this returns: the kernel lists one more receiver on the device. A fixed
    sleep is a guess on a slow guest, and the gateway answers within milliseconds (a CI run
    missed its re-claim)."""
    device = channel.split(",")[0]
    before = _raw_receivers(device)
    dump = subprocess.Popen(candump_argv(channel, "-L"), stdout=path.open("w"))
    deadline = time.monotonic() + LISTEN_TIMEOUT_S
    while _raw_receivers(device) <= before:
        assert dump.poll() is None, f"candump on {channel} exited: {dump.returncode}"
        assert time.monotonic() < deadline, f"candump on {channel} not listening"
        time.sleep(0.02)
    return dump


def _vcan_problem(channel: str) -> str | None:
    missing = [t for t in ("candump", "canplayer", "cansend", "ip") if shutil.which(t) is None]
    if missing:
        return f"can-utils/iproute2 not installed: {', '.join(missing)}"
    try:
        can.Bus(interface="socketcan", channel=channel).shutdown()
    except (OSError, can.CanError) as err:
        return f"no SocketCAN interface {channel} here ({err}); run tests/vcan in the vcan VM"
    return None


@pytest.fixture(scope="session")
def vcan0() -> str:
    """The name of a real, up vcan interface."""
    problem = _vcan_problem("vcan0")
    if problem:
        pytest.skip(problem)
    return "vcan0"


def prepare(out: Path) -> Path:
    """Simulate a ~45 s run (rest, one pass, a turn) and replay it: imu.log, gnss.nmea,
    truth.npz and the gateway's output gateway.log."""
    base = SCENARIOS["short"]
    scenario = dataclasses.replace(
        base, vehicle=dataclasses.replace(base.vehicle, n_passes=2, start_stop_s=15.0)
    )
    run = generate(scenario, out, seed=11)
    # with the vehicle's config: without its 3 m mast the gateway would rightly say DEGRADED
    replay(run.imu_log, run.gnss_log, out / "gateway.log", load_config(run.config_file))
    return out


@pytest.fixture(scope="session")
def sim_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The prepared run (see :func:`prepare`), made here unless CI prepared it on the host."""
    prepared = os.environ.get(PREPARED)
    if prepared and (Path(prepared) / "gateway.log").is_file():
        return Path(prepared)
    return prepare(tmp_path_factory.mktemp("vcan-sim"))


@pytest.fixture
def candump(vcan0: str, tmp_path: Path) -> Iterator[Path]:
    """``candump -L`` recording the bus into a file for the duration of the test, listening
    from the start of it."""
    path = tmp_path / "candump.log"
    proc = record_candump(vcan0, path)
    try:
        yield path
    finally:
        proc.terminate()
        proc.wait(timeout=5)


if __name__ == "__main__":
    prepare(Path(sys.argv[1]))
