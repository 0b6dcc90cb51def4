"""Per-IMU-sample cost of the observer engine in CPython (target <= 20 us).

Run:  .venv/bin/python benchmarks/observer_cost.py

Drives :class:`gateway.engine_observer.ObserverEngine` with 10 minutes of exact motion (straight
and circles, 204.8 Hz IMU, 10 Hz GNSS) and reports the mean wall time per IMU sample, GNSS
epochs included (amortised), and the cost of the bare observer propagation.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from gateway.engine_observer import ObserverEngine
from gateway.estimator_config import ObserverConfig
from tests.kinematics import Motion, Segment, gnss_stream, imu_stream, run


def main() -> None:
    """Print microseconds per IMU sample for the engine and the bare observer."""
    motion = Motion(
        [Segment(10.0), Segment(2.0, accel_mps2=1.5)]
        + [Segment(60.0), Segment(30.0, yaw_rate_rps=0.3)] * 6,
        roll_rad=0.05,
    )
    lever = (0.5, 0.0, -3.0)
    imu = imu_stream(
        motion,
        bias_g_rps=(0.002, -0.002, 0.003),
        bias_a_mps2=(0.05, 0.0, 0.0),
        noise_g_rps=0.003,
        noise_a_mps2=0.02,
    )
    fixes = gnss_stream(motion, antenna_lever_arm_m=lever, vel_noise_mps=0.02)
    engine = ObserverEngine(ObserverConfig(antenna_lever_arm_m=lever))
    t0 = time.perf_counter()
    run(engine, imu, fixes)
    t_engine = time.perf_counter() - t0
    obs = engine._observer
    assert obs is not None
    obs.learn = True
    w, f, dt = (0.01, 0.02, 0.3), (0.1, 0.2, -9.8), imu[0].dt
    n = 200_000
    t0 = time.perf_counter()
    for _ in range(n):
        obs.propagate(w, f, dt)
    t_obs = time.perf_counter() - t0
    print(
        f"engine:   {1e6 * t_engine / len(imu):6.2f} us/sample over {len(imu)} samples "
        f"and {len(fixes)} GNSS epochs"
    )
    print(f"observer: {1e6 * t_obs / n:6.2f} us/sample (propagate only, learning on)")
    print(f"python {sys.version.split()[0]}")


if __name__ == "__main__":
    main()
