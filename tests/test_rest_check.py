"""The rest check of a warm start (gateway/fusion/rest_check.py): the means at rest, and a
seed against them; the end-to-end cases on the simulator are in tests/test_warm_start.py."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from drivers.samples import FixQuality, GnssFix, ImuSample
from drivers.units import DEG_TO_RAD, MG_MPS2
from gateway.estimation.solution import LearnedState
from gateway.fusion.rest_check import (
    MIN_REST_S,
    SETTLE_S,
    RestMean,
    RestRecord,
    check_seed,
    drove_off,
)

DT = 1.0 / 204.8
LEARNED = LearnedState(
    bias_g_rps=(0.001, -0.002, 0.0005),
    sigma_g_rps=(0.01 * DEG_TO_RAD,) * 3,
    bias_a_mps2=(0.05, -0.08, 0.0),
    sigma_a_mps2=(0.002, 0.002, 0.003),
)
THEN = RestRecord(
    t_s=100.0,
    lat_deg=52.2,
    lon_deg=10.5,
    sigma_m=0.014,
    f_b_mps2=(0.2, -0.35, -9.79),
    w_b_rps=(0.001, -0.002, 0.0005),
    sigma_f_mps2=(0.0005,) * 3,
    sigma_w_rps=(1e-5,) * 3,
    duration_s=60.0,
)


def _fix(t: float, sog_mps: float, lat: float = 52.2) -> GnssFix:
    return GnssFix(
        t=t, t_utc=None, quality=FixQuality.RTK_FIXED, lat_deg=lat, lon_deg=10.5, alt_m=80.0,
        sog_mps=sog_mps, cog_rad=0.0,
    )  # fmt: skip


def _rest(mean: RestMean, t0: float, seconds: float, f: tuple[float, float, float]) -> float:
    rng = np.random.default_rng(int(t0))
    t = t0
    while t < t0 + seconds:
        if round((t - t0) / DT) % 20 == 0:
            mean.gnss(_fix(t, 0.02))
        noise = rng.normal(0.0, 0.2, 3)
        f_b = (f[0] + noise[0], f[1] + noise[1], f[2] + noise[2])
        mean.imu(ImuSample(t, DT, (0.001, -0.002, 0.0005), f_b, 0))
        t += DT
    return t


def test_the_rest_mean_and_its_sigma() -> None:
    """The mean of the samples with 0.2 m/s^2 of vibration after the first SETTLE_S, its
    1-sigma 0.2 / sqrt(n); none before MIN_REST_S of it; a turn or a moving fix ends it and
    keeps it as the last one."""
    mean = RestMean()
    _rest(mean, 0.0, SETTLE_S + MIN_REST_S - 0.5, (0.2, -0.35, -9.79))
    assert mean.current() is None
    t = _rest(mean, SETTLE_S + MIN_REST_S - 0.5, 10.0, (0.2, -0.35, -9.79))
    now = mean.current()
    assert now is not None and now.duration_s == pytest.approx(MIN_REST_S + 9.5, abs=0.01)
    n = (MIN_REST_S + 9.5) / DT
    assert now.sigma_f_mps2 == pytest.approx((0.2 / math.sqrt(n),) * 3, rel=0.1)
    assert now.f_b_mps2 == pytest.approx((0.2, -0.35, -9.79), abs=4.0 * 0.2 / math.sqrt(n))
    mean.imu(ImuSample(t, DT, (0.0, 0.0, 0.1), (0.0, 0.0, -9.8), 0))  # one sample: noise
    assert mean.current() is not None
    for k in range(1, 30):  # 0.15 s at 5.7 deg/s: a turn, the end
        mean.imu(ImuSample(t + k * DT, DT, (0.0, 0.0, 0.1), (0.0, 0.0, -9.8), 0))
    assert mean.current() is None and mean.last is not None and mean.record() == mean.last
    assert mean.last.duration_s >= now.duration_s
    t += 30 * DT
    mean.gnss(_fix(t + 1.0, 1.5))  # driving: no rest until a fix says standing again
    mean.imu(ImuSample(t + 1.0, DT, (0.0, 0.0, 0.0), (0.0, 0.0, -9.8), 0))
    assert mean.current() is None and mean.record() == mean.last


def test_a_seed_at_the_same_spot_with_the_same_means_is_taken_with_its_sigma_grown() -> None:
    now = replace(THEN, t_s=9000.0, f_b_mps2=(0.2 + 0.002, -0.35, -9.79), duration_s=5.0)
    learned, why = check_seed(LEARNED, THEN, now)
    assert learned is not None and "checked at rest on the same spot" in why
    assert learned.bias_a_mps2 == LEARNED.bias_a_mps2 and learned.sigma_g_rps == LEARNED.sigma_g_rps
    assert learned.sigma_a_mps2[0] == pytest.approx(math.hypot(0.002, 0.002))
    assert learned.sigma_a_mps2[1:] == LEARNED.sigma_a_mps2[1:]


@pytest.mark.parametrize(
    ("change", "reason"),
    [
        ({"f_b_mps2": (0.2 + 10.0 * MG_MPS2, -0.35, -9.79)}, "accel x +10.00 mg off"),
        ({"w_b_rps": (0.001, -0.002 + 0.1 * DEG_TO_RAD, 0.0005)}, "gyro y +0.1000 deg/s"),
        ({"lat_deg": 52.2 + 1e-5}, "the vehicle stands 1.11 m from where it stopped"),
    ],
)
def test_a_seed_is_refused_where_the_imu_or_the_spot_differs(
    change: dict[str, object], reason: str
) -> None:
    """10 mg of specific force (a new turn-on bias, or a tilt of 0.6 deg), 0.1 deg/s of
    rate, or 1.1 m of position: not the IMU state or the place the seed was learned in."""
    learned, why = check_seed(LEARNED, THEN, replace(THEN, **change))  # type: ignore[arg-type]
    assert learned is None and reason in why, why


@pytest.mark.parametrize(
    ("quality", "sog_mps", "standing", "driving"),
    [
        (FixQuality.RTK_FIXED, 0.05, True, False),
        (FixQuality.RTK_FIXED, 0.3, False, False),  # creeping: no rest, not yet driving off
        (FixQuality.RTK_FIXED, 0.6, False, True),
        (FixQuality.GNSS, 0.3, True, False),  # single point: 0.1 m/s of speed noise a axis
        (FixQuality.GNSS, 0.7, False, True),
    ],
)
def test_standing_and_driving_off_are_judged_against_the_fix_qualitys_speed_noise(
    quality: FixQuality, sog_mps: float, standing: bool, driving: bool
) -> None:
    fix = replace(_fix(0.0, sog_mps), quality=quality)
    mean = RestMean()
    mean.gnss(fix)
    t = 0.0
    while t < SETTLE_S + MIN_REST_S + 0.1:
        mean.imu(ImuSample(t, DT, (0.0, 0.0, 0.0), (0.0, 0.0, -9.8), 0))
        t += DT
    assert (mean.current() is not None) == standing
    assert drove_off(fix) == driving
