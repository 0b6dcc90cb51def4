"""Time the simulated RTK receiver over 15 min at 10 Hz (budget: < 2 s).

.venv/bin/python benchmarks/gnss_sim.py
"""

from __future__ import annotations

import time

import numpy as np

from gateway.estimation.geodesy import ned_to_lla
from sim_bus.gnss_receiver import GnssReceiverConfig, simulate_receiver
from sim_bus.truth import Truth

DURATION_S = 15 * 60.0
DT_S = 4.0 / 819.2  # IMU at 204.8 Hz, as the vehicle simulator writes it
ORIGIN = np.array([52.2, 10.5, 80.0])


def headland_circles() -> Truth:
    """Circles of 6 m radius at 3 m/s: the truth the receiver interpolates (204.8 Hz rows)."""
    t = 1_700_000_000.0 + np.arange(0.0, DURATION_S, DT_S)
    n, ang = len(t), (t - t[0]) * 0.5
    pos = np.column_stack((6.0 * np.cos(ang), 6.0 * np.sin(ang), np.zeros(n)))
    vel = np.column_stack((-3.0 * np.sin(ang), 3.0 * np.cos(ang), np.zeros(n)))
    rpy = np.column_stack((np.zeros(n), np.zeros(n), ang + np.pi / 2))
    lla, zeros, flags = ned_to_lla(pos, ORIGIN), np.zeros((n, 3)), np.zeros(n, bool)
    return Truth(
        t, pos, lla, vel, rpy, zeros, zeros, pos, lla, vel, flags, flags, zeros, zeros, ORIGIN
    )


def main() -> None:
    truth = headland_circles()
    config = GnssReceiverConfig(rate_hz=10.0, hdt=True)
    start = time.perf_counter()
    out = simulate_receiver(truth, config)
    elapsed = time.perf_counter() - start
    print(
        f"gnss_sim: {len(out.t_utc)} epochs, {len(out.lines)} sentences "
        f"(15 min at 10 Hz, all six types) in {elapsed:.3f} s"
    )


if __name__ == "__main__":
    main()
