"""The accelerometer-bias filter (``[observer] accel_bias_filter``): on a hand-made tilt loop,
and in the observer engine on a simulated steep-ground run against eq. (12)."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest

from drivers.units import DEG_TO_RAD, GRAVITY_MPS2, MG_MPS2, SQRT_SECONDS_PER_HOUR
from gateway.demo.accuracy import evaluate
from gateway.estimation.attitude import Mat9
from gateway.estimation.ekf.ekf_config import GM_ALLAN_FLOOR
from gateway.estimation.observer.accel_bias_filter import (
    NIS_WINDOW_Z,
    AccelBiasFilter,
    BiasFilterNoise,
    chi_square_quantile,
)
from sim_bus.scenarios import SCENARIOS

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

TAU_S, T_S = 4.0, 0.1
SIGMA_V = 0.02
NOISE = BiasFilterNoise(
    accel_psd=(0.12 / SQRT_SECONDS_PER_HOUR) ** 2 + 0.15**2 * 4.0 / 819.2,
    arw_rad_per_sqrt_s=2.0 * DEG_TO_RAD / SQRT_SECONDS_PER_HOUR,
    accel_bias_sigma_mps2=0.1 * MG_MPS2 / GM_ALLAN_FLOOR,
    gyro_bias_sigma_rps=0.007 * DEG_TO_RAD / GM_ALLAN_FLOOR,
    bias_correlation_s=100.0,
)


def level_c9(psi: float) -> Mat9:
    """C_b^p of a level body heading ``psi``."""
    c, s = math.cos(psi), math.sin(psi)
    return (c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0)


def loop_run(
    bias_b: tuple[float, float], turns: int, seed: int = 0
) -> tuple[list[tuple[float, np.ndarray, float, bool]], np.ndarray]:
    """Seed 000's tilt loop on level ground, one horizontal tilt error x (as a specific force,
    NED) corrected by e / tau each epoch, with the filter learning the body's x/y bias: 60 s
    straight, then ``turns`` U-turns (two 5 s quarter turns each, alternately left and right)
    between 30 s straights. Levelled at rest on the bias (x = -C b). Returns (time, bias
    estimate, filter sigma, whether the filter finds its innovations inconsistent) per epoch,
    and the true bias."""
    rng = np.random.default_rng(seed)
    b = np.array(bias_b)
    b_hat = np.zeros(2)
    flt = AccelBiasFilter(TAU_S)
    psi = 0.3
    rate = []  # yaw rate per epoch
    rate += [0.0] * 600
    for k in range(turns):
        w = (math.pi / 2 / 5.0) * (1 if k % 2 == 0 else -1)
        rate += [w] * 100 + [0.0] * 300
    c_h = np.array(level_c9(psi)).reshape(3, 3)[:2, :2]
    x = -c_h @ b
    v_noise_prev = rng.normal(0.0, SIGMA_V, 2)
    flt.start(level_c9(psi), 0.1, (0.0, 0.0, 0.0, 0.0, 0.0), NOISE)
    out = []
    e_applied = np.zeros(2)
    for k, w in enumerate(rate):
        t = (k + 1) * T_S
        # over the interval: the loop's control, the gyro's walk, the body turning
        x_start = x
        x = x + T_S / TAU_S * e_applied
        x = x + GRAVITY_MPS2 * NOISE.arw_rad_per_sqrt_s * math.sqrt(T_S) * rng.normal(size=2)
        psi_mid = psi + 0.5 * w * T_S
        psi += w * T_S
        c_mid = np.array(level_c9(psi_mid)).reshape(3, 3)[:2, :2]
        f_true = -c_mid @ (b - b_hat)  # what e averages to, besides the tilt
        v_noise = rng.normal(0.0, SIGMA_V, 2)
        accel = math.sqrt(NOISE.accel_psd / T_S) * rng.normal(size=2)
        e = -0.5 * (x_start + x) + f_true + (v_noise - v_noise_prev) / T_S + accel
        v_noise_prev = v_noise
        db = flt.epoch(t, (e[0], e[1]), (e[0], e[1]), (0.0, 0.0), level_c9(psi),
                       (*b_hat, 0.0, 0.0, 0.0), SIGMA_V, learn=True)  # fmt: skip
        b_hat = b_hat + np.array(db)
        e_applied = e
        out.append((t, b_hat.copy(), flt.sigma_mps2, flt.inconsistent()))
    return out, b


def test_nothing_is_learnt_before_the_heading_changes() -> None:
    """Until the first turn a bias and the tilt it levelled are one quantity (x = -C b)."""
    out, _ = loop_run((0.03, -0.02), turns=0)
    t, b_hat, sigma, _ = out[-1]
    assert t == pytest.approx(60.0)
    assert np.max(np.abs(b_hat)) < 2.0 * MG_MPS2  # of 3 mg / -2 mg true
    assert sigma > 0.09  # the 0.1 m/s^2 it started with


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_turns_both_ways_find_the_bias_within_its_sigma(seed: int) -> None:
    out, b = loop_run((0.03, -0.02), turns=6, seed=seed)
    _, b_hat, sigma, _ = out[-1]
    err = b_hat - b
    assert np.max(np.abs(err)) < 1.0 * MG_MPS2
    assert np.max(np.abs(err)) < 3.0 * sigma
    assert sigma < 1.0 * MG_MPS2
    # the first U-turn alone takes out most of it
    after_first = next(bh for tt, bh, _, _ in out if tt >= 60.0 + 10.0 + 30.0)
    assert np.max(np.abs(after_first - b)) < 0.3 * np.max(np.abs(b))
    assert not any(bad for _, _, _, bad in out)  # a consistent filter's innovations


def test_the_window_bound_is_the_chi_square_quantile() -> None:
    """Wilson-Hilferty against the chi-square quantiles at z = 4.75 (scipy's, 1.02e-6): 2
    degrees of freedom 27.6 (the per-epoch gate), 10: 46.8, 100: 182.1 (10 s at 10 Hz)."""
    assert chi_square_quantile(2, NIS_WINDOW_Z) == pytest.approx(27.6, rel=0.1)
    assert chi_square_quantile(10, NIS_WINDOW_Z) == pytest.approx(46.8, rel=0.03)
    assert chi_square_quantile(100, NIS_WINDOW_Z) == pytest.approx(182.1, rel=0.003)


def test_a_platform_turned_by_the_engine_is_not_read_as_bias() -> None:
    """A heading alignment turns the platform (and its tilt error) about the vertical, not the
    body: told so, the filter's tilt error turns with it, and it learns nothing of the bias
    the levelling hid (untold, the step looks like a turn: it took the bias for zero, sigma
    0.1 -> 0.0075 m/s^2)."""
    flt = AccelBiasFilter(TAU_S)
    b_hat = np.zeros(2)
    flt.start(level_c9(0.0), 0.1, (0.0, 0.0, 0.0, 0.0, 0.0), NOISE)
    x = np.array([0.02, -0.01])  # levelled on a bias of -C^T x, the body's
    for k in range(600):
        psi = 0.0 if k < 300 else 2.0  # aligned 115 deg round at 30 s
        if k == 300:
            flt.rotate_about_vertical(2.0)
            c, s = math.cos(2.0), math.sin(2.0)
            x = np.array([[c, -s], [s, c]]) @ x
        # the bias turns with the body, the tilt with the platform: e stays 0
        db = flt.epoch((k + 1) * T_S, (0.0, 0.0), (0.0, 0.0), (0.0, 0.0), level_c9(psi),
                       (0, 0, 0, 0, 0), SIGMA_V, learn=True)  # fmt: skip
        b_hat += db
    assert np.max(np.abs(b_hat)) < 0.5 * MG_MPS2
    assert flt.sigma_mps2 > 0.09


@pytest.mark.parametrize("told", [True, False], ids=["told", "untold"])
def test_a_stop_s_gyro_bias_update_is_no_tilt_after_it(told: bool) -> None:
    """20 s at rest, levelled every epoch, the zero-rate update moving the x gyro bias
    estimate by 0.2 deg/s (a unit twice its datasheet's turn-on spread). The platform is
    then level on the bias and the gyro bias known: told so (``level``), the filter drives
    off with nothing to correct. Untold (as before ``level``), it carries the move as a
    gyro bias error and predicts the tilt that error would build over the stop (0.7 m/s^2),
    and before any turn takes 1 mg of y bias out of it."""
    flt = AccelBiasFilter(TAU_S)
    c9 = level_c9(0.3)
    flt.start(c9, 0.1, (0.0, 0.0, 0.0, 0.0, 0.0), NOISE)
    t = 0.0
    for _ in range(50):
        t += T_S
        flt.epoch(t, (0.0, 0.0), (0.0, 0.0), (0.0, 0.0), c9, (0.0, 0.0, 0.0, 0.0, 0.0),
                  SIGMA_V, learn=True)  # fmt: skip
    flt.open(t, c9)
    bg_x = 0.0
    for _ in range(200):  # at rest: levelled each epoch, the gyro bias observed
        t += T_S
        bg_x += 0.2 * DEG_TO_RAD / 200
        if told:
            flt.level(t, c9, (0.0, 0.0, 0.0, bg_x, 0.0), 0.02 * DEG_TO_RAD, 0.01 * DEG_TO_RAD)
    correction = np.zeros(2)
    for _ in range(100):  # driving straight on: nothing wrong, e = 0
        t += T_S
        db = flt.epoch(t, (0.0, 0.0), (0.0, 0.0), (0.0, 0.0), c9, (0.0, 0.0, 0.0, bg_x, 0.0),
                       SIGMA_V, learn=True)  # fmt: skip
        correction += db
    assert not flt.inconsistent()
    assert flt.sigma_mps2 > 0.09  # nothing learnt before a turn
    # told: no correction; untold: 1 mg of y bias out of the tilt it predicted
    assert (np.max(np.abs(correction)) < 0.2 * MG_MPS2) == told, correction


def test_in_the_engine_the_filter_learns_the_biases_better_than_eq_12() -> None:
    """steep-turns seed 1 (8-10 deg of side slope, tight headland turns), 6 minutes, after
    200 s: the observer with the filter against the paper's eq. (12). Measured: x/y accel
    bias RMS 0.0058/0.0037 against 0.0258/0.0069 m/s^2, roll/pitch 0.059/0.070 against
    0.073/0.161 deg (eq. 12 has not yet learnt the x bias of -0.068 m/s^2)."""
    from accuracy import run_engines, simulate_inputs

    data = simulate_inputs(SCENARIOS["steep-turns"], seed=1, minutes=6.0)
    traces = run_engines(data, ["observer-eq12", "observer"])
    lever = data.setup.antenna_lever_arm_m
    paper, filt = (evaluate(traces[k], data.truth, lever, 200.0) for k in traces)
    assert max(filt.bias_a_rms_mps2[:2]) < 0.4 * max(paper.bias_a_rms_mps2[:2])
    assert max(filt.bias_a_rms_mps2[:2]) < 0.01  # issue 16's target on slopes
    assert max(filt.rpy_rms_rad[:2]) < 0.6 * max(paper.rpy_rms_rad[:2])
