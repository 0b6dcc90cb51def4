"""Per-IMU-sample cost of each engine on the same data, measured in one run, and the ratio.

Run:  .venv/bin/python benchmarks/engine_cost.py [scenario] [seed]

The scenario (default ``short``) goes through the log formats and the real drivers
(LogInputs) once; each engine then gets the same merged stream, and ``solution()`` is read at
50 Hz as the output scheduler does. Best of three passes per engine.
"""

from __future__ import annotations

import dataclasses
import sys
import tempfile
import time
from collections.abc import Callable
from functools import partial

from drivers.samples import GnssFix, ImuSample
from gateway.config.gateway_config import Engine, GatewayConfig, GnssSection, VehicleSection
from gateway.estimation.solution import Estimator
from gateway.fusion.engines import make_engine
from gateway.offline.log_inputs import Input, LogInputs
from sim_bus.scenarios import SCENARIOS, generate
from sim_bus.truth import Truth


def _cost_us(make: Callable[[], Estimator], inputs: list[Input], n_imu: int) -> float:
    best = float("inf")
    for _ in range(3):
        engine = make()
        next_solution = 0.0
        start = time.perf_counter()
        for item in inputs:
            if isinstance(item, ImuSample):
                engine.imu(item)
                if item.t >= next_solution:
                    engine.solution()
                    next_solution = item.t + 0.02
            elif isinstance(item, GnssFix):
                engine.gnss(item)
        best = min(best, time.perf_counter() - start)
    return best / n_imu * 1e6


def main() -> None:
    """Print us/sample of the observer (its default accel-bias filter, or eq. 12) and the EKF
    (two covariance rates) and the ratios."""
    name = sys.argv[1] if len(sys.argv) > 1 else "short"
    seed = int(sys.argv[2]) if len(sys.argv) > 2 else 1
    with tempfile.TemporaryDirectory() as tmp:
        run = generate(SCENARIOS[name], tmp, seed)
        truth = Truth.load(run.truth_file)
        inputs = list(LogInputs(run.imu_log, run.gnss_log))
    n_imu = sum(isinstance(i, ImuSample) for i in inputs)
    config = GatewayConfig(
        vehicle=VehicleSection(
            antenna_lever_arm_m=tuple(truth.antenna_lever_arm_m),
            imu_lever_arm_m=tuple(truth.imu_lever_arm_m),
        ),
        gnss=GnssSection(receiver_latency_s=0.065),
    )
    ekf_every_sample = dataclasses.replace(
        config, ekf=dataclasses.replace(config.ekf, covariance_period_s=0.0)
    )
    eq12 = dataclasses.replace(
        config, observer=dataclasses.replace(config.observer, accel_bias_filter=False)
    )
    costs = {
        "observer": _cost_us(partial(make_engine, config), inputs, n_imu),
        "observer, eq. (12)": _cost_us(partial(make_engine, eq12), inputs, n_imu),
        "ekf (covariance every 50 ms)": _cost_us(
            partial(make_engine, config.with_engine(Engine.EKF)), inputs, n_imu
        ),
        "ekf (covariance every sample)": _cost_us(
            partial(make_engine, ekf_every_sample.with_engine(Engine.EKF)), inputs, n_imu
        ),
    }
    print(f"{name} seed {seed}: {n_imu} IMU samples; python {sys.version.split()[0]}")
    for engine, us in costs.items():
        print(f"  {engine:30s} {us:6.1f} us/sample  {us / costs['observer']:4.1f}x the observer")
    print(f"command: .venv/bin/python benchmarks/engine_cost.py {name} {seed}")


if __name__ == "__main__":
    main()
