"""The mounting's roll and pitch from an INS: the IMU axes' tilt against the body's.

An engine fed the IMU samples integrates the gyros, so the attitude it converges to is that
of the IMU's own axes: a turn rotates an accelerometer bias with the IMU and gravity not,
which tells the bias from a tilt of the axes (ALGORITHMS.md 1, eq. 12). It cannot tell its
heading from the course (that channel is steered to it), but its roll and pitch are the
IMU's. The body's are on the ground:

- pitch: a wheeled vehicle drives along its own x axis, so the body's pitch is the slope of
  its track, which RTK heights give (d h / d s); the engine's pitch minus that slope, over
  forward driving, is the mounting's pitch;
- roll: nothing on one pass tells the ground's cross slope, but on the same place driven the
  other way the body's roll is opposite and the mounting's is not: the mean of the engine's
  roll both ways over the same cells of ground is the mounting's roll.

Only epochs where the engine navigates with its accelerometer biases learnt count: its
convergence flag, or its stated roll/pitch 1-sigma within ``max_tilt_sigma_deg`` (what a
determined axis may have; the accelerometer bias over g is part of it). Running
sums, but for the cells: a bounded map (``MAX_CELLS``) of ``cell_m`` squares around the
first position.

Fed an engine's solution at each GNSS epoch (:meth:`InsTilt.epoch`): the own observer of
``navgw calibrate`` (:mod:`gateway.calibration.mounting`), and the fusion core's engine,
whose check of the mounting in effect tells the bus when the drive shows it off
(:mod:`gateway.fusion.mounting_check`).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, replace

from drivers.samples import FixQuality, GnssFix
from drivers.units import wrap_pi
from gateway.estimation.line_fit import LineSums
from gateway.estimation.solution import Mode, Solution

#: Ground cells kept (4 m cells: 80 km of single track); later cells are not started.
MAX_CELLS = 20_000
#: Cells are grouped into blocks of this many a side, whose errors count as independent.
BLOCK_CELLS = 5
#: Forward driving is cut into segments this long: their scatter gives the pitch's sigma ...
SEGMENT_M = 50.0
#: ... and shorter ones (at the end of a stretch) are not used: their end heights dominate.
MIN_SEGMENT_M = 20.0
#: A segment ends where the vehicle turns faster than this (rad/s: 5 deg/s, a 34 m radius
#: at 3 m/s; headland turns are 10-20 deg/s, contours under 2): at the headland the
#: implement is lifted, pitching the chassis on its tyres against the ground, as the roll
#: turns over. Segments through the turns of `field`, the chassis 0.5 deg and 1 deg more
#: over each headland, fitted a pitch from roll of a 9-25 deg mounting yaw (1.1-1.7 of the
#: bound: a false verdict at 211-241 s, both engines); without them 0.13-0.35.
SEGMENT_TURN_RATE_RPS = math.radians(5.0)
_EARTH_RADIUS_M = 6_371_000.0
_OPPOSITE_RAD = 0.75 * math.pi  # headings at least this far apart count as opposite
_SAME_RAD = 0.25 * math.pi  # ... at most this far apart as the same way


@dataclass(frozen=True, slots=True)
class TiltEstimate:
    """One axis: the mounting angle (rad, None before anything usable), its 1-sigma (rad),
    how much drive went in and how much was driven in all (m: forward for pitch; both ways
    on the same cells, the lesser way, for roll; in all: whether or not the engine had learnt
    its biases yet), and the blocks whose scatter gave the sigma (few: a rough sigma)."""

    angle_rad: float | None
    sigma_rad: float
    distance_m: float
    driven_m: float
    blocks: int


@dataclass(slots=True)
class _BlockMean:
    """A weighted mean over blocks of rows, by running sums: per block its weight W, its
    weighted sum B and its distance; the scatter between blocks is sum (B - mean W)^2."""

    blocks: int = 0
    weight: float = 0.0
    weighted: float = 0.0
    distance_m: float = 0.0
    bb: float = 0.0
    bw: float = 0.0
    ww: float = 0.0

    def add(self, weight: float, weighted: float, distance_m: float) -> None:
        """One block."""
        self.blocks += 1
        self.weight += weight
        self.weighted += weighted
        self.distance_m += distance_m
        self.bb += weighted * weighted
        self.bw += weighted * weight
        self.ww += weight * weight

    def estimate(self, floor_rad: float, driven_m: float) -> TiltEstimate:
        """The mean; its 1-sigma from the scatter (errors independent between blocks, times
        G / (G - 1)), no less than ``floor_rad``; unknown with fewer than two blocks."""
        if self.weight <= 0.0:
            return TiltEstimate(None, math.inf, self.distance_m, driven_m, self.blocks)
        mean = self.weighted / self.weight
        g = self.blocks
        scatter = max(self.bb - 2.0 * mean * self.bw + mean * mean * self.ww, 0.0)
        variance = scatter * g / max(g - 1, 1) / self.weight**2
        sigma = math.sqrt(variance + floor_rad**2) if g > 1 else math.inf
        return TiltEstimate(mean, sigma, self.distance_m, driven_m, g)


@dataclass(frozen=True, slots=True)
class RollCoupling:
    """Pitch against the ground fitted per segment as a line in the roll, ``a + coupling x
    roll``: a mounting yaw psi turns a side slope's roll into the axes' pitch, coupling
    -sin(psi) (what the mean of :meth:`InsTilt.pitch` cancels when the slope is driven both
    ways, and what the pitch sent carries on each pass). Its 1-sigma from the segments'
    scatter about the line, no less than their stated errors give it; the roll's RMS over the
    segments (rad) and their number."""

    coupling: float
    sigma_coupling: float
    roll_rms_rad: float
    segments: int


@dataclass(slots=True)
class _LineFit:
    """Weighted least squares of e = a + b r by running sums (weights: distance), and the
    sums that give the slope's variance from each segment's own error sigma."""

    sums: LineSums = dataclasses.field(default_factory=LineSums)
    wee: float = 0.0
    v: float = 0.0  # sum (w sigma)^2
    vr: float = 0.0  # ... times r
    vrr: float = 0.0  # ... times r^2

    def add(self, weight: float, e: float, r: float, sigma: float) -> None:
        """One segment, its error no less than ``sigma``."""
        self.sums.add(weight, r, e)
        self.wee += weight * e * e
        v = (weight * sigma) ** 2
        self.v += v
        self.vr += v * r
        self.vrr += v * r * r

    def fit(self) -> RollCoupling | None:
        """The line's slope and its 1-sigma: the residuals' scatter, and no less than what
        the segments' own errors give it (the engine's stated tilt: its error wanders
        slowly, so segments on nearly the same roll can line up along a slope the scatter
        cannot see: five segments of one swath, roll 3.6-4.0 deg and the engine's pitch
        error settling 0.13 deg, fitted a coupling of 0.33 +/- 0.08). None with fewer than
        three segments or no spread of roll."""
        s = self.sums
        det = s.det
        if s.n < 3 or det <= 1e-12 * s.w * s.w:
            return None
        a, b = s.line()
        s2 = max(self.wee - a * s.wy - b * s.wxy, 0.0) / (s.n - 2)
        # b = sum c_i e_i, c_i = w_i (r_i - r_mean) w / det: its variance from the segments'
        r_mean = s.wx / s.w
        own = max(self.vrr - 2.0 * r_mean * self.vr + r_mean * r_mean * self.v, 0.0)
        sigma_b = math.sqrt(max(s2 * s.w / det, own * (s.w / det) ** 2))
        return RollCoupling(b, sigma_b, math.sqrt(s.wxx / s.w), s.n)


@dataclass(slots=True)
class _Cell:
    """Sums of one cell of ground, per way (the first way it was driven, the opposite):
    distance driven, distance with the biases learnt, and that distance times the roll."""

    heading_rad: float
    ways: tuple[list[float], list[float]]  # [m, learnt m, roll m] each way


class InsTilt:
    """Compares an engine's roll and pitch with the ground's."""

    def __init__(
        self,
        antenna_lever_arm_m: tuple[float, float, float],
        cell_m: float = 4.0,
        min_speed_mps: float = 1.0,
        fix_qualities: tuple[int, ...] = (FixQuality.RTK_FIXED,),
        *,
        max_tilt_sigma_deg: float,
    ) -> None:
        self.l_ant = antenna_lever_arm_m
        self.cell_m = cell_m
        self.min_speed_mps = min_speed_mps
        self.fix_qualities = fix_qualities
        self.max_tilt_sigma_rad = math.radians(max_tilt_sigma_deg)
        self.learnt = False  # the engine's accelerometer biases converged at some point
        self.sigma_tilt_rad = math.inf  # the engine's own roll/pitch 1-sigma, last
        self._origin: tuple[float, float] | None = None
        self._t_s: float | None = None  # the previous epoch's receipt
        self._cells: dict[tuple[int, int], _Cell] = {}
        self._last: tuple[float, float] | None = None  # height, pitch at the segment's end
        # distance m, sum tan(pitch) ds, height at start, sum roll ds, sum stated tilt ds
        self._segment = [0.0, 0.0, 0.0, 0.0, 0.0]
        self._segments = _BlockMean()  # per segment: distance, distance x pitch estimate
        self._coupling = _LineFit()  # per segment: distance, pitch estimate, mean roll
        self._forward_m = 0.0  # usable forward driving, learnt or not

    def epoch(
        self, fix: GnssFix, sol: Solution, mean_tilt_rad: tuple[float, float] | None = None
    ) -> None:
        """One GNSS epoch and the engine's solution after it, compared with the ground;
        ``mean_tilt_rad``: the mean roll and pitch sent since the last epoch (None: the
        solution's). Taken at the epochs alone, a 1 Hz receiver at 12 m/s on bumpy ground
        gave five samples of a body rocking on the bumps per 60 m, roll and pitch together:
        a pitch from roll of a 25 deg mounting yaw on an IMU mounted true (the EKF, `field`
        with 12 m/s passes, seed 631: DEGRADED from 230 s)."""
        if mean_tilt_rad is not None:
            sol = replace(sol, roll_rad=mean_tilt_rad[0], pitch_rad=mean_tilt_rad[1])
        dt_s = fix.t - self._t_s if self._t_s is not None else 0.0
        self._t_s = fix.t
        moving = (
            sol.mode is Mode.NAVIGATING
            and not sol.reversing
            and int(fix.quality) in self.fix_qualities
            and fix.sog_mps is not None
            and fix.sog_mps >= self.min_speed_mps
            and fix.alt_m is not None
        )
        learnt = sol.convergence.accel_xy or (
            sol.sigma_tilt_rad is not None and sol.sigma_tilt_rad <= self.max_tilt_sigma_rad
        )
        if learnt and sol.sigma_tilt_rad is not None:
            self.learnt = True
            self.sigma_tilt_rad = sol.sigma_tilt_rad
        if not moving or fix.sog_mps is None or fix.alt_m is None:
            self._end_segment()
            return
        ds_m = fix.sog_mps * dt_s
        self._forward_m += ds_m
        self._roll(sol, ds_m, learnt)
        turning = sol.yaw_rate_rps is not None and abs(sol.yaw_rate_rps) > SEGMENT_TURN_RATE_RPS
        if learnt and math.isfinite(self.sigma_tilt_rad) and not turning:
            self._pitch(sol, ds_m, fix.alt_m)
        else:
            self._end_segment()

    def _pitch(self, sol: Solution, ds_m: float, alt_m: float) -> None:
        """Add the stretch since the last epoch to the current segment of forward driving."""
        pitch = sol.pitch_rad or 0.0
        lx, _, lz = self.l_ant
        height = alt_m - math.sin(pitch) * lx + math.cos(pitch) * lz  # the reference point's
        last, self._last = self._last, (height, pitch)
        if last is None:
            self._segment = [0.0, 0.0, height, 0.0, 0.0]
            return
        self._segment[0] += ds_m
        self._segment[1] += 0.5 * (math.tan(pitch) + math.tan(last[1])) * ds_m
        self._segment[3] += (sol.roll_rad or 0.0) * ds_m
        self._segment[4] += self.sigma_tilt_rad * ds_m
        if self._segment[0] >= SEGMENT_M:
            self._end_segment()
            self._last = (height, pitch)
            self._segment = [0.0, 0.0, height, 0.0, 0.0]

    def _end_segment(self) -> None:
        """Close the segment of forward driving."""
        if (segment := self._segment_estimate()) is not None:
            distance, estimate, roll, sigma = segment
            self._segments.add(distance, distance * estimate, distance)
            self._coupling.add(distance, estimate, roll, sigma)
        self._last = None
        self._segment = [0.0, 0.0, 0.0, 0.0, 0.0]

    def _segment_estimate(self) -> tuple[float, float, float, float] | None:
        """The open segment's (distance m, mean tan(pitch) of the axes - slope of the track,
        mean roll rad, mean stated tilt sigma rad)."""
        distance, tan_sum, height0, roll_sum, sigma_sum = self._segment
        if self._last is None or distance < MIN_SEGMENT_M:
            return None
        slope = (tan_sum - (self._last[0] - height0)) / distance
        return distance, slope, roll_sum / distance, sigma_sum / distance

    def _roll(self, sol: Solution, ds_m: float, learnt: bool) -> None:
        """Add the epoch's roll to its cell of ground, on the way it faces."""
        if sol.lat_deg is None or sol.lon_deg is None or sol.yaw_rad is None:
            return
        if self._origin is None:
            self._origin = (sol.lat_deg, sol.lon_deg)
        lat0, lon0 = self._origin
        north = math.radians(sol.lat_deg - lat0) * _EARTH_RADIUS_M
        east = math.radians(sol.lon_deg - lon0) * _EARTH_RADIUS_M * math.cos(math.radians(lat0))
        key = (math.floor(north / self.cell_m), math.floor(east / self.cell_m))
        cell = self._cells.get(key)
        if cell is None:
            if len(self._cells) >= MAX_CELLS:
                return
            cell = self._cells[key] = _Cell(sol.yaw_rad, ([0.0, 0.0, 0.0], [0.0, 0.0, 0.0]))
        off = abs(wrap_pi(sol.yaw_rad - cell.heading_rad))
        way = 0 if off <= _SAME_RAD else 1 if off >= _OPPOSITE_RAD else None
        if way is not None:
            sums = cell.ways[way]
            sums[0] += ds_m
            if learnt:
                sums[1] += ds_m
                sums[2] += ds_m * (sol.roll_rad or 0.0)

    def pitch(self) -> TiltEstimate:
        """Mounting pitch: distance-weighted over the segments, the scatter between them."""
        segments = dataclasses.replace(self._segments)
        if (segment := self._segment_estimate()) is not None:
            segments.add(segment[0], segment[0] * segment[1], segment[0])
        return segments.estimate(self.sigma_tilt_rad, self._forward_m)

    def roll_coupling(self) -> RollCoupling | None:
        """The closed segments' pitch against their roll (None: too few, or no roll spread),
        each segment's error no less than the engine's stated tilt over it."""
        return self._coupling.fit()

    def roll(self) -> TiltEstimate:
        """Mounting roll: per cell driven both ways, the mean roll of the two ways, weighted
        by the lesser way's distance; the scatter between blocks of cells. The engine's own
        tilt sigma is the floor: its bias errors are the same both ways."""
        blocks: dict[tuple[int, int], list[float]] = {}
        driven_m = 0.0
        for (kn, ke), cell in self._cells.items():
            (m0, l0, r0), (m1, l1, r1) = cell.ways
            driven_m += min(m0, m1)
            if l0 > 0.0 and l1 > 0.0:
                weight = l0 * l1 / (l0 + l1)
                sums = blocks.setdefault((kn // BLOCK_CELLS, ke // BLOCK_CELLS), [0.0, 0.0, 0.0])
                sums[0] += weight
                sums[1] += weight * 0.5 * (r0 / l0 + r1 / l1)
                sums[2] += min(l0, l1)
        mean = _BlockMean()
        for weight, weighted, distance_m in blocks.values():
            mean.add(weight, weighted, distance_m)
        return mean.estimate(self.sigma_tilt_rad, driven_m)
