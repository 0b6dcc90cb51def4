"""The first heading from the courses of the last second, not of one epoch (both engines).

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
them, adds its share.
"""

from __future__ import annotations

import math
from collections import deque

from drivers.units import wrap_pi

#: Courses this recent make the first heading, s.
ALIGN_WINDOW_S = 1.0


class CourseAlignment:
    """The platform's azimuth error from the recent epochs' courses (module text)."""

    def __init__(self, gate_rad: float) -> None:
        """``gate_rad``: an epoch whose offset is farther than this from the latest one's is
        not the same drive (a reversal, a glitch) and is left out."""
        self._gate_rad = gate_rad
        self._epochs: deque[tuple[float, float, float]] = deque()

    def add(self, t_s: float, offset_rad: float, sigma_rad: float) -> None:
        """One epoch: its course less the platform's yaw at ``t_s``, and the course's sigma."""
        self._epochs.append((t_s, offset_rad, sigma_rad))
        while self._epochs and self._epochs[0][0] < t_s - ALIGN_WINDOW_S:
            self._epochs.popleft()

    def clear(self) -> None:
        """The platform's yaw was set, or no longer continues the epochs' (a restart)."""
        self._epochs.clear()

    def offset(self, sigma_bz_rps: float) -> tuple[float, float]:
        """(offset, 1-sigma) rad of the epochs added, the latest last: their weighted mean,
        and its sigma with the z-gyro bias's turn of the platform over their mean age."""
        t_last, anchor, _ = self._epochs[-1]
        weight = mean = age = 0.0
        for t_s, offset_rad, sigma_rad in self._epochs:
            d = wrap_pi(offset_rad - anchor)
            if abs(d) > self._gate_rad:
                continue
            w = 1.0 / (sigma_rad * sigma_rad)
            weight += w
            mean += w * d
            age += w * (t_last - t_s)
        drift = sigma_bz_rps * age / weight
        return wrap_pi(anchor + mean / weight), math.sqrt(1.0 / weight + drift * drift)
