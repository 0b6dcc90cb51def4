"""The tilt loop's control (eq. 3): first order as in seed 000, second order as the product's.

One horizontal axis at the epoch rate: the platform's tilt error theta walks with the gyro's
ARW (and a gyro bias), the epoch's e is g theta plus the difference of two white velocity
errors over T plus the accelerometer's white noise, and the control turns the platform back
by u T / (g tau_s).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from drivers.units import DEG_TO_RAD, GRAVITY_MPS2
from gateway.estimation.observer.tilt_loop import TiltLoop

T_S = 0.1  # 10 Hz epochs
ARW = 2.0 * DEG_TO_RAD / 60.0  # the ADIS16334's 2 deg/rt-h, rad/rt-s
SIGMA_V = 0.02  # RTK velocity, m/s
G = GRAVITY_MPS2


def held_at(tau_s: float, second_order: bool = True) -> TiltLoop:
    """A loop whose tau stays ``tau_s``: told of a gyro so noisy that its fastest is best."""
    loop = TiltLoop(tau_s, second_order)
    loop.set_imu_noise(1.0, 0.0)
    return loop


def run_loop(
    loop: TiltLoop,
    n: int,
    seed: int,
    arw: float = 0.0,
    sigma_v: float = 0.0,
    sigma_a: float = 0.0,
    bias_rps: float = 0.0,
    theta0_rad: float = 0.0,
) -> np.ndarray:
    """The tilt error (rad) after each epoch; ``sigma_a`` the accelerometer's white noise on
    an epoch's mean, m/s^2."""
    rng = np.random.default_rng(seed)
    theta, v_prev = theta0_rad, rng.normal(0.0, sigma_v) if sigma_v else 0.0
    out = np.empty(n)
    for k in range(n):
        theta_start = theta
        theta += arw * math.sqrt(T_S) * rng.normal() + bias_rps * T_S
        v = rng.normal(0.0, sigma_v) if sigma_v else 0.0
        e = G * 0.5 * (theta_start + theta) + (v - v_prev) / T_S + sigma_a * rng.normal()
        v_prev = v
        u, _ = loop.control((e, 0.0), T_S, T_S, max(sigma_v, SIGMA_V))
        theta -= u * T_S / (loop.tau_s * G)
        out[k] = theta
    return out


def rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(x**2)))


@pytest.mark.parametrize("sigma_v", [SIGMA_V, 0.1])
@pytest.mark.parametrize("second_order", [False, True])
def test_every_e_is_applied_in_full_in_the_end(second_order: bool, sigma_v: float) -> None:
    """Each epoch's e T is owed until applied, rejected spans (interval > period) included:
    what the control applies adds up to the sum of e T / tau (tau now: a noisy fix's slower
    loop), so the velocity noise still telescopes to one velocity's."""
    loop = TiltLoop(2.0, second_order)
    loop.set_imu_noise(ARW, 0.0)
    rng = np.random.default_rng(5)
    owed, applied = 0.0, 0.0
    for k in range(200):
        interval = T_S * (3 if k % 17 == 0 else 1)
        e = float(rng.normal(0.0, 0.3))
        u, _ = loop.control((e, 0.0), interval, T_S, sigma_v)
        owed += e * interval / loop.tau_now_s
        applied += u * T_S / loop.tau_s
    if second_order:  # the low-pass still holds a part ...
        assert abs(applied - owed) > 1e-3 * abs(owed)
    for _ in range(300):  # ... which epochs with nothing new apply
        u, _ = loop.control((0.0, 0.0), T_S, T_S, sigma_v)
        applied += u * T_S / loop.tau_s
    assert applied == pytest.approx(owed, rel=1e-9)


def test_the_second_order_loop_passes_a_third_of_the_velocity_noise() -> None:
    """White RTK velocity noise alone, both loops at 2 s: the first order's tilt is
    sigma_v / (g tau), the second order's sqrt(2 T / tau) of it, as each loop states."""
    out = {}
    for second in (False, True):
        loop = held_at(2.0, second)
        out[second] = rms(run_loop(loop, 30_000, seed=1, sigma_v=SIGMA_V)[1000:])
        assert out[second] == pytest.approx(loop.velocity_tilt_sigma(SIGMA_V, T_S), rel=0.15)
    assert out[True] < 0.4 * out[False]


@pytest.mark.parametrize("second_order", [False, True])
def test_the_imu_noise_through_the_loop_is_what_the_loop_states(second_order: bool) -> None:
    """Gyro ARW and the accelerometer's white noise (0.2 m/s^2 a sample at 204.8 Hz): the
    tilt variance is ARW^2 tau / 2 (second order 5 tau / 8) + S_a / (2 g^2 tau)."""
    sigma_a = 0.2 / math.sqrt(204.8 * T_S)  # an epoch's mean
    loop = TiltLoop(2.0, second_order)
    loop.set_imu_noise(ARW, sigma_a**2 * T_S)
    loop.control((0.0, 0.0), T_S, T_S, SIGMA_V)
    tilt = run_loop(loop, 60_000, seed=2, arw=ARW, sigma_a=sigma_a)[1000:]
    assert float(np.mean(tilt**2)) == pytest.approx(loop.noise_tilt_var(), rel=0.15)


@pytest.mark.parametrize("second_order", [False, True])
def test_a_gyro_bias_leaves_the_steady_tilt_b_tau(second_order: bool) -> None:
    loop = held_at(2.0, second_order)
    b = 0.01 * DEG_TO_RAD
    tilt = run_loop(loop, 400, seed=3, bias_rps=b)
    assert tilt[-1] == pytest.approx(b * 2.0, rel=0.05)


@pytest.mark.parametrize("second_order", [False, True])
def test_a_tilt_left_on_the_platform_decays_as_the_loop_takes_it_out(second_order: bool) -> None:
    """A levelling 1 deg off, the loop closed from then: what :meth:`TiltLoop.decay` says is
    left, epoch by epoch, is what the loop leaves (second order: (1 + 2t/tau) exp(-2t/tau),
    0.74 after half a tau where exp(-t/tau) would say 0.61)."""
    loop = held_at(2.0, second_order)
    tilt = run_loop(loop, 60, seed=7, theta0_rad=DEG_TO_RAD)
    left, held = DEG_TO_RAD, 0.0
    for k in range(60):
        left, held = loop.decay(left, held, T_S)
        assert tilt[k] == pytest.approx(left, abs=0.03 * DEG_TO_RAD)
    if second_order:
        assert loop.decay(1.0, 0.0, 1.0)[0] == pytest.approx(2.0 * math.exp(-1.0))


def test_the_loop_takes_the_tau_of_least_tilt_variance() -> None:
    """The datasheet's ARW, the config's 0.2 m/s^2 of vibration and RTK's velocity: the
    loop's own tau (about 2.6 s) does better than 0.6 and 1.7 times it, and a tenth better
    than the paper's first-order loop at 4 s."""
    sigma_a = 0.2 / math.sqrt(204.8 * T_S)
    noise = {"arw": ARW, "sigma_v": SIGMA_V, "sigma_a": sigma_a}
    loop = TiltLoop(1.0, True)
    loop.set_imu_noise(ARW, sigma_a**2 * T_S)
    best = rms(run_loop(loop, 40_000, seed=4, **noise)[1000:])
    tau = loop.tau_now_s
    assert 2.3 < tau < 2.9
    for other in (0.6 * tau, 1.7 * tau):
        assert best < rms(run_loop(held_at(other), 40_000, seed=4, **noise)[1000:])
    assert best < 0.93 * rms(run_loop(held_at(4.0, False), 40_000, seed=4, **noise)[1000:])


def test_noisier_fixes_slower_receivers_and_rougher_engines_slow_the_loop() -> None:
    """Single point's 10 cm/s: about 4.2 s, and the tilt smaller than a loop held at the RTK
    optimum's 2 s; a 1 Hz receiver slower than a 10 Hz one; 20 Hz as fast as 10 Hz (never
    faster than tau_s); a rough engine's accelerometer (0.8 m/s^2) at 4 tau_s at most."""
    loop = TiltLoop(2.0, True)
    loop.set_imu_noise(ARW, 0.0)
    assert loop.optimal_tau_s(SIGMA_V, T_S) == 2.0
    assert loop.optimal_tau_s(SIGMA_V, 0.05) == 2.0
    assert loop.optimal_tau_s(SIGMA_V, 1.0) > 3.0
    assert 4.0 < loop.optimal_tau_s(0.1, T_S) < 4.4
    slowed = rms(run_loop(loop, 30_000, seed=6, arw=ARW, sigma_v=0.1)[1000:])
    assert slowed < 0.8 * rms(run_loop(held_at(2.0), 30_000, seed=6, arw=ARW, sigma_v=0.1)[1000:])
    stated = math.sqrt(loop.noise_tilt_var() + loop.velocity_tilt_sigma(0.1, T_S) ** 2)
    assert slowed == pytest.approx(stated, rel=0.2)
    loop.set_imu_noise(ARW, 0.8**2 / 204.8)
    assert loop.optimal_tau_s(SIGMA_V, T_S) == 8.0
    first = TiltLoop(4.0, False)
    first.set_imu_noise(ARW, 0.0)
    first.control((0.1, 0.0), T_S, T_S, 0.1)
    assert first.tau_now_s == 4.0  # the paper's loop keeps its tau
