"""Cost of one output instant with every PGN due (9 PGNs, 15 frames), in microseconds.

Run: ``python benchmarks/output_encode.py``.
"""

from __future__ import annotations

import math
import time

import numpy as np

from drivers.samples import FixQuality
from gateway.estimation.solution import Mode, Solution
from gateway.isobus.n2k_encode import LAYOUTS, LoopStatus, OutputEncoder

REPEATS = 2000


def solution(t: float) -> Solution:
    """A fully populated solution, so every field takes the numeric path."""
    return Solution(
        t=t,
        mode=Mode.NAVIGATING,
        roll_rad=0.01,
        pitch_rad=-0.02,
        yaw_rad=1.0,
        yaw_rate_rps=0.05,
        lat_deg=52.1,
        lon_deg=10.5,
        alt_m=80.0,
        vel_ned_mps=(2.0, 1.0, 0.0),
        bias_g_rps=np.array([1e-4, 2e-4, 3e-4]),
        bias_a_mps2=np.array([0.01, 0.02, 0.03]),
        sigma_tilt_rad=math.radians(0.2),
        fix_quality=FixQuality.RTK_FIXED,
        num_sats=15,
        hdop=0.7,
        age_s=1.0,
    )


def main() -> None:
    encoder, loop = OutputEncoder(), LoopStatus(address_claimed=True)
    sols = [solution(1_700_000_000.0 + k * 0.1) for k in range(REPEATS)]
    start = time.perf_counter()
    frames = 0
    for k, sol in enumerate(sols):
        for pgn in LAYOUTS:
            frames += len(encoder.frames(pgn, sol, loop, k % 253))
    elapsed = time.perf_counter() - start
    print(
        f"output instant, all {len(LAYOUTS)} PGNs due ({frames // REPEATS} frames): "
        f"{elapsed / REPEATS * 1e6:.0f} us"
    )


if __name__ == "__main__":
    main()
