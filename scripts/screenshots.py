"""The README's pictures of ``navgw monitor`` and ``navgw plot``, from a simulated run.

Run:  .venv/bin/python scripts/screenshots.py [--out docs/img]

Simulates the ``short`` scenario (seed 3), replays it with its vehicle's config, then writes
``navgw-monitor.svg`` (the monitor, headless, 100 s into the run: Textual's own SVG
screenshot) and ``navgw-plot.png`` (``navgw plot`` of the run with its truth).
"""

from __future__ import annotations

import argparse
import asyncio
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from gateway.config.gateway_config import load_config
from gateway.demo.run_plot import save_run_plot
from gateway.monitor.app import MonitorApp
from gateway.monitor.sources import LogSource
from gateway.offline.log_replay import replay
from gateway.readback.run_series import read_run
from sim_bus.scenarios import SCENARIOS, generate
from sim_bus.truth import Truth

SEED = 3
AT_S = 100.0  # the monitor's picture: this far into the run
SIZE = (150, 48)


class _Jump:
    """A clock for LogSource: the start, then AT_S later (the log at 1x)."""

    def __init__(self) -> None:
        self.calls = 0

    def __call__(self) -> float:
        self.calls += 1
        return 0.0 if self.calls == 1 else AT_S


async def monitor_svg(log: Path, path: Path) -> Path:
    """The monitor on ``log`` at AT_S, as an SVG."""
    app = MonitorApp(LogSource(log, clock=_Jump()))
    async with app.run_test(size=SIZE) as pilot:
        await pilot.pause(0.5)
        app.sub_title = f"log {log.name}"
        await pilot.pause(0.1)
        app.save_screenshot(path.name, str(path.parent))
    return path


def main() -> None:
    """Simulate, replay, and write both pictures."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, default=Path("docs/img"))
    args = ap.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        run = Path(tmp)
        generate(SCENARIOS["short"], run, seed=SEED)
        log = run / "navgw-output.log"
        replay(run / "imu.log", run / "gnss.nmea", log, load_config(run / "navgw.toml"))
        print(asyncio.run(monitor_svg(log, args.out / "navgw-monitor.svg")))
        truth = Truth.load(run / "truth.npz")
        print(save_run_plot(read_run(log), args.out / "navgw-plot.png", truth))


if __name__ == "__main__":
    main()
