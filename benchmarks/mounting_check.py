"""The live check of the IMU mounting in effect: when it says "off", and how near it comes.

Run:  .venv/bin/python benchmarks/mounting_check.py                 # the docs' table
      .venv/bin/python benchmarks/mounting_check.py --mountings 0,0,0 --seeds 41 42 43

Each case simulates a scenario with the IMU bolted at a mounting (roll, pitch, yaw deg) and
replays it through the fusion core (:class:`gateway.fusion.fusion_core.FusionCore`, as
``navgw replay`` runs it) with no mounting configured, so that the check
(:mod:`gateway.fusion.mounting_check`) judges the drive. Per case: when NAVGW_STATUS went
DEGRADED for it (s from the start; "never"), the axes it named, and for each axis the
largest ratio of the error it saw to the bound it judges by over the run (off beyond 1).
With the true mounting 0, 0, 0 every "off" is a false alarm, and the ratios are the margin.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import sys
import tempfile
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from gateway.config.driver_settings import imu_config
from gateway.config.gateway_config import Engine, GatewayConfig, load_config
from gateway.fusion.fusion_core import FusionCore
from gateway.fusion.mounting_check import CHECK_INTERVAL_S
from gateway.offline.log_inputs import LogInputs
from sim_bus.scenarios import SCENARIOS, generate

Vec3 = tuple[float, float, float]
AXES = ("roll", "pitch", "yaw")
#: (mounting, scenarios) of the table in docs/ROBUSTNESS.md, "A mounting the config does
#: not have".
CASES: tuple[tuple[Vec3, tuple[str, ...]], ...] = (
    ((0.0, 0.0, 0.0), tuple(name for name in SCENARIOS if name != "short")),
    ((0.0, 1.0, 0.0), ("field", "calibration")),
    ((3.0, -2.0, 4.0), ("field", "calibration")),
    ((0.0, 0.0, 5.0), ("field", "hillside")),
)


def judge(
    scenario: str, mounting: Vec3, seed: int, engines: Sequence[str]
) -> dict[str, tuple[float | None, str, dict[str, float]]]:
    """Per engine: (when off, s from the start, or None; the axes named; the largest ratio
    per axis)."""
    sc = SCENARIOS[scenario]
    sc = dataclasses.replace(sc, imu=dataclasses.replace(sc.imu, imu_mounting_rpy_deg=mounting))
    out = {}
    with tempfile.TemporaryDirectory(prefix="navgw-mcheck-") as tmp:
        run = generate(sc, tmp, seed)
        config = load_config(run.config_file)
        vehicle = dataclasses.replace(config.vehicle, imu_mounting_rpy_deg=(0.0, 0.0, 0.0))
        config = dataclasses.replace(config, vehicle=vehicle)
        for engine in engines:
            out[engine] = judge_run(run.imu_log, run.gnss_log, config.with_engine(Engine(engine)))
    return out


def replay_core(
    imu_log: Path, gnss_log: Path, config: GatewayConfig, look: Callable[[FusionCore, float], None]
) -> FusionCore:
    """One replay through the core as ``navgw replay`` runs it, ``look`` called after every
    input with the core and the input's time (s from the first); the core at the end."""
    inputs = LogInputs(imu_log, gnss_log, imu_config(config))
    core = FusionCore.from_config(config, inputs.imu_lost)
    inputs.own_name, inputs.own_address = core.claimer.name, config.isobus.preferred_address
    t0: float | None = None
    for x in inputs:
        if t0 is None:
            t0 = x.t
            list(core.start(x.t))
        list(core.on_input(x))
        look(core, x.t - t0)
    return core


def judge_run(
    imu_log: Path, gnss_log: Path, config: GatewayConfig
) -> tuple[float | None, str, dict[str, float]]:
    """The mounting check's verdict (when off, s from the start, or None), the axes it named,
    and the largest ratio per axis, looked at every ``CHECK_INTERVAL_S`` of input time."""
    ratios = dict.fromkeys(AXES, 0.0)
    off_s: float | None = None
    next_look = -math.inf

    def look(core: FusionCore, t_s: float) -> None:
        nonlocal off_s, next_look
        check = core.mounting
        assert check is not None
        if t_s >= next_look:
            next_look = t_s + CHECK_INTERVAL_S
            for off in check.judged():
                ratios[off.axis] = max(ratios[off.axis], off.ratio)
        if off_s is None and check.off:
            off_s = t_s

    check = replay_core(imu_log, gnss_log, config, look).mounting
    assert check is not None
    return off_s, " ".join(f.axis for f in check.found), ratios


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--mountings", nargs="+", help="roll,pitch,yaw deg (default: the docs')")
    parser.add_argument("--scenarios", nargs="+", choices=sorted(SCENARIOS))
    parser.add_argument("--seeds", nargs="+", type=int, default=[1, 2])
    parser.add_argument("--engines", nargs="+", choices=[e.value for e in Engine])
    parser.add_argument("--jobs", type=int, default=2, help="worker processes")
    args = parser.parse_args(argv)
    engines = args.engines or [e.value for e in Engine]
    if args.mountings:
        given = [tuple(float(v) for v in m.split(",")) for m in args.mountings]
        cases = [(m, tuple(args.scenarios or SCENARIOS)) for m in given]
    else:
        cases = [(m, tuple(s for s in names if not args.scenarios or s in args.scenarios))
                 for m, names in CASES]  # fmt: skip
    jobs = [(name, m, seed) for m, names in cases for name in names for seed in args.seeds]
    print("| mounting deg | scenario | seed | engine | off at s | axes | roll | pitch | yaw |")
    print("|---|---|---|---|---|---|---|---|---|")
    with ProcessPoolExecutor(args.jobs) as pool:
        results = pool.map(judge, *zip(*jobs, strict=True), [engines] * len(jobs))
        for (name, m, seed), result in zip(jobs, results, strict=True):
            for engine, (off_s, axes, ratios) in result.items():
                when = "never" if off_s is None else f"{off_s:.0f}"
                cells = " | ".join(f"{ratios[a]:.2f}" for a in AXES)
                mounting = ", ".join(f"{v:g}" for v in m)
                print(
                    f"| {mounting} | {name} | {seed} | {engine} | {when} | {axes} | {cells} |",
                    flush=True,
                )


if __name__ == "__main__":
    main()
