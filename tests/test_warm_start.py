"""Warm start on the simulator (issue 17): a second run continuing the first run's IMU is
accurate within 30 s from the learned state, and not from a cold start; a corrupt or
foreign store changes nothing but a warning; the service saves while running and at stop.

The first run (5 minutes, seven U-turns) is replayed with the EKF as `navgw replay
--state-dir` does; its store seeds both engines (the biases are the IMU's). How each engine
does from its own store after the 16-minute field run is in docs/ACCURACY.md ("Warm start").
"""

from __future__ import annotations

import asyncio
import dataclasses
import json
import logging
import math
import shutil
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from drivers.samples import GnssFix, ImuAux, ImuSample
from gateway.cli.main import main
from gateway.config.driver_settings import imu_config
from gateway.config.gateway_config import (
    Engine,
    GatewayConfig,
    GnssSection,
    StateSection,
    load_config,
)
from gateway.demo.accuracy import (
    StartAccuracy,
    attitude_error_rad,
    record_core,
    start_accuracy,
    truth_at,
)
from gateway.estimation.solution import LearnedState
from gateway.fusion.engines import make_engine
from gateway.fusion.fusion_core import FusionCore
from gateway.offline.log_inputs import LogInputs
from gateway.offline.log_replay import replay
from gateway.service.live_loop import STOP_SAVE_S, GatewayService
from gateway.service.timebase import TimeBase
from gateway.state.keeper import StateKeeper
from gateway.state.store import STATE_FILE, read_state
from sim_bus.scenarios import SCENARIOS, Scenario, SimRun, continuation, generate
from sim_bus.truth import Truth

SHORT = SCENARIOS["short"]
FIRST = dataclasses.replace(
    SHORT, name="short-8", vehicle=dataclasses.replace(SHORT.vehicle, n_passes=8)
)
SECOND = dataclasses.replace(SHORT, vehicle=dataclasses.replace(SHORT.vehicle, n_passes=2))
SEED = 3  # true accelerometer bias at the restart (0.053, -0.084) m/s^2: a cold start shows it


@dataclasses.dataclass(frozen=True)
class Runs:
    second: SimRun
    state_dir: Path  # what the first run learned
    first_truth: Truth


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> Runs:
    out = tmp_path_factory.mktemp("warm-start")
    first = generate(FIRST, out / "first", seed=SEED)
    truth = Truth.load(first.truth_file)
    second = generate(
        continuation(FIRST, truth, SECOND, pause_s=120.0, previous_seed=SEED), out / "second", SEED
    )
    state_dir = out / "state"
    argv = ["replay", "--can", str(first.imu_log), "--nmea", str(first.gnss_log)]
    argv += ["--out", str(out / "first.log"), "--config", str(first.config_file)]
    assert main([*argv, "--engine", "ekf", "--state-dir", str(state_dir)]) == 0
    return Runs(second, state_dir, truth)


def start(run: SimRun, engine: Engine, state_dir: Path | None) -> tuple[StartAccuracy, bool]:
    config = load_config(run.config_file).with_engine(engine)
    keeper = StateKeeper(config, state_dir) if state_dir is not None else None
    warm = keeper.warm_start if keeper is not None and keeper.load() else None
    inputs = LogInputs(run.imu_log, run.gnss_log, imu_config(config))
    core = FusionCore.from_config(config, inputs.imu_lost, warm_start=warm)
    return start_accuracy(record_core(core, inputs), Truth.load(run.truth_file)), core.warm_started


@pytest.mark.parametrize("engine", list(Engine))
def test_a_restarted_gateway_is_accurate_within_half_a_minute(runs: Runs, engine: Engine) -> None:
    """Roll/pitch within 0.1 deg (10 s RMS, held 10 s) and the x/y accelerometer biases
    within 0.01 m/s^2 (held 10 s): warm within 30 s of the start, cold not within 45 s."""
    warm, seeded = start(runs.second, engine, runs.state_dir)
    cold, cold_seeded = start(runs.second, engine, None)
    assert seeded and not cold_seeded
    assert warm.attitude_s is not None and warm.attitude_s <= 30.0, warm
    assert warm.accel_bias_s is not None and warm.accel_bias_s <= 30.0, warm
    assert cold.attitude_s is None or cold.attitude_s > 45.0, cold
    assert cold.accel_bias_s is None or cold.accel_bias_s > 45.0, cold


def test_a_seed_at_rest_levels_the_observer_on_the_rest_with_the_seeded_biases(
    runs: Runs,
) -> None:
    """The observer levelled on the turn-on guess and then ran its tilt loop on the
    turn-on gyro bias until the seed; at rest the seed levels it again on the rest's mean
    specific force less the seeded accelerometer bias. Over the 2 s after the seed roll and
    pitch are within 0.08 deg of truth (seed 3: 0.03; levelled only for the bias change,
    0.21 deg, decaying over 20 s through the tilt loop)."""
    config = load_config(runs.second.config_file).with_engine(Engine.OBSERVER)
    keeper = StateKeeper(config, runs.state_dir)
    assert keeper.load() is not None
    inputs = LogInputs(runs.second.imu_log, runs.second.gnss_log, imu_config(config))
    core = FusionCore.from_config(config, inputs.imu_lost, warm_start=keeper.warm_start)
    trace = record_core(core, inputs)
    assert core.warm_started
    ba_x = trace.bias_a_mps2[:, 0]
    finite = np.isfinite(ba_x)
    seeded_at = int(np.argmax(finite & (ba_x != ba_x[np.argmax(finite)])))  # the turn-on 0
    assert seeded_at > 0
    after = (trace.t >= trace.t[seeded_at]) & (trace.t <= trace.t[seeded_at] + 2.0)
    truth = truth_at(Truth.load(runs.second.truth_file), trace.t[after])
    err = attitude_error_rad(trace.rpy_rad[after], truth.rpy_rad)
    assert np.max(np.abs(err[:, :2])) < math.radians(0.08)


def _replay(run: SimRun, out: Path, state_dir: Path | None) -> bytes:
    config = load_config(run.config_file).with_engine(Engine.OBSERVER)
    replay(run.imu_log, run.gnss_log, out, config, state_dir=state_dir)
    return out.read_bytes()


def test_a_corrupt_or_foreign_store_is_reported_and_ignored(
    runs: Runs, tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """Replayed from a corrupt store, and from the store of another unit, the output is
    byte for byte the cold start's; one warning each says why; the store is then replaced
    by what this run learned."""
    cold = _replay(runs.second, tmp_path / "cold.log", None)
    corrupt = tmp_path / "corrupt"
    corrupt.mkdir()
    (corrupt / STATE_FILE).write_text('{"schema_version": 1, "identity": {')
    foreign = tmp_path / "foreign"
    shutil.copytree(runs.state_dir, foreign)
    doc = json.loads((foreign / STATE_FILE).read_text())
    doc["identity"]["identity_number"] = 42
    (foreign / STATE_FILE).write_text(json.dumps(doc))
    for name, state_dir, reason in (
        ("corrupt", corrupt, "not valid JSON"),
        ("foreign", foreign, "identity_number is 42 in the store, 1 in the config"),
    ):
        caplog.clear()
        with caplog.at_level(logging.WARNING, logger="gateway"):
            assert _replay(runs.second, tmp_path / f"{name}.log", state_dir) == cold
        warnings = [r.getMessage() for r in caplog.records if r.name.startswith("gateway.state")]
        assert len(warnings) == 1 and reason in warnings[0], warnings
        entry = read_state(state_dir / STATE_FILE).bands[0]
        assert entry.engine == "observer" and entry.t_s > doc["bands"][0]["t_s"]


def _power_on(scenario: Scenario) -> Scenario:
    """The same IMU after a power cycle: its accelerometer turn-on bias 10 mg off in x (two
    sigma of the simulator's turn-on spread)."""
    imu = scenario.imu
    bias = imu.accel_turn_on_bias_mps2
    assert bias is not None  # (a continuation's: where the first run's ended)
    turned_on = (bias[0] + 0.1, bias[1], bias[2])
    return dataclasses.replace(
        scenario, imu=dataclasses.replace(imu, accel_turn_on_bias_mps2=turned_on)
    )


def _moved(doc: dict[str, Any]) -> None:
    doc["rest"]["lat_deg"] += 1e-4  # 11 m north


def _no_rest(doc: dict[str, Any]) -> None:
    doc["rest"] = None


def _first_pass_at_once(scenario: Scenario) -> Scenario:
    vehicle = dataclasses.replace(scenario.vehicle, start_stop_s=0.0)
    return dataclasses.replace(scenario, vehicle=vehicle)


@pytest.mark.parametrize(
    ("case", "scenario_change", "store_change", "reason"),
    [
        ("power-on", _power_on, None, "accel x +"),
        ("moved", None, _moved, "the vehicle stands 11."),
        ("no rest", None, _no_rest, "no rest stored with it"),
        ("drove off", _first_pass_at_once, None, "the vehicle drove off before it had stood 4 s"),
    ],
)
def test_a_seed_that_cannot_be_checked_at_rest_on_the_same_spot_is_not_used(
    runs: Runs,
    tmp_path: Path,
    caplog: pytest.LogCaptureFixture,
    case: str,
    scenario_change: Callable[[Scenario], Scenario] | None,
    store_change: Callable[[dict[str, Any]], None] | None,
    reason: str,
) -> None:
    """The learned state is used only where the vehicle stopped, once the IMU measures at
    rest what it measured there: after a power cycle that moved a turn-on bias by 10 mg,
    11 m from the stored rest, with no rest stored, or driven off at once, the start is
    cold (the output byte for byte the cold start's) with one warning saying why."""
    second = runs.second
    if scenario_change is not None:
        scenario = continuation(FIRST, runs.first_truth, SECOND, 120.0, previous_seed=SEED)
        second = generate(scenario_change(scenario), tmp_path / "second", SEED)
    state_dir = tmp_path / "state"
    shutil.copytree(runs.state_dir, state_dir)
    if store_change is not None:
        doc = json.loads((state_dir / STATE_FILE).read_text())
        store_change(doc)
        (state_dir / STATE_FILE).write_text(json.dumps(doc))
    cold = _replay(second, tmp_path / "cold.log", None)
    with caplog.at_level(logging.WARNING, logger="gateway.fusion"):
        assert _replay(second, tmp_path / f"{case}.log", state_dir) == cold
    (warning,) = (r.getMessage() for r in caplog.records if r.name.startswith("gateway.fusion"))
    assert warning.startswith("learned state not used") and reason in warning, warning


def test_an_engine_restarted_after_an_imu_gap_keeps_what_it_learned(runs: Runs) -> None:
    """A 2 s hole in the IMU stream restarts the engine; the new one starts from the old
    one's biases and sigmas, not from the turn-on guess."""
    config = load_config(runs.second.config_file)
    inputs = LogInputs(runs.second.imu_log, runs.second.gnss_log, imu_config(config))
    keeper = StateKeeper(config, runs.state_dir)
    keeper.load()
    core = FusionCore.from_config(config, inputs.imu_lost, keeper.warm_start)
    t0, before, after = None, None, None
    for item in inputs:
        t0 = item.t if t0 is None else t0
        if isinstance(item, ImuSample) and 60.0 <= item.t - t0 < 62.0:
            continue  # the hole
        if isinstance(item, ImuSample) and item.t - t0 >= 62.0 and after is None:
            before = core.engine.learned_state()
            for _ in core.on_input(item):
                pass
            after = core.engine.learned_state()
            break
        for _ in core.on_input(item):
            pass
    assert core.stats.engine_restarts == 1 and core.warm_started
    assert before is not None and after is not None
    assert after.bias_a_mps2 == pytest.approx(before.bias_a_mps2, abs=1e-12)
    assert after.sigma_a_mps2 == pytest.approx(before.sigma_a_mps2, rel=1e-9)
    assert max(after.sigma_a_mps2[:2]) < 0.02  # not the turn-on 0.1


def _service_config(
    run: SimRun, engine: Engine, tmp_path: Path, state_dir: Path, save_interval_s: float
) -> GatewayConfig:
    """The run's config for a service on a virtual bus with no receiver, keeping its state."""
    base = load_config(run.config_file).with_engine(engine)
    return dataclasses.replace(
        base,
        imu=dataclasses.replace(base.imu, interface="virtual", channel=f"ws{id(tmp_path)}"),
        gnss=GnssSection(port=str(tmp_path / "no-receiver")),
        state=StateSection(enabled=True, directory=str(state_dir), save_interval_s=save_interval_s),
    )


async def _first_save(keeper: StateKeeper) -> None:
    """Until the service's state task has written once (10 s wall at most)."""
    deadline = time.monotonic() + 10.0
    while keeper.saves == 0 and time.monotonic() < deadline:
        await asyncio.sleep(0.02)


def test_the_service_saves_while_running_and_at_a_clean_stop(runs: Runs, tmp_path: Path) -> None:
    """On a scaled clock (save_interval_s of 10 s is 0.1 s), a service started from the first
    run's store (warm: checked at rest where the first run stopped) and fed the second run
    saves from its state task, then once more at stop, with the second run's last stop."""
    state_dir = tmp_path / "state"
    shutil.copytree(runs.state_dir, state_dir)
    config = _service_config(runs.second, Engine.EKF, tmp_path, state_dir, 10.0)
    inputs = list(LogInputs(runs.second.imu_log, runs.second.gnss_log, imu_config(config)))

    async def run() -> tuple[int, int]:
        service = GatewayService(config, timebase=TimeBase(inputs[-1].t, time.time(), 100.0))
        for item in inputs:
            for _ in service.core.on_input(item):
                pass
        keeper = service.state
        assert keeper is not None and service.core.warm_started
        running = asyncio.create_task(service.run())
        await _first_save(keeper)
        periodic = keeper.saves
        service.request_stop()
        assert await running == 0
        return periodic, keeper.saves

    periodic, saves = asyncio.run(run())
    assert (periodic, saves) == (1, 2)
    stored = read_state(state_dir / STATE_FILE)
    learned = StateKeeper(config, state_dir)
    assert learned.load() == stored and stored.last is not None
    (entry,) = stored.bands
    assert entry.engine == "ekf" and inputs[-1].t - 1.0 < entry.t_s <= inputs[-1].t
    assert max(entry.accel_mps2.sigma[:2]) < 0.01
    rest = stored.rest
    assert rest is not None and inputs[-1].t - 1.0 < rest.t_s <= inputs[-1].t
    assert rest.duration_s >= 3.0


def test_the_service_saves_a_stop_once_it_is_long_enough(runs: Runs, tmp_path: Path) -> None:
    """A gateway whose power is cut at key-off never stops cleanly: the stop the next start
    checks against is saved once it has lasted STOP_SAVE_S, not at the next save_interval_s
    (an hour here), and once per stop. Fed the second run's first 20 s (parked)."""
    state_dir = tmp_path / "state"
    state_dir.mkdir()
    config = _service_config(runs.second, Engine.OBSERVER, tmp_path, state_dir, 3600.0)
    inputs = list(LogInputs(runs.second.imu_log, runs.second.gnss_log, imu_config(config)))
    parked = [item for item in inputs if item.t - inputs[0].t <= 20.0]

    async def run() -> tuple[int, int]:
        service = GatewayService(config, timebase=TimeBase(parked[-1].t, time.time(), 100.0))
        for item in parked:
            for _ in service.core.on_input(item):
                pass
        keeper = service.state
        assert keeper is not None
        running = asyncio.create_task(service.run())
        await _first_save(keeper)
        first = keeper.saves
        await asyncio.sleep(0.5)  # 50 s of service time: some 50 more looks at the same stop
        again = keeper.saves
        service.request_stop()
        assert await running == 0
        return first, again

    assert asyncio.run(run()) == (1, 1)  # the stop saved once, not again
    rest = read_state(state_dir / STATE_FILE).rest
    assert rest is not None and STOP_SAVE_S <= rest.duration_s < 20.0


def test_without_the_imu_temperature_the_start_is_cold(
    runs: Runs, caplog: pytest.LogCaptureFixture
) -> None:
    """A bridge that sends no IMU_AUX: the learned state is per temperature, so after 3 s
    without one the engine starts cold, and says so once."""
    config = load_config(runs.second.config_file)
    inputs = LogInputs(runs.second.imu_log, runs.second.gnss_log, imu_config(config))
    keeper = StateKeeper(config, runs.state_dir)
    assert keeper.load() is not None
    core = FusionCore.from_config(config, inputs.imu_lost, keeper.warm_start)
    t0 = None
    with caplog.at_level(logging.WARNING, logger="gateway"):
        for item in inputs:
            t0 = item.t if t0 is None else t0
            if item.t - t0 > 10.0:
                break
            if not isinstance(item, ImuAux):
                for _ in core.on_input(item):
                    pass
    (warning,) = (r.getMessage() for r in caplog.records)
    assert "no IMU temperature (IMU_AUX) within 3 s of the first IMU sample: cold start" in warning
    assert not core.warm_started and core.imu_temp_c is None


SEEDED = LearnedState(
    bias_g_rps=(0.002, -0.001, 0.0005),
    sigma_g_rps=(math.radians(0.02),) * 3,
    bias_a_mps2=(0.05, -0.08, 0.0),
    sigma_a_mps2=(0.02, 0.02, 0.05),
)


@pytest.mark.parametrize("engine", list(Engine))
def test_a_seed_states_its_own_accuracy_and_is_taken_only_before_learning(
    runs: Runs, engine: Engine
) -> None:
    """45 s of the second run (30 s parked, then a straight pass, no turn yet): a seeded
    engine states the seed's accelerometer bias sigma (the observer through its learning
    exponent: no convergence flag for 0.02 m/s^2), not the turn-on one; the roll/pitch sigma
    carries it. An engine that has begun to learn refuses a seed, and a second seed too."""
    config = load_config(runs.second.config_file).with_engine(engine)
    inputs = LogInputs(runs.second.imu_log, runs.second.gnss_log, imu_config(config))
    seeded, cold = make_engine(config), make_engine(config)
    assert seeded.seed(SEEDED) and not seeded.seed(SEEDED)
    t0 = None
    for item in inputs:
        t0 = item.t if t0 is None else t0
        if item.t - t0 > 45.0:
            break
        for e in (seeded, cold):
            if isinstance(item, ImuSample):
                e.imu(item)
            elif isinstance(item, GnssFix):
                e.gnss(item)
    learned, sol = seeded.learned_state(), seeded.solution()
    assert learned is not None and sol.sigma_tilt_rad is not None
    if engine is Engine.OBSERVER:
        assert learned.sigma_a_mps2[:2] == pytest.approx((0.02, 0.02), rel=0.05)
        assert learned.bias_a_mps2[:2] == pytest.approx((0.05, -0.08), abs=0.005)
        assert not sol.convergence.accel_xy
    else:  # P's bias block started from the seed and learned on from it
        assert 0.003 < min(learned.sigma_a_mps2[:2]) <= max(learned.sigma_a_mps2[:2]) <= 0.0201
    assert sol.sigma_tilt_rad >= 0.02 / 9.80665 * 0.95
    cold_learned = cold.learned_state()
    assert cold_learned is not None and not cold.seed(SEEDED)
    assert cold.learned_state() == cold_learned
