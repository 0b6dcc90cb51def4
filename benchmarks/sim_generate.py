"""Time ``navgw sim field``: each stage and the whole run (logs written to a temp dir).

Run: ``.venv/bin/python benchmarks/sim_generate.py [SCENARIO]``
"""

from __future__ import annotations

import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

from sim_bus.adis16334 import simulate
from sim_bus.gnss_receiver import simulate_receiver
from sim_bus.imu_frames import frames
from sim_bus.scenarios import SCENARIOS, generate
from sim_bus.vehicle import simulate_vehicle


def _best(fn: Callable[[], object], repeat: int = 3) -> float:
    best = float("inf")
    for _ in range(repeat):
        start = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - start)
    return best


def main() -> None:
    """Print the best of three wall times per stage and for the whole generation."""
    sc = SCENARIOS[sys.argv[1] if len(sys.argv) > 1 else "field"]
    truth = simulate_vehicle(sc.vehicle, sc.t0_s, sc.imu.dt_s)
    imu_out = simulate(truth.t, truth.w_ib_b, truth.f_ib_b_imu, sc.imu)
    duration = truth.t[-1] - truth.t[0]
    print(f"{sc.name}: {duration:.0f} s simulated, {len(truth)} IMU samples")
    print(f"  vehicle truth      {_best(lambda: simulate_vehicle(sc.vehicle, sc.t0_s)):6.2f} s")
    stage = _best(lambda: simulate(truth.t, truth.w_ib_b, truth.f_ib_b_imu, sc.imu))
    print(f"  ADIS16334 model    {stage:6.2f} s")
    stage = _best(lambda: sum(1 for _ in frames(imu_out, sc.bridge)))
    print(f"  CAN frames         {stage:6.2f} s")
    print(f"  RTK receiver       {_best(lambda: simulate_receiver(truth, sc.gnss)):6.2f} s")
    with tempfile.TemporaryDirectory() as tmp:
        total = _best(lambda: generate(sc, Path(tmp)))
    print(f"  whole run to disk  {total:6.2f} s  ({duration / total:.0f}x real time)")


if __name__ == "__main__":
    main()
