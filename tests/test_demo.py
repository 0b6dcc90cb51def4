"""``navgw demo``: a short simulated run through the live service, files and sane numbers."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

from sim_bus.truth import Truth
from tests.n2k_check import (
    Plausible,
    cadence_problems,
    decode_log,
    implausible_frames,
    status_modes,
)

REPO = Path(__file__).resolve().parents[1]
SPEED = 10.0
MINUTES = 1.25
#: The longest a guidance controller may go without attitude or position while navigating,
#: in real (wall) seconds: 12 frames at 50 Hz; at SPEED that is SPEED times more log time.
MAX_GAP_WALL_S = 0.25

pytestmark = pytest.mark.live


def test_short_demo_writes_its_files_and_sane_numbers(tmp_path: Path) -> None:
    out = tmp_path / "demo"
    result = subprocess.run(
        [sys.executable, "-m", "gateway.cli.main", "demo", "--scenario", "short", "--minutes",
         str(MINUTES), "--speed", str(SPEED), "--out", str(out)],
        cwd=REPO, capture_output=True, text=True, check=False, timeout=120,
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    assert "the engine raised" not in result.stderr, result.stderr
    text = result.stdout
    for name in ("navgw-output.log", "navgw-demo.log", "sim/truth.npz"):
        assert (out / name).stat().st_size > 0, name
    assert "\x1b[" not in text  # not a terminal: plain text
    assert re.search(r"sim +\d+\.\d s +mode ", text)  # the live view

    # every frame on the ISOBUS is a plausible reading of the truth, from the first on
    truth = Truth.load(out / "sim" / "truth.npz")
    frames = decode_log(out / "navgw-output.log")
    bad = implausible_frames(
        frames,
        truth,
        Plausible(lag_s=MAX_GAP_WALL_S * SPEED),
        status_modes(out / "navgw-output.log"),
    )
    assert not bad, f"{len(bad)} implausible frames:\n" + "\n".join(bad[:20])

    # inputs: every sample played is accounted for; on a virtual bus nothing is lost on the
    # way, so a sample counted lost is one the service itself dropped (at the core, or its
    # frames shed unread), and says so
    inputs = re.search(r"inputs +(\d+) IMU samples \((\d+) lost\)", text)
    shed = re.search(r"(\d+) (?:IMU samples )?dropped by", text)
    assert inputs is not None and shed is not None, text
    samples, lost = map(int, inputs.groups())
    dropped = int(shed[1])
    # (the demo stops its service right after the playback: a loaded host may leave up to the
    # latency a controller tolerates unread)
    played, backlog = MINUTES * 60 * 204.8, MAX_GAP_WALL_S * SPEED * 204.8
    assert samples + lost <= played + 5 and samples + lost + dropped >= played - backlog, text
    read_late = re.search(r"(\d+) frames read too late shed", text)
    assert read_late is not None, text
    assert lost == 0 or dropped + int(read_late[1]) > 0, text  # no false losses
    final_mode = re.search(r"final mode (\w+)", text)
    assert final_mode is not None, text[-2000:]
    final = final_mode[1]
    assert final != "fault", text[-2000:]
    # the summary's RMS errors from 30 s after the first NAVIGATING ("not measured" if the
    # run ended before)
    rpy = re.search(r"roll (\d+\.\d+), pitch (\d+\.\d+), heading (\d+\.\d+) deg", text)
    position = re.search(r"horizontal RMS error after alignment: (\d+\.\d+) m", text)
    if lost or dropped:
        # 10x magnifies the host's stalls 10 times: a loaded host may make the service shed
        # stale samples, each gap DEGRADED for a while, a long one a new alignment: it sends
        # fewer frames, and says so, but no wrong one
        return

    # it kept up: navigating to the end, accurate, attitude and position at their rate without
    # long gaps (the summary's RMS covers every solution after alignment, DEGRADED spans after
    # dropped samples included, so it is held to its bounds only here)
    assert final == "navigating", text[-2000:]
    if rpy:
        roll, pitch, heading = map(float, rpy.groups())
        assert roll < 0.5 and pitch < 0.5 and heading < 3.0, text
    if position:
        assert float(position[1]) < 1.0, text
    assert (out / "navgw-demo.png").stat().st_size > 0
    navigating = re.search(r"navigating after (\d+\.\d+) s", text)
    assert navigating and rpy and position, text[-2000:]
    t0 = truth.t[0]
    start, end = t0 + float(navigating[1]) + 1.0, t0 + MINUTES * 60.0 - 0.5
    late = cadence_problems(frames, start, end, MAX_GAP_WALL_S * SPEED)
    assert not late, late
