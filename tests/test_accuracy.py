"""Accuracy metrics against hand-worked cases, and an end-to-end accuracy regression."""

import math
import sys
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose

from drivers.units import wrap_pi
from gateway.demo.accuracy import (
    Trace,
    attitude_error_rad,
    evaluate,
    first_time,
    horizontal_error_m,
    lever_arm_error_h_m,
    max_abs,
    rms,
)
from gateway.estimation.geodesy import ned_to_lla
from sim_bus.truth import Truth

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

DEG = math.pi / 180.0


def test_rms_and_max_ignore_nan() -> None:
    assert rms([3.0, -4.0, math.nan]) == pytest.approx(math.sqrt(12.5))
    assert max_abs([1.0, -7.0, math.nan]) == 7.0
    assert math.isnan(rms([math.nan]))


def test_angle_errors_wrap_across_north() -> None:
    err = attitude_error_rad([[0.0, 0.0, 359.0 * DEG]], [[0.0, 0.0, 1.0 * DEG]])
    assert_allclose(err, [[0.0, 0.0, -2.0 * DEG]], atol=1e-12)
    assert_allclose(wrap_pi(np.array([math.pi, -math.pi, 3 * math.pi])), [-math.pi] * 3)


def test_lever_arm_error_of_a_roll_error_on_a_3_m_mast() -> None:
    # ALGORITHMS.md 4: 0.1 deg of roll costs 3 m * sin(0.1 deg) = 5.2 mm across track
    est = [[0.1 * DEG, 0.0, 0.3]]
    true = [[0.0, 0.0, 0.3]]
    assert lever_arm_error_h_m(est, true, (0.0, 0.0, -3.0))[0] == pytest.approx(
        3.0 * math.sin(0.1 * DEG), rel=1e-9
    )
    # a pure yaw error moves only a horizontal arm: 0.3 m * 1 deg = 5.2 mm
    assert lever_arm_error_h_m([[0, 0, 1 * DEG]], [[0, 0, 0.0]], (0.3, 0.0, 0.0))[
        0
    ] == pytest.approx(2 * 0.3 * math.sin(0.5 * DEG), rel=1e-9)
    assert_allclose(horizontal_error_m([[3.0, 4.0, 9.0]], [[0.0, 0.0, 0.0]]), [5.0])


def test_first_time_is_when_the_flag_rises_for_good() -> None:
    t = np.arange(6.0)
    assert first_time(t, [0, 1, 0, 1, 1, 1]) == 3.0
    assert first_time(t, [1, 1, 1, 1, 1, 1]) == 0.0
    assert first_time(t, [1, 1, 1, 1, 1, 0]) is None


def _truth(n: int) -> Truth:
    t = np.arange(n, dtype=float)
    z3 = np.zeros((n, 3))
    origin = np.array([52.0, 10.0, 80.0])
    return Truth(
        t=t,
        pos_ned_m=z3.copy(),
        lla=ned_to_lla(z3, origin),
        vel_ned_mps=z3,
        rpy_rad=z3.copy(),
        w_ib_b=z3,
        f_ib_b_imu=z3,
        pos_ant_ned_m=z3,
        lla_ant=ned_to_lla(z3, origin),
        vel_ant_ned_mps=z3,
        reversing=np.zeros(n, bool),
        stationary=np.zeros(n, bool),
        bias_g_rps=np.tile([0.01, 0.0, 0.0], (n, 1)),
        bias_a_mps2=np.tile([0.1, 0.0, 0.0], (n, 1)),
        origin_lla=origin,
    )


def test_evaluate_on_a_hand_made_trace() -> None:
    truth = _truth(10)
    roll = np.where(np.arange(10) < 5, 1.0, 0.1) * DEG  # 1 deg before t = 5, then 0.1 deg
    ref_ned = np.zeros((10, 3))
    ref_ned[:, 1] = 0.02  # 2 cm east
    trace = Trace(
        t=truth.t.copy(),
        rpy_rad=np.column_stack((roll, np.zeros(10), np.zeros(10))),
        ref_lla=ned_to_lla(ref_ned, truth.origin_lla),
        bias_g_rps=np.tile([0.012, 0.0, 0.0], (10, 1)),
        bias_a_mps2=np.tile([0.09, 0.0, 0.0], (10, 1)),
        gyro_xy_converged=np.arange(10) >= 5,
        accel_xy_converged=np.arange(10) >= 5,
    )
    acc = evaluate(trace, truth, (0.0, 0.0, -3.0))
    assert acc.converged_from_s == 5.0  # both flags rise at t = 5
    assert acc.gyro_xy_converged_s == 5.0
    assert_allclose(acc.rpy_rms_rad, [0.1 * DEG, 0.0, 0.0], atol=1e-12)
    assert_allclose(acc.bias_g_final_rps, [0.002, 0.0, 0.0], atol=1e-12)
    assert_allclose(acc.bias_a_rms_mps2, [0.01, 0.0, 0.0], atol=1e-12)
    assert acc.ref_h_rms_m == pytest.approx(0.02, abs=1e-6)
    assert acc.ref_from_att_h_rms_m == pytest.approx(3.0 * math.sin(0.1 * DEG), rel=1e-9)


def test_observer_on_short_with_the_papers_biases() -> None:
    """End to end through the drivers (LogInputs) on the 2-minute scenario with seed 000's
    biases (0.08/0.13 deg/s, 0.11 m/s^2). Without bias estimation the tilt sits at
    b_g tau + b_a / g (0.5-0.8 deg per axis); over the last 20 s, after both U-turns have made
    the accelerometer bias observable, the observer must be well below it (with eq. 12,
    seeds 1-3 gave 5.0-6.5x; its accelerometer bias is not fully converged after two turns)."""
    from accuracy import paper_scenario, run_engines, simulate_inputs

    data = simulate_inputs(paper_scenario("short"), seed=1)
    traces = run_engines(data, ["observer", "observer-no-bias"])
    lever = data.setup.antenna_lever_arm_m
    last_20_s = float(data.truth.t[-1] - data.truth.t[0]) - 20.0
    obs = evaluate(traces["observer"], data.truth, lever, converged_from_s=last_20_s)
    base = evaluate(traces["observer-no-bias"], data.truth, lever, converged_from_s=last_20_s)
    assert max(obs.rpy_rms_rad[:2]) < 0.3 * DEG
    assert obs.ref_from_att_h_rms_m < 0.02
    assert np.hypot(*base.rpy_rms_rad[:2]) > 4.0 * np.hypot(*obs.rpy_rms_rad[:2])
    assert base.ref_from_att_h_rms_m > 4.0 * obs.ref_from_att_h_rms_m
    # gyro x/y biases of 0.08/0.13 deg/s found to within 0.03 deg/s in 2 minutes
    assert max(abs(obs.bias_g_final_rps[:2])) < 0.03 * DEG


def test_the_second_order_tilt_loop_beats_the_papers_first_order_loop() -> None:
    """gnss-outage seed 4 (a seed the loop was not looked at on: RTK float, DGNSS, a minute
    of single point and two outages): after 600 s the second-order loop, its tau from the
    noise of the IMU and of each fix, against seed 000's first-order loop at 4 s
    (``observer-first-order``). Measured: roll/pitch 0.067/0.055 deg against 0.086/0.071,
    terrain compensation from attitude 0.45 cm against 0.58."""
    from accuracy import converged_from_s, run_engines, simulate_inputs

    from sim_bus.scenarios import SCENARIOS

    data = simulate_inputs(SCENARIOS["gnss-outage"], seed=4)
    traces = run_engines(data, ["observer", "observer-first-order"])
    t_conv = converged_from_s(data, traces["observer"])
    lever = data.setup.antenna_lever_arm_m
    second = evaluate(traces["observer"], data.truth, lever, converged_from_s=t_conv)
    first = evaluate(traces["observer-first-order"], data.truth, lever, converged_from_s=t_conv)
    assert max(second.rpy_rms_rad[:2]) < 0.07 * DEG
    assert np.all(second.rpy_rms_rad[:2] < 0.85 * first.rpy_rms_rad[:2])
    assert second.ref_from_att_h_rms_m < 0.9 * first.ref_from_att_h_rms_m
