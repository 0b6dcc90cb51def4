"""The check of the antenna lever arm in effect (gateway.fusion.lever_arm_check): what the
drive shows of the antenna's height above the reference point, and the bound it is judged by.

Synthetic drives: 3 m/s north for two minutes, the cab rocking on its tyres about the ground
(roll rate 1 deg/s RMS at 0.4 and 0.9 Hz), a slow crab of 5 cm/s, the antenna ``height_m``
above the reference point; the IMU's rates with ADIS16334-like noise at 204.8 Hz, the GNSS
velocity with 2 cm/s at 10 Hz. Then the whole path on the simulated `short` run (3 m mast)
through ``navgw replay``, the frames decoded by the independent ``nmea2000`` package.
"""

from __future__ import annotations

import dataclasses
import logging
import math
from pathlib import Path

import numpy as np
import pytest

from drivers.samples import FixQuality, GnssFix
from gateway.config.gateway_config import Engine, load_config
from gateway.estimation.solution import Mode, Solution
from gateway.fusion.lever_arm_check import TOLERANCE_M, LeverArmCheck
from gateway.offline.log_replay import replay
from sim_bus.scenarios import SCENARIOS, SimRun, generate
from sim_bus.truth import Truth
from tests.n2k_check import DEGRADED, settled, status_modes, tilt_beyond_stated

IMU_HZ = 204.8
GNSS_HZ = 10.0
SPEED_MPS = 3.0


def drive(
    check: LeverArmCheck,
    height_m: float,
    roll_rate_dps: float = 1.0,
    seconds: float = 120.0,
    gnss_hz: float = GNSS_HZ,
) -> None:
    """The synthetic drive above, fed to ``check`` as the core does."""
    rng = np.random.default_rng(7)
    w_amp = math.radians(roll_rate_dps)  # RMS of the two sinusoids together
    per_epoch = round(IMU_HZ / gnss_hz)
    dt = 1.0 / (per_epoch * gnss_hz)
    roll = 0.0
    for k in range(int(seconds * gnss_hz)):
        for i in range(per_epoch):
            t = (k * per_epoch + i) * dt
            w_x = w_amp * (math.sin(2.0 * math.pi * 0.4 * t) + math.sin(2.0 * math.pi * 0.9 * t))
            roll += w_x * dt
            noise = rng.normal(0.0, math.radians(0.5), 3)  # ARW 2 deg/rt-h plus vibration
            check.imu(t, (w_x + noise[0], noise[1], 0.002 + noise[2]))
        t = (k + 1) * per_epoch * dt
        # the ground point does not move sideways: the antenna does, by w_x times its height
        v_lat = 0.05 + w_x * height_m + rng.normal(0.0, 0.02)
        v_n = SPEED_MPS + rng.normal(0.0, 0.02)
        fix = GnssFix(
            t=t,
            t_utc=None,
            quality=FixQuality.RTK_FIXED,
            sog_mps=math.hypot(v_n, v_lat),
            cog_rad=math.atan2(v_lat * math.cos(roll), v_n) % (2.0 * math.pi),
        )
        sol = Solution(t=t, mode=Mode.NAVIGATING, roll_rad=roll, pitch_rad=0.0, yaw_rad=0.0)
        check.epoch(fix, sol)


def checked(configured_m: float, height_m: float, **kwargs: float) -> LeverArmCheck:
    check = LeverArmCheck((0.3, 0.0, -configured_m))
    drive(check, height_m, **kwargs)
    return check


def test_the_configured_mast_is_not_seen_off_and_its_height_is_measured() -> None:
    check = checked(2.5, 2.5)
    fit = check.fit()
    assert fit is not None and not check.off
    assert abs(fit.height_m - 2.5) < 3.0 * fit.sigma_m + 0.05, fit  # 1 % shrinks with noise
    assert fit.sigma_m < 0.1, fit


def test_a_1_hz_receivers_velocity_is_matched_with_the_rates_at_its_epoch() -> None:
    """The rates of the 0.1 s before each epoch, not the whole second: that averaged the
    rocking away and centred it half a second early (a 3 m mast measured 2.2 m on field)."""
    check = checked(3.0, 3.0, gnss_hz=1.0, seconds=600.0)
    fit = check.fit()
    assert fit is not None and not check.off
    assert abs(fit.height_m - 3.0) < 0.3, fit


def test_a_mast_left_out_of_the_config_is_found_within_a_minute() -> None:
    check = checked(0.0, 2.5, seconds=60.0)
    assert check.found is not None
    assert abs(check.found.height_m - 2.5) < 0.5, check.found
    assert check.found.configured_m == 0.0


def test_a_mast_measured_roughly_is_within_the_tolerance() -> None:
    """The ground point's roll centre is not exact: 0.8 m off is within TOLERANCE_M, 1.5 m
    is not."""
    assert TOLERANCE_M == 1.0
    assert not checked(2.2, 3.0).off
    assert checked(1.5, 3.0).off


@pytest.mark.parametrize("configured_m", [3.0, 0.0])
def test_without_rocking_nothing_is_judged(configured_m: float) -> None:
    """Smooth ground: no roll rate to judge by (and none to move the antenna sideways). The
    gyro's noise alone would fit a height of zero: a correctly configured mast called off."""
    for rate_dps in (0.0, 0.1):
        check = checked(configured_m, 3.0, roll_rate_dps=rate_dps, seconds=600.0)
        assert not check.off and check.fit() is None, rate_dps


def test_the_verdict_is_logged_once_with_what_to_do(caplog: pytest.LogCaptureFixture) -> None:
    with caplog.at_level(logging.WARNING, logger="gateway.fusion.lever_arm_check"):
        checked(0.0, 2.5)
    (record,) = [r for r in caplog.records if r.name == "gateway.fusion.lever_arm_check"]
    assert "antenna_lever_arm_m" in record.getMessage()
    assert "above the reference point, configured 0.00 m" in record.getMessage()


@pytest.fixture(scope="module")
def short_run(tmp_path_factory: pytest.TempPathFactory) -> SimRun:
    """The `short` run: 30 s parked, then 50 s of driving, the antenna on a 3 m mast."""
    return generate(SCENARIOS["short"], tmp_path_factory.mktemp("mast"), seed=3)


@pytest.mark.parametrize("engine", list(Engine))
@pytest.mark.parametrize("configured_m", [3.0, 0.0], ids=["true", "unset"])
def test_a_mast_left_out_is_degraded_on_the_bus_before_anything_is_off(
    engine: Engine,
    configured_m: float,
    short_run: SimRun,
    tmp_path: Path,
    caplog: pytest.LogCaptureFixture,
) -> None:
    """``navgw replay`` of the drive. With the mast left out, the observer's pitch went 2 deg
    off with 0.46 stated, the EKF's 0.4 with 0.08: now NAVGW_STATUS says DEGRADED within
    seconds of driving off, to the end, and no frame before is beyond its stated accuracy.
    With the true lever arm configured, none says DEGRADED once the heading has
    settled after driving off."""
    base = load_config(short_run.config_file).with_engine(engine)
    x, y, z = base.vehicle.antenna_lever_arm_m
    assert z == -3.0
    vehicle = dataclasses.replace(base.vehicle, antenna_lever_arm_m=(x, y, -configured_m))
    out = tmp_path / "out.log"
    with caplog.at_level(logging.WARNING, logger="gateway.fusion.lever_arm_check"):
        replay(
            short_run.imu_log, short_run.gnss_log, out, dataclasses.replace(base, vehicle=vehicle)
        )
    truth = Truth.load(short_run.truth_file)
    checked_frames, beyond = tilt_beyond_stated(out, truth)
    assert checked_frames > 1000 and not beyond, beyond[:10]
    modes = [(t - truth.t[0], mode) for t, mode in status_modes(out)]
    records = [r for r in caplog.records if r.name == "gateway.fusion.lever_arm_check"]
    if configured_m == 3.0:
        assert not records
        # navigating within seconds of driving off (30 s), and never DEGRADED from then on
        assert settled(modes)[0][0] < 37.0
        assert not [t for t, mode in settled(modes) if mode >= DEGRADED]
        return
    (record,) = records
    height = float(record.getMessage().split("puts the antenna ")[1].split(" +/- ")[0])
    assert abs(height - 3.0) < 0.5, record.getMessage()
    # the verdict, and from then on every NAVGW_STATUS (the engines' own DEGRADED came before)
    off_from = float(record.getMessage().split(":")[0].removeprefix("t=")) - truth.t[0]
    assert off_from < 50.0  # driving from 30 s
    assert all(mode >= DEGRADED for t, mode in modes if t >= off_from + 0.1)
