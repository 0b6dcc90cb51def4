"""The first heading from the recent courses, not from one epoch (both engines).

Before the heading is known the platform's yaw is arbitrary, but the gyro carries it from
epoch to epoch. Each epoch's course (the reference point's, from the antenna's with the lever
arm's velocity taken out: :func:`gateway.estimation.lever_arm.heading_from_antenna_course`)
less the platform's yaw then is a measurement of one offset: the platform's azimuth error.
At the alignment speed a course is 0.8 deg 1-sigma (RTK Doppler, 2 cm/s at 1.4 m/s), so one
epoch alone left the observer's heading 3.7 deg off on a 3-sigma draw with the mast rocking on
a slope (slope-start seed 540), its heading channel stating 0.74; the EKF, aligning on one
course with 3 deg stated, said DEGRADED for 0.8-1.8 s until its filter had averaged the
courses itself. The offsets of the epochs within :data:`ALIGN_WINDOW_S`, each weighed by its
course's sigma, average that noise down; the z-gyro bias, which turned the platform between
them, adds its share, and so does the gyro's angle random walk since each. A vehicle slower
than the alignment speed waits for more of them (:data:`SLOW_ALIGN_WINDOWS_S`) and for the
direction of travel (:func:`direction_known`).
"""

from __future__ import annotations

import math
from collections import deque

from drivers.units import DEG_TO_RAD, GRAVITY_MPS2, wrap_pi

#: Courses this recent make the first heading at the alignment speed, s ...
ALIGN_WINDOW_S = 1.0
#: ... and under it, once they give NAVIGATING's accuracy (:meth:`CourseAlignment.alignment`):
#: whichever of these gives the smaller sigma (more courses, against the z bias's turn).
SLOW_ALIGN_WINDOWS_S = (10.0, 30.0, 60.0)
#: Forward or reversing after a rest, before the heading is known: the inertial velocity
#: change along body x, once it exceeds this many sigma of what the tilt puts into it and
#: this floor (m/s: the engine vibration integrated over the first epochs). The observer
#: also takes its own velocity along body x under a held course as a direction beyond this
#: many sigma of the fix's velocity noise (``ObserverEngine._antenna_velocity``).
DIRECTION_SIGMAS = 3.0
DIRECTION_DV_FLOOR_MPS = 0.02


def direction_known(dv_x_mps: float, sigma_tilt_rad: float, since_s: float) -> bool:
    """Does the inertial velocity change along body x since a rest, ``dv_x_mps`` after
    ``since_s``, tell forward from reversing? Beyond :data:`DIRECTION_SIGMAS` of the tilt's
    share, g theta t, and :data:`DIRECTION_DV_FLOOR_MPS`."""
    sigma_dv = GRAVITY_MPS2 * sigma_tilt_rad * since_s + DIRECTION_DV_FLOOR_MPS
    return abs(dv_x_mps) >= DIRECTION_SIGMAS * sigma_dv


class CourseAlignment:
    """The platform's azimuth error from the recent epochs' courses (module text)."""

    def __init__(self, gate_rad: float) -> None:
        """``gate_rad``: an epoch whose offset is farther than this from the latest one's is
        not the same drive (a reversal, a glitch) and is left out."""
        self._gate_rad = gate_rad
        self._epochs: deque[tuple[float, float, float]] = deque()
        self._first_s: float | None = None  # the first epoch since the yaw was set

    def add(self, t_s: float, offset_rad: float, sigma_rad: float) -> None:
        """One epoch: its course less the platform's yaw at ``t_s``, and the course's sigma."""
        self._epochs.append((t_s, offset_rad, sigma_rad))
        if self._first_s is None:
            self._first_s = t_s
        while self._epochs and self._epochs[0][0] < t_s - SLOW_ALIGN_WINDOWS_S[-1]:
            self._epochs.popleft()

    def clear(self) -> None:
        """The platform's yaw was set, or no longer continues the epochs' (a restart)."""
        self._epochs.clear()
        self._first_s = None

    def alignment(
        self,
        sigma_bz_rps: float,
        arw_rad_per_sqrt_s: float,
        speed_mps: float,
        align_speed_mps: float,
        navigating_sigma_deg: float,
        direction_known: bool,
        refined: bool = False,
    ) -> tuple[float, float] | None:
        """(offset, 1-sigma) rad to align on now, or None: at ``align_speed_mps`` the last
        :data:`ALIGN_WINDOW_S`'s courses; slower, those of one of
        :data:`SLOW_ALIGN_WINDOWS_S`, once they give the heading within NAVIGATING's 1-sigma
        and the direction of travel is known. Why: a vineyard tractor at 1 m/s, a planter at
        0.5, never reach 1.5 m/s, and both engines stayed ALIGNING, no heading and no
        position, for a whole 21-minute run; with a 1 Hz receiver a planter's 10 s of
        courses (2 deg each at 0.6 m/s) give 0.7 deg, and it stayed so with them alone.
        The alignment speed stands for "forward" (vehicles reverse slower): under it, a
        restart while reversing at 0.8 m/s aligned 180 deg off until the direction was asked
        for. The short window stays at speed: there the slower courses of a pull-away, the
        mast rocking, took the first heading 0.7 deg off where the last second's are 0.3.

        ``refined``: the engine's filter goes on estimating the heading and the z bias from
        every course (the EKF): once it has taken courses for as long as the longest window
        it takes the best window's whatever its sigma (up to a third of the gate, within
        which the courses are one drive) and says DEGRADED until its own heading sigma is
        NAVIGATING's. A planter at 0.5 m/s with a 1 Hz receiver and a unit twice as noisy
        as its datasheet never had a window within 0.5 deg (2.6 deg a course, the z bias's
        walk between them): no heading, no position and, the levelled tilt's sigma grown
        past the field's range, no roll or pitch for an hour (`field` seed 578); aligned on
        0.7 deg, the EKF was NAVIGATING 80 % of it. The observer's heading channel takes
        the alignment as its heading and waits: aligned so, it read the error left for a z
        bias change and sent headings beyond their accuracy."""
        if speed_mps >= align_speed_mps:
            return self.offset(sigma_bz_rps, arw_rad_per_sqrt_s, ALIGN_WINDOW_S)
        if not direction_known:
            return None
        offset = min(
            (self.offset(sigma_bz_rps, arw_rad_per_sqrt_s, w) for w in SLOW_ALIGN_WINDOWS_S),
            key=lambda o: o[1],
        )
        if offset[1] <= navigating_sigma_deg * DEG_TO_RAD:
            return offset
        if not refined or offset[1] > self._gate_rad / 3.0:
            return None
        assert self._first_s is not None
        waited = self._epochs[-1][0] - self._first_s >= SLOW_ALIGN_WINDOWS_S[-1]
        return offset if waited else None

    def offset(
        self, sigma_bz_rps: float, arw_rad_per_sqrt_s: float, window_s: float
    ) -> tuple[float, float]:
        """(offset, 1-sigma) rad of the epochs of the last ``window_s``, the latest last:
        their weighted mean, and its sigma with the z-gyro bias's turn of the platform over
        their mean age and the angle random walk's since each epoch (an epoch of age a is
        ARW^2 a off the latest, two share the younger one's: ARW^2 sum w_i w_j min(a_i,
        a_j) / W^2 on the mean). Without the walk, 60 s of 1 Hz courses of 2.6 deg each
        from a unit twice as noisy as its datasheet stated 0.33 deg where they were 0.44
        (tests/test_course_alignment.py)."""
        t_last, anchor, _ = self._epochs[-1]
        weight = mean = age = walk = 0.0
        for t_s, offset_rad, sigma_rad in self._epochs:  # oldest first
            d = wrap_pi(offset_rad - anchor)
            if abs(d) > self._gate_rad or t_s < t_last - window_s:
                continue
            w = 1.0 / (sigma_rad * sigma_rad)
            a = t_last - t_s
            walk += w * a * (w + 2.0 * weight)  # with itself and each older epoch
            weight += w
            mean += w * d
            age += w * a
        drift = sigma_bz_rps * age / weight
        var = 1.0 / weight + drift * drift + arw_rad_per_sqrt_s**2 * walk / (weight * weight)
        return wrap_pi(anchor + mean / weight), math.sqrt(var)
