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
delays go on through a step. All but one kind: a step forward by a whole number of IMU SEQ
wraps looks to the IMU decoder exactly like an outage of that many samples, and it takes it
for one (its times jump with the host clock's). Then the delays jump too, if it was a step:
the next fix tells (:meth:`EpochClock.host_jumped`).
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
        self._least = SlidingMin(DELAY_WINDOW_S)  # every receive delay
        self._least_possible = SlidingMin(DELAY_WINDOW_S)  # those a synced host can have
        self._last_epoch_s: float | None = None  # the latest epoch placed
        self._jump_s = 0.0  # the core's time jumped this much with the host's, maybe
        self.unordered = 0  # epochs not placed: not after the last one placed
        self._log = LogLimiter(log)

    @property
    def host_follows_utc(self) -> bool | None:
        """Whether the host clock follows UTC, as the mode and the delays say (None: no date)."""
        if self._least.value is None:
            return None
        return self._follows_utc(self._least_possible.value)

    @property
    def epoch_sigma_s(self) -> float:
        """1-sigma of the epoch times placed, s: 0 on a host that follows UTC (the receiver's
        UTC is exact), the receiver latency's (``receiver_latency_sigma_s``, by default
        :data:`RECEIVE_EPOCH_SIGMA_S`: not measured) on a free-running one or before the
        date."""
        return 0.0 if self.host_follows_utc else self.receiver_latency_sigma_s

    def host_jumped(self, jump_s: float) -> None:
        """The core's time jumped forward by ``jump_s`` with the host clock's and the IMU's
        SEQ went on: an IMU outage of whole SEQ wraps, or a step of the host clock by as much.
        The next fix with a UTC time tells: receive delays by over half the jump above the
        least are the step, and the delays kept are moved by it (else an epoch on a host
        clock that follows UTC would be placed ``jump_s`` off for a minute, and so would the
        receive-time epochs of a free-running one)."""
        self._jump_s = jump_s

    def _follows_utc(self, least_possible_s: float | None) -> bool:
        if self.mode is not EpochTime.AUTO:
            return self.mode is EpochTime.UTC
        return least_possible_s is not None and least_possible_s <= SYNCED_DELAY_S[1]

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
            if least is not None and delay_s - least > 0.5 * self._jump_s:
                self._least.shift(self._jump_s)
                self._least_possible.shift(self._jump_s)
            self._jump_s = 0.0
        least_s = self._least.add(fix.t, delay_s)
        # The least possible delay leaves out delays before the epoch (below SYNCED_DELAY_S):
        # an epoch cannot arrive before it happened on a synchronised host, so they are the
        # receiver's UTC jumping ahead for a while (a firmware glitch, a leap second), or a
        # host clock behind UTC, whose every delay is one.
        if delay_s >= SYNCED_DELAY_S[0]:
            self._least_possible.add(fix.t, delay_s)
        else:
            self._least_possible.expire(fix.t)
        least_possible_s = self._least_possible.value
        if not self._follows_utc(least_possible_s):
            return fix.t_utc + least_s - self.receiver_latency_s
        last = self._last_epoch_s
        if least_possible_s is not None and (
            delay_s < SYNCED_DELAY_S[0] or (last is not None and fix.t_utc <= last)
        ):
            return fix.t - least_possible_s
        return fix.t_utc


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
