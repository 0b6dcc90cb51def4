"""What a levelling window cannot see: the vehicle's own acceleration.

Roll and pitch from the mean specific force over a window take the window's mean horizontal
acceleration ``a`` for tilt, an error of about ``a / g`` rad (0.84 m/s^2 of a tractor pulling
away is 4.9 deg). The gyro cannot tell: driving straight while speeding up is "quiet". GNSS
velocity measures that mean acceleration in any frame, ``(v_last - v_first) / (t_last -
t_first)``, so :class:`WindowMotion` collects the velocities of fixes received during the
window and turns them into the 1-sigma the levelled tilt carries. Engines add it to their
roll/pitch sigma, so NAVGW_STATUS states it and the output guard withholds roll and pitch
until the estimator has corrected them (an engine restarted while the vehicle drives, after
a host stall, levels on a moving window).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from drivers.samples import GnssFix
from drivers.units import GRAVITY_MPS2
from gateway.estimation.gnss_error import fix_velocity_ne_mps

#: A window levels with its samples up to this long ago, s: GNSS says "moving" one epoch
#: and its latency after the vehicle pulls away, the IMU feels it at once.
ALIGN_LAG_S = 0.5

#: Tilt 1-sigma of a window levelled while moving with fewer than two GNSS velocities in it
#: (1 Hz GNSS, a lost fix): 2 m/s^2, hard braking or pulling away of a farm vehicle, over g.
UNKNOWN_MOTION_TILT_RAD = math.atan(2.0 / GRAVITY_MPS2)


@dataclass
class WindowMotion:
    """GNSS velocities seen while one levelling window fills (receive-time clock, s)."""

    vel_sigma_mps: float  # horizontal GNSS velocity 1-sigma per axis
    stationary_speed_mps: float  # below this speed the vehicle is at rest
    #: the vehicle was last seen moving (an engine restarted mid-run): a window without GNSS
    #: velocity is of unknown motion, not a parked vehicle's
    moving_before: bool = False
    _first: tuple[float, float, float] | None = None  # t, vN, vE
    _last: tuple[float, float, float] | None = None
    _moving: bool = False

    def restart(self) -> None:
        """A new window begins: of the last one's velocities only the latest is kept, as the
        velocity at its start (a window begun in the last of a stop's braking, 0.14 m/s to
        0 in 0.3 s, saw only speeds below the stationary speed: taken for a rest, it levelled
        0.6 deg off with 0.09 stated; headland-reversing seed 3, an engine restarted while
        braking)."""
        last = self._first = self._last
        self._moving = last is not None and self._is_motion(last)

    def add(self, fix: GnssFix) -> None:
        """Note the fix's velocity if it has one (:func:`fix_velocity_ne_mps`: a slow speed
        without a course is standing still). Without that rule an engine restarted in a
        parked vehicle's first alignment took its rest for unknown motion (11.5 deg of tilt
        sigma) and, started with it, its filter went 7 deg off while stating 0.4 (outages
        seed 101, a stall at 25 s)."""
        vel = fix_velocity_ne_mps(fix, self.stationary_speed_mps) if fix.measures else None
        if vel is None or not math.isfinite(vel[0] + vel[1] + fix.t):
            self._moving |= fix.sog_mps is not None and fix.sog_mps >= self.stationary_speed_mps
            return
        self._last = (fix.t, vel[0], vel[1])
        self._moving |= self._is_motion(self._last)
        if self._first is None:
            self._first = self._last

    def _is_motion(self, velocity: tuple[float, float, float]) -> bool:
        return math.hypot(velocity[1], velocity[2]) >= self.stationary_speed_mps

    def tilt_sigma_rad(self) -> float:
        """1-sigma tilt error the window's motion causes: 0 at rest (or before any GNSS
        velocity, when a gateway powers up with its parked vehicle, unless ``moving_before``),
        ``a / g`` plus the velocity noise of the difference when moving,
        :data:`UNKNOWN_MOTION_TILT_RAD` when moving without two velocities to difference."""
        first, last = self._first, self._last
        if not self._moving:
            return UNKNOWN_MOTION_TILT_RAD if first is None and self.moving_before else 0.0
        assert first is not None and last is not None
        span_s = last[0] - first[0]
        if span_s <= 0.0:
            return UNKNOWN_MOTION_TILT_RAD
        dv_mps = math.hypot(last[1] - first[1], last[2] - first[2])
        accel_mps2 = (dv_mps + math.sqrt(2.0) * self.vel_sigma_mps) / span_s
        return math.atan(accel_mps2 / GRAVITY_MPS2)
