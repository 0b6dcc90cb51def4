"""Forward or reversing: the course over ground against the heading the gyro carried on.

A farm vehicle reverses at headlands, and its course then points behind it. The heading is
the course while driving forward, carried on by the gyro's z rate through stops; a course
more than 90 deg from it means reversing (ALGORITHMS.md 2). The first drive counts as
forward. A mounting error of up to some 10 deg scales the z rate by its cosine: a few
degrees over a U-turn, far from 90.
"""

from __future__ import annotations

import math

from drivers.units import wrap_pi


class TravelDirection:
    """Fed the yaw rate between epochs and each epoch's course at speed."""

    def __init__(self) -> None:
        self.heading_rad: float | None = None
        self.forward = True

    def turn(self, yaw_rate_rps: float, dt_s: float) -> None:
        """Carry the heading on over ``dt_s``."""
        if self.heading_rad is not None:
            self.heading_rad += yaw_rate_rps * dt_s

    def course(self, cog_rad: float) -> bool:
        """A course over ground taken at speed; returns whether the vehicle drives forward."""
        if self.heading_rad is not None:
            self.forward = abs(wrap_pi(cog_rad - self.heading_rad)) < 0.5 * math.pi
        self.heading_rad = cog_rad if self.forward else cog_rad + math.pi
        return self.forward
