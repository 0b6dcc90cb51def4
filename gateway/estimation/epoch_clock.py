"""When a GNSS epoch happened, on the host clock that also times the IMU samples.

A fix carries its receive time ``t`` (host clock, the end of the epoch's last sentence) and,
once a date is known, its epoch in UTC ``t_utc`` from the sentences. The receive delay
``d = t - t_utc`` is the receiver's output latency, the serial transmission of the epoch and
the host clock's offset from UTC together. Aligning the epoch with the IMU to a few ms
matters: 50 ms off at 3 m/s puts the reference point 15 cm along track, and in a turn it
tilts the GNSS specific force against the platform's.

- ``utc``: the host clock follows UTC (PPS, NTP, gpsd); the epoch is ``t_utc``, exact.
- ``receive``: the host clock runs free; the epoch is ``t_utc`` plus the smallest recent
  receive delay (the serial jitter filtered out) minus the configured receiver latency.
- ``auto`` (default): ``utc`` while the smallest recent receive delay is one a receiver on a
  synchronised host can have (``SYNCED_DELAY_S``), else ``receive``. Logs stamped on a UTC
  host clock (SPEC 3) so line up exactly whatever the receiver's latency.

"Recent" is the last :data:`DELAY_WINDOW_S` of receive time: a reader held up only adds to
the delays, and the smallest delay over a minute is the clock's, not the host's load (a
busy host whose reader stalls for seconds stays on UTC).

Before the date is known (no RMC/ZDA yet) a fix has no ``t_utc``; its epoch is then ``t``
minus the configured latency in every mode.

In every mode an epoch is placed after the last one placed, or not at all: two epochs at one
instant, or one before the epoch before it, cannot both be right, and an engine would
correct back in time with it (:meth:`EpochClock.epoch_time`).

The core's time is the host clock less its steps (:mod:`drivers.host_clock`), so the receive
delays go on through a step, and either clock may be the one that follows UTC: the host's
before the step, or after it (NTP setting a clock that ran free). Each clock's least possible
delay is kept (the host's from the core's delays and the steps, ``GnssFix.host_offset_s``);
a clock ahead of UTC only adds to its delays, so of two that look synchronised the one with
the lesser delay is taken, and an epoch is placed at its UTC on that clock. A step forward
by a whole number of IMU SEQ wraps looks to the IMU decoder exactly like an outage of that
many samples, and it takes it for one (its times jump with the host clock's). Then the
delays jump too, if it was a step: the next fix tells (:meth:`EpochClock.host_jumped`).
"""

from __future__ import annotations

import logging
from collections import deque
from enum import Enum
from typing import Protocol

from drivers.log_limit import LogLimiter
from drivers.samples import GnssFix

log = logging.getLogger(__name__)

#: Receive delays (s) of a receiver on a host clock that follows UTC: an epoch cannot arrive
#: before it happened (a few ms of NTP error aside), and the output latency plus the serial
#: transmission of one epoch at >= 38400 baud stay well under half a second.
SYNCED_DELAY_S = (-0.02, 0.5)

#: 1-sigma of an epoch's time on a free-running host, s: the configured receiver latency's
#: error. Receivers' output latency runs 20-100 ms by make, rate and sentences, and the
#: serial transmission of an epoch's sentences 30-100 ms more at 115200-38400 baud, against
#: the default `[gnss] receiver_latency_s` of 50 ms: -30..+150 ms. The EKF starts its
#: EPOCH state with it and learns the error as the speed changes; started at 30 ms, a
#: receiver 128 ms later than the default (4 sigma) had it send 519 tilt frames beyond
#: 0.1 deg + 3 sigma (pitch 0.2 deg RMS) and 357 positions beyond NAVIGATING's 0.2 m
#: (robustness `host-clock-free+imu-noise-x2+latency-150ms`, field seed 626).
RECEIVE_EPOCH_SIGMA_S = 0.1

#: Receive time (s) over which the smallest receive delay is taken: the epoch least delayed
#: by serial scheduling and host load. Long enough that a reader held up for seconds cannot
#: fill it with late epochs: over 10 s (100 epochs at 10 Hz), a test at 8x real time whose
#: reader stalled for 2.5 s of wall time (20 s of log time) turned ``auto`` to ``receive``
#: on the backlog's delays and placed every epoch 10-20 s late: the observer aligned on them,
#: 25 m off, COASTING without DEGRADED. Short enough that a free-running clock's drift
#: (50 ppm: 3 ms a minute) stays well inside :data:`RECEIVE_EPOCH_SIGMA_S`.
DELAY_WINDOW_S = 60.0


class EpochTime(Enum):
    """How a fix's epoch is placed on the host clock."""

    AUTO = "auto"
    UTC = "utc"
    RECEIVE = "receive"


class EpochSettings(Protocol):
    """The GNSS timing settings a clock is made of ([gnss], or an engine's config)."""

    @property
    def epoch_time(self) -> EpochTime: ...
    @property
    def receiver_latency_s(self) -> float: ...
    @property
    def receiver_latency_sigma_s(self) -> float: ...


class EpochClock:
    """Epoch instant of each GNSS fix on the host clock; fed every fix in arrival order."""

    @classmethod
    def of(cls, settings: EpochSettings) -> EpochClock:
        """The clock of ``settings``' timing: every caller's one way to make it."""
        return cls(
            settings.epoch_time, settings.receiver_latency_s, settings.receiver_latency_sigma_s
        )

    def __init__(
        self,
        mode: EpochTime,
        receiver_latency_s: float,
        receiver_latency_sigma_s: float = RECEIVE_EPOCH_SIGMA_S,
    ) -> None:
        self.mode = mode
        self.receiver_latency_s = receiver_latency_s
        self.receiver_latency_sigma_s = receiver_latency_sigma_s
        # Receive delays on core time; the host's are these plus host_offset_s.
        self._least = SlidingMin(DELAY_WINDOW_S)  # every receive delay
        self._least_possible = SlidingMin(DELAY_WINDOW_S)  # those a synced core clock can have
        self._host_possible = SlidingMin(DELAY_WINDOW_S)  # those a synced host clock can have
        self._recent: deque[tuple[float, float]] = deque()  # (t, delay) of the window
        self._host_offset_s = 0.0  # host time less core time, the latest fix's
        self._last_epoch_s: float | None = None  # the latest epoch placed
        self._jump_s = 0.0  # the core's time jumped this much with the host's, maybe
        self.unordered = 0  # epochs not placed: not after the last one placed
        self._log = LogLimiter(log)

    @property
    def host_follows_utc(self) -> bool | None:
        """Whether the host clock follows UTC, or did before the steps taken out of the
        core's time, as the mode and the delays say (None: no date)."""
        if self._least.value is None:
            return None
        return self._utc_clock() is not None

    @property
    def epoch_sigma_s(self) -> float:
        """1-sigma of the epoch times placed, s: 0 on a host that follows UTC (the receiver's
        UTC is exact), the receiver latency's (``receiver_latency_sigma_s``, by default
        :data:`RECEIVE_EPOCH_SIGMA_S`: not measured) on a free-running one or before the
        date."""
        return 0.0 if self.host_follows_utc else self.receiver_latency_sigma_s

    def host_jumped(self, jump_s: float) -> None:
        """The core's time jumped by ``jump_s`` with the host clock's and the IMU's SEQ went
        on: forward, an IMU outage of whole SEQ wraps, or a step of the host clock by as much;
        back, a step before the IMU's anchor had settled. The next fix with a UTC time tells:
        a receive delay moved from the least by over half the jump, its way, is the step, and
        the delays kept and the last epoch placed are moved by it (else an epoch on a host
        clock that follows UTC would be placed ``jump_s`` off for a minute, and so would the
        receive-time epochs of a free-running one; after a step back every epoch would be
        dropped as out of order for as long as it went back)."""
        self._jump_s = jump_s

    def _utc_clock(self) -> tuple[float, float | None] | None:
        """The clock that follows UTC, as (its time less core time, its least possible
        delay on core time), or None: the host's if the mode is ``utc``; in ``auto`` the
        core's or the host's (they differ after a step), whichever looks synchronised, the
        one with the lesser delay if both do."""
        if self.mode is not EpochTime.AUTO:
            if self.mode is EpochTime.RECEIVE:
                return None
            host = self._host_possible if self._host_offset_s else self._least_possible
            return self._host_offset_s, host.value
        core_s = self._least_possible.value
        synced = SYNCED_DELAY_S[1]
        core = None if core_s is None or core_s > synced else (0.0, core_s)
        offset_s = self._host_offset_s
        host_s = self._host_possible.value if offset_s else None
        if host_s is None or host_s + offset_s > synced:
            return core
        if core is not None and core_s is not None and core_s <= host_s + offset_s:
            return core
        return offset_s, host_s

    def epoch_time(self, fix: GnssFix) -> float | None:
        """Epoch instant of ``fix`` on the host clock, s; None if it would not be after the
        last epoch placed: the epoch is dropped, counted (:attr:`unordered`) and logged.

        Why: a host 10 s behind its serial port (a test at 8x real time on a loaded machine)
        turned ``auto`` to ``receive`` on the backlog's delays, which placed a burst of 11
        epochs at one instant, and back on UTC the next epoch 0.43 s before them: the
        observer corrected back in time, its open-loop span came out negative and raised,
        and the service stopped."""
        t_e = self._place(fix)
        last = self._last_epoch_s
        if last is not None and t_e <= last:
            self.unordered += 1
            self._log.warning(fix.t, unordered_epoch_text(fix, t_e, last), "unordered")
            return None
        self._last_epoch_s = t_e
        return t_e

    def _place(self, fix: GnssFix) -> float:
        """Epoch instant of ``fix`` by the mode and the delays (:meth:`epoch_time`).

        On a host that follows UTC, an epoch whose UTC cannot be right is placed by its
        arrival, less the least possible delay: its data are right, its time stamp is not.
        - It arrived before its UTC (the receiver's clock ahead for a while). Five seconds of
          UTC 1 s ahead (field seed 1, moving) had turned ``auto`` to ``receive`` with that
          delay as the least for the window's 10 s after them: epochs 1 s early, positions
          3-4 m off, NAVIGATING.
        - Its UTC is not after the last epoch's (the clock went back, or stands still). Five
          seconds of UTC 1 s behind had both engines fuse 1 s old velocities in a turn
          (steep-turns seed 2): 1.3 m off, COASTING without DEGRADED for 0.3 s.
        Late arrivals with their UTC advancing (a busy host) keep their UTC."""
        if fix.t_utc is None:
            return fix.t - self.receiver_latency_s
        delay_s = fix.t - fix.t_utc
        if self._jump_s:
            least = self._least.value
            if least is not None and (delay_s - least) / self._jump_s > 0.5:
                self._shift(self._jump_s)
                if self._last_epoch_s is not None:
                    self._last_epoch_s += self._jump_s
            self._jump_s = 0.0
        if fix.host_offset_s != self._host_offset_s:
            self._host_offset_s = fix.host_offset_s
            self._rebuild_possible()
        recent = self._recent
        recent.append((fix.t, delay_s))
        while recent[0][0] < fix.t - DELAY_WINDOW_S:
            recent.popleft()
        least_s = self._least.add(fix.t, delay_s)
        # The least possible delay leaves out delays before the epoch (below SYNCED_DELAY_S):
        # an epoch cannot arrive before it happened on a synchronised host, so they are the
        # receiver's UTC jumping ahead for a while (a firmware glitch, a leap second), or a
        # host clock behind UTC, whose every delay is one.
        self._add_possible(fix.t, delay_s)
        clock = self._utc_clock()
        if clock is None:
            return fix.t_utc + least_s - self.receiver_latency_s
        offset_s, least_possible_s = clock
        t_utc = fix.t_utc - offset_s  # the epoch's UTC on core time
        last = self._last_epoch_s
        if least_possible_s is not None and (
            delay_s + offset_s < SYNCED_DELAY_S[0] or (last is not None and t_utc <= last)
        ):
            return fix.t - least_possible_s
        return t_utc

    def _shift(self, jump_s: float) -> None:
        """Move the delays kept by ``jump_s``: the core's time jumped with the host clock's."""
        self._least.shift(jump_s)
        self._recent = deque((t, d + jump_s) for t, d in self._recent)
        self._rebuild_possible()

    def _rebuild_possible(self) -> None:
        """The least possible delays of the core's and the host's clocks again, from the
        delays of the window (:meth:`_place`), after a step moved them."""
        self._least_possible = SlidingMin(DELAY_WINDOW_S)
        self._host_possible = SlidingMin(DELAY_WINDOW_S)
        for t, d in self._recent:
            self._add_possible(t, d)

    def _add_possible(self, t: float, delay_s: float) -> None:
        """Receive delay ``delay_s`` (core time) at ``t`` to the least possible delays of the
        clocks it is possible on: not before the epoch (module docstring, ``_place``)."""
        for possible, offset_s in (
            (self._least_possible, 0.0),
            (self._host_possible, self._host_offset_s),
        ):
            if delay_s + offset_s >= SYNCED_DELAY_S[0]:
                possible.add(t, delay_s)
            else:
                possible.expire(t)


class SlidingMin:
    """The least value added within the last ``window_s`` (of the times given with them),
    in O(1) per value: a queue of the values that can still become the least."""

    def __init__(self, window_s: float) -> None:
        self.window_s = window_s
        self._candidates: deque[tuple[float, float]] = deque()  # (time, value), values rising

    @property
    def value(self) -> float | None:
        """The least value in the window; None if there is none."""
        return self._candidates[0][1] if self._candidates else None

    def add(self, t: float, value: float) -> float:
        """Add ``value`` at time ``t`` (times in arrival order); the least in the window."""
        while self._candidates and self._candidates[-1][1] >= value:
            self._candidates.pop()
        self._candidates.append((t, value))
        self.expire(t)
        return self._candidates[0][1]

    def shift(self, delta: float) -> None:
        """Move every value kept by ``delta`` (their order stays)."""
        self._candidates = deque((t, value + delta) for t, value in self._candidates)

    def expire(self, now: float) -> None:
        """Forget the values added before ``now - window_s``."""
        while self._candidates and self._candidates[0][0] < now - self.window_s:
            self._candidates.popleft()


def unordered_epoch_text(fix: GnssFix, t_e: float, last_s: float) -> str:
    """The warning for an epoch not placed: ``t_e`` not after the last one placed."""
    utc = "no UTC" if fix.t_utc is None else f"UTC t={fix.t_utc:.3f}"
    return (
        f"GNSS epoch received at t={fix.t:.3f} ({utc}) dropped: its time t={t_e:.3f} is "
        f"{last_s - t_e:.3f} s before or at the last epoch's (t={last_s:.3f}); expected "
        "epochs in time order (the receiver's clock, a backlog of sentences on a busy host, "
        "or [gnss] epoch_time?)"
    )


def late_epoch_text(t_e: float, oldest_s: float) -> str:
    """The warning for an epoch dropped because it is older than an engine's history."""
    return (
        f"GNSS epoch at t={t_e:.3f} dropped: {oldest_s - t_e:.3f} s older than the IMU "
        f"history kept (from t={oldest_s:.3f}); expected a receiver latency within it "
        "(the receiver's clock, or [gnss] epoch_time?)"
    )
