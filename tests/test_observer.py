"""Tereshkov observer: sign conventions, time constant, bias observability (seed 000)."""

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from drivers.units import GRAVITY_MPS2
from gateway.estimation.attitude import dcm_from_rpy, rpy_from_dcm
from gateway.estimation.observer.observer_config import ObserverConfig
from gateway.estimation.observer.observer_engine import ACCEL_BIAS_Z_FLOOR_MPS2, ObserverEngine
from gateway.estimation.observer.tereshkov import TereshkovObserver
from tests.kinematics import Motion, Segment, gnss_stream, imu_stream, run

G = GRAVITY_MPS2
DT = 0.005  # 200 Hz, 20 samples per 10 Hz GNSS epoch


def _run_at_rest(
    obs: TereshkovObserver,
    c_true: np.ndarray,
    seconds: float,
    bias_g: tuple[float, float, float] = (0.0, 0.0, 0.0),
) -> list[float]:
    """Closed loop at rest: true f_n = -g, GNSS acceleration 0. Returns roll error per epoch."""
    f_b = tuple((c_true.T @ [0.0, 0.0, -G]).tolist())
    roll_err = []
    for _ in range(int(seconds * 10)):
        s_n = s_e = 0.0
        for _ in range(20):
            fp = obs.propagate(bias_g, f_b, DT)
            s_n += fp[0]
            s_e += fp[1]
        obs.correct_tilt(0.0 - s_n / 20, 0.0 - s_e / 20)
        roll_err.append(rpy_from_dcm(obs.c_bp)[0] - rpy_from_dcm(c_true)[0])
    return roll_err


def test_zero_input_leaves_attitude_and_biases_unchanged() -> None:
    c = dcm_from_rpy(0.0, 0.0, 1.0)
    obs = TereshkovObserver(4.0, 40.0, math.radians(45.0), c)
    obs.learn = True
    _run_at_rest(obs, c, 600.0)
    assert_allclose(obs.c_bp, c, atol=1e-12)
    assert_allclose(obs.bg_hat_rps, 0.0, atol=1e-15)
    assert_allclose(obs.ba_hat_mps2, 0.0, atol=1e-15)


def test_tilt_error_decays_with_time_constant_tau() -> None:
    c_true = dcm_from_rpy(0.0, 0.0, 0.7)
    theta0 = math.radians(1.0)
    obs = TereshkovObserver(4.0, 40.0, math.radians(45.0), dcm_from_rpy(theta0, 0.0, 0.7))
    err = _run_at_rest(obs, c_true, 12.0)
    # one epoch of transport delay in the loop: allow 3 %
    assert_allclose(err[39] / theta0, math.exp(-1.0), rtol=0.03)  # t = 4 s = tau
    assert_allclose(err[119] / theta0, math.exp(-3.0), rtol=0.06)  # t = 12 s = 3 tau
    assert all(e > 0 for e in err)  # first order: no overshoot


def test_gyro_bias_alone_gives_steady_tilt_b_tau_without_learning() -> None:
    """Eq. (10) steady state with learning off: w_p = b_g, tilt = b_g tau."""
    c_true = np.eye(3)
    obs = TereshkovObserver(4.0, 40.0, math.radians(45.0), c_true)
    b = math.radians(0.1)
    err = _run_at_rest(obs, c_true, 40.0, bias_g=(b, 0.0, 0.0))
    assert_allclose(err[-1], b * 4.0, rtol=0.03)


def _engine(
    motion: Motion,
    bias_g: tuple[float, float, float] = (0.0, 0.0, 0.0),
    bias_a: tuple[float, float, float] = (0.0, 0.0, 0.0),
) -> ObserverEngine:
    engine = ObserverEngine(ObserverConfig())
    run(engine, imu_stream(motion, bias_g_rps=bias_g, bias_a_mps2=bias_a), gnss_stream(motion))
    return engine


def test_the_z_accel_bias_is_learnt_from_the_heights_and_leaves_the_side_slope_roll() -> None:
    """On a 10 deg side slope C f_b puts b_az sin(roll) on the horizontal: 5 mg of z bias
    held the roll 0.051 deg off for good, on a straight or in any turn (it turns with the
    slope). The height loop's mean correction learns it (60 s low-pass), and the roll with it;
    the stated z sigma falls from the turn-on 0.1 m/s^2 to its floor."""
    roll, b_az = math.radians(10.0), 0.05
    motion = Motion([Segment(3.0), Segment(3.0, accel_mps2=1.0), Segment(300.0)], roll_rad=roll)
    imu, fixes = imu_stream(motion, bias_a_mps2=(0.0, 0.0, b_az)), gnss_stream(motion)
    engines = (
        ObserverEngine(ObserverConfig()),
        ObserverEngine(ObserverConfig(estimate_biases=False)),
    )
    for engine in engines:
        run(engine, imu, fixes)
    learnt, fixed = (e.solution() for e in engines)
    assert learnt.roll_rad is not None and fixed.roll_rad is not None
    assert learnt.bias_a_mps2 is not None
    assert math.degrees(abs(fixed.roll_rad - roll)) == pytest.approx(
        math.degrees(b_az * math.sin(roll) / G), rel=0.05
    )
    assert math.degrees(abs(learnt.roll_rad - roll)) < 0.002
    assert learnt.bias_a_mps2[2] == pytest.approx(b_az, abs=0.001)
    state = engines[0].learned_state()
    assert state is not None and state.sigma_a_mps2[2] == ACCEL_BIAS_Z_FLOOR_MPS2


def test_gyro_xy_bias_converges_on_a_straight_drive() -> None:
    b = (math.radians(0.1), math.radians(-0.15), 0.0)
    motion = Motion([Segment(3.0), Segment(3.0, accel_mps2=1.0), Segment(300.0)], yaw0_rad=2.0)
    sol = _engine(motion, bias_g=b).solution()
    assert sol.bias_g_rps is not None
    assert_allclose(np.degrees(sol.bias_g_rps[:2]), [0.1, -0.15], atol=0.002)
    assert sol.convergence.gyro_xy
    assert not sol.convergence.accel_xy
    assert abs(sol.roll_rad or 0.0) < math.radians(0.01)


def test_accel_bias_y_not_learned_straight_x_by_the_climb_both_in_circles() -> None:
    ba = (0.1, -0.1, 0.0)
    start = [Segment(3.0), Segment(3.0, accel_mps2=1.0)]
    straight = _engine(Motion([*start, Segment(200.0)]), bias_a=ba).solution()
    assert straight.bias_a_mps2 is not None and straight.roll_rad is not None
    # y unobservable on a straight: not learned (z is learnt from the heights: -1 mg here,
    # the tilt error's g (1 - cos) the turn-on x/y biases leave in the vertical) ...
    assert abs(straight.bias_a_mps2[1]) < 1e-3
    # ... and it shows up as tilt: roll error = b_ay / g (eq. 8)
    assert_allclose(straight.roll_rad, -ba[1] / G, atol=2e-4)
    # x is, by the track's climb angle (a wheeled vehicle moves along body x), but only down
    # to the chassis's own pitch against its track: its 0.25 deg prior keeps a sixth of
    # the bias's 0.58 deg
    assert 0.75 * ba[0] < straight.bias_a_mps2[0] < 0.9 * ba[0]
    assert straight.pitch_rad is not None
    assert_allclose(straight.pitch_rad, 0.16 * ba[0] / G, atol=0.03 * ba[0] / G)
    # headland pattern: straights and half circles alternating right and left. In one
    # endless circle only b_g + w_z b_a / g is observable (eq. 10); both turn directions
    # separate the two.
    u_turn = math.pi / 0.3
    headlands = [
        Segment(20.0),
        Segment(u_turn, yaw_rate_rps=0.3),
        Segment(20.0),
        Segment(u_turn, yaw_rate_rps=-0.3),
    ]
    turning = _engine(Motion([*start, *headlands * 4]), bias_a=ba).solution()
    assert turning.bias_a_mps2 is not None and turning.roll_rad is not None
    assert_allclose(turning.bias_a_mps2[:2], ba[:2], atol=0.005)
    assert turning.convergence.accel_xy
    assert abs(turning.roll_rad) < math.radians(0.02)


def test_standing_the_tilt_is_the_stops_mean_not_the_loops_arw_and_gyro_bias() -> None:
    """Parked on a slope at a cold start, with the ADIS16334's noise, the simulator's engine
    vibration and x/y gyro biases of the turn-on spread (0.1 deg/s): the tilt loop alone
    holds b_g tau (0.4 deg, eq. 10) until eq. (11) has learnt them (tau_g 40 s), and its ARW
    floor is 0.05 deg. Levelled on the stop's mean specific force the error is what 20 s of
    vibration leaves (0.03 deg), within the stated sigma, and the gyro biases are learnt
    from the mean body rate: within 0.025 deg/s (3.5 sigma of the 0.007 deg/s that the ARW
    leaves) 25 s after the start, where eq. (11)'s loop leaves 0.06."""
    roll, pitch = math.radians(6.0), math.radians(-4.0)
    motion = Motion([Segment(90.0)], roll_rad=roll, pitch_rad=pitch)
    b_g = (math.radians(0.1), math.radians(-0.08), 0.0)
    arw = math.radians(2.0) / 60.0  # deg/sqrt(h) -> rad/sqrt(s)
    imu = imu_stream(
        motion,
        bias_g_rps=b_g,
        noise_g_rps=arw / math.sqrt(4.0 / 819.2),
        noise_a_mps2=0.26,
        seed=3,
    )
    engine = ObserverEngine(ObserverConfig())
    errors: list[tuple[float, float, float, float]] = []

    def record(sample: object) -> None:
        sol = engine.solution()
        if sol.roll_rad is not None and sol.pitch_rad is not None and sol.sigma_tilt_rad:
            assert sol.bias_g_rps is not None
            err = max(abs(sol.roll_rad - roll), abs(sol.pitch_rad - pitch))
            err_bg = max(abs(sol.bias_g_rps[0] - b_g[0]), abs(sol.bias_g_rps[1] - b_g[1]))
            errors.append((sol.t or 0.0, err, sol.sigma_tilt_rad, err_bg))

    run(engine, imu, gnss_stream(motion, vel_noise_mps=0.02), every=41, on_sample=record)
    t0 = errors[0][0]
    late = np.array([e for t, e, _, _ in errors if t - t0 > 20.0])
    assert math.degrees(float(np.sqrt(np.mean(late**2)))) < 0.035
    assert all(e < 3.0 * s for t, e, s, _ in errors if t - t0 > 5.0)
    assert all(math.degrees(e_bg) < 0.025 for t, _, _, e_bg in errors if t - t0 > 25.0)
    assert engine.solution().stationary
