"""Decode cost per IMU sample (two frames) of drivers.imu_can.ImuDecoder, in microseconds.

.venv/bin/python benchmarks/imu_decode.py [SECONDS]
"""

from __future__ import annotations

import sys
import time

import numpy as np

from drivers.imu_can import ImuDecoder, sample_period_s
from sim_bus.adis16334 import Adis16334Config, simulate
from sim_bus.imu_frames import frames


def main(seconds: float = 60.0) -> None:
    """Simulate ``seconds`` of IMU frames, decode them, print the cost per sample."""
    dt = sample_period_s(2)
    n = int(seconds / dt)
    t = 1.7e9 + np.arange(n) * dt
    out = simulate(t, np.zeros((n, 3)), np.tile([0.0, 0.0, -9.80665], (n, 1)), Adis16334Config())
    msgs = list(frames(out))
    decoder = ImuDecoder()
    feed = decoder.feed
    start = time.perf_counter()
    for msg in msgs:
        feed(msg)
    elapsed = time.perf_counter() - start
    assert decoder.counters.samples == n
    print(
        f"{n} samples ({len(msgs)} frames): {elapsed / n * 1e6:.1f} us per sample, "
        f"{elapsed / len(msgs) * 1e6:.1f} us per frame, "
        f"{elapsed / n / dt * 100:.2f} % of one core at {1 / dt:.1f} Hz"
    )


if __name__ == "__main__":
    main(float(sys.argv[1]) if len(sys.argv) > 1 else 60.0)
