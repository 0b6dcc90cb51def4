"""Time the vehicle simulator on the ``field`` preset (about 15 min at 204.8 Hz)."""

from __future__ import annotations

import time

from sim_bus.vehicle import VEHICLE_PRESETS, simulate_vehicle


def main() -> None:
    """Print rows, simulated duration and the best wall time of three runs."""
    best_s = float("inf")
    for _ in range(3):
        start = time.perf_counter()
        truth = simulate_vehicle(VEHICLE_PRESETS["field"], t0_s=1_700_000_000.0, seed=0)
        best_s = min(best_s, time.perf_counter() - start)
    duration_s = truth.t[-1] - truth.t[0]
    print(f"field: {len(truth)} rows, {duration_s:.0f} s simulated, {best_s:.2f} s wall")


if __name__ == "__main__":
    main()
