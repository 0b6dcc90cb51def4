"""Inputs as a loaded host delivers them to the engines, injected deterministically.

- GNSS epochs late and in bursts: when the service's event loop was starved, the serial reader
  ran seconds late and the epochs of several seconds reached the engine at once, each seconds
  older than the IMU. The observer added its position loop's velocity correction without the
  position it implies over that age, and the vertical loop fed the mismatch back: the height
  diverged to 1e15 m and 129025 carried the antipode of the field.
- IMU samples dropped (an overloaded inbox drops the oldest): the engines integrate over the
  elapsed time, and a gap longer than a few samples makes the solution DEGRADED for a while.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable

import numpy as np
import pytest

from drivers.samples import GnssFix, ImuSample
from gateway.estimation.ekf.ekf_config import EkfConfig
from gateway.estimation.ekf.ekf_engine import EkfEngine
from gateway.estimation.epoch_clock import EpochTime
from gateway.estimation.geodesy import horizontal_ned
from gateway.estimation.observer.observer_config import ObserverConfig
from gateway.estimation.observer.observer_engine import ObserverEngine
from gateway.estimation.solution import IMU_GAP_DEGRADED_S, Estimator, Mode
from tests.kinematics import (
    ORIGIN_LLA,
    Motion,
    Segment,
    gnss_stream,
    imu_stream,
    motion_time,
    state_at,
)

LEVER = (0.5, 0.0, -3.0)
MOTION = Motion(
    [
        Segment(10.0),
        Segment(5.0, accel_mps2=0.6),
        Segment(20.0),
        Segment(math.pi / 0.3, yaw_rate_rps=0.3),
        Segment(20.0),
        Segment(5.0, yaw_rate_rps=-0.2),
        Segment(20.0),
    ]
)


def starved(
    imu: list[ImuSample], fixes: list[GnssFix], every_s: float, delay_s: float
) -> list[ImuSample | GnssFix]:
    """Inputs in the order a starved loop delivers them: fixes held back ``delay_s`` past
    their receive time, then released together at most every ``every_s`` and stamped with
    the release (the time the reader finally ran), after the IMU samples before it."""
    out: list[ImuSample | GnssFix] = []
    held: list[GnssFix] = []
    j, last_release = 0, -math.inf
    for s in imu:
        while j < len(fixes) and fixes[j].t <= s.t:
            held.append(fixes[j])
            j += 1
        if held and s.t >= held[0].t + delay_s and s.t - last_release >= every_s:
            out += [dataclasses.replace(f, t=s.t) for f in held]
            held, last_release = [], s.t
        out.append(s)
    return out


def worst_position_error_m(engine: Estimator, inputs: list[ImuSample | GnssFix]) -> float:
    """Largest horizontal error of the reference point over the run (inf if not finite)."""
    worst = 0.0
    for k, item in enumerate(inputs):
        if isinstance(item, GnssFix):
            engine.gnss(item)
            continue
        engine.imu(item)
        if k % 41:
            continue
        sol = engine.solution()
        if sol.lat_deg is None or sol.lon_deg is None:
            continue
        ne = horizontal_ned((sol.lat_deg, sol.lon_deg), ORIGIN_LLA)
        truth = state_at(MOTION, motion_time(sol.t)).p_ned_m[0]
        err = float(np.hypot(*(ne - truth[:2])))
        worst = max(worst, err if math.isfinite(err) else math.inf)
    return worst


ENGINES: dict[str, Callable[[], Estimator]] = {
    "observer": lambda: ObserverEngine(
        ObserverConfig(antenna_lever_arm_m=LEVER, epoch_time=EpochTime.UTC)
    ),
    "ekf": lambda: EkfEngine(EkfConfig(antenna_lever_arm_m=LEVER, epoch_time=EpochTime.UTC)),
}


@pytest.mark.parametrize("engine", sorted(ENGINES))
@pytest.mark.parametrize(("every_s", "delay_s"), [(0.5, 1.0), (1.0, 2.0), (2.0, 4.0)])
def test_late_bursts_of_epochs_keep_the_reference_point_on_the_track(
    engine: str, every_s: float, delay_s: float
) -> None:
    imu = imu_stream(MOTION, noise_g_rps=1e-4, noise_a_mps2=0.01)
    fixes = gnss_stream(MOTION, antenna_lever_arm_m=LEVER, latency_s=0.07)
    prompt = worst_position_error_m(ENGINES[engine](), starved(imu, fixes, 0.0, 0.0))
    late = worst_position_error_m(ENGINES[engine](), starved(imu, fixes, every_s, delay_s))
    assert prompt < 0.1
    # Seconds of free inertial navigation between bursts, on a motion with turns: metres at
    # most (the divergence this guards against reached 1e15 m, i.e. the antipode).
    assert late < 2.0 + 1.0 * delay_s, (prompt, late)


def yaw_error_deg(engine: Estimator, imu: list[ImuSample], fixes: list[GnssFix]) -> float:
    """Worst heading error over the last 30 s (after the turns) of the run."""
    worst = 0.0
    for k, item in enumerate(starved(imu, fixes, 0.0, 0.0)):
        if isinstance(item, GnssFix):
            engine.gnss(item)
            continue
        engine.imu(item)
        t = motion_time(item.t)
        if k % 41 or t < MOTION.duration_s - 30.0:
            continue
        yaw = engine.solution().yaw_rad
        assert yaw is not None
        d = yaw - float(state_at(MOTION, t).yaw_rad[0])
        worst = max(worst, abs(math.degrees((d + math.pi) % (2 * math.pi) - math.pi)))
    return worst


@pytest.mark.parametrize("engine", sorted(ENGINES))
def test_lost_imu_samples_are_integrated_over_the_elapsed_time(engine: str) -> None:
    """5 % of the samples dropped at random: their rotation is still applied."""
    imu = imu_stream(MOTION, noise_g_rps=1e-4, noise_a_mps2=0.01)
    keep = np.random.default_rng(7).random(len(imu)) >= 0.05
    lossy = [s for s, k in zip(imu, keep, strict=True) if k]
    fixes = gnss_stream(MOTION, antenna_lever_arm_m=LEVER, latency_s=0.07)
    complete = yaw_error_deg(ENGINES[engine](), imu, fixes)
    assert yaw_error_deg(ENGINES[engine](), lossy, fixes) < complete + 0.2


@pytest.mark.parametrize("engine", sorted(ENGINES))
def test_a_gap_in_the_imu_stream_is_reported_degraded_then_recovers(engine: str) -> None:
    imu = imu_stream(MOTION, noise_g_rps=1e-4, noise_a_mps2=0.01)
    gap = (70.0, 70.5)
    imu = [s for s in imu if not gap[0] <= motion_time(s.t) < gap[1]]
    fixes = gnss_stream(MOTION, antenna_lever_arm_m=LEVER, latency_s=0.07)
    modes: dict[float, Mode] = {}
    eng = ENGINES[engine]()
    for item in starved(imu, fixes, 0.0, 0.0):
        if isinstance(item, GnssFix):
            eng.gnss(item)
        else:
            eng.imu(item)
            modes[round(motion_time(item.t), 2)] = eng.solution().mode
    before = [m for t, m in modes.items() if 60.0 <= t < gap[0]]
    during = [m for t, m in modes.items() if gap[1] <= t < gap[1] + IMU_GAP_DEGRADED_S - 0.1]
    after = [m for t, m in modes.items() if gap[1] + IMU_GAP_DEGRADED_S + 0.1 <= t < 85.0]
    assert set(before) == {Mode.NAVIGATING}
    assert during and set(during) == {Mode.DEGRADED}
    assert set(after) == {Mode.NAVIGATING}
