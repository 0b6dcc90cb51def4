"""The heading a restarted engine inherits from the one it replaces, to tell forward from
reversing at its first course over ground (both engines).

An engine restarted after an IMU gap levels again and finds its heading from the course, as
at power-up: forward or reversing is what its own velocity change along body x says. After a
stop too short to level on (under ~2 s), a start gentler than the tilt error left by the
levelling (g theta > a) reads the other way round, and the heading aligned 180 deg off (the
observer: a levelling while braking out of a reversing manoeuvre, 1 s still, 0.15 m/s^2
forward); a stall in a long reverse leaves no rest to measure from at all, and both engines
took the course as a forward drive's. The old engine knew the heading; over the gap the
vehicle turns at most :data:`MAX_YAW_RATE_RPS`, and after it the new engine's gyro carries
that heading on. Within :data:`MAX_BOUND_RAD` it decides the direction (the boundary is 90
deg away).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from drivers.units import DEG_TO_RAD, wrap_pi

#: Yaw rate a farm vehicle does not exceed, rad/s (29 deg/s; a tight headland turn is 20-25).
MAX_YAW_RATE_RPS = 0.5
#: Bound of the inherited heading beyond which it decides nothing, rad: 30 deg short of the
#: forward/reversing boundary, for the gyro's drift since and the course's noise.
MAX_BOUND_RAD = 60.0 * DEG_TO_RAD


@dataclass
class HeadingHint:
    """True heading (rad) of the vehicle when the new engine's platform yaw is 0, within
    ``bound_rad``. The engine's platform starts at yaw 0 when it levels; until then
    :meth:`turn` carries the heading on with the body z rate."""

    yaw_rad: float
    bound_rad: float

    @classmethod
    def over_gap(cls, yaw_rad: float, yaw_rate_rps: float, gap_s: float) -> HeadingHint | None:
        """The old engine's heading and rate at its last sample, ``gap_s`` before the new
        engine's first; None when the vehicle may have turned too far in between, or the
        clock stepped back (a negative gap says nothing of the time between)."""
        bound = MAX_YAW_RATE_RPS * gap_s
        if not 0.0 <= bound <= MAX_BOUND_RAD:
            return None
        return cls(yaw_rad + yaw_rate_rps * gap_s, bound)

    def turn(self, w_z_rps: float, dt_s: float) -> None:
        """One IMU sample before the engine has levelled (its platform does not exist yet)."""
        self.yaw_rad += w_z_rps * dt_s

    def forward(self, heading_if_forward_rad: float, platform_yaw_rad: float) -> bool:
        """Whether the vehicle drives forward: the heading its course means if it does,
        against the inherited heading carried on by the platform's yaw since levelling."""
        expected = self.yaw_rad + platform_yaw_rad
        return abs(wrap_pi(heading_if_forward_rad - expected)) <= 0.5 * math.pi
