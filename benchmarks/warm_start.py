"""Warm start (issue 17): how soon after a start roll/pitch and the accelerometer biases are
accurate, cold and from the learned state of the run before.

For each seed: a first run (``--first``, default the 16-minute field run) is replayed as
``navgw replay --state-dir`` does (the learned state saved at its end); a second run
(``--second``) continues it ``--pause-s`` later with the same IMU (its bias goes on from
where it ended: :func:`sim_bus.scenarios.continuation`), parked where the first stopped. The
second run goes through the fusion core twice per engine, cold and warm, and
:func:`gateway.demo.accuracy.start_accuracy` says when roll/pitch (10 s RMS within 0.1 deg,
held 10 s) and the x/y accelerometer biases (within 0.01 m/s^2, held 10 s) were reached, in
seconds from the start. A third run is the second after a power cycle (a new turn-on bias,
drawn as for any run): is the store used, and when is roll/pitch right?

    .venv/bin/python benchmarks/warm_start.py --seeds 1 2 3 4 5
    .venv/bin/python benchmarks/warm_start.py --first short --passes 8 --seeds 1 2 3
"""

from __future__ import annotations

import argparse
import dataclasses
import logging
import tempfile
from pathlib import Path

import numpy as np

from drivers.units import MG_MPS2
from gateway.config.driver_settings import imu_config
from gateway.config.gateway_config import Engine, GatewayConfig, load_config
from gateway.demo.accuracy import StartAccuracy, record_core, start_accuracy, truth_at
from gateway.fusion.fusion_core import FusionCore
from gateway.offline.log_inputs import LogInputs
from gateway.offline.log_replay import replay
from gateway.state.keeper import StateKeeper
from sim_bus.scenarios import SCENARIOS, Scenario, SimRun, continuation, generate
from sim_bus.truth import Truth


def second_run(
    run: SimRun, config: GatewayConfig, state_dir: Path | None
) -> tuple[StartAccuracy, bool]:
    """The second run through the core, warm from ``state_dir`` (None: cold)."""
    keeper = None
    if state_dir is not None:
        keeper = StateKeeper(config, state_dir)
        keeper.load()
    inputs = LogInputs(run.imu_log, run.gnss_log, imu_config(config))
    warm = keeper.warm_start if keeper is not None and keeper.stored else None
    core = FusionCore.from_config(config, inputs.imu_lost, warm_start=warm)
    trace = record_core(core, inputs)
    return start_accuracy(trace, Truth.load(run.truth_file)), core.warm_started


def with_passes(scenario: Scenario, passes: int | None) -> Scenario:
    """``scenario`` with ``passes`` swaths (None: as it is)."""
    if passes is None:
        return scenario
    vehicle = dataclasses.replace(scenario.vehicle, n_passes=passes)
    return dataclasses.replace(scenario, name=f"{scenario.name}-{passes}", vehicle=vehicle)


#: ``--engines`` names: the engine, and whether the observer learns its x/y accelerometer
#: biases with the filter (``[observer] accel_bias_filter``, the default) or eq. (12).
VARIANTS = {
    "observer": (Engine.OBSERVER, True),
    "observer-eq12": (Engine.OBSERVER, False),
    "ekf": (Engine.EKF, False),
}


def with_variant(config: GatewayConfig, name: str) -> GatewayConfig:
    """``config`` with the engine variant ``name`` of :data:`VARIANTS`."""
    engine, accel_bias_filter = VARIANTS[name]
    cfg = config.with_engine(engine)
    observer = dataclasses.replace(cfg.observer, accel_bias_filter=accel_bias_filter)
    return dataclasses.replace(cfg, observer=observer)


def configured(path: str | Path, name: str) -> GatewayConfig:
    """The config file at ``path`` with the engine variant ``name`` of :data:`VARIANTS`."""
    return with_variant(load_config(path), name)


def _s(x: float | None) -> str:
    return "never" if x is None else f"{x:.0f}"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--first", default="field", choices=sorted(SCENARIOS))
    ap.add_argument("--passes", type=int, help="swaths of the first run (default: its own)")
    ap.add_argument("--second", default="short", choices=sorted(SCENARIOS))
    ap.add_argument("--pause-s", type=float, default=120.0)
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3])
    ap.add_argument("--engines", nargs="+", default=["observer", "ekf"], choices=list(VARIANTS))
    args = ap.parse_args()
    logging.basicConfig(level=logging.ERROR)
    first = with_passes(SCENARIOS[args.first], args.passes)
    print(
        f"first run {first.name}, second run {args.second} {args.pause_s:g} s later; "
        "seconds from the start of the second run"
    )
    print(
        "| seed | engine | true accel bias x, y at restart m/s^2 | learned accel bias error "
        "x, y | roll/pitch within 0.1 deg cold / warm s | accel x/y bias within 0.01 "
        "cold / warm s | after a power cycle: turn-on change x, y mg: store used?, roll/pitch "
        "within 0.1 deg s |"
    )
    print("|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for seed in args.seeds:
            out = Path(tmp) / str(seed)
            run1 = generate(first, out / "first", seed=seed)
            truth1 = Truth.load(run1.truth_file)
            second = continuation(
                first, truth1, SCENARIOS[args.second], args.pause_s, previous_seed=seed
            )
            run2 = generate(second, out / "second", seed=seed + 1000)
            truth2 = Truth.load(run2.truth_file)
            # the same, after a power cycle: a new turn-on bias, drawn as for any run
            imu_on = dataclasses.replace(
                second.imu, gyro_turn_on_bias_rps=None, accel_turn_on_bias_mps2=None
            )
            power_on = dataclasses.replace(second, imu=imu_on)
            run3 = generate(power_on, out / "power-on", seed=seed + 1000)
            for name in args.engines:
                state_dir = out / f"state-{name}"
                replay(
                    run1.imu_log,
                    run1.gnss_log,
                    out / f"first-{name}.log",
                    configured(run1.config_file, name),
                    state_dir=state_dir,
                )
                stored = StateKeeper(load_config(run1.config_file), state_dir).load()
                assert stored is not None and stored.bands
                entry = stored.bands[-1]
                true_end = truth_at(truth1, np.array([entry.t_s])).bias_a_mps2[0]
                learned_err = np.array(entry.accel_mps2.bias[:2]) - true_end[:2]
                config2 = configured(run2.config_file, name)
                cold, _ = second_run(run2, config2, None)
                warm, seeded = second_run(run2, config2, state_dir)
                on, on_seeded = second_run(run3, config2, state_dir)
                ba0 = truth2.bias_a_mps2[0]
                jump = Truth.load(run3.truth_file).bias_a_mps2[0] - ba0
                print(
                    f"| {seed} | {name} | {ba0[0]:+.3f}, {ba0[1]:+.3f} | "
                    f"{learned_err[0]:+.4f}, {learned_err[1]:+.4f} | "
                    f"{_s(cold.attitude_s)} / {_s(warm.attitude_s)}"
                    f"{'' if seeded else ' (not used)'} | "
                    f"{_s(cold.accel_bias_s)} / {_s(warm.accel_bias_s)} | "
                    f"{jump[0] / MG_MPS2:+.1f}, {jump[1] / MG_MPS2:+.1f}: "
                    f"{'used' if on_seeded else 'not used'}, {_s(on.attitude_s)} |",
                    flush=True,
                )


if __name__ == "__main__":
    main()
