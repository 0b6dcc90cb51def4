"""The service's clock: host wall-clock time mapped to the time the fusion core runs on.

Live, the mapping is the identity: IMU frames carry their arrival time (``msg.timestamp``),
GNSS chunks the host time they were read, claim timers ``time.time()``. A demo plays
recorded logs ``speed`` times faster than real time; then every one of those times goes
through the same map, ``t = origin + (t_wall - origin_wall) * speed``, so the IMU decoder's
SEQ/DEC anchor, the GNSS receive times and the address-claim timers stay consistent with
each other and with the logs' own clock. The map is applied in one place (the service).
"""

from __future__ import annotations

import time
from dataclasses import dataclass


@dataclass(frozen=True)
class TimeBase:
    """``t = origin + (t_wall - origin_wall) * speed``; the default is the identity (live)."""

    origin: float = 0.0  # service time at origin_wall, s
    origin_wall: float = 0.0  # host wall-clock time (time.time()), s
    speed: float = 1.0  # service seconds per wall second

    def __post_init__(self) -> None:
        if not self.speed > 0.0:
            raise ValueError(f"speed={self.speed}: expected > 0")

    def at(self, t_wall: float) -> float:
        """Service time of host wall-clock time ``t_wall``."""
        return self.origin + (t_wall - self.origin_wall) * self.speed

    def now(self) -> float:
        """Service time now."""
        return self.at(time.time())

    def wall_s(self, seconds: float) -> float:
        """Wall-clock duration of ``seconds`` of service time (for sleeps)."""
        return seconds / self.speed

    def wall_at(self, t: float) -> float:
        """Host wall-clock time at which the service clock reads ``t``."""
        return self.origin_wall + (t - self.origin) / self.speed


#: Live: service time is host time.
LIVE = TimeBase()
