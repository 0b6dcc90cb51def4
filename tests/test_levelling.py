"""WindowMotion: the tilt error a levelling window's own acceleration causes, from GNSS."""

from __future__ import annotations

import math

import pytest

from drivers.samples import FixQuality, GnssFix
from drivers.units import GRAVITY_MPS2
from gateway.estimation.levelling import UNKNOWN_MOTION_TILT_RAD, WindowMotion


def fix(t: float, sog_mps: float | None, cog_deg: float = 90.0) -> GnssFix:
    return GnssFix(
        t=t,
        t_utc=t,
        quality=FixQuality.RTK_FIXED,
        sog_mps=sog_mps,
        cog_rad=None if sog_mps is None else math.radians(cog_deg),
    )


def test_at_rest_or_before_any_velocity_the_window_adds_nothing() -> None:
    motion = WindowMotion(vel_sigma_mps=0.02, stationary_speed_mps=0.1)
    assert motion.tilt_sigma_rad() == 0.0
    for k in range(11):
        motion.add(fix(0.1 * k, 0.03))
    motion.add(fix(1.2, None))
    assert motion.tilt_sigma_rad() == 0.0


def test_after_a_restart_on_the_move_a_window_without_velocity_is_of_unknown_motion() -> None:
    """An engine that takes over from one that saw the vehicle moving (``moving_before``):
    no GNSS velocity in the window (an outage) is not a parked vehicle; slow velocities
    still are."""
    motion = WindowMotion(vel_sigma_mps=0.02, stationary_speed_mps=0.1, moving_before=True)
    assert motion.tilt_sigma_rad() == UNKNOWN_MOTION_TILT_RAD
    motion.restart()  # (a new window of the same engine)
    assert motion.tilt_sigma_rad() == UNKNOWN_MOTION_TILT_RAD
    for k in range(11):
        motion.add(fix(0.1 * k, 0.03))
    assert motion.tilt_sigma_rad() == 0.0


def test_a_slow_speed_without_a_course_is_a_vehicle_standing_still() -> None:
    """A receiver gives no course before it has moved (u-blox's NMEA blanks it below 0.1 m/s
    too): after a restart, a window of such fixes is a parked vehicle's, not unknown motion
    (an EKF restarted in a parked vehicle's first alignment stated 11.5 deg, and its filter
    went 7 deg off when it started with it); a faster one without a course tells nothing."""
    motion = WindowMotion(vel_sigma_mps=0.02, stationary_speed_mps=0.1, moving_before=True)
    for k in range(11):
        motion.add(GnssFix(t=0.1 * k, t_utc=0.1 * k, quality=FixQuality.RTK_FIXED, sog_mps=0.03))
    assert motion.tilt_sigma_rad() == 0.0
    motion.restart()
    motion.add(GnssFix(t=2.0, t_utc=2.0, quality=FixQuality.RTK_FIXED, sog_mps=0.5))
    assert motion.tilt_sigma_rad() == UNKNOWN_MOTION_TILT_RAD


@pytest.mark.parametrize("accel_mps2", [0.3, 0.84, 2.0])
def test_a_speeding_up_window_carries_its_acceleration_over_g(accel_mps2: float) -> None:
    motion = WindowMotion(vel_sigma_mps=0.02, stationary_speed_mps=0.1)
    for k in range(11):
        motion.add(fix(100.0 + 0.1 * k, 1.0 + accel_mps2 * 0.1 * k))
    sigma = motion.tilt_sigma_rad()
    assert sigma == pytest.approx(
        math.atan((accel_mps2 + math.sqrt(2.0) * 0.02) / GRAVITY_MPS2), rel=1e-9
    )
    assert math.degrees(sigma) > math.degrees(accel_mps2 / GRAVITY_MPS2)  # never below a/g
    # a new window starts with the last velocity, the one at its start: moving, with no
    # second one yet, its motion is unknown; then the acceleration since its start counts
    motion.restart()
    assert motion.tilt_sigma_rad() == UNKNOWN_MOTION_TILT_RAD
    motion.add(fix(101.5, 1.0 + accel_mps2 * 1.5))
    assert motion.tilt_sigma_rad() == pytest.approx(
        math.atan((accel_mps2 * 0.5 + math.sqrt(2.0) * 0.02) / (0.5 * GRAVITY_MPS2)), rel=1e-9
    )


def test_a_window_begun_in_the_last_of_a_stop_carries_the_braking() -> None:
    """Braking from 0.14 m/s to 0 in 0.3 s: the window that begins on it sees only speeds
    below the stationary speed, but the velocity at its start is the last fix before it
    (headland-reversing seed 3: an engine restarted while braking levelled 0.6 deg off with
    0.09 deg stated, the window taken for a rest)."""
    motion = WindowMotion(vel_sigma_mps=0.02, stationary_speed_mps=0.1)
    motion.add(fix(10.0, 0.14))
    motion.restart()
    for k, speed in enumerate((0.06, 0.02, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)):
        motion.add(fix(10.1 + 0.1 * k, speed))
    assert math.degrees(motion.tilt_sigma_rad()) > 0.6 / 3.0


def test_a_turn_at_constant_speed_is_an_acceleration_too() -> None:
    """Centripetal: 3 m/s turning 90 deg in 1 s is |dv| = 4.2 m/s over 1 s."""
    motion = WindowMotion(vel_sigma_mps=0.02, stationary_speed_mps=0.1)
    motion.add(fix(0.0, 3.0, 0.0))
    motion.add(fix(1.0, 3.0, 90.0))
    assert motion.tilt_sigma_rad() > math.atan(4.2 / GRAVITY_MPS2)


def test_moving_with_a_single_velocity_is_unknown_motion() -> None:
    motion = WindowMotion(vel_sigma_mps=0.02, stationary_speed_mps=0.1)
    motion.add(fix(5.0, 2.0))
    assert motion.tilt_sigma_rad() == UNKNOWN_MOTION_TILT_RAD
