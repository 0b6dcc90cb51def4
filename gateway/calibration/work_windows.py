"""Work and energy over stretches of forward driving: the IMU side and the GNSS side.

A wheeled vehicle moves along its own x axis (no side slip at the reference point, e.g. the
rear axle's centre), so per unit mass d(u^2/2 + g h)/dt = u f_x: the specific force along
the body's x axis does all the work on the speed u and the height h (the along-track
gravity g sin(pitch) is in f_x and in g dh/dt alike). Over a window, GNSS gives the energy
change (speed from SOG and the slope of the heights, height from GGA), the IMU gives
sum u f dt as a vector in its own axes: the body's x axis in those axes is the direction
that turns the one into the other (:mod:`gateway.calibration.forward_axis`). Energy needs
no differentiation of GNSS: its noise is that of the end points, whatever the window's length.

Both sides are moved to the reference point with the lever arms (SPEC 5): the antenna's
speed loses (w x l_ant)_x, its height C l_ant's vertical part, the IMU's specific force the
lever arm's angular and centripetal acceleration. Each epoch is used a few epochs late, once
the fixes around it give its slope and the IMU intervals on both sides its rate.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass
from itertools import pairwise

from drivers.samples import FixQuality, GnssFix
from drivers.units import GRAVITY_MPS2
from gateway.calibration.imu_intervals import ImuInterval, Vec3
from gateway.calibration.travel_direction import STILL_SPEED_MPS, TravelDirection

#: Epochs each side of an epoch whose heights give its slope (0.5 s at 10 Hz).
SLOPE_SPAN = 5
#: Epochs each side of an epoch whose speeds are averaged into its speed (white SOG noise).
SPEED_SPAN = 2
#: Epochs kept: the slope's span each side of the epoch in hand.
BUFFER = 2 * SLOPE_SPAN + 1
#: An epoch interval longer than this (s) is an outage, not a step of the drive.
MAX_EPOCH_STEP_S = 1.1


@dataclass(frozen=True, slots=True)
class WorkWindow:
    """One stretch of forward driving ending at ``t_s``: ``work_m2ps2`` = sum u f dt at the
    reference point (3,), in the IMU samples' axes; the ``distance_m`` driven; and the change
    of u^2/2 + g h by GNSS, ``energy_m2ps2``. All per unit mass."""

    t_s: float
    work_m2ps2: Vec3
    distance_m: float
    energy_m2ps2: float


@dataclass(slots=True)
class _Epoch:
    """One fix as the window needs it, and the IMU interval that ends at it."""

    t_s: float
    sog_mps: float | None  # None: not a usable fix (quality, missing fields)
    alt_m: float
    interval: ImuInterval | None
    forward: bool


@dataclass(frozen=True, slots=True)
class _State:
    """An epoch's reference-point speed (3-D, m/s), energy (m^2/s^2) and gyro rate."""

    t_s: float
    speed_mps: float
    energy_m2ps2: float
    w_rps: Vec3


class WorkWindows:
    """Fed each epoch (on the IMU's clock) with its fix and IMU interval; emits windows."""

    def __init__(
        self,
        antenna_lever_arm_m: Vec3,
        imu_lever_arm_m: Vec3,
        window_s: float = 2.0,
        min_speed_mps: float = 1.0,
        fix_qualities: tuple[int, ...] = (FixQuality.RTK_FIXED,),
    ) -> None:
        self.l_ant = antenna_lever_arm_m
        self.l_imu = imu_lever_arm_m
        self.window_s = window_s
        self.min_speed_mps = min_speed_mps
        self.fix_qualities = fix_qualities
        self.direction = TravelDirection()
        self._epochs: deque[_Epoch] = deque(maxlen=BUFFER)
        self._prev: _State | None = None
        self._start: _State | None = None  # where the open window began
        self._work = [0.0, 0.0, 0.0]
        self._distance_m = 0.0

    def add(self, t_s: float, fix: GnssFix, interval: ImuInterval | None) -> WorkWindow | None:
        """One epoch at ``t_s``; returns the window it closes, if any."""
        if interval is None or interval.duration_s > MAX_EPOCH_STEP_S:
            self.direction.heading_rad = None  # no rate to carry it over the gap
            interval = None
        else:
            self.direction.turn(interval.w_rps[2], interval.duration_s)
            if fix.sog_mps is not None and fix.sog_mps < STILL_SPEED_MPS:
                self.direction.still(interval.f_mps2[0])
            elif fix.sog_mps is not None:
                self.direction.rolling(interval.f_mps2[0], interval.duration_s, fix.sog_mps)
        usable = (
            int(fix.quality) in self.fix_qualities
            and fix.sog_mps is not None
            and fix.alt_m is not None
        )
        moving = usable and fix.sog_mps is not None and fix.sog_mps >= self.min_speed_mps
        forward = (
            self.direction.course(fix.cog_rad) if moving and fix.cog_rad is not None else False
        )
        self._epochs.append(
            _Epoch(t_s, fix.sog_mps if usable else None, fix.alt_m or 0.0, interval, forward)
        )
        if len(self._epochs) < BUFFER:
            return None
        return self._step(self._state(SLOPE_SPAN))

    def _state(self, j: int) -> _State | None:
        """Epoch ``j`` of the buffer as a usable forward-driving state, or None."""
        epochs = list(self._epochs)
        e = epochs[j]
        if e.sog_mps is None or not e.forward or e.sog_mps < self.min_speed_mps:
            return None
        distance_m = 0.0
        for a, b in pairwise(epochs):  # the slope's span
            if a.sog_mps is None or b.sog_mps is None:
                return None
            distance_m += 0.5 * (a.sog_mps + b.sog_mps) * (b.t_s - a.t_s)
        rates = [_rate_at(a.interval, b.interval) for a, b in pairwise(epochs)]
        lx, ly, lz = self.l_ant
        speeds = []
        for i in range(j - SPEED_SPAN, j + SPEED_SPAN + 1):
            w, sog = rates[i], epochs[i].sog_mps
            if w is None or sog is None:
                return None
            speeds.append(sog - (w[1] * lz - w[2] * ly))  # less the antenna's (w x l_ant)_x
            if i == j:
                w_j = w
        if distance_m <= 0.0:
            return None
        slope = (epochs[-1].alt_m - epochs[0].alt_m) / distance_m
        pitch = math.atan(slope)
        speed = sum(speeds) / len(speeds) * math.sqrt(1.0 + slope * slope)
        height = e.alt_m - math.sin(pitch) * lx + math.cos(pitch) * lz
        return _State(e.t_s, speed, 0.5 * speed * speed + GRAVITY_MPS2 * height, w_j)

    def _step(self, state: _State | None) -> WorkWindow | None:
        """Add the interval from the previous epoch to ``state``'s; close a full window, or
        the open one where forward driving with usable fixes ends."""
        prev, self._prev = self._prev, state
        interval = self._epochs[SLOPE_SPAN].interval
        if state is None or prev is None or interval is None:
            window = self._emit(prev) if self._start is not None else None
            self._start = None
            return window
        dt = interval.duration_s
        u = 0.5 * (prev.speed_mps + state.speed_mps)
        f_ref = _minus_lever_arm(interval, prev.w_rps, state.w_rps, self.l_imu)
        if self._start is None:
            self._start = prev
        for i in range(3):
            self._work[i] += u * f_ref[i] * dt
        self._distance_m += u * dt
        if state.t_s - self._start.t_s < self.window_s:
            return None
        window = self._emit(state)
        self._start = state
        return window

    def _emit(self, end: _State | None) -> WorkWindow | None:
        """The open window up to ``end`` if it spans at least half a window; sums reset."""
        start = self._start
        work, self._work = self._work, [0.0, 0.0, 0.0]
        distance_m, self._distance_m = self._distance_m, 0.0
        if start is None or end is None or end.t_s - start.t_s < 0.5 * self.window_s:
            return None
        return WorkWindow(
            end.t_s, (work[0], work[1], work[2]), distance_m, end.energy_m2ps2 - start.energy_m2ps2
        )


def _rate_at(before: ImuInterval | None, after: ImuInterval | None) -> Vec3 | None:
    """The gyro rate at the epoch between two IMU intervals: their time-weighted mean."""
    if before is None or after is None:
        return None
    t_a, t_b = before.duration_s, after.duration_s
    wa, wb = before.w_rps, after.w_rps
    return (
        (wa[0] * t_a + wb[0] * t_b) / (t_a + t_b),
        (wa[1] * t_a + wb[1] * t_b) / (t_a + t_b),
        (wa[2] * t_a + wb[2] * t_b) / (t_a + t_b),
    )


def _minus_lever_arm(interval: ImuInterval, w0: Vec3, w1: Vec3, l_imu: Vec3) -> Vec3:
    """The interval's mean specific force at the reference point: less dw/dt x l and
    w x (w x l) of the IMU's lever arm ``l_imu`` (rates at the interval's ends w0, w1)."""
    dt = interval.duration_s
    wx, wy, wz = interval.w_rps
    lx, ly, lz = l_imu
    ax, ay, az = ((b - a) / dt for a, b in zip(w0, w1, strict=True))
    wl = wx * lx + wy * ly + wz * lz
    ww = wx * wx + wy * wy + wz * wz
    fx, fy, fz = interval.f_mps2
    return (
        fx - (ay * lz - az * ly) - (wx * wl - lx * ww),
        fy - (az * lx - ax * lz) - (wy * wl - ly * ww),
        fz - (ax * ly - ay * lx) - (wz * wl - lz * ww),
    )
