"""The IMU's temperature rate and the bias walks it drives (gateway/estimation/temperature.py)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from drivers.units import DEG_TO_RAD, MG_MPS2
from gateway.estimation.temperature import MIN_READINGS, WINDOW_S, TemperatureRate, TemperatureWalk

TEMP_LSB_C = 0.06785  # TEMP_OUT's step (SPEC 1)


def readings(rate_c_per_s: float, seconds: int, seed: int = 0) -> list[tuple[float, float]]:
    """IMU_AUX temperatures at 1 Hz: a ramp from 5 degC, 0.05 degC of noise, TEMP_OUT's steps."""
    rng = np.random.default_rng(seed)
    t = np.arange(seconds, dtype=float)
    temp = 5.0 + rate_c_per_s * t + 0.05 * rng.standard_normal(seconds)
    return list(zip(t, np.rint(temp / TEMP_LSB_C) * TEMP_LSB_C, strict=True))


def rate_after(points: list[tuple[float, float]]) -> float:
    rate = TemperatureRate()
    for t, c in points:
        rate.add(t, c)
    return rate.rate_c_per_s


@pytest.mark.parametrize("rate_c_per_s", [0.0, 0.02, 0.133])
def test_a_warm_up_s_rate_through_temp_out_s_steps_and_noise(rate_c_per_s: float) -> None:
    """8 degC a minute (a cold unit's first minutes), 1.2 degC a minute, steady: each
    within 4 mdegC/s over seeds (a rate of 4 mdegC/s walks the gyro bias by a tenth of the
    in-run wander's walk), steady exactly 0 (the engines then behave as they would without
    a temperature)."""
    for seed in range(10):
        rate = rate_after(readings(rate_c_per_s, 60, seed))
        assert rate == pytest.approx(rate_c_per_s, abs=0.004)
        assert rate_c_per_s or rate == 0.0


def test_a_garbled_reading_moves_the_rate_little() -> None:
    """One reading 100 degC off (an SPI bit error, no checksum): the median of the
    pairwise slopes hardly moves, where a least-squares slope would have made 0.6 degC/s;
    readings no IMU can have are not taken at all."""
    points = readings(0.02, 40)
    garbled = [*points[:-1], (points[-1][0], points[-1][1] + 100.0)]
    assert rate_after(garbled) == pytest.approx(0.02, abs=0.004)
    t, c = np.array(garbled).T
    window = t > t[-1] - WINDOW_S
    assert np.polyfit(t[window], c[window], 1)[0] > 0.5
    for bad in (math.nan, 400.0, -100.0):
        assert rate_after([*points, (40.0, bad)]) == rate_after(points)


def test_the_rate_is_of_the_last_window_and_starts_again_when_time_goes_back() -> None:
    warm = readings(0.133, 120)
    steady = [(120.0 + t, 21.0) for t in range(40)]
    assert rate_after(warm + steady) == 0.0  # the warm-up has left the window
    rate = TemperatureRate()
    for t, c in warm:
        rate.add(t, c)
    assert rate.rate_c_per_s > 0.1
    for t in range(MIN_READINGS - 1):  # the engine's clock restarted: too few readings
        rate.add(float(t), 21.0)
        assert rate.rate_c_per_s == 0.0


def test_the_walks_are_the_datasheet_coefficients_times_the_rate_over_the_correlation_time() -> (
    None
):
    walk = TemperatureWalk(0.01, 0.1, 100.0)
    for t, c in readings(0.1, 30, seed=3):
        walk.add(t, c)
    rate = walk.rate.rate_c_per_s
    assert rate == pytest.approx(0.1, abs=0.002)
    assert walk.gyro_rps2_per_s == pytest.approx((0.01 * DEG_TO_RAD * rate) ** 2 * 100.0)
    assert walk.accel_mps4_per_s == pytest.approx((0.1 * MG_MPS2 * rate) ** 2 * 100.0)
