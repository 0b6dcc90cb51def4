"""Decode cost per IMU sample (two frames) of drivers.imu_can.ImuDecoder, in microseconds.

.venv/bin/python benchmarks/imu_decode.py [SECONDS] [--mounted]

CPU time (``time.process_time``: a busy host slows the wall clock, not the figure), best of
``REPEATS`` runs, every output kept as replay keeps it (allocating for a growing list costs
more than reusing freed memory). ``--mounted``: with a mounting rotation (the product C v
then runs through numpy). Issue 14's budget for this stage: 3 us a sample;
benchmarks/replay_speed.py measures it the same way inside a whole replay.
"""

from __future__ import annotations

import sys
import time

import numpy as np

from drivers.imu_can import ImuCanConfig, ImuDecoder, sample_period_s
from gateway.estimation.attitude import dcm_from_rpy_deg
from sim_bus.adis16334 import Adis16334Config, simulate
from sim_bus.imu_frames import frames

REPEATS = 5
BUDGET_US = 3.0


def main(seconds: float = 60.0, mounted: bool = False) -> None:
    """Simulate ``seconds`` of IMU frames, decode them, print the cost per sample."""
    dt = sample_period_s(2)
    n = int(seconds / dt)
    t = 1.7e9 + np.arange(n) * dt
    out = simulate(t, np.zeros((n, 3)), np.tile([0.0, 0.0, -9.80665], (n, 1)), Adis16334Config())
    msgs = list(frames(out))
    config = ImuCanConfig()
    if mounted:
        c = dcm_from_rpy_deg((10.0, -5.0, 30.0))
        config = ImuCanConfig(c_b_imu=tuple(tuple(float(x) for x in row) for row in c))
    best = float("inf")
    for _ in range(REPEATS):
        decoder = ImuDecoder(config)
        feed = decoder.feed
        start = time.process_time()
        kept = [item for msg in msgs for item in feed(msg)]
        best = min(best, time.process_time() - start)
        assert decoder.counters.samples == n and len(kept) >= n
    per_sample = best / n * 1e6
    print(
        f"{n} samples ({len(msgs)} frames{', mounted' if mounted else ''}): "
        f"{per_sample:.2f} us per sample, {best / len(msgs) * 1e6:.2f} us per frame, "
        f"{best / n / dt * 100:.3f} % of one core at {1 / dt:.1f} Hz "
        f"({'within' if per_sample <= BUDGET_US else 'OVER'} the {BUDGET_US:.0f} us budget)"
    )


if __name__ == "__main__":
    args = [a for a in sys.argv[1:] if a != "--mounted"]
    main(float(args[0]) if args else 60.0, mounted="--mounted" in sys.argv[1:])
