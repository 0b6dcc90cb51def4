"""``navgw demo``: a short simulated run through the live service, files and sane numbers."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def test_short_demo_writes_its_files_and_sane_numbers(tmp_path: Path) -> None:
    out = tmp_path / "demo"
    result = subprocess.run(
        [sys.executable, "-m", "gateway.cli", "demo", "--scenario", "short", "--minutes",
         "1.25", "--speed", "10", "--out", str(out)],
        cwd=REPO, capture_output=True, text=True, check=False, timeout=120,
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    text = result.stdout
    for name in ("navgw-output.log", "navgw-demo.png", "navgw-demo.log", "sim/truth.npz"):
        assert (out / name).stat().st_size > 0, name
    assert "\x1b[" not in text  # not a terminal: plain text
    assert re.search(r"sim +\d+\.\d s +mode ", text)  # the live view
    assert "final mode navigating" in text
    roll, pitch, heading = map(float, re.search(
        r"roll (\d+\.\d+), pitch (\d+\.\d+), heading (\d+\.\d+) deg", text).groups())  # fmt: skip
    assert roll < 0.5 and pitch < 0.5 and heading < 3.0, text
    position = float(re.search(r"horizontal RMS error after alignment: (\d+\.\d+) m", text)[1])
    assert position < 1.0, text
    samples = int(re.search(r"inputs +(\d+) IMU samples \((\d+) lost\)", text)[1])
    assert abs(samples - 75 * 204.8) < 5
