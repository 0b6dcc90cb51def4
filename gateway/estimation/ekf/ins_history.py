"""History of the INS state for GNSS epochs that arrive late (:class:`InsHistory`).

A row is the INS state after one IMU sample: t, p (3), v (3), C_bn row major (9), w_b (3).
Every correction of the INS (a fused epoch, the non-holonomic constraint, a reset) must move
the rows too, so that the next epoch is compared with the corrected past. The history spans
seconds (a thousand rows) but an epoch reads two rows close to its end: rows are stored as
written and each correction is kept in a log, applied to a row only when it is read, in the
order it was made and by the same operations as on the whole history at once.
"""

from __future__ import annotations

import math
from bisect import bisect_left, bisect_right
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from drivers.samples import Float3
from gateway.estimation.attitude import Mat9, dcm_mul

Array = npt.NDArray[np.float64]

#: Row columns: time, position, velocity, C_bn row major, body rate.
ROW_T, ROW_P, ROW_V, ROW_C, ROW_W = 0, slice(1, 4), slice(4, 7), slice(7, 16), slice(16, 19)


class Shift(NamedTuple):
    """A state correction of time ``t_e``: p += dp (+ dv (t - t_e) after t_e), v += dv,
    C <- rot C."""

    dp: Float3
    dv: Float3
    rot: Mat9
    t_e: float

    def apply(self, row: list[float]) -> None:
        """Correct ``row`` (19 floats) in place (in floats: an epoch reads two rows)."""
        dp, dv = self.dp, self.dv
        m = max(row[ROW_T] - self.t_e, 0.0)
        for i in range(3):
            row[1 + i] += dp[i] + m * dv[i]
            row[4 + i] += dv[i]
        row[ROW_C] = dcm_mul(self.rot, row[ROW_C])


class InsHistory:
    """The last ``n`` INS rows; corrections (:meth:`shift`) reach a row when it is read."""

    def __init__(self, n: int) -> None:
        self._n = n
        # rows as written, their times, and how many shifts had been made before each; the
        # lists keep up to 2 n rows (trimmed in one go), the last n are the history
        self._rows: list[tuple[float, ...]] = []
        self._times: list[float] = []
        self._marks: list[int] = []
        self._shifts: list[Shift] = []  # shifts still pending for some row kept
        self._first_shift = 0  # number of the first one in _shifts

    def append(self, row: tuple[float, ...]) -> None:
        """Add the row (19 floats) of the latest IMU sample."""
        if len(self._rows) == 2 * self._n:
            self._trim()
        self._rows.append(row)
        self._times.append(row[ROW_T])
        self._marks.append(self._first_shift + len(self._shifts))

    def _trim(self) -> None:
        """Drop the rows beyond the last ``n``, and the shifts only they were waiting for."""
        del self._rows[: self._n], self._times[: self._n], self._marks[: self._n]
        done = self._marks[0] - self._first_shift
        del self._shifts[:done]
        self._first_shift += done

    @property
    def _start(self) -> int:
        """Index of the oldest row kept."""
        return max(0, len(self._rows) - self._n)

    def _corrected(self, lo: int, hi: int) -> list[list[float]]:
        """Rows ``lo`` to ``hi`` (excluded) with every shift made since each was written."""
        rows = [list(row) for row in self._rows[lo:hi]]
        marks = self._marks[lo:hi]
        for k in range(marks[0], self._first_shift + len(self._shifts)):
            shift = self._shifts[k - self._first_shift]
            for row in rows[: bisect_right(marks, k)]:
                shift.apply(row)
        return rows

    def at(self, t_s: float) -> Array | None:
        """Row (19,) linearly interpolated at ``t_s``; None if outside the history."""
        times, start = self._times, self._start
        if len(times) == 0 or not times[start] <= t_s <= times[-1]:
            return None
        i = bisect_left(times, t_s, start)
        if i == start:
            return np.array(self._corrected(i, i + 1)[0])
        a, b = self._corrected(i - 1, i + 1)
        u = (t_s - times[i - 1]) / (times[i] - times[i - 1])  # (shifts leave t alone)
        return np.array([x + u * (y - x) for x, y in zip(a, b, strict=True)])

    def spacing(self, t_s: float) -> float:
        """Time between the rows around ``t_s`` (long across lost IMU samples); 0 if outside."""
        times, start = self._times, self._start
        i = bisect_left(times, t_s, start)
        if i == start or i >= len(times):
            return 0.0
        return times[i] - times[i - 1]

    @property
    def full(self) -> bool:
        """Old rows are being dropped: the history spans its whole length."""
        return len(self._rows) >= self._n

    def oldest_s(self) -> float:
        """Time of the oldest row kept."""
        return self._times[self._start]

    def mean_rate(self, t_s: float, half_width_s: float) -> Array:
        """Mean body rate (3,) of the rows within ``half_width_s`` of ``t_s`` (centred, no lag)."""
        times, start = self._times, self._start
        i = bisect_left(times, t_s, start)
        lo, hi = i, i  # the rows within reach form one run around i (times increase)
        while lo > start and abs(times[lo - 1] - t_s) <= half_width_s:
            lo -= 1
        while hi < len(times) and abs(times[hi] - t_s) <= half_width_s:
            hi += 1
        if lo == hi:
            return np.array(self._rows[-1][ROW_W])
        # what np.mean(axis=0) of the rows' rates computes (row by row in order, then / count),
        # in floats: numpy's way cost 12 us an epoch, most of it making the array
        rows, x = self._rows, ROW_W.start
        sx, sy, sz = rows[lo][ROW_W]
        for k in range(lo + 1, hi):
            row = rows[k]
            sx += row[x]
            sy += row[x + 1]
            sz += row[x + 2]
        n = hi - lo
        return np.array((sx / n, sy / n, sz / n))

    def turn(self, rot: Mat9, p_ref: Sequence[float]) -> None:
        """Turn every row about the vertical by ``rot`` as the heading's alignment turns the
        INS: C <- rot C, and the motion integrated in the old azimuth with it: v <- rot v,
        the position about ``p_ref`` (the INS's now). (A correction turns the attitude
        alone: the velocity was integrated with the attitude it had.) Once an engine's
        life, so the rows are rewritten at once, their shifts so far applied first."""
        rows = self._corrected(0, len(self._rows)) if self._rows else []
        a, b, c, d = rot[0], rot[1], rot[3], rot[4]  # the horizontal 2 x 2 of rot
        n, v = ROW_P.start, ROW_V.start
        for row in rows:
            row[ROW_C] = dcm_mul(rot, row[ROW_C])
            x, y = row[v], row[v + 1]
            row[v], row[v + 1] = a * x + b * y, c * x + d * y
            x, y = row[n] - p_ref[0], row[n + 1] - p_ref[1]
            row[n], row[n + 1] = p_ref[0] + a * x + b * y, p_ref[1] + c * x + d * y
        self._rows = [tuple(row) for row in rows]
        self._first_shift += len(self._shifts)
        self._shifts = []
        self._marks = [self._first_shift] * len(self._rows)

    def shift(self, dp: Array, dv: Array, rot: Mat9, t_e: float = math.inf) -> None:
        """Correct every row by :class:`Shift` (dp, dv, rot, t_e) (when it is read)."""
        (dpx, dpy, dpz), (dvx, dvy, dvz) = dp.tolist(), dv.tolist()
        self._shifts.append(Shift((dpx, dpy, dpz), (dvx, dvy, dvz), rot, t_e))
