"""Steps of the host clock, and the step-free time the fusion core runs on.

The host clock stamps every input: CAN frames (SocketCAN, or the candump log), GNSS receive
times (the serial reader, or the NMEA log), and both logs of a recording share it (SPEC 3).
NTP, chrony or timesyncd step it: at boot when it first syncs (from months off on an ECU
with no RTC), and later by 0.1-1 s when it has drifted past their thresholds. The core must
not see a step: its IMU samples run on the IMU's own clock (SEQ and DEC), anchored to the
host's by their earliest arrivals, and each GNSS epoch is placed against them by its
receive time. Left in, a step of 0.3 s slid the IMU's anchor over 10 s while the epochs
kept the GNSS receive delays of the minute before (up to 60 s): both engines sent tilt and
position beyond their stated accuracy without DEGRADED (`short` seed 5, steps at 100 s).

So the core runs on *core time*: host time less the steps found so far. The IMU decoder
finds them (:mod:`drivers.imu_can`: arrivals that stay late, or come early, by one amount
with no SEQ gap) and keeps its samples' times going through them; every other stream of
host times (GNSS receive times, other nodes' frames) goes through a :class:`HostStream`,
which takes a step from the first of its own times after it. Frames the gateway writes to a
log are stamped back in host time (:meth:`HostClock.host`), as the inputs were.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

from drivers.samples import GnssFix


@dataclass(frozen=True)
class ClockStep:
    """One step of the host clock, as the IMU's arrivals showed it."""

    t_s: float  # core time of the first IMU sample that arrived on the new clock
    host_s: float  # the old clock's reading then (t_s plus the correction before the step)
    delta_s: float  # new clock minus old, s: + forward (time skipped), - back (time repeated)


class HostClock:
    """The steps found so far, oldest first; core time = host time - :attr:`correction_s`."""

    def __init__(self) -> None:
        self.steps: list[ClockStep] = []
        self.correction_s = 0.0  # the sum of the steps, s

    def step(self, t_s: float, delta_s: float) -> ClockStep:
        """The host clock stepped by ``delta_s`` at core time ``t_s`` (found by the IMU)."""
        found = ClockStep(t_s, t_s + self.correction_s, delta_s)
        self.steps.append(found)
        self.correction_s += delta_s
        return found

    def host(self, t_s: float) -> float:
        """Host time of core time ``t_s``: the steps up to then added back."""
        for i in range(len(self.steps) - 1, -1, -1):
            step = self.steps[i]
            if t_s >= step.t_s:
                return t_s + step.host_s - step.t_s + step.delta_s
        return t_s

    def stream(self) -> HostStream:
        """A converter for one more stream of host times (GNSS receive times, bus frames)."""
        return HostStream(self)


class HostStream:
    """Core time of one stream's host times, fed in the stream's order.

    A step counts for the stream from the first of its times that is on the new clock:
    - forward (time skipped), a time past the old clock's reading at the step by over half
      the step (the old clock never read that far before it: the IMU saw it within a sample);
    - back (time repeated), such a time too, or one before a time the stream already had
      (the stream's host times do not go back but at a step); else, given the UTC of what it
      received (a GNSS epoch's), one whose receive delay on the old clock is nearer the last
      one's less the step than the last one's (a 1 Hz receiver's next fix may come after
      the last one's time on the new clock: taken before the step, its epoch was placed a
      step early).
    """

    def __init__(self, clock: HostClock) -> None:
        self._clock = clock
        self._passed = 0  # steps this stream is past
        self.correction_s = 0.0  # theirs, s
        self._latest_s = -math.inf  # the stream's latest host time since its last step
        self._last: tuple[float, float | None] = (math.nan, None)  # host time, receive delay
        self._delay_before: float | None = None  # the receive delay of the time before it

    def core(self, h: float, utc_s: float | None = None) -> float:
        """Core time of host time ``h``, the stream's next, received ``h - utc_s`` after it
        happened if ``utc_s`` is given (the same ``h`` again gives the same answer, with the
        steps found since taken in)."""
        if h != self._last[0]:
            self._delay_before = self._last[1]
        steps = self._clock.steps
        while self._passed < len(steps) and self._after(steps[self._passed], h, utc_s):
            self._passed += 1
            self.correction_s += steps[self._passed - 1].delta_s
            self._latest_s = -math.inf
        if h > self._latest_s:
            self._latest_s = h
        t = h - self.correction_s
        self._last = (h, None if utc_s is None else t - utc_s)
        return t

    def _after(self, step: ClockStep, h: float, utc_s: float | None) -> bool:
        """Host time ``h`` (of UTC ``utc_s``) is on the clock after ``step`` (class doc)."""
        if h >= step.host_s + 0.5 * abs(step.delta_s):
            return True
        if step.delta_s >= 0.0:
            return False
        if h < self._latest_s:
            return True
        if utc_s is None or self._delay_before is None:
            return False
        moved = h - self.correction_s - utc_s - self._delay_before  # on the old clock
        return abs(moved - step.delta_s) < abs(moved)


def retimed(fix: GnssFix, t_s: float) -> GnssFix:
    """``fix``, received at host time ``fix.t``, at core time ``t_s`` (itself if that is
    its time already), the difference kept as its ``host_offset_s``."""
    return fix if t_s == fix.t else replace(fix, t=t_s, host_offset_s=fix.t - t_s)
