"""The cross-track floor through a minute of RTK float: a covariance analysis (issue 16).

What the best causal filter can do with the simulator's receiver (sim_bus/gnss_receiver.py)
and this IMU, whatever its design: one horizontal axis across the track, states

- x: cross-track position error, x' = u psi (no sideslip: the wheeled-vehicle constraint);
- psi: heading error, a random walk of the gyro's ARW (ADIS16334: 2 deg/sqrt(h));
- b: the float fix's error, first-order Gauss-Markov (15 cm, 60 s),

measured at 10 Hz by the lateral GNSS velocity (u psi + white) and the float fix (x + b).
Starting from RTK fixed (1 cm), the RMS of sqrt(P_xx) over the minute is the floor of the
cross-track RMS through it (cm: RMS over the minute / at its end). Dead reckoning on the
GNSS velocity instead of the gyro gives the same within a few mm: at a minute's time scale
the gyro's heading wanders more than the course over ground (ARW alone: 0.26 deg in 60 s),
so the IMU cannot hold the track better than the integrated velocity noise,
sigma_v sqrt(T t).

    .venv/bin/python benchmarks/float_floor.py
"""

from __future__ import annotations

import argparse
import math

import numpy as np

from drivers.units import DEG_TO_RAD, SQRT_SECONDS_PER_HOUR

EPOCH_S = 0.1  # 10 Hz receiver
SPEED_MPS = 3.0
FLOAT_SIGMA_M = 0.15  # sim_bus.gnss_receiver.DEFAULT_NOISE, RTK float, per horizontal axis
FLOAT_TAU_S = 60.0
FIXED_SIGMA_M = 0.01  # the position when float starts
HEADING_SIGMA0_RAD = 0.05 * DEG_TO_RAD  # converged heading before the float minute
ARW_RAD_PER_SQRT_S = 2.0 * DEG_TO_RAD / SQRT_SECONDS_PER_HOUR


def cross_track_floor_m(
    sigma_vel_mps: float, use_imu: bool, use_fixes: bool, minute_s: float = 60.0
) -> tuple[float, float]:
    """(RMS over the minute, value at its end) of the cross-track 1-sigma, m."""
    decay = math.exp(-EPOCH_S / FLOAT_TAU_S)
    q_b = FLOAT_SIGMA_M**2 * (1.0 - decay * decay)
    if use_imu:
        f = np.array([[1.0, SPEED_MPS * EPOCH_S, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, decay]])
        q = np.diag([0.0, ARW_RAD_PER_SQRT_S**2 * EPOCH_S, q_b])
    else:  # x += measured lateral velocity * T
        f = np.diag([1.0, 1.0, decay])
        q = np.diag([(sigma_vel_mps * EPOCH_S) ** 2, 0.0, q_b])
    p = np.diag([FIXED_SIGMA_M**2, HEADING_SIGMA0_RAD**2, FLOAT_SIGMA_M**2])
    h_vel = np.array([[0.0, SPEED_MPS, 0.0]])
    h_fix = np.array([[1.0, 0.0, 1.0]])
    var_x = []
    for _ in range(round(minute_s / EPOCH_S)):
        p = f @ p @ f.T + q
        updates = [(h_vel, sigma_vel_mps**2)] if use_imu else []
        if use_fixes:
            updates.append((h_fix, 1e-8))  # the float error is all wander (the simulator)
        for h, r in updates:
            k = p @ h.T / float((h @ p @ h.T)[0, 0] + r)
            p = p - k @ h @ p
        var_x.append(float(p[0, 0]))
    return math.sqrt(sum(var_x) / len(var_x)), math.sqrt(var_x[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sigma-vel", type=float, nargs="+", default=[0.03, 0.02])
    args = ap.parse_args()
    print(
        "| velocity sigma cm/s | IMU + fixes | IMU, no fixes | GNSS velocity + fixes "
        "| GNSS velocity only |"
    )
    print("|---|---|---|---|---|")
    for s in args.sigma_vel:
        cells = [
            "{:.1f} / {:.1f}".format(*(100.0 * x for x in cross_track_floor_m(s, imu, fixes)))
            for imu, fixes in ((True, True), (True, False), (False, True), (False, False))
        ]
        print(f"| {100.0 * s:.0f} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
