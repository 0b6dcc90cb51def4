"""The live check of the antenna lever arm in effect: when it says "off", and how near it comes.

Run:  .venv/bin/python benchmarks/lever_arm_check.py                       # the docs' table
      .venv/bin/python benchmarks/lever_arm_check.py --variants default gnss-1hz --seeds 41

Each case simulates a variant of the robustness benchmark (``benchmarks/robustness.py``,
the `field` preset or ``--base``) and replays it through the fusion core as ``navgw replay``
does, once with the vehicle's true [vehicle] keys and once with the antenna's height left
out (lever arm z = 0). Per engine: with the true lever arm, the largest ratio of the height
error to the bound the check judges by (:mod:`gateway.fusion.lever_arm_check`, off beyond
1; any "off" is a false alarm); with the height left out, when NAVGW_STATUS went DEGRADED
for it (s from the start), the height it measured then, and the attitude frames beyond
0.1 deg + 3 stated sigma of the truth (those excused by DEGRADED not counted: before the
verdict, or from another cause).
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import tempfile
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from mounting_check import replay_core
from robustness import VARIANTS

from gateway.config.gateway_config import Engine, GatewayConfig, VehicleSection
from gateway.fusion.fusion_core import FusionCore
from gateway.offline.log_replay import replay
from sim_bus.scenarios import SCENARIOS, generate, scenario_from_toml
from sim_bus.truth import Truth
from tests.n2k_check import tilt_beyond_stated


@dataclasses.dataclass
class Verdict:
    """What one replay showed: the largest ratio, when off (s), the fit then."""

    ratio: float = 0.0
    off_s: float | None = None
    found: str = ""
    beyond: int = 0  # attitude frames beyond 0.1 deg + 3 stated sigma (DEGRADED excused)


def judge(
    variant: str, seed: int, engines: Sequence[str], base: str
) -> dict[str, tuple[Verdict, Verdict]]:
    """Per engine: (true lever arm, height left out)."""
    scenario = scenario_from_toml({"base": base, "name": variant, **VARIANTS[variant][1]})
    out = {}
    with tempfile.TemporaryDirectory(prefix="navgw-acheck-") as tmp:
        run = generate(scenario, tmp, seed)
        truth = Truth.load(run.truth_file)
        x, y, z = (float(v) for v in truth.antenna_lever_arm_m)
        vehicle = VehicleSection(
            antenna_lever_arm_m=(x, y, z),
            imu_lever_arm_m=tuple(float(v) for v in truth.imu_lever_arm_m),  # type: ignore[arg-type]
            imu_mounting_rpy_deg=scenario.imu.imu_mounting_rpy_deg,
        )
        left_out = dataclasses.replace(vehicle, antenna_lever_arm_m=(x, y, 0.0))
        for engine in engines:
            configs = [
                GatewayConfig(vehicle=v).with_engine(Engine(engine)) for v in (vehicle, left_out)
            ]
            true, wrong = (judge_run(run.imu_log, run.gnss_log, c) for c in configs)
            frames = Path(tmp) / f"{engine}.log"
            replay(run.imu_log, run.gnss_log, frames, configs[1])
            wrong.beyond = len(tilt_beyond_stated(frames, truth)[1])
            out[engine] = (true, wrong)
    return out


def judge_run(imu_log: Path, gnss_log: Path, config: GatewayConfig) -> Verdict:
    """One replay; the fit looked at once a second of input time."""
    verdict = Verdict()
    next_look = 0.0

    def look(core: FusionCore, t_s: float) -> None:
        nonlocal next_look
        check = core.lever_arm
        assert check is not None
        if t_s >= next_look:
            next_look = t_s + 1.0
            fit = check.fit()
            if fit is not None:
                verdict.ratio = max(verdict.ratio, fit.ratio)
        if verdict.off_s is None and check.found is not None:
            verdict.off_s, verdict.found = t_s, check.found.text()

    replay_core(imu_log, gnss_log, config, look)
    return verdict


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--variants", nargs="+", choices=list(VARIANTS), default=list(VARIANTS))
    parser.add_argument("--seeds", nargs="+", type=int, default=[1])
    parser.add_argument("--engines", nargs="+", choices=[e.value for e in Engine])
    parser.add_argument("--base", default="field", choices=sorted(SCENARIOS), help="scenario")
    parser.add_argument("--jobs", type=int, default=2, help="worker processes")
    args = parser.parse_args(argv)
    engines = args.engines or [e.value for e in Engine]
    jobs = [(v, s) for v in args.variants for s in args.seeds]
    print(
        "| variant | seed | engine | true: ratio | off | left out: off at s | measured | beyond |"
    )
    print("|---|---|---|---|---|---|---|---|")
    with ProcessPoolExecutor(args.jobs) as pool:
        results = pool.map(
            judge,
            [v for v, _ in jobs],
            [s for _, s in jobs],
            [engines] * len(jobs),
            [args.base] * len(jobs),
        )
        for (variant, seed), result in zip(jobs, results, strict=True):
            for engine, (true, left_out) in result.items():
                off = "never" if true.off_s is None else f"{true.off_s:.0f} s: {true.found}"
                when = "never" if left_out.off_s is None else f"{left_out.off_s:.0f}"
                print(
                    f"| {variant} | {seed} | {engine} | {true.ratio:.2f} | {off} | {when} | "
                    f"{left_out.found} | {left_out.beyond} |",
                    flush=True,
                )


if __name__ == "__main__":
    main()
