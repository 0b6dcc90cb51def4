"""IMU mounting calibration (issue 17): random mountings found back, and what they are worth.

Run:  .venv/bin/python benchmarks/mounting.py                       # seeds 1-6
      .venv/bin/python benchmarks/mounting.py --scenario field --seeds 1 2 3 --no-accuracy

Per seed, a mounting drawn uniformly in +/-10 deg on each axis (numpy default_rng(seed)).
The calibration drive (``--scenario``, default ``calibration``) is simulated with the IMU so
mounted and calibrated as ``navgw calibrate`` does, from its config with no mounting set; the
error is the rotation from the true mounting to the one found, per axis. Then the accuracy
run (``--accuracy``, default ``field``) is simulated with the same mounting and replayed
through both engines with the true mounting configured, with the calibrated one and with
none: roll, pitch and yaw RMS error and the reference point's error from attitude, over the
converged part (after 600 s on field; :func:`gateway.demo.accuracy.evaluate`).
"""

from __future__ import annotations

import argparse
import dataclasses
import logging
import math
import sys
import tempfile
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from accuracy import FIXED_CONVERGED_S, summary

from drivers.samples import GnssFix, ImuSample
from drivers.units import RAD_TO_DEG
from gateway.cli.cmd_calibrate import calibrate
from gateway.config.driver_settings import imu_config
from gateway.config.gateway_config import GatewayConfig, load_config
from gateway.demo.accuracy import evaluate, record
from gateway.demo.baselines import ENGINES, RunSetup
from gateway.estimation.attitude import dcm_from_rpy_deg, rpy_from_dcm
from gateway.offline.log_inputs import LogInputs
from sim_bus.scenarios import SCENARIOS, generate
from sim_bus.truth import Truth

Vec3 = tuple[float, float, float]
ENGINE_NAMES = ("observer", "ekf")


@dataclass(frozen=True)
class SeedResult:
    """One seed: the mounting, the one found, its sigma and state; the accuracy per engine
    and mounting configured ("true", "calibrated", "not set"): roll, pitch, yaw RMS deg,
    ref(att) cm."""

    seed: int
    truth_deg: Vec3
    found_deg: Vec3 | None
    sigma_deg: Vec3
    determined: bool
    missing: list[str]
    accuracy: dict[tuple[str, str], tuple[float, float, float, float]]

    @property
    def error_deg(self) -> Vec3:
        """Per axis, the rotation from the true mounting to the one found (NaN: none)."""
        if self.found_deg is None:
            return (math.nan, math.nan, math.nan)
        c = dcm_from_rpy_deg(self.found_deg) @ dcm_from_rpy_deg(self.truth_deg).T
        roll, pitch, yaw = rpy_from_dcm(c)
        yaw = (yaw + math.pi) % (2.0 * math.pi) - math.pi
        return (roll * RAD_TO_DEG, pitch * RAD_TO_DEG, yaw * RAD_TO_DEG)


def mounted(scenario: str, mounting: Vec3, out: Path, seed: int) -> GatewayConfig:
    """Generate ``scenario`` with the IMU at ``mounting``; its config without the mounting."""
    sc = SCENARIOS[scenario]
    sc = dataclasses.replace(sc, imu=dataclasses.replace(sc.imu, imu_mounting_rpy_deg=mounting))
    run = generate(sc, out, seed)
    config = load_config(run.config_file)
    return with_mounting(config, (0.0, 0.0, 0.0))


def with_mounting(config: GatewayConfig, mounting: Vec3) -> GatewayConfig:
    """``config`` with ``[vehicle] imu_mounting_rpy_deg = mounting``."""
    vehicle = dataclasses.replace(config.vehicle, imu_mounting_rpy_deg=mounting)
    return dataclasses.replace(config, vehicle=vehicle)


def engine_accuracy(
    run_dir: Path, scenario: str, config: GatewayConfig
) -> dict[str, tuple[float, float, float, float]]:
    """Both engines on the run's logs decoded with ``config``'s mounting."""
    inputs = [
        x
        for x in LogInputs(run_dir / "imu.log", run_dir / "gnss.nmea", imu_config(config))
        if isinstance(x, ImuSample | GnssFix)
    ]
    truth = Truth.load(run_dir / "truth.npz")
    setup = RunSetup(config.vehicle.antenna_lever_arm_m, config.vehicle.imu_lever_arm_m)
    out = {}
    for name in ENGINE_NAMES:
        trace = record(ENGINES[name](setup), inputs)
        acc = evaluate(trace, truth, setup.antenna_lever_arm_m, FIXED_CONVERGED_S.get(scenario))
        rms = acc.rpy_rms_rad * RAD_TO_DEG
        out[name] = (float(rms[0]), float(rms[1]), float(rms[2]), acc.ref_from_att_h_rms_m * 100)
    return out


def one_seed(seed: int, scenario: str, accuracy_scenario: str | None) -> SeedResult:
    """Calibrate one random mounting; then the accuracy with it and with the true one."""
    logging.getLogger("gateway.estimation").setLevel(logging.ERROR)  # "not set": it complains
    r, p, y = np.random.default_rng(seed).uniform(-10.0, 10.0, 3)
    truth = (float(r), float(p), float(y))
    with tempfile.TemporaryDirectory(prefix="navgw-mount-") as tmp:
        config = mounted(scenario, truth, Path(tmp), seed)
        cal = calibrate(Path(tmp) / "imu.log", Path(tmp) / "gnss.nmea", config, 0.15)
    result = cal.result
    accuracy: dict[tuple[str, str], tuple[float, float, float, float]] = {}
    if accuracy_scenario is not None and cal.mounting_rpy_deg is not None:
        with tempfile.TemporaryDirectory(prefix="navgw-mount-") as tmp:
            config = mounted(accuracy_scenario, truth, Path(tmp), seed)
            for label, mounting in (
                ("true", truth),
                ("calibrated", cal.mounting_rpy_deg),
                ("not set", (0.0, 0.0, 0.0)),
            ):
                acc = engine_accuracy(Path(tmp), accuracy_scenario, with_mounting(config, mounting))
                for engine, values in acc.items():
                    accuracy[(engine, label)] = values
    return SeedResult(
        seed,
        truth,
        cal.mounting_rpy_deg,
        result.sigma_deg if result else (math.inf, math.inf, math.inf),
        cal.determined,
        result.manoeuvres if result else [],
        accuracy,
    )


def calibration_table(results: Sequence[SeedResult], scenario: str) -> str:
    """Per seed: true mounting, found, error and 1-sigma per axis; mean/worst |error|."""
    lines = [
        f"**Calibration on {scenario}** (deg; error = found - true as a rotation, per axis)\n",
        "| seed | true r, p, y | found r, p, y | error r | error p | error y | sigma r, p, y "
        "| determined |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for s in results:
        found = "-" if s.found_deg is None else ", ".join(f"{a:.2f}" for a in s.found_deg)
        err = s.error_deg
        lines.append(
            f"| {s.seed} | {', '.join(f'{a:.2f}' for a in s.truth_deg)} | {found} | "
            + " | ".join(f"{e:+.3f}" for e in err)
            + f" | {', '.join(f'{x:.2f}' for x in s.sigma_deg)} | "
            + ("yes" if s.determined else "no: " + "; ".join(s.missing))
            + " |"
        )
    worst = [summary([abs(s.error_deg[i]) for s in results], 3) for i in range(3)]
    lines.append(f"| mean/worst abs | | | {' | '.join(worst)} | | |")
    return "\n".join(lines) + "\n"


def accuracy_table(results: Sequence[SeedResult], scenario: str) -> str:
    """Per engine and mounting configured: RMS errors, mean/worst over the seeds."""
    lines = [
        f"**Accuracy on {scenario}** with the true, the calibrated and no mounting, seeds "
        f"{', '.join(str(s.seed) for s in results)} (mean/worst; deg, cm)\n",
        "| engine | mounting | roll rms | pitch rms | yaw rms | ref(att) rms cm |",
        "|---|---|---|---|---|---|",
    ]
    for engine in ENGINE_NAMES:
        for label in ("true", "calibrated", "not set"):
            cells = [
                summary([s.accuracy[(engine, label)][i] for s in results if s.accuracy], 3)
                for i in range(4)
            ]
            lines.append(f"| {engine} | {label} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def main(argv: Sequence[str] | None = None) -> None:
    """Parse options, run the seeds in worker processes, print the tables."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenario", choices=sorted(SCENARIOS), default="calibration")
    ap.add_argument("--accuracy", choices=sorted(SCENARIOS), default="field")
    ap.add_argument("--no-accuracy", action="store_true", help="calibration errors only")
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3, 4, 5, 6])
    ap.add_argument("--jobs", type=int, default=2, help="worker processes")
    args = ap.parse_args(argv)
    accuracy = None if args.no_accuracy else args.accuracy
    with ProcessPoolExecutor(max_workers=args.jobs) as pool:
        futures = [pool.submit(one_seed, s, args.scenario, accuracy) for s in args.seeds]
        results = [f.result() for f in futures]
    print(calibration_table(results, args.scenario))
    if accuracy is not None:
        print(accuracy_table(results, accuracy))


if __name__ == "__main__":
    main()
