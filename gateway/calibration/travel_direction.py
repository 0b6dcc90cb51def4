"""Forward or reversing: the course over ground against the heading the gyro carried on.

A farm vehicle reverses at headlands, and its course then points behind it. The heading is
the course while driving forward, carried on by the gyro's z rate through stops; a course
more than 90 deg from it means reversing (ALGORITHMS.md 2). A mounting error of up to some
10 deg scales the z rate by its cosine: a few degrees over a U-turn, far from 90.

The first drive (or the first after the gyro lost the heading) has no heading to compare
with: its direction is the IMU's, the change of the x specific force from its mean at the
rest before, integrated until the GNSS speed reaches :data:`DECIDE_SPEED_MPS` (0.3 m/s
within a second or so of leaving the rest, against the rest mean's noise and a slope's
change of a few mm/s). Taken as forward, a drive that began by backing out of a shed
labelled every later drive the wrong way round: the calibration drive then found no forward
driving and said so. Without a rest before it, forward.
"""

from __future__ import annotations

import math

from drivers.units import wrap_pi

#: GNSS speed below which an epoch is at rest, m/s (5 sigma of 2 cm/s velocity noise).
STILL_SPEED_MPS = 0.1
#: GNSS speed at which the direction of a drive leaving a rest is decided, m/s.
DECIDE_SPEED_MPS = 0.3


class TravelDirection:
    """Fed the yaw rate between epochs, each epoch's course at speed, and around a rest the
    x specific force (:meth:`still`, :meth:`rolling`)."""

    def __init__(self) -> None:
        self.heading_rad: float | None = None
        self.forward = True
        self._f_rest_x: float | None = None  # mean x specific force at the last rest, m/s^2
        self._n_rest = 0
        self._dv_x = 0.0  # its change integrated since, m/s
        self._leaving_forward: bool | None = None  # the direction decided for this drive

    def turn(self, yaw_rate_rps: float, dt_s: float) -> None:
        """Carry the heading on over ``dt_s``."""
        if self.heading_rad is not None:
            self.heading_rad += yaw_rate_rps * dt_s

    def still(self, f_x_mps2: float) -> None:
        """An interval at rest with mean x specific force ``f_x_mps2`` (gravity and bias)."""
        if self._leaving_forward is not None or self._dv_x:
            self._f_rest_x, self._n_rest = None, 0  # a new rest
        self._n_rest += 1
        mean = self._f_rest_x or 0.0
        self._f_rest_x = mean + (f_x_mps2 - mean) / self._n_rest
        self._dv_x, self._leaving_forward = 0.0, None

    def rolling(self, f_x_mps2: float, dt_s: float, speed_mps: float) -> None:
        """An interval under way: its mean x specific force over ``dt_s``, the GNSS speed."""
        if self._f_rest_x is None or self._leaving_forward is not None:
            return
        self._dv_x += (f_x_mps2 - self._f_rest_x) * dt_s
        if speed_mps >= DECIDE_SPEED_MPS:
            self._leaving_forward = self._dv_x >= 0.0

    def course(self, cog_rad: float) -> bool:
        """A course over ground taken at speed; returns whether the vehicle drives forward."""
        if self.heading_rad is not None:
            self.forward = abs(wrap_pi(cog_rad - self.heading_rad)) < 0.5 * math.pi
        elif self._leaving_forward is not None:
            self.forward = self._leaving_forward
        self.heading_rad = cog_rad if self.forward else cog_rad + math.pi
        return self.forward
