"""The heading through a long stop, both engines: the vehicle has not turned, so its heading
has not changed, whatever the gyro says; and it goes out NAVIGATING throughout.

Before, a 10-minute stop left the EKF's heading 1.8-8.5 deg off (its z-gyro bias unobserved at
rest), NAVIGATING, and the observer's 0.5 deg off (the gyro's random walk)."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from drivers.units import DEG_TO_RAD, wrap_pi
from gateway.config.gateway_config import Engine, load_config
from gateway.estimation.ekf.ekf_config import EkfConfig
from gateway.estimation.ekf.ekf_engine import EkfEngine
from gateway.estimation.observer.observer_config import ObserverConfig
from gateway.estimation.observer.observer_engine import ObserverEngine
from gateway.estimation.solution import LearningEstimator, Mode
from gateway.offline.log_replay import replay
from sim_bus.scenarios import SCENARIOS, SimRun, generate
from sim_bus.truth import Truth
from tests.kinematics import (
    GYRO_ARW_PER_SAMPLE_RPS,
    Motion,
    Segment,
    gnss_stream,
    imu_stream,
    solutions,
    state_at,
)
from tests.n2k_check import heading_beyond_navigating, status_modes

LEVER = (0.5, 0.0, -3.0)
STOP_S = (70.0, 670.0)  # at rest, motion time
MOTION = Motion(
    [
        Segment(10.0),
        Segment(5.0, accel_mps2=0.6),
        Segment(20.0),
        Segment(10.0, yaw_rate_rps=0.1),
        Segment(20.0),
        Segment(5.0, accel_mps2=-0.6),  # stopped at 70 s
        Segment(600.0),
        Segment(5.0, accel_mps2=0.6),
        Segment(20.0),
    ],
    yaw0_rad=0.7,
)


def _engine(name: str) -> LearningEstimator:
    if name == "observer":
        return ObserverEngine(ObserverConfig(antenna_lever_arm_m=LEVER))
    return EkfEngine(EkfConfig(antenna_lever_arm_m=LEVER))


@pytest.mark.parametrize("hdt", [False, True], ids=["course", "hdt"])
@pytest.mark.parametrize("seed", [1, 2])
@pytest.mark.parametrize("name", ["observer", "ekf"])
def test_a_ten_minute_stop_holds_the_heading_and_says_navigating(
    name: str, seed: int, hdt: bool
) -> None:
    """A 0.03 deg/s z-gyro bias, learnt from the course in the first minute, and the
    datasheet's ARW. Through the stop the heading stays within 0.35 deg of where it
    stopped (the observer's holds every 5 s: the bias error and the random walk within one,
    3 sigma 0.3 deg), and within 0.45 deg of the truth until 20 s after driving off,
    NAVIGATING all the while. Before: the observer's 0.46-0.49 deg from where it stopped,
    the random walk of 10 minutes (0.82 deg 1-sigma); the EKF's 1.8-8.5 deg. With a dual
    antenna's heading (HDT, at rest too) as well: the observer's first hold had doubled
    what HDT had corrected, and the next doubled that (18 deg off after 40 s parked)."""
    imu = imu_stream(
        MOTION,
        bias_g_rps=(0.0, 0.0, 0.03 * DEG_TO_RAD),
        noise_g_rps=GYRO_ARW_PER_SAMPLE_RPS,
        noise_a_mps2=0.01,
        seed=seed,
    )
    fixes = gnss_stream(MOTION, antenna_lever_arm_m=LEVER, vel_noise_mps=0.02, hdt=hdt, seed=seed)
    out = [(t, s) for t, s in solutions(_engine(name), imu, fixes) if t >= STOP_S[0]]
    assert out[-1][0] > STOP_S[1] + 20.0
    t = np.array([t for t, _ in out])
    c_bn = state_at(MOTION, t).c_bn
    yaw_true = np.arctan2(c_bn[:, 1, 0], c_bn[:, 0, 0])
    errors = np.array(
        [math.degrees(wrap_pi(s.yaw_rad - y)) for (_, s), y in zip(out, yaw_true, strict=True)]
    )
    at_rest = t < STOP_S[1]
    assert np.max(np.abs(errors[at_rest] - errors[0])) < 0.35
    assert np.max(np.abs(errors)) < 0.45
    assert {s.mode for _, s in out} == {Mode.NAVIGATING}


@pytest.mark.parametrize("name", ["observer", "ekf"])
def test_inching_round_a_full_lock_turn_is_not_taken_for_a_gyro_bias(name: str) -> None:
    """After the stop, 30 s turning at 0.5 deg/s on the spot: under the stationary speed
    (a tractor inching round a 4 m turn does 3.5 cm/s), but a turn. It is not held and not
    learnt as a z bias: the heading follows it and is within 1 deg of the truth when it
    ends, 3 sigma of the learnt bias's error over 30 s (0.3 deg at 0.01 deg/s) and the
    gyro's random walk (0.18 deg); learnt as a bias the turn would leave it 15 deg off.
    (The bound was 0.35 deg, about 1.2 sigma: seeds 1-7 of this drive end 0.09-0.50 deg
    off, the RMS 0.3, whichever way the heading is aligned.)"""
    turn = Motion(
        [*MOTION.segments[:6], Segment(20.0), Segment(30.0, yaw_rate_rps=0.5 * DEG_TO_RAD)],
        yaw0_rad=MOTION.yaw0_rad,
    )
    imu = imu_stream(turn, noise_g_rps=GYRO_ARW_PER_SAMPLE_RPS, noise_a_mps2=0.01, seed=3)
    fixes = gnss_stream(turn, antenna_lever_arm_m=LEVER, vel_noise_mps=0.02, seed=3)
    out = solutions(_engine(name), imu, fixes)
    t_end, sol = out[-1]
    assert t_end > turn.duration_s - 0.5 and sol.yaw_rad is not None
    c_bn = state_at(turn, np.array([t_end])).c_bn[0]
    error_deg = math.degrees(wrap_pi(sol.yaw_rad - math.atan2(c_bn[1, 0], c_bn[0, 0])))
    assert abs(error_deg) < 1.0, error_deg


@pytest.fixture(scope="module")
def stop_run(tmp_path_factory: pytest.TempPathFactory) -> SimRun:
    """The `short` run (ADIS16334 noise and wandering biases, engine vibration, RTK at
    10 Hz) with a 5-minute stop after its first pass: 7 minutes."""
    sc = SCENARIOS["short"]
    vehicle = dataclasses.replace(sc.vehicle, mid_stop_pass=1, mid_stop_s=300.0)
    return generate(dataclasses.replace(sc, vehicle=vehicle), tmp_path_factory.mktemp("stop"), 1)


@pytest.mark.parametrize("engine", list(Engine))
def test_no_heading_goes_out_beyond_its_accuracy_through_a_stop(
    engine: Engine, stop_run: SimRun, tmp_path: Path
) -> None:
    """``navgw replay`` of the run, decoded by the independent ``nmea2000`` package: no
    127257 heading sent beyond 3 x NAVIGATING's 0.5 deg 1-sigma + 0.1 of the truth while
    NAVGW_STATUS says it is not DEGRADED, and NAVIGATING through the stop. Before, the
    EKF's was 1.6 deg off as it drove off (3615 such frames)."""
    out = tmp_path / "out.log"
    replay(
        stop_run.imu_log,
        stop_run.gnss_log,
        out,
        load_config(stop_run.config_file).with_engine(engine),
    )
    truth = Truth.load(stop_run.truth_file)
    checked, beyond = heading_beyond_navigating(out, truth)
    assert checked > 15_000 and not beyond, beyond[:5]
    stopped = truth.t[truth.stationary]
    late_stop = (stopped > truth.t[0] + 100.0) & (stopped < stopped.max() - 5.0)
    t0, t1 = stopped[late_stop].min() + 5.0, stopped[late_stop].max()
    assert t1 - t0 > 250.0
    assert {mode for t, mode in status_modes(out) if t0 <= t <= t1} == {Mode.NAVIGATING}
