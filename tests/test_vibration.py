"""A vehicle parked with a rough engine: gyro noise and vibration above the alignment's
quiet threshold sample by sample (tests/kinematics.py, exact motion plus white noise).

The EKF took a rest window as quiet only while every sample's rate was under
``align_quiet_rate_dps``. One sample of the ADIS16334's gyro noise is 0.5 deg/s an axis, and
with three times the simulator's engine vibration no window was ever quiet: the INS levelled
on a moving window without the gyro bias after 10 s and drifted open loop, pitch 5 deg off
after 23 s parked (steep-turns seed 94), and the drive-off aligned the heading 180 deg off.
The quiet test now takes the rate low-passed, as the observer takes its window's mean.
"""

from __future__ import annotations

import math

import pytest

from drivers.units import DEG_TO_RAD, wrap_pi
from gateway.estimation.ekf.ekf_config import EkfConfig
from gateway.estimation.ekf.ekf_engine import EkfEngine
from gateway.estimation.observer.observer_config import ObserverConfig
from gateway.estimation.observer.observer_engine import ObserverEngine
from gateway.estimation.solution import LearningEstimator, Solution
from tests.kinematics import Motion, Segment, gnss_stream, imu_stream, solutions

LEVER = (0.5, 0.0, -3.0)
ROLL, PITCH, YAW0 = math.radians(6.0), math.radians(4.0), 1.0
PARKED_S = 40.0
#: per-sample gyro noise an axis (the ADIS16334's ARW alone is 0.48 deg/s a sample): |w|
#: passes 2 deg/s on a few samples in a hundred
GYRO_NOISE_RPS = 0.7 * DEG_TO_RAD
ACCEL_NOISE_MPS2 = 0.5
GYRO_BIAS_RPS = (0.1 * DEG_TO_RAD, -0.15 * DEG_TO_RAD, 0.05 * DEG_TO_RAD)


def _engine(name: str) -> LearningEstimator:
    if name == "observer":
        return ObserverEngine(ObserverConfig(antenna_lever_arm_m=LEVER))
    return EkfEngine(EkfConfig(antenna_lever_arm_m=LEVER))


def _run(name: str) -> list[tuple[float, Solution]]:
    segments = [Segment(PARKED_S), Segment(4.0, accel_mps2=0.5), Segment(10.0)]
    motion = Motion(segments, roll_rad=ROLL, pitch_rad=PITCH, yaw0_rad=YAW0)
    engine = _engine(name)
    imu = imu_stream(
        motion,
        bias_g_rps=GYRO_BIAS_RPS,
        noise_g_rps=GYRO_NOISE_RPS,
        noise_a_mps2=ACCEL_NOISE_MPS2,
        seed=3,
    )
    return solutions(
        engine, imu, gnss_stream(motion, antenna_lever_arm_m=LEVER, vel_noise_mps=0.02)
    )


def test_parked_on_a_rough_engine_the_ekf_levels_at_rest() -> None:
    """Parked 40 s with noise over the quiet threshold: from 15 s on roll and pitch within
    0.15 deg (before: 4.6 deg of pitch off at 40 s, open loop on a 0.15 deg/s gyro bias,
    with 2.9 stated)."""
    parked = [s for t, s in _run("ekf") if 15.0 < t < PARKED_S]
    assert parked
    for sol in parked:
        assert sol.roll_rad is not None and sol.pitch_rad is not None
        tilt_deg = math.degrees(max(abs(sol.roll_rad - ROLL), abs(sol.pitch_rad - PITCH)))
        assert tilt_deg < 0.15, (sol.t, tilt_deg)


@pytest.mark.parametrize("name", ["observer", "ekf"])
def test_parked_on_a_rough_engine_the_tilt_is_within_its_sigma_and_the_heading_aligns(
    name: str,
) -> None:
    """Parked, then driving off: roll and pitch within 0.1 deg + 3 stated sigma throughout
    (the observer, whose rest window takes this much gyro noise for rotation, stands 0.6
    deg off on the gyro bias's b_g tau and says so), and after the drive-off the heading
    within 1 deg of the truth."""
    out = _run(name)
    for _, sol in out:
        if sol.roll_rad is None or sol.pitch_rad is None or sol.sigma_tilt_rad is None:
            continue
        tilt = max(abs(sol.roll_rad - ROLL), abs(sol.pitch_rad - PITCH))
        assert tilt < math.radians(0.1) + 3.0 * sol.sigma_tilt_rad, (sol.t, math.degrees(tilt))
    driving = [s for t, s in out if t > PARKED_S + 8.0]
    assert driving and all(s.yaw_rad is not None for s in driving)
    yaw_err_deg = max(math.degrees(abs(wrap_pi((s.yaw_rad or 0.0) - YAW0))) for s in driving)
    assert yaw_err_deg < 1.0
