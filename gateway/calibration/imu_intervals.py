"""IMU samples cut at GNSS epoch instants: what the IMU measured between two epochs.

A fix arrives after the IMU samples of its epoch (receiver latency, serial transmission), so
the samples wait in a bounded buffer until the epoch that closes them is known. Comparing
the IMU with GNSS velocity over exactly the epochs' interval is what makes the comparison
fair (ALGORITHMS.md 1: "compare like with like").
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

from drivers.samples import ImuSample
from gateway.estimation.solution import MAX_IMU_STEP_S

Vec3 = tuple[float, float, float]

#: Samples kept waiting for their epoch: 4 s at 204.8 Hz (a late fix, or an outage, beyond).
MAX_PENDING = 820


@dataclass(frozen=True, slots=True)
class ImuInterval:
    """Mean rate and specific force over (t0_s, t1_s], in the IMU samples' axes, SI."""

    t0_s: float
    t1_s: float
    w_rps: Vec3
    f_mps2: Vec3

    @property
    def duration_s(self) -> float:
        """Length of the interval, s."""
        return self.t1_s - self.t0_s


class ImuIntervals:
    """Fed every IMU sample, cut at each epoch: the interval since the previous cut."""

    def __init__(self) -> None:
        self._pending: deque[tuple[float, float, float, float, float, float, float, bool]] = deque(
            maxlen=MAX_PENDING
        )
        self._cut_s: float | None = None
        self._last_s: float | None = None  # last sample taken into an interval
        self._broken = False  # samples dropped unseen since the last cut

    def add(self, sample: ImuSample) -> None:
        """One sample; flagged samples (alarm, saturated, stuck) spoil their interval."""
        if self._cut_s is not None and sample.t <= self._cut_s:
            return
        if len(self._pending) == MAX_PENDING:
            self._broken = True
        w, f = sample.w_ib_b, sample.f_ib_b
        ok = not (sample.alarm or sample.saturated or sample.stuck)
        self._pending.append(
            (sample.t, float(w[0]), float(w[1]), float(w[2]),
             float(f[0]), float(f[1]), float(f[2]), ok)
        )  # fmt: skip

    def cut(self, t_s: float) -> ImuInterval | None:
        """The interval from the previous cut to ``t_s``; None for the first cut, or when the
        interval has a gap of over ``MAX_IMU_STEP_S``, a flagged or a dropped sample."""
        if self._cut_s is not None and t_s <= self._cut_s:
            return None
        t0_s, self._cut_s = self._cut_s, t_s
        valid = t0_s is not None and not self._broken
        self._broken = False
        n = 0
        sums = [0.0] * 6
        last_s = self._last_s
        pending = self._pending
        while pending and pending[0][0] <= t_s:
            t, *values, ok = pending.popleft()
            if not ok or (last_s is not None and t - last_s > MAX_IMU_STEP_S):
                valid = False
            last_s = t
            n += 1
            for i, v in enumerate(values):
                sums[i] += v
        self._last_s = last_s
        if not valid or n == 0 or t0_s is None or last_s is None or t_s - last_s > MAX_IMU_STEP_S:
            return None
        w = (sums[0] / n, sums[1] / n, sums[2] / n)
        f = (sums[3] / n, sums[4] / n, sums[5] / n)
        return ImuInterval(t0_s, t_s, w, f)
