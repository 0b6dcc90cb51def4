"""The IMU's white noise measured at rest (gateway/estimation/imu_noise.py), and the EKF
taking it as its process noise where it is beyond the config's."""

from __future__ import annotations

import logging
import math

import numpy as np
import pytest

from drivers.imu_can import sample_period_s
from drivers.units import DEG_TO_RAD
from gateway.estimation.ekf.ekf_config import EkfConfig, EkfTuning
from gateway.estimation.ekf.ekf_engine import EkfEngine
from gateway.estimation.imu_noise import (
    EDGE_BLOCKS,
    MIN_BLOCK_PAIRS,
    VIBRATION_SAMPLE_PERIOD_S,
    ImuNoiseMeter,
    block_samples,
    vibration_per_sample,
)
from gateway.estimation.observer.observer_config import ObserverConfig
from gateway.estimation.observer.observer_engine import ObserverEngine
from tests.kinematics import Motion, Segment, gnss_stream, imu_stream, motion_time, run

DT_S = 1.0 / 204.8
BLOCK_SAMPLES = block_samples(DT_S)


def _feed(
    meter: ImuNoiseMeter, n: int, sig_g: float, sig_a: float, vib_a: float, dt_s: float = DT_S
) -> None:
    """n samples at rest: white noise plus a 28 Hz engine vibration of amplitude vib_a on
    every accelerometer axis (and vib_a / 3 deg/s on the gyro's)."""
    rng = np.random.default_rng(5)
    t = np.arange(n) * dt_s
    vib = np.sin(2.0 * math.pi * 28.0 * t)
    for k in range(n):
        w = sig_g * rng.standard_normal(3) + vib_a / 3.0 * DEG_TO_RAD * vib[k] + 0.002
        f = sig_a * rng.standard_normal(3) + vib_a * vib[k] + (0.1, -0.2, -9.8)
        meter.add(
            (float(w[0]), float(w[1]), float(w[2])), (float(f[0]), float(f[1]), float(f[2])), dt_s
        )


@pytest.mark.parametrize("rate_hz", [102.4, 409.6, 819.2])
def test_the_excess_over_the_datasheet_is_no_larger_at_another_output_rate(rate_hz: float) -> None:
    """The same unit at another DEC: white noise of one density (0.45 m/s^2 a sample at
    204.8 Hz, sqrt(rate) times that a sample) and the same 28 Hz vibration of 1.8 m/s^2. Its
    excess over the datasheet's noise is at most the 204.8 Hz one's (1.43) + 10 % and still
    counts the vibration: blocks of 0.1 s whatever the rate (1.55, 1.11, 1.16 at 102.4,
    409.6, 819.2 Hz; a single tone's share moves with the block's exact length, 0.098 or
    0.100 s). With blocks of 20 samples: 1.80, 2.48, 2.98, and both engines stated 1.05 deg
    of tilt where 0.59 was right, DEGRADED until the first turn (`short` seed 3, DEC 0 or 1)."""
    sig_a = 0.45

    def excess(dt_s: float) -> float:
        meter = ImuNoiseMeter()
        white = sig_a * math.sqrt(DT_S / dt_s)
        _feed(meter, round(20.0 / dt_s), 0.5 * DEG_TO_RAD, white, 1.8, dt_s)
        return meter.excess(1.0, white)[1]

    at_204 = excess(DT_S)
    assert 1.3 < at_204 < 1.6
    assert 1.05 < excess(1.0 / rate_hz) < 1.1 * at_204


def test_the_configured_vibration_keeps_its_density_at_every_output_rate() -> None:
    """``vibration_*`` are 1-sigma per sample at 204.8 Hz: the decimation filter keeps a
    broadband noise's density, so the EKF's process noise is the same at DEC 0-4 and the
    observer's per-sample figure scales by sqrt(period ratio). Taken per sample at every
    rate, the filters assumed a quarter of the density at 819.2 Hz: on `short` seed 3 at DEC 0
    the observer measured its vibration as beyond the config's and was DEGRADED in the first
    pass (tests/test_imu_output_rates.py)."""
    assert sample_period_s(2) == VIBRATION_SAMPLE_PERIOD_S
    assert vibration_per_sample(0.2, sample_period_s(0)) == pytest.approx(0.4, rel=1e-12)
    assert vibration_per_sample(0.2, sample_period_s(4)) == pytest.approx(0.1, rel=1e-12)
    cfg = EkfConfig()
    q = [EkfTuning.from_config(cfg, sample_period_s(dec)) for dec in range(5)]
    vrw = cfg.accel_vrw_mps_per_sqrt_h / 60.0
    expected = vrw**2 + cfg.vibration_accel_mps2**2 * VIBRATION_SAMPLE_PERIOD_S
    for tuning in q:
        assert tuning.q_accel_m2_per_s3 == pytest.approx(expected, rel=1e-12)
        assert tuning.q_gyro_rad2_per_s == pytest.approx(q[2].q_gyro_rad2_per_s, rel=1e-12)


def test_the_white_noise_is_measured() -> None:
    """0.5 deg/s and 0.45 m/s^2 of white noise a sample: the measured sigmas within 10 %."""
    meter = ImuNoiseMeter()
    _feed(meter, 20 * 205, 0.5 * DEG_TO_RAD, 0.45, 0.0)
    measured = meter.sigma_per_sample()
    assert measured is not None
    sig_g, sig_a = measured
    assert abs(math.degrees(sig_g) / 0.5 - 1.0) < 0.1
    assert abs(sig_a / 0.45 - 1.0) < 0.1


def test_an_engine_vibration_counts_as_far_as_it_does_not_average_out_over_an_epoch() -> None:
    """A 28 Hz vibration of 1.8 m/s^2 (four times the 0.45 m/s^2 of white noise) raises the
    measured accelerometer noise (0.70 m/s^2), but less than 60 % of the samples' spread
    (1.3 m/s^2 of it: sample by sample the vibration would count in full)."""
    meter = ImuNoiseMeter()
    _feed(meter, 20 * 205, 0.5 * DEG_TO_RAD, 0.45, 1.8)
    measured = meter.sigma_per_sample()
    assert measured is not None
    assert 0.45 < measured[1] < 0.6 * math.hypot(0.45, 1.8 / math.sqrt(2.0))


def test_nothing_before_three_seconds_and_a_restart_keeps_what_was_measured() -> None:
    """A rest's first and last EDGE_BLOCKS are left out: 3 s of differences take 5 s."""
    meter = ImuNoiseMeter()
    edges = 2 * EDGE_BLOCKS
    _feed(meter, BLOCK_SAMPLES * (MIN_BLOCK_PAIRS + edges - 1), 0.01, 0.3, 0.0)  # one short
    assert meter.sigma_per_sample() is None
    meter.restart()
    _feed(meter, BLOCK_SAMPLES * (edges + 1), 0.01, 0.3, 0.0)  # a new chain: one more pair
    measured = meter.sigma_per_sample()
    assert measured is not None and abs(measured[1] / 0.3 - 1.0) < 0.25
    assert meter.pairs == MIN_BLOCK_PAIRS


def test_a_drive_off_before_the_rest_test_sees_it_is_left_out() -> None:
    """The last 0.6 s of a rest are a drive-off that the rest test on the GNSS speed has not
    seen yet: 0.3 m/s^2, the body squatting by 0.5 deg in its first 0.25 s. The noise
    measured is the rest's (0.5 deg/s and 0.2 m/s^2 a sample, within 10 %): the squat's
    start and end in block differences weigh as much as 100 of the gyro's noise at rest
    (0.58 deg/s measured with them)."""
    meter = ImuNoiseMeter()
    rng = np.random.default_rng(7)
    n_rest, n_off = 200 * BLOCK_SAMPLES, int(0.6 / DT_S)
    for k in range(n_rest + n_off):
        off, squat = k >= n_rest, n_rest <= k < n_rest + int(0.25 / DT_S)
        w = 0.5 * DEG_TO_RAD * rng.standard_normal(3) + (0.0, 2.0 * DEG_TO_RAD * squat, 0.0)
        f = 0.2 * rng.standard_normal(3) + (0.3 if off else 0.0, 0.0, -9.8)
        meter.add(
            (float(w[0]), float(w[1]), float(w[2])), (float(f[0]), float(f[1]), float(f[2])), DT_S
        )
    meter.restart()
    measured = meter.sigma_per_sample()
    assert measured is not None
    assert abs(math.degrees(measured[0]) / 0.5 - 1.0) < 0.1
    assert abs(measured[1] / 0.2 - 1.0) < 0.1


def _sigma_after_drive_off(
    name: str, accel_noise_mps2: float, turning_s: float
) -> tuple[float, float]:
    """Parked 30 s, then driving off, 12 s straight (the observer's accel-bias filter starts
    after its 8 s hold-off) and into a turn of ``turning_s``: the engine's stated tilt sigma
    at the end and its largest tilt error over the drive, deg."""
    roll, pitch = math.radians(3.0), math.radians(2.0)
    motion = Motion(
        [
            Segment(30.0),
            Segment(4.0, accel_mps2=0.5),
            Segment(12.0),
            Segment(turning_s, yaw_rate_rps=0.1),
        ],
        roll_rad=roll,
        pitch_rad=pitch,
        yaw0_rad=0.5,
    )
    engine = (
        EkfEngine(EkfConfig())
        if name == "ekf"
        else ObserverEngine(ObserverConfig(accel_bias_filter=name != "observer-eq12"))
    )
    imu = imu_stream(motion, noise_g_rps=0.5 * DEG_TO_RAD, noise_a_mps2=accel_noise_mps2, seed=2)
    out: list[tuple[float, float, float]] = []

    def record(_: object) -> None:
        s = engine.solution()
        if s.sigma_tilt_rad is not None and s.roll_rad is not None and s.pitch_rad is not None:
            err = max(abs(s.roll_rad - roll), abs(s.pitch_rad - pitch))
            out.append((motion_time(s.t), s.sigma_tilt_rad, err))

    run(engine, imu, gnss_stream(motion, vel_noise_mps=0.02), every=41, on_sample=record)
    driving = [(sig, err) for t, sig, err in out if t > 40.0]
    assert driving
    return math.degrees(driving[-1][0]), math.degrees(max(e for _, e in driving))


@pytest.mark.parametrize(
    ("name", "turning_s", "gain"),
    [("ekf", 20.0, 1.15), ("observer", 120.0, 1.2), ("observer-eq12", 120.0, 1.3)],
)
def test_an_engine_states_the_noise_of_a_rough_engine(
    name: str, turning_s: float, gain: float
) -> None:
    """An accelerometer four times noisier a sample than ``vibration_accel_mps2`` (0.8
    m/s^2, a rough engine): the stated tilt sigma at the end of the drive is above that with
    the config's noise (0.2 m/s^2; the same before, the config's noise for both), and the
    tilt within 0.1 deg + 3 sigma of it. The EKF's process noise follows it, and so do the
    observer's residual bias floors (:meth:`ObserverEngine._noise_as_measured`), which it
    reaches after two minutes of turning (eq. 12: 0.18 deg stated for both before, 0.38 deg
    off on the rough one; 0.28 stated then). The drive goes straight for 12 s before its
    turn, so that the observer's accel-bias filter starts: driving off into the turn it did
    not, and since 2026-12-05 its stated bias sigma stays the turn-on one until it does
    (0.59 deg; eq. 12's exponent had taken it to 0.215 with nothing learnt). Now 0.18 quiet,
    0.415 rough (eq. 12 0.154, 0.415; the EKF 0.152, 0.201)."""
    sig_quiet, _ = _sigma_after_drive_off(name, 0.2, turning_s)
    sig_rough, err_rough = _sigma_after_drive_off(name, 0.8, turning_s)
    assert sig_rough > gain * sig_quiet
    assert err_rough < 0.1 + 3.0 * sig_rough


def _sigma_started_on_the_move(name: str, meter: ImuNoiseMeter | None, turns: int) -> float:
    """An engine started at 3 m/s (a restart after an IMU stall: no rest before it starts)
    with the rough engine's noise, driving ``turns`` pairs of 20 s turns: its stated tilt
    sigma at the end, deg."""
    turn_pair = [Segment(20.0, yaw_rate_rps=0.1), Segment(20.0, yaw_rate_rps=-0.1)]
    motion = Motion([Segment(10.0), *turn_pair * turns, Segment(20.0)], v0_mps=3.0, yaw0_rad=0.5)
    engine: EkfEngine | ObserverEngine = (
        EkfEngine(EkfConfig(), None, meter)
        if name == "ekf"
        else ObserverEngine(ObserverConfig(), None, meter)
    )
    engine.moving_before()
    imu = imu_stream(motion, noise_g_rps=0.5 * DEG_TO_RAD, noise_a_mps2=0.8, seed=4)
    run(engine, imu, gnss_stream(motion, vel_noise_mps=0.02))
    sigma = engine.solution().sigma_tilt_rad
    assert sigma is not None
    return math.degrees(sigma)


@pytest.mark.parametrize(("name", "turns"), [("ekf", 1), ("observer", 3)])
def test_an_engine_restarted_on_the_move_keeps_the_noise_measured_at_rest(
    name: str, turns: int, caplog: pytest.LogCaptureFixture
) -> None:
    """The fusion core hands one meter to every engine it starts (as it does the epoch
    clock): an engine restarted while driving takes the noise its predecessor measured
    parked, not the config's, and says so; it states the rough engine's noise (EKF: 0.15
    deg after 70 s of driving; observer, once its bias floors are reached: 0.27 after 150 s)
    against the 0.09 and 0.17 its model gives the datasheet's noise. (Without the meter the
    engine also ends up stating more than its model, since its tilt corrections show noise
    beyond it, :mod:`gateway.estimation.bias_change`; the meter is what states it at once.)"""
    meter = ImuNoiseMeter()
    _feed(meter, 20 * 205, 0.5 * DEG_TO_RAD, 0.8, 0.0)
    with caplog.at_level(logging.INFO, logger="gateway"):
        sigma = _sigma_started_on_the_move(name, meter, turns)
    told = [r.getMessage() for r in caplog.records if "IMU noise at rest" in r.getMessage()]
    assert told, "the measured noise was not taken"
    caplog.clear()
    with caplog.at_level(logging.INFO, logger="gateway"):
        _sigma_started_on_the_move(name, None, turns)
    assert not [r for r in caplog.records if "IMU noise at rest" in r.getMessage()]
    assert sigma > 1.3 * {"ekf": 0.09, "observer": 0.17}[name]


@pytest.mark.parametrize("name", ["ekf", "observer"])
def test_samples_lost_in_short_runs_do_not_pass_for_noise(
    name: str, caplog: pytest.LogCaptureFixture
) -> None:
    """Parked 30 s with the datasheet's noise and half the samples lost, eight at a time (an
    overloaded reader shedding stale frames: steps of 44 ms, each bridged by the next
    sample): the noise is measured per sample against the IMU's sample period, not the
    step, so it is the config's and nothing is said of it (the observer took the step for
    the period and said "2.7 times (gyro)", dozens of times, as the step changed)."""
    motion = Motion([Segment(30.0)], roll_rad=0.05, pitch_rad=-0.03)
    imu = imu_stream(motion, noise_g_rps=0.48 * DEG_TO_RAD, noise_a_mps2=0.2, seed=6)
    engine = EkfEngine(EkfConfig()) if name == "ekf" else ObserverEngine(ObserverConfig())
    with caplog.at_level(logging.INFO):
        run(engine, [s for k, s in enumerate(imu) if k % 16 < 8], gnss_stream(motion))
    assert not [r.message for r in caplog.records if "IMU noise at rest" in r.message]
