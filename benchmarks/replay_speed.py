"""Replay speed: a 15-minute 204.8 Hz field run through ``navgw replay`` with the observer.

.venv/bin/python benchmarks/replay_speed.py [--profile]

Generates the ``field`` scenario into a temporary directory, replays it (the same code as
``navgw replay``) and prints wall time and times real time (target: >= 50x). ``--profile``
also prints the top functions by own time (cProfile).
"""

from __future__ import annotations

import argparse
import cProfile
import pstats
import tempfile
import time
from pathlib import Path

from gateway.config.gateway_config import Engine, GatewayConfig
from gateway.offline.log_replay import replay
from sim_bus.scenarios import SCENARIOS, generate

TARGET_X = 50.0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--profile", action="store_true", help="print a cProfile summary")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        run = generate(SCENARIOS["field"], tmp, seed=0)
        config = GatewayConfig().with_engine(Engine.OBSERVER)
        out = Path(tmp) / "out.log"
        profiler = cProfile.Profile() if args.profile else None
        start = time.perf_counter()
        if profiler is not None:
            profiler.enable()
        summary = replay(run.imu_log, run.gnss_log, out, config)
        if profiler is not None:
            profiler.disable()
        wall = time.perf_counter() - start
    speed = summary.log_span_s / wall
    print(
        f"replay of field ({summary.log_span_s:.0f} s, {summary.stats.imu_samples} IMU samples, "
        f"{summary.stats.gnss_fixes} fixes, {summary.stats.frames_out} frames out): "
        f"{wall:.2f} s wall, {speed:.0f}x real time "
        f"({'meets' if speed >= TARGET_X else 'BELOW'} the {TARGET_X:.0f}x target)"
    )
    if profiler is not None:
        pstats.Stats(profiler).sort_stats("tottime").print_stats(20)


if __name__ == "__main__":
    main()
