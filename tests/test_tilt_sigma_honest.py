"""The roll/pitch accuracy sent (NAVGW_STATUS byte 7) is honest: the attitude sent is within it.

A cold start on a 6-8 deg slope (scenario ``slope-start``, three seeds), both engines,
through ``navgw replay``; the attitude (127257) decoded by the independent ``nmea2000``
package, the stated 1-sigma by cantools with the project's DBC, each 127257 frame paired
with the last NAVGW_STATUS before it. Per frame the larger of the roll and pitch errors:
for a true Gaussian 1-sigma about 9 % of such frames lie beyond 2 sigma and 0.5 % beyond 3
sigma; asserted: under 30 % and 1 %. Before the observer's accelerometer-bias exponent had
the tilt loop's lag (``ObserverEngine._update_gates``) it stated 0.09 deg while 0.3-0.4 deg
off: on seed 21, 46 % of the frames beyond 2 sigma and 9 % beyond 3.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import cast

import numpy as np
import pytest

from drivers.imu_can import sample_period_s
from drivers.samples import GnssFix, ImuSample
from gateway.config.gateway_config import (
    Engine,
    GatewayConfig,
    GnssSection,
    VehicleSection,
    load_config,
)
from gateway.estimation.observer.observer_config import ObserverConfig
from gateway.estimation.solution import LearnedState, Mode, Solution
from gateway.fusion.engines import make_engine
from gateway.offline.log_replay import replay
from sim_bus.scenarios import SCENARIOS, SimRun, gateway_config, generate, scenario_from_toml
from sim_bus.truth import Truth
from tests.kinematics import (
    GYRO_ARW_PER_SAMPLE_RPS,
    IMU_DT_S,
    ChassisStep,
    Motion,
    Segment,
    fed,
    gnss_stream,
    imu_stream,
    motion_time,
    state_at,
)
from tests.n2k_check import (
    attitude_errors_deg,
    decode_log,
    heading_beyond_navigating,
    position_beyond_mode,
    stated_tilts,
    status_modes,
    tilt_beyond_stated,
)


def beyond_stated(t_s: float, off_deg: float, sigma_rad: float) -> list[str]:
    """The never-lie check of one solution: a line if its tilt, ``off_deg`` from the truth,
    is beyond 0.1 deg + 3 stated sigmas; else none."""
    sigma_deg = math.degrees(sigma_rad)
    if off_deg > 0.1 + 3.0 * sigma_deg:
        return [f"{t_s:.1f} s: {off_deg:.2f} deg off, {sigma_deg:.3f} stated"]
    return []


@pytest.fixture(scope="module", params=[5, 21, 34])
def slope_start(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory) -> SimRun:
    """The run of one seed."""
    return generate(SCENARIOS["slope-start"], tmp_path_factory.mktemp("sigma"), seed=request.param)


def error_over_sigma(log: Path, truth: Truth) -> np.ndarray:
    """Per 127257 frame with roll and pitch: max(|roll error|, |pitch error|) over the 1-sigma
    stated by the NAVGW_STATUS frame last sent before it."""
    ratios = []
    for f in stated_tilts(log):
        assert f.sigma_deg is not None, f"roll/pitch sent at t={f.t:.3f} without an accuracy"
        true = [np.interp(f.t, truth.t, truth.rpy_rad[:, k]) for k in range(2)]
        error_deg = np.degrees(np.max(np.abs(np.subtract((f.roll_rad, f.pitch_rad), true))))
        ratios.append(error_deg / f.sigma_deg)
    return np.array(ratios)


@pytest.mark.parametrize(
    ("engine", "observer_table"),
    [(Engine.OBSERVER, ""), (Engine.OBSERVER, "accel_bias_filter = false"), (Engine.EKF, "")],
    ids=["observer", "observer-eq12", "ekf"],
)
def test_roll_and_pitch_stay_within_their_stated_accuracy_from_a_cold_start_on_a_slope(
    engine: Engine, observer_table: str, slope_start: SimRun, tmp_path: Path
) -> None:
    """Through ``navgw replay`` with the scenario's config file (and an [observer] table)."""
    config = tmp_path / "navgw.toml"
    config.write_text(
        Path(slope_start.config_file).read_text() + f"\n[observer]\n{observer_table}\n"
    )
    out = tmp_path / "out.log"
    replay(slope_start.imu_log, slope_start.gnss_log, out, load_config(config).with_engine(engine))
    ratios = error_over_sigma(out, Truth.load(slope_start.truth_file))
    assert len(ratios) > 5000  # most of the run's 50 Hz attitude frames
    beyond_2, beyond_3 = np.mean(ratios > 2.0), np.mean(ratios > 3.0)
    # the EKF's P is somewhat optimistic in the first minutes on a slope: 25 % beyond 2 sigma
    # (seed 21), still 0.4 % beyond 3
    assert beyond_2 < 0.3, f"{beyond_2:.1%} of the frames beyond 2 sigma"
    assert beyond_3 < 0.01, f"{beyond_3:.2%} of the frames beyond 3 sigma"


def test_on_a_first_straight_the_ekf_states_the_roll_it_cannot_tell_from_the_y_bias() -> None:
    """outages seed 57 (stall check): after a cold start, on the first straight (no turn
    yet), roll and the accelerometer's y bias are one quantity: C b_a and g phi push the
    velocity alike until the heading changes. P keeps that, but only along the roll axis;
    the stated sigma was the mean of the two tilt axes, 0.19 deg with roll 0.7 deg off (a
    10 mg y bias, 2 sigma of the turn-on model). Now the worse axis: here, heading north
    with a 2-sigma y bias, the roll error stays within 2.5 stated sigmas: 2.0 (2.7 before)."""
    drive = Motion([Segment(15.0), Segment(5.0, accel_mps2=0.6), Segment(60.0)], yaw0_rad=0.0)
    cfg = GatewayConfig(vehicle=VehicleSection(antenna_lever_arm_m=(0.3, 0.0, -3.0)))
    cfg = cfg.with_engine(Engine.EKF)
    sig_b0 = cfg.ekf.accel_bias_sigma0_mps2
    c_bn = state_at(drive, 0.0).c_bn[0]  # roll and pitch stay as they start
    roll_true = math.atan2(c_bn[2, 1], c_bn[2, 2])
    imu = imu_stream(drive, bias_a_mps2=(0.0, 2.0 * sig_b0, 0.0), noise_a_mps2=0.02, seed=3)
    fixes = gnss_stream(drive, antenna_lever_arm_m=cfg.vehicle.antenna_lever_arm_m)
    engine = make_engine(cfg)
    ratios = []
    for k, _ in fed(engine, imu, fixes):
        sol = engine.solution()
        if k % 50 or sol.mode != Mode.NAVIGATING or sol.roll_rad is None:
            continue
        assert sol.sigma_tilt_rad is not None
        ratios.append(abs(sol.roll_rad - roll_true) / sol.sigma_tilt_rad)
    assert len(ratios) > 100
    assert max(ratios) < 2.5, max(ratios)


#: Both engines, the observer with each x/y accelerometer bias law (the filter, eq. 12).
ENGINES_AND_BIAS_LAWS = pytest.mark.parametrize(
    ("engine", "accel_bias_filter"),
    [(Engine.OBSERVER, True), (Engine.OBSERVER, False), (Engine.EKF, True)],
    ids=["observer", "observer-eq12", "ekf"],
)


@ENGINES_AND_BIAS_LAWS
def test_a_paper_sized_accelerometer_bias_is_within_the_stated_accuracy_from_the_start(
    engine: Engine, accel_bias_filter: bool
) -> None:
    """Seed 000's example, an accelerometer y bias of 0.2 m/s^2 (a unit not nulled at
    installation; the paper's own had 0.11 on x): until the heading changes it is roll,
    1.2 deg of it. The EKF's P0 has the simulator's 5 mg, and stated 0.30 deg, at rest and
    on the straight (field seed 1 with it: 1094 frames beyond 0.1 deg + 3 sigma); the stated
    accuracy now covers `accel_bias_sigma_covered_mps2` (0.1 m/s^2, the observer's figure)
    until the filter has observed the bias. Every roll sent, from the levelling at rest on,
    within 3 stated sigmas."""
    drive = Motion([Segment(15.0), Segment(5.0, accel_mps2=0.6), Segment(40.0)], yaw0_rad=0.0)
    cfg = GatewayConfig(
        vehicle=VehicleSection(antenna_lever_arm_m=(0.3, 0.0, -3.0)),
        observer=ObserverConfig(accel_bias_filter=accel_bias_filter),
    )
    cfg = cfg.with_engine(engine)
    c_bn = state_at(drive, 0.0).c_bn[0]
    roll_true = math.atan2(c_bn[2, 1], c_bn[2, 2])
    imu = imu_stream(drive, bias_a_mps2=(0.0, 0.2, 0.0), noise_a_mps2=0.02, seed=4)
    fixes = gnss_stream(drive, antenna_lever_arm_m=cfg.vehicle.antenna_lever_arm_m)
    estimator = make_engine(cfg)
    ratios = []
    for k, _ in fed(estimator, imu, fixes):
        sol = estimator.solution()
        if k % 50 or sol.roll_rad is None or sol.mode in (Mode.DEGRADED, Mode.FAULT):
            continue
        assert sol.sigma_tilt_rad is not None
        ratios.append(abs(sol.roll_rad - roll_true) / sol.sigma_tilt_rad)
    assert len(ratios) > 200
    assert max(ratios) < 3.0, max(ratios)


@ENGINES_AND_BIAS_LAWS
def test_a_paper_sized_bias_learnt_in_the_first_turn_is_within_the_stated_accuracy(
    engine: Engine, accel_bias_filter: bool
) -> None:
    """Seed 000's bias size, 0.2/-0.15 m/s^2 (1.4 deg of tilt), then a U-turn. The
    accel-bias filter learns it within the turn, while the tilt it held leaves the platform
    only with the loop's tau: it stated 0.39 deg with roll still 1.17 deg off (field seed 5
    with this bias and IMU stalls: 170 frames beyond 0.1 deg + 3 sigma); the stated accuracy
    now carries the tilt the recent corrections left. Every roll and pitch sent within 0.1
    deg + 3 stated sigmas, and the bias learnt by the end."""
    drive = Motion(
        [Segment(15.0), Segment(5.0, accel_mps2=0.6), Segment(20.0)]
        + [Segment(15.0, yaw_rate_rps=math.pi / 15.0), Segment(30.0)],
        yaw0_rad=0.0,
    )
    cfg = GatewayConfig(
        vehicle=VehicleSection(antenna_lever_arm_m=(0.3, 0.0, -3.0)),
        observer=ObserverConfig(accel_bias_filter=accel_bias_filter),
    ).with_engine(engine)
    imu = imu_stream(drive, bias_a_mps2=(0.2, -0.15, 0.0), noise_a_mps2=0.02, seed=6)
    fixes = gnss_stream(drive, antenna_lever_arm_m=cfg.vehicle.antenna_lever_arm_m)
    estimator = make_engine(cfg)
    beyond, checked, last_err = [], 0, math.inf
    for k, s in fed(estimator, imu, fixes):
        sol = estimator.solution()
        if k % 20 or sol.roll_rad is None or sol.pitch_rad is None:
            continue
        assert sol.sigma_tilt_rad is not None
        last_err = math.degrees(max(abs(sol.roll_rad), abs(sol.pitch_rad)))  # level ground
        if sol.mode in (Mode.DEGRADED, Mode.FAULT):
            continue
        checked += 1
        beyond += beyond_stated(motion_time(s.t), last_err, sol.sigma_tilt_rad)
    assert checked > 500
    assert not beyond, beyond[:5]
    if engine is Engine.EKF or accel_bias_filter:  # eq. (12) needs more than one turn
        assert last_err < 0.2


@pytest.mark.parametrize("engine", [Engine.OBSERVER, Engine.EKF])
def test_a_noisier_unit_s_wider_turn_on_bias_is_within_the_stated_accuracy(
    engine: Engine,
) -> None:
    """A unit twice as noisy as its datasheet (gyro ARW), its y accelerometer bias 0.3
    m/s^2: 1.5 sigma of such a unit's doubled spread, 3 of the datasheet unit's the stated
    accuracy covered (`accel_bias_sigma_covered_mps2`). The observer's turn-on prior grows
    with the noise excess measured at rest; the EKF's covered spread did not, and it stated
    0.59 deg with roll 1.9 deg off (a noisy unit's 0.24 m/s^2 in the first U-turn of
    `float-spells` seed 612, gnss-20hz+imu-noise-x2: 63 frames beyond). Every roll sent,
    from the levelling at rest on, within 0.1 deg + 3 stated sigmas."""
    drive = Motion([Segment(15.0), Segment(5.0, accel_mps2=0.6), Segment(40.0)], yaw0_rad=0.0)
    cfg = GatewayConfig(vehicle=VehicleSection(antenna_lever_arm_m=(0.3, 0.0, -3.0)))
    cfg = cfg.with_engine(engine)
    c_bn = state_at(drive, 0.0).c_bn[0]
    roll_true = math.atan2(c_bn[2, 1], c_bn[2, 2])
    imu = imu_stream(drive, bias_a_mps2=(0.0, 0.3, 0.0), noise_a_mps2=0.02,
                     noise_g_rps=2.0 * GYRO_ARW_PER_SAMPLE_RPS, seed=4)  # fmt: skip
    fixes = gnss_stream(drive, antenna_lever_arm_m=cfg.vehicle.antenna_lever_arm_m)
    estimator = make_engine(cfg)
    beyond, checked = [], 0
    for k, s in fed(estimator, imu, fixes):
        sol = estimator.solution()
        if k % 50 or sol.roll_rad is None or sol.mode in (Mode.DEGRADED, Mode.FAULT):
            continue
        assert sol.sigma_tilt_rad is not None
        checked += 1
        off_deg = math.degrees(abs(sol.roll_rad - roll_true))
        beyond += beyond_stated(motion_time(s.t), off_deg, sol.sigma_tilt_rad)
    assert checked > 200
    assert not beyond, beyond[:5]


def ekf_stated_tilt_deg(hdt: bool) -> list[float]:
    """The EKF's stated roll/pitch sigma (deg) every 10 s of a drive (20 s parked, a
    straight, a U-turn) on a unit twice as noisy as its datasheet, its heading from the
    courses or, with ``hdt``, a dual-antenna receiver's (from the first epoch)."""
    drive = Motion(
        [Segment(20.0), Segment(5.0, accel_mps2=0.6), Segment(40.0)]
        + [Segment(15.0, yaw_rate_rps=math.pi / 15.0), Segment(30.0)],
        yaw0_rad=0.3,
    )
    cfg = GatewayConfig(vehicle=VehicleSection(antenna_lever_arm_m=(0.3, 0.0, -3.0)))
    imu = imu_stream(drive, noise_g_rps=2.0 * GYRO_ARW_PER_SAMPLE_RPS, noise_a_mps2=0.4, seed=4)
    fixes = gnss_stream(drive, antenna_lever_arm_m=cfg.vehicle.antenna_lever_arm_m, hdt=hdt,
                        vel_noise_mps=0.02)  # fmt: skip
    estimator = make_engine(cfg.with_engine(Engine.EKF))
    stated = []
    for k, _ in fed(estimator, imu, fixes):
        sol = estimator.solution()
        if k % 2048 == 0 and sol.sigma_tilt_rad is not None:
            stated.append(math.degrees(sol.sigma_tilt_rad))
    return stated


def test_with_a_dual_antenna_heading_the_ekf_still_takes_the_noise_measured_at_rest() -> None:
    """With HDT the EKF's filter starts at the first epoch after levelling, before the noise
    meter has its 3 s at rest: a unit twice as noisy as its datasheet ran on the datasheet's
    process noise, stating 0.15 deg of tilt where the same drive aligned on courses stated
    0.47 (`field` seed 613 of imu-noise-x2+hdt: 0.35-0.44 deg off with 0.08 stated, 509
    frames beyond 0.1 deg + 3 sigma). The process noise now takes the noise measured at
    every epoch at rest: the same stated accuracy either way, within 15 %."""
    courses, hdt = ekf_stated_tilt_deg(False), ekf_stated_tilt_deg(True)
    assert len(courses) == len(hdt) > 8
    for c, h in zip(courses[1:], hdt[1:], strict=True):
        assert abs(h - c) < 0.15 * c, (courses, hdt)


def stated_tilt_after_a_short_rest_deg(engine: Engine, noise: float) -> float:
    """The stated roll/pitch sigma (deg) 60 s into a drive that starts 6 s after power-up
    (`slope-start`'s rest), on a unit ``noise`` times its datasheet's gyro ARW."""
    drive = Motion([Segment(6.0), Segment(5.0, accel_mps2=0.6), Segment(60.0)], yaw0_rad=0.3)
    cfg = GatewayConfig(vehicle=VehicleSection(antenna_lever_arm_m=(0.3, 0.0, -3.0)))
    imu = imu_stream(drive, noise_g_rps=noise * GYRO_ARW_PER_SAMPLE_RPS, seed=4)
    fixes = gnss_stream(drive, antenna_lever_arm_m=cfg.vehicle.antenna_lever_arm_m,
                        vel_noise_mps=0.02)  # fmt: skip
    estimator = make_engine(cfg.with_engine(engine))
    for _ in fed(estimator, imu, fixes):
        pass
    sigma = estimator.solution().sigma_tilt_rad
    assert sigma is not None
    return math.degrees(sigma)


@pytest.mark.parametrize("engine", [Engine.OBSERVER, Engine.EKF])
def test_a_noisy_unit_is_measured_in_a_short_first_rest(engine: Engine) -> None:
    """The IMU's noise is measured at rest, and a cold start's rest may be short: 6 s on
    `slope-start`. The meter wanted 3 s of block differences after the rest's first second
    and before its last, so a unit twice as noisy as its datasheet was never measured there
    and the observer stated its datasheet's noise all run (roll 0.4 deg off with 0.1 stated
    on a 1 Hz receiver, seed 600 of imu-noise-x2+gnss-1hz: 40 frames beyond). With 2 s it
    is: the stated tilt on the straight 60 s on is at least 1.15 times the datasheet unit's
    (the observer's was the same for both on the tree before: its rest here gives 24
    differences; the EKF's, whose rest test starts sooner, took the noise then too)."""
    noisy = stated_tilt_after_a_short_rest_deg(engine, 2.0)
    datasheet = stated_tilt_after_a_short_rest_deg(engine, 1.0)
    assert noisy > 1.15 * datasheet, (noisy, datasheet)


def test_a_warm_start_from_a_run_that_never_turned_states_the_bias_it_could_not_see() -> None:
    """The learned state carries P's 1-sigma of the accelerometer bias; a run that never
    turned leaves it near P0's 5 mg while the bias may be seed 000's 0.2 m/s^2, unseen. The
    EKF warm-started from it, parked (the filter waits for the heading), stated the seed's
    0.29 deg with roll 1.2 deg off; the stated accuracy now adds the part of the covered
    spread the seed's sigma says is unobserved. Every roll sent within 3 stated sigmas."""
    parked = Motion([Segment(30.0)], roll_rad=math.radians(6.0), yaw0_rad=0.0)
    cfg = GatewayConfig(vehicle=VehicleSection(antenna_lever_arm_m=(0.3, 0.0, -3.0)))
    cfg = cfg.with_engine(Engine.EKF)
    never_turned = LearnedState(
        bias_g_rps=(0.0, 0.0, 0.0),
        sigma_g_rps=(1e-4, 1e-4, 1e-4),
        bias_a_mps2=(0.0, 0.0, 0.0),
        sigma_a_mps2=(0.98 * cfg.ekf.accel_bias_sigma0_mps2,) * 3,
    )
    estimator = make_engine(cfg)
    assert estimator.seed(never_turned)
    imu = imu_stream(parked, bias_a_mps2=(0.0, 0.2, 0.0), noise_a_mps2=0.02, seed=5)
    fixes = gnss_stream(parked, antenna_lever_arm_m=cfg.vehicle.antenna_lever_arm_m)
    ratios = []
    for k, _ in fed(estimator, imu, fixes):
        sol = estimator.solution()
        if k % 50 or sol.roll_rad is None:
            continue
        assert sol.sigma_tilt_rad is not None
        ratios.append(abs(sol.roll_rad - math.radians(6.0)) / sol.sigma_tilt_rad)
    assert len(ratios) > 100
    assert max(ratios) < 3.0, max(ratios)


@pytest.mark.parametrize("chassis_deg", [0.0, 0.4, -0.4])
def test_a_gross_x_bias_leaves_the_pitch_on_the_first_straight(chassis_deg: float) -> None:
    """An x bias of 0.45 m/s^2, 4.5 sigma of the observer's turn-on prior: parked, nothing
    tells it from a pitch (2.6 deg off, 0.6 stated: the prior's). Moving off on a 3 deg
    climb, a wheeled vehicle's track does: the accel-bias filter's height chain takes the
    pitch to within the chassis's own pitch against its track (here 0 and +/-0.4 deg; its
    prior 0.25 deg keeps a sixth of the bias's pitch). Before, the pitch stayed 2.6 deg off
    until the first turn (imu-bias-x5 of benchmarks/robustness.py: 2.9 deg for 130 s,
    5,854 frames beyond 0.1 deg + 3 sigma). From 15 s after moving off, every pitch sent
    within 0.1 deg + 3 stated sigmas."""
    slope = math.radians(3.0)
    chassis = math.radians(chassis_deg)
    drive = Motion(
        [Segment(15.0), Segment(5.0, accel_mps2=0.5), Segment(70.0)],
        yaw0_rad=0.7,
        pitch_rad=slope + chassis,
        chassis_pitch_rad=chassis,
    )
    cfg = GatewayConfig(vehicle=VehicleSection(antenna_lever_arm_m=(0.3, 0.0, -3.0)))
    cfg = cfg.with_engine(Engine.OBSERVER)
    imu = imu_stream(drive, bias_a_mps2=(0.45, 0.0, 0.0), noise_a_mps2=0.02, seed=7)
    fixes = gnss_stream(drive, antenna_lever_arm_m=cfg.vehicle.antenna_lever_arm_m)
    estimator = make_engine(cfg)
    parked, beyond, checked, last = [], [], 0, math.inf
    for k, s in fed(estimator, imu, fixes):
        sol = estimator.solution()
        if k % 20 or sol.pitch_rad is None:
            continue
        assert sol.sigma_tilt_rad is not None
        t, last = motion_time(s.t), math.degrees(abs(sol.pitch_rad - drive.pitch_rad))
        if 10.0 <= t < 15.0:
            parked.append(last)
        elif t >= 35.0 and sol.mode is Mode.NAVIGATING:
            checked += 1
            beyond += beyond_stated(t, last, sol.sigma_tilt_rad)
    assert min(parked) > 2.4  # b_x / g: the bias, not yet told from a pitch
    assert checked > 500
    assert not beyond, beyond[:5]
    # what is left: the prior's share of the bias (0.16 of 2.6 deg) and the chassis's pitch
    assert last < 0.2 * min(parked) + abs(chassis_deg), last


#: One ADIS16334 gyro sample's white noise at 204.8 Hz (ARW 2 deg/sqrt(h)), rad/s.
ADIS_GYRO_SAMPLE_NOISE_RPS = math.radians(2.0) / 60.0 / math.sqrt(IMU_DT_S)
#: The x/y/z accelerometer bias of the U-turn drives, m/s^2.
U_TURN_B_A_MPS2 = (0.03, -0.02, 0.0)


def u_turns(rows: int) -> list[Segment]:
    """Parked 15 s, off at 0.5 m/s^2, ``rows`` rows of 40 s each ended by a 12 s U-turn (the
    first at 60-72 s), both ways in turn, and a last row."""
    segments = [Segment(15.0), Segment(5.0, accel_mps2=0.5)]
    for k in range(rows):
        segments += [Segment(40.0), Segment(12.0, yaw_rate_rps=math.pi / 12.0 * (-1) ** k)]
    return [*segments, Segment(40.0)]


def tilt_after_the_first_turn(
    cfg: GatewayConfig, drive: Motion, imu: list[ImuSample], fixes: list[GnssFix]
) -> tuple[list[tuple[float, float, float, float]], Solution]:
    """The engine of ``cfg`` fed ``imu`` and ``fixes`` of ``drive``: (t, roll and pitch error
    deg, stated 1-sigma rad) of every 20th solution from 75 s (the first U-turn's end), and
    the last solution."""
    estimator = make_engine(cfg)
    checked = []
    for k, s in fed(estimator, imu, fixes):
        t = motion_time(s.t)
        if k % 20 or t < 75.0:
            continue
        sol = estimator.solution()
        assert sol.roll_rad is not None and sol.pitch_rad is not None
        assert sol.sigma_tilt_rad is not None
        c = state_at(drive, t).c_bn[0]
        roll_off = math.degrees(sol.roll_rad - math.atan2(c[2, 1], c[2, 2]))
        pitch_off = math.degrees(sol.pitch_rad + math.asin(c[2, 0]))
        checked.append((t, roll_off, pitch_off, sol.sigma_tilt_rad))
    return checked, sol


def pitch_after_the_first_turn(
    drive: Motion, engine: Engine, noise_g_rps: float = 0.003
) -> tuple[list[str], int, Solution]:
    """``engine`` on ``drive`` (biases, noise of ``noise_g_rps`` a sample, a 3 m mast): the
    never-lie check of every 20th pitch sent from 75 s (the first U-turn's end) against the
    truth: the lines beyond, the number checked, and the last solution."""
    cfg = GatewayConfig(vehicle=VehicleSection(antenna_lever_arm_m=(0.3, 0.0, -3.0)))
    cfg = cfg.with_engine(engine)
    imu = imu_stream(drive, bias_g_rps=(0.001, -0.001, 0.0005), bias_a_mps2=U_TURN_B_A_MPS2,
                     noise_g_rps=noise_g_rps, noise_a_mps2=0.02, seed=7)  # fmt: skip
    fixes = gnss_stream(drive, antenna_lever_arm_m=cfg.vehicle.antenna_lever_arm_m,
                        vel_noise_mps=0.02)  # fmt: skip
    checked, sol = tilt_after_the_first_turn(cfg, drive, imu, fixes)
    beyond = [line for t, _, off, sigma in checked for line in beyond_stated(t, abs(off), sigma)]
    return beyond, len(checked), sol


@pytest.mark.parametrize("chassis_deg", [0.5, -0.5])
@pytest.mark.parametrize("engine", [Engine.OBSERVER, Engine.EKF], ids=["observer", "ekf"])
def test_a_chassis_pitched_on_its_tyres_is_not_read_as_accelerometer_bias(
    engine: Engine, chassis_deg: float
) -> None:
    """A lifted rear implement pitches a tractor some 0.5 deg against the ground it drives:
    the track's climb angle is then not the body's pitch. Both engines take the climb as a
    pitch measurement (the EKF in its non-holonomic constraint), so both must allow for it.
    Without the chassis's pitch as a state the EKF read it as 0.045 m/s^2 of x bias and
    sent pitch 0.2-0.33 deg off with 0.065 stated after its turns. Four U-turns on a 2 deg
    climb: from the first turn on every pitch sent within 0.1 deg + 3 stated sigmas, and
    the x bias learnt within 0.01 m/s^2."""
    chassis = math.radians(chassis_deg)
    drive = Motion(
        u_turns(4), yaw0_rad=0.7, pitch_rad=math.radians(2.0) + chassis, chassis_pitch_rad=chassis
    )
    beyond, checked, sol = pitch_after_the_first_turn(drive, engine)
    assert checked > 1500
    assert not beyond, beyond[:5]
    assert sol.bias_a_mps2 is not None
    assert abs(sol.bias_a_mps2[0] - U_TURN_B_A_MPS2[0]) < 0.01, sol.bias_a_mps2


@pytest.mark.parametrize("engine", [Engine.OBSERVER, Engine.EKF], ids=["observer", "ekf"])
def test_an_implement_lifted_through_every_headland_does_not_walk_the_x_bias(
    engine: Engine,
) -> None:
    """An implement lifted before each U-turn and lowered after it pitches the chassis by a
    degree on its tyres within two seconds, twice a headland: a step, where the chassis's
    pitch is modelled as a random walk (0.25 deg in two minutes). The observer weighed the
    track's height against its pitch after its turns, and each step's height split between
    the chassis's pitch, the tilt and the x bias: the bias walked 5 mg a headland and after
    eight the pitch went out 0.4-1.1 deg off with 0.09 stated. Ten rows on a 2 deg climb:
    every pitch sent after the first turn within 0.1 deg + 3 stated sigmas, the x bias
    within 0.01 m/s^2 at the end."""
    lift = math.radians(1.0)
    steps = []
    for k in range(10):  # row k's U-turn is at 60 + 52 k s
        steps += [ChassisStep(57.0 + 52.0 * k, lift), ChassisStep(72.0 + 52.0 * k, -lift)]
    drive = Motion(u_turns(10), yaw0_rad=0.7, pitch_rad=math.radians(2.0), chassis_steps=steps)
    beyond, checked, sol = pitch_after_the_first_turn(drive, engine)
    assert checked > 5000
    assert not beyond, beyond[:5]
    assert sol.bias_a_mps2 is not None
    assert abs(sol.bias_a_mps2[0] - U_TURN_B_A_MPS2[0]) < 0.01, sol.bias_a_mps2


@pytest.mark.parametrize("engine", [Engine.OBSERVER, Engine.EKF], ids=["observer", "ekf"])
def test_an_imu_twice_as_noisy_as_its_datasheet_learns_the_x_bias_in_its_turns(
    engine: Engine,
) -> None:
    """The observer's accel-bias filter starts once the vehicle has not turned for its
    hold-off, and it took an epoch as a turn when the last sample's rate was beyond 2
    deg/s. With twice the datasheet's ARW (0.95 deg/s a sample) one epoch in 28 was, so the
    filter never started and the x/y biases were never learnt (slope-start seed 61 of
    imu-noise-x2 in benchmarks/robustness.py, a 27 mg x bias: pitch 1.6 deg off for 150 s
    with 0.46 stated, 3,986 frames beyond 0.1 deg + 3 sigma). Now an epoch's mean rate
    decides. Three U-turns on a 2 deg climb with that noise: every pitch sent after the
    first turn within 0.1 deg + 3 stated sigmas, the x bias learnt within 0.01 m/s^2."""
    noise_g_rps = 2.0 * ADIS_GYRO_SAMPLE_NOISE_RPS
    drive = Motion(u_turns(3), yaw0_rad=0.7, pitch_rad=math.radians(2.0))
    beyond, checked, sol = pitch_after_the_first_turn(drive, engine, noise_g_rps)
    assert checked > 1000
    assert not beyond, beyond[:5]
    assert sol.bias_a_mps2 is not None
    assert abs(sol.bias_a_mps2[0] - U_TURN_B_A_MPS2[0]) < 0.01, sol.bias_a_mps2


def weaving_rows(rows: int, rate_rps: float = math.radians(4.0)) -> list[Segment]:
    """:func:`u_turns`' drive with each row weaving: the yaw rate +-``rate_rps`` in turn
    every 0.5 s (the heading +-1 deg at 4 deg/s), as a rough field's bumps rock a fast
    tractor's body."""
    weave = [Segment(0.5, yaw_rate_rps=rate_rps * (-1) ** k) for k in range(80)]
    return [s for seg in u_turns(rows) for s in (weave if seg == Segment(40.0) else [seg])]


@pytest.mark.parametrize("engine", [Engine.OBSERVER, Engine.EKF], ids=["observer", "ekf"])
def test_a_field_whose_bumps_rock_the_heading_learns_the_biases_in_its_turns(
    engine: Engine,
) -> None:
    """The observer's accel-bias filter starts once the vehicle has not turned for its
    hold-off, and an epoch whose mean rate was beyond 2 deg/s was a turn: on rough ground at
    6 m/s the bumps rock the body's heading by +-4 deg/s, so the filter never started, and
    the roll/pitch sigma, taken down by the turns' exponent of eq. (12), which is off with
    the filter, stated the biases learnt (`short` seed 547 of fast-wide+rough-slope in
    benchmarks/robustness.py: roll 0.75 deg off all run, 0.12 stated, 3,681 frames beyond
    0.1 deg + 3 sigma). Now the mean rate over the tilt loop's tau decides, and until the
    filter starts the sigma is the turn-on one. Three weaving rows with a 0.09 m/s^2 y bias
    (roll 0.53 deg off when levelled): every tilt sent from the first turn's end on within
    0.1 deg + 3 stated sigmas, the y bias learnt within 0.01 m/s^2."""
    b_a = (0.03, 0.09, 0.0)
    drive = Motion(weaving_rows(3), yaw0_rad=0.7, roll_rad=math.radians(3.0))
    cfg = GatewayConfig(vehicle=VehicleSection(antenna_lever_arm_m=(0.3, 0.0, -3.0)))
    cfg = cfg.with_engine(engine)
    imu = imu_stream(drive, bias_g_rps=(0.001, -0.001, 0.0005), bias_a_mps2=b_a,
                     noise_g_rps=0.003, noise_a_mps2=0.02, seed=7)  # fmt: skip
    fixes = gnss_stream(drive, antenna_lever_arm_m=cfg.vehicle.antenna_lever_arm_m,
                        vel_noise_mps=0.02)  # fmt: skip
    checked, sol = tilt_after_the_first_turn(cfg, drive, imu, fixes)
    assert len(checked) > 1000
    beyond = [
        line
        for t, roll_off, pitch_off, sigma in checked
        for line in beyond_stated(t, max(abs(roll_off), abs(pitch_off)), sigma)
    ]
    assert not beyond, beyond[:5]
    assert sol.bias_a_mps2 is not None
    assert abs(sol.bias_a_mps2[1] - b_a[1]) < 0.01, sol.bias_a_mps2


@pytest.mark.parametrize("seed", [67, 70])
def test_a_unit_noisier_than_its_datasheet_is_allowed_a_gyro_bias_that_wanders_more(
    seed: int, tmp_path: Path
) -> None:
    """An ADIS16334 twice as noisy as its datasheet in ARW, VRW, in-run wander and turn-on
    biases (`benchmarks/robustness.py` `imu-noise-x2`), the config the datasheet's, a cold
    start on `short`. On seed 67 the gyro x bias wandered 0.07 deg/s in the first 50 s and
    the y accelerometer bias was 0.27 m/s^2: the accel-bias filter started with the gyro
    bias known to 0.02 deg/s where it was 0.045 off, its first U-turn read that tilt for y
    bias (0.06 m/s^2 off) and the observer sent roll 0.5-0.7 deg off with 0.15 stated (133
    frames beyond 0.1 deg + 3 sigma; seed 70 pitch 0.65 with 0.18, 71). That prior is now
    scaled by the noise measured at rest, as the stated floors are: none beyond."""
    checked, beyond = noisy_short_beyond(seed, tmp_path)
    assert checked > 5000
    assert not beyond, beyond[:5]


def test_a_stop_s_gyro_bias_update_is_not_read_as_tilt_in_the_first_u_turn(
    tmp_path: Path,
) -> None:
    """`short` seed 94 of `imu-noise-x2`: the accel-bias filter started, then the vehicle
    stood 22 s, where the zero-rate update moved the x/y gyro bias estimates by their
    turn-on error. The filter took that move for a gyro bias error and predicted the tilt
    it would build over the stop (1.8 m/s^2 as a specific force); its first epoch after the
    stop was beyond its gate, the tilt was taken as lost from the bias, and the first U-turn
    read its turning tilt as 0.1 m/s^2 of y bias: roll 0.6 deg off with 0.15 stated. The
    engine now tells the filter each levelling at rest and the gyro's update there."""
    checked, beyond = noisy_short_beyond(94, tmp_path)
    assert checked > 5000
    assert not beyond, beyond[:5]


@pytest.mark.parametrize("seed", [5, 16])
def test_the_ekf_allows_a_noisier_unit_a_bias_that_wanders_more(seed: int, tmp_path: Path) -> None:
    """The EKF on the unit above: it raised its ARW and VRW to the noise measured at rest
    but kept the datasheet's bias walk, and on `short` seeds 5 and 16 of 50 sent 4 and 7
    tilt frames beyond 0.1 deg + 3 sigma (`field` seed 580: 47). The walk is now raised
    with them, as the observer's floors are: none beyond on seeds 1-50; the datasheet's
    units' figures unchanged (their measured noise is the tuning's)."""
    checked, beyond = noisy_short_beyond(seed, tmp_path, Engine.EKF)
    assert checked > 5000
    assert not beyond, beyond[:5]


def test_the_ekf_takes_a_unit_s_gyro_noise_excess_for_its_accelerometer_bias_walk_too(
    tmp_path: Path,
) -> None:
    """The unit above on `headland-reversing` seed 560: its gyro noise at rest is 1.8 times
    the datasheet's, its accelerometer's under the config's vibration allowance (1.0), so
    the accelerometer bias walk stayed the datasheet's while the unit's wandered twice as
    far: the y bias 0.013 m/s^2 off with 0.006 stated, and 5 roll frames beyond (0.39 deg
    off, 0.09 stated). Both walks now take the larger excess, as the observer's floors do
    (:meth:`EkfEngine._noise_as_measured`): none."""
    checked, beyond = noisy_short_beyond(560, tmp_path, Engine.EKF, "headland-reversing")
    assert checked > 20000
    assert not beyond, beyond[:5]


def test_a_unit_noisier_than_its_datasheet_is_allowed_biases_that_wander_more(
    tmp_path: Path,
) -> None:
    """The observer's accel-bias filter took the datasheet's in-run wander for a unit twice
    as noisy in every figure: its x/y gyro biases wandered 0.015-0.025 deg/s from the
    estimates against the filter's 0.010, and turns read their tilt as accelerometer bias
    (`headland-reversing` seed 615 of imu-noise-x2+gnss-1hz: 2 frames beyond; `steep-turns`
    seed 614 of fast-wide+imu-noise-x2+hdt: the x bias 0.040 m/s^2 off with 0.011 stated,
    70). The wander now grows with the excess measured at rest, as the EKF's bias walks
    do: none beyond here (the second run 22)."""
    checked, beyond = noisy_short_beyond(615, tmp_path, base="headland-reversing", gnss_hz=1.0)
    assert checked > 20000
    assert not beyond, beyond[:5]


def noisy_short_beyond(
    seed: int,
    tmp_path: Path,
    engine: Engine = Engine.OBSERVER,
    base: str = "short",
    gnss_hz: float | None = None,
) -> tuple[int, list[str]]:
    """``base`` (`short`) with an ADIS16334 twice as noisy as its datasheet (the robustness
    benchmark's `imu-noise-x2`, whose name draws its runs; with ``gnss_hz`` its
    `imu-noise-x2+gnss-1hz`'s), the config the datasheet's, through ``navgw replay`` with
    ``engine``: :func:`tilt_beyond_stated`."""
    deg, mg = math.pi / 180.0, 9.80665e-3
    noisy = {
        "gyro_arw_rad_per_sqrt_s": 2 * 2.0 * deg / 60.0,
        "accel_vrw_mps_per_sqrt_s": 2 * 0.12 / 60.0,
        "gyro_bias_stability_rps": 2 * 0.007 * deg,
        "accel_bias_stability_mps2": 2 * 0.1 * mg,
        "gyro_turn_on_sigma_rps": 2 * 0.1 * deg,
        "accel_turn_on_sigma_mps2": 2 * 5.0 * mg,
    }
    table = {"base": base, "imu": noisy} | ({"name": "imu-noise-x2"} if base != "short" else {})
    if gnss_hz is not None:
        table |= {"name": f"imu-noise-x2+gnss-{gnss_hz:g}hz", "gnss": {"rate_hz": gnss_hz}}
    run = generate(scenario_from_toml(table), tmp_path, seed=seed)
    out = tmp_path / "out.log"
    replay(run.imu_log, run.gnss_log, out, load_config(Path(run.config_file)).with_engine(engine))
    return tilt_beyond_stated(out, Truth.load(run.truth_file))


def rocking_drive_tilt(
    engine: Engine, latency_s: float, dt_s: float
) -> list[tuple[float, float, float, float]]:
    """The engine on four U-turns rocking +/-2 deg in roll at 2 Hz (IMU 1 m above the axle,
    3 m mast, ADIS16334 gyro noise at the IMU period ``dt_s``, a receiver ``latency_s``
    late): :func:`tilt_after_the_first_turn`'s checked solutions."""
    l_imu = (0.5, 0.1, -1.0)
    drive = Motion(
        u_turns(4), yaw0_rad=0.7, rock_rad=math.radians(2.0), rock_hz=2.0, rock_from_s=20.0
    )
    vehicle = VehicleSection(antenna_lever_arm_m=(0.3, 0.0, -3.0), imu_lever_arm_m=l_imu)
    cfg = GatewayConfig(vehicle=vehicle).with_engine(engine)
    noise_g = ADIS_GYRO_SAMPLE_NOISE_RPS * math.sqrt(IMU_DT_S / dt_s)  # the same ARW
    imu = imu_stream(drive, imu_lever_arm_m=l_imu, bias_a_mps2=U_TURN_B_A_MPS2,
                     noise_g_rps=noise_g, noise_a_mps2=0.02, seed=7, dt_s=dt_s)  # fmt: skip
    fixes = gnss_stream(drive, antenna_lever_arm_m=cfg.vehicle.antenna_lever_arm_m,
                        latency_s=latency_s, vel_noise_mps=0.02)  # fmt: skip
    return tilt_after_the_first_turn(cfg, drive, imu, fixes)[0]


@pytest.mark.parametrize("latency_s", [0.0, 0.04, 0.07])
@pytest.mark.parametrize("engine", [Engine.OBSERVER, Engine.EKF], ids=["observer", "ekf"])
def test_rocking_on_rough_ground_the_lever_arm_velocities_are_the_moments(
    engine: Engine, latency_s: float
) -> None:
    """Rough ground rocks the body about the wheels (here +/-2 deg at 2 Hz through four
    U-turns), the antenna on its 3 m mast swaying at 0.8 m/s and the IMU, 1 m above the
    axle, at 0.26. Both engines take the lever-arm velocities w x l from mean body rates,
    and a mean that lags or shrinks the rate leaves cm/s in them that are not there:
    - the EKF's non-holonomic constraint took w from the rate low-passed for the outputs,
      50 ms behind (with the next, 0.11 deg RMS; steep-turns seed 61 of `rough-slope`: pitch
      0.3 deg off with 0.06 stated);
    - a receiver 0-40 ms late leaves fewer samples after the epoch than the 50 ms the
      antenna's window wants, and a window cut on one side lags: 5 ms at 40 ms late, 12 ms
      at 0 (the 25 ms before the epoch), where the observer's roll and pitch went 3-9 deg
      off with about 1 deg stated (1,609 of 1,977 checked beyond). The epoch now waits for
      the samples after it;
    - one centred mean keeps 93 % of a 2 Hz rate: the observer 0.17 deg RMS at any latency
      once it waited, where curvature-free means give 0.057.
    From the first turn on: roll/pitch within 0.08 deg RMS, every one sent within 0.1 deg
    + 3 stated sigmas."""
    checked = rocking_drive_tilt(engine, latency_s, IMU_DT_S)
    assert len(checked) > 1500
    beyond = [line for t, r, p, sigma in checked
              for line in beyond_stated(t, max(abs(r), abs(p)), sigma)]  # fmt: skip
    assert not beyond, beyond[:5]
    errors = [x for _, r, p, _ in checked for x in (r, p)]
    rms = math.sqrt(float(np.mean(np.square(errors))))
    assert rms < 0.08, rms


@pytest.mark.parametrize("engine", [Engine.OBSERVER, Engine.EKF], ids=["observer", "ekf"])
def test_rocking_in_roll_puts_no_mean_error_into_pitch_at_102_hz(engine: Engine) -> None:
    """The same drive with the IMU at 102.4 Hz (DEC = 3). The EKF's non-holonomic
    constraint took the reference point's lever-arm velocity from the mean rate of the last
    20 ms, 15 ms behind: the lateral velocity that lag leaves is in phase with the roll,
    which turns it into the body's vertical, and the constraint read its mean as pitch
    (+0.069 deg, RMS 0.080; +0.052 at 204.8 Hz). It now takes the rate centred on the
    state 50 ms back: +0.036, RMS 0.067 (the observer +0.034, 0.053). The pitch does not
    rock here, so its mean error is what the rocking rectifies."""
    checked = rocking_drive_tilt(engine, 0.04, sample_period_s(3))
    assert len(checked) > 900
    pitch_mean = float(np.mean([p for _, _, p, _ in checked]))
    assert abs(pitch_mean) < 0.05, pitch_mean
    errors = [x for _, r, p, _ in checked for x in (r, p)]
    rms = math.sqrt(float(np.mean(np.square(errors))))
    assert rms < 0.075, rms


#: rough ground: 3x the bumps, 6-9 deg side slopes, 4 deg along (robustness `rough-slope`)
ROUGH_GROUND = {
    "bump_amplitude_m": 0.03,
    "side_slope_min_deg": 6.0,
    "side_slope_max_deg": 9.0,
    "along_slope_deg": 4.0,
}


def free_host_replay(
    out: Path,
    table: dict[str, object],
    seed: int,
    engine: Engine,
    gnss: Sequence[GnssSection] = (GnssSection(),),
) -> tuple[list[Path], Truth]:
    """``table``'s scenario with its host clock 30 s off UTC, simulated into ``out`` and
    replayed through `navgw replay` by ``engine`` once per ``gnss`` section (the default:
    `[gnss]` left as it is); the output logs and the truth."""
    gnss_table = {"host_clock_offset_s": 30.0, **cast(dict[str, object], table.get("gnss", {}))}
    scenario = scenario_from_toml({**table, "gnss": gnss_table})
    run = generate(scenario, out, seed=seed)
    vehicle = gateway_config(scenario, receiver_latency_s=0.0).vehicle
    logs = []
    for i, section in enumerate(gnss):
        log = out / f"out-{i}.log"
        config = GatewayConfig(vehicle=vehicle, gnss=section).with_engine(engine)
        replay(run.imu_log, run.gnss_log, log, config)
        logs.append(log)
    return logs, Truth.load(run.truth_file)


@pytest.mark.parametrize(
    ("seed", "vehicle_table"), [(543, {}), (625, ROUGH_GROUND)], ids=["field", "rough-ground"]
)
def test_a_free_running_host_clock_s_epoch_error_is_learnt_not_taken_for_pitch(
    tmp_path: Path, seed: int, vehicle_table: dict[str, float]
) -> None:
    """A host clock 30 s off UTC (no PPS/NTP): the epochs are placed at their arrival less
    `[gnss] receiver_latency_s`, left at its default 50 ms (the receiver's is 68 ms). 18 ms
    late, a fix is the antenna v 18 ms back along its track: an offset along the body x
    axis either way, which the 3 m mast's lever arm makes pitch. Through its cm-sigma RTK
    fixes the EKF read it as pitch: 0.3 deg off with 0.06 stated (field seed 543: 311
    frames beyond 0.1 deg + 3 sigma); with the v dt that an epoch time 30 ms uncertain
    moves in the fixes' sigmas (white), still 0.1 deg off on the mean, and on rough ground
    0.17 with 0.08 stated (seed 625: 858 frames beyond). The epoch's error is now a state
    (EPOCH), told from pitch as the speed changes: none beyond, pitch within 0.06 deg on
    the mean after 10 minutes, through `navgw replay`."""
    table: dict[str, object] = {"base": "field"}
    if vehicle_table:
        table["vehicle"] = vehicle_table
    (out,), truth = free_host_replay(tmp_path, table, seed, Engine.EKF)
    checked, beyond = tilt_beyond_stated(out, truth)
    assert checked > 40_000 and beyond == []
    pitch_deg = attitude_errors_deg(decode_log(out), truth, after_s=600.0)[:, 1]
    assert abs(float(np.mean(pitch_deg))) < 0.06, float(np.mean(pitch_deg))


@pytest.mark.parametrize(
    ("base", "seed", "gnss_table", "navigating_s"),
    [
        ("slope-start", 626, {"latency_s": 0.068}, 5.0),
        ("slope-start", 627, {"latency_s": 0.15}, 15.0),
        ("short", 632, {"hdt": True}, 5.0),
    ],
    ids=["18-ms-off", "128-ms-off", "parked-on-hdt"],
)
def test_a_free_running_host_s_pull_away_is_no_epoch_time_on_the_bus(
    tmp_path: Path, base: str, seed: int, gnss_table: dict[str, object], navigating_s: float
) -> None:
    """The EKF's cold start on a slope, the vehicle pulling away as it aligns, on a host
    clock 30 s off UTC: the epochs are placed at arrival less the default 50 ms, 18 ms
    late with the receiver's 68 ms, 128 ms with a 150 ms one. While the speed rises, an
    epoch dtau off and a velocity error look alike (p - v dtau and v - a dtau against dv t
    and dv): the EPOCH state took the velocity's timing error as white (a dtau's size in
    its sigma) and fitted the alignment's velocity error as epoch time, -81 ms against 18
    (6 positions 0.20 m off, NAVIGATING; 0.45 m with the 150 ms receiver). The velocity
    now carries a_ant dtau in its model, the INS's acceleration, and NAVIGATING waits for
    the speed times the epoch time's sigma to be within 5 cm: every position within
    NAVIGATING's bound, and NAVIGATING 2 s after the alignment (13 s with the 128 ms
    error: at 3 m/s a straight line tells the epoch time only slowly), through `navgw
    replay`. Aligned on HDT and parked (`short` seed 632), the INS's own velocity and
    acceleration noise in the EPOCH columns, shared with the residuals, had taken the
    epoch time to -108 ms with 14 stated before the pull-away (0.20 m off): parked, an
    epoch time moves nothing and is left alone."""
    (out,), truth = free_host_replay(tmp_path, {"base": base, "gnss": gnss_table}, seed, Engine.EKF)
    checked, beyond = position_beyond_mode(out, truth)
    assert checked > 6_000 and beyond == []
    assert tilt_beyond_stated(out, truth)[1] == []
    modes = status_modes(out)
    aligned = next(t for t, mode in modes if mode not in (Mode.INITIALISING, Mode.ALIGNING))
    navigating = next(t for t, mode in modes if mode == Mode.NAVIGATING)
    assert navigating - aligned < navigating_s, navigating - aligned


def test_the_observer_on_a_free_running_host_states_the_epoch_time_it_cannot_learn(
    tmp_path: Path,
) -> None:
    """A host clock 30 s off UTC and a receiver 120 ms late (148 to its last sentence,
    against the default `[gnss] receiver_latency_s` of 50 ms): every epoch is placed 98 ms
    late. The observer has no state for it: the fixes went 0.20 m behind the vehicle and
    the heading 1-2 deg off after turns, NAVIGATING (`short` seed 635: 2,397 positions and
    216 headings beyond). It now says DEGRADED while the speed times the epochs' time sigma
    (`receiver_latency_sigma_s`, 0.1 s unless measured) is beyond 5 cm: nothing beyond.
    With the latency measured (148 ms, 10 ms 1-sigma) it navigates again, within its
    accuracy: NAVIGATING most of the drive, nothing beyond. What turns leave in the
    heading outlasts the speed: stopped after them on `steep-turns` (seed 636, a 150 ms
    receiver) 1,362 headings went out 1.6 deg off, NAVIGATING; the courses' sigmas now
    carry w dtau, and the mode holds DEGRADED for a minute after the speed allowed it."""
    measured = GnssSection(receiver_latency_s=0.148, receiver_latency_sigma_s=0.01)
    logs, truth = free_host_replay(
        tmp_path / "short", {"base": "short", "gnss": {"latency_s": 0.12}}, 635,
        Engine.OBSERVER, (GnssSection(), measured),
    )  # fmt: skip
    steep, steep_truth = free_host_replay(
        tmp_path / "steep", {"base": "steep-turns", "gnss": {"latency_s": 0.15}}, 636,
        Engine.OBSERVER,
    )  # fmt: skip
    shares = []
    for out, run_truth in zip((*logs, *steep), (truth, truth, steep_truth), strict=True):
        beyond = position_beyond_mode(out, run_truth)[1]
        assert beyond == [], (out, beyond[:3])
        assert heading_beyond_navigating(out, run_truth)[1] == [], out
        assert tilt_beyond_stated(out, run_truth)[1] == [], out
        modes = [mode for _, mode in status_modes(out)]
        shares.append(modes.count(Mode.NAVIGATING) / len(modes))
    assert shares[0] < 0.3 < 0.7 < shares[1], shares


def test_a_noisier_unit_s_accel_bias_unlearnt_without_a_heading_is_within_the_stated() -> None:
    """A unit twice as noisy as its datasheet, its x accelerometer bias 0.32 m/s^2 (1.6
    sigma of a doubled turn-on spread, 3.2 of the observer's 0.1 m/s^2 prior), parked on a
    slope, then driving at 0.45 m/s, under the speed of a course: no heading, so nothing
    learns the bias, and its pitch is 1.9 deg off. The observer stated its 0.1 m/s^2 prior
    (0.58 deg), as for a datasheet unit: a planter with a 1 Hz receiver sent roll and
    pitch 1.3-2.0 deg off with 0.54-0.65 stated for an hour (`field` seed 591 of
    `planter+gnss-1hz+imu-noise-x2`). The prior is now as much larger as the noise measured
    at rest, as the gyro's and the floors are: every roll and pitch within 0.1 deg + 3
    stated sigma."""
    drive = Motion(
        [Segment(40.0), Segment(1.5, accel_mps2=0.3), Segment(120.0)],
        yaw0_rad=0.4,
        roll_rad=math.radians(3.0),
        pitch_rad=math.radians(2.0),
    )
    cfg = GatewayConfig(vehicle=VehicleSection(antenna_lever_arm_m=(0.3, 0.0, -3.0)))
    imu = imu_stream(
        drive,
        bias_a_mps2=(0.32, 0.0, 0.0),
        noise_g_rps=2.0 * ADIS_GYRO_SAMPLE_NOISE_RPS,
        noise_a_mps2=0.02,
        seed=8,
    )
    fixes = gnss_stream(drive, antenna_lever_arm_m=cfg.vehicle.antenna_lever_arm_m)
    estimator = make_engine(cfg.with_engine(Engine.OBSERVER))
    beyond, checked = [], 0
    for k, sample in fed(estimator, imu, fixes):
        sol = estimator.solution()
        if k % 50 or sol.roll_rad is None or sol.pitch_rad is None or sol.sigma_tilt_rad is None:
            continue
        if sol.mode in (Mode.DEGRADED, Mode.FAULT):
            continue
        off = math.degrees(
            max(abs(sol.roll_rad - drive.roll_rad), abs(sol.pitch_rad - drive.pitch_rad))
        )
        checked += 1
        beyond += beyond_stated(motion_time(sample.t), off, sol.sigma_tilt_rad)
    assert checked > 500
    assert not beyond, beyond[:5]
