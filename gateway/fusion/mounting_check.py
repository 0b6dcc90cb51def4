"""Is the IMU mounting in effect the vehicle's? The drive tells, and so does NAVGW_STATUS.

A roll or pitch of the IMU that the configured mounting (SPEC 5) leaves out is a tilt error
no engine can see: the samples are those of a rigid frame, and every estimate follows that
frame. The roll and pitch sent are off by it while the accuracy stated is the engine's (a
mounting left unset on a unit bolted 3 deg nose-up: pitch 3 deg off, 0.06 deg stated). The
drive shows it: :class:`~gateway.estimation.ins_tilt.InsTilt` on the engine's solutions, as
``navgw calibrate`` does on its own observer's (pitch against the RTK track's slope, roll
over the same ground driven both ways). A mounting yaw tilts nothing on level ground, but on
a side slope it turns the roll into the axes' pitch (pitch off by roll x sin(yaw)): the
segments' pitch against their roll
(:meth:`~gateway.estimation.ins_tilt.InsTilt.roll_coupling`; the segments leave out the
turns, where an implement lifted at the headland pitches the chassis as the roll turns
over). Once the roll or pitch is off by more than ``SIGMAS`` of its 1-sigma plus
``OFFSET_TOLERANCE_DEG`` (what a chassis leans on its tyres), or the pitch from roll at the
roll driven (RMS) by more than ``SIGMAS`` of its plus ``COUPLING_TOLERANCE_DEG``, from at
least ``MIN_BLOCKS`` blocks of driving, :attr:`MountingCheck.off` is set and the core sends
DEGRADED (SPEC 4: a value beyond its stated accuracy goes out only with NAVGW_STATUS saying
so) until restarted: the mounting does not change while the service runs, and an estimate
near its bound would flicker (the EKF on field with a 3, -2, 4 deg mounting: off at 211 s,
within at 231, off from 271). The mounting itself is never changed while running (``navgw
calibrate``, or the live estimate's line in the log, gives the one to configure).

Per GNSS epoch only, nothing per IMU sample; the estimate is looked at every
``CHECK_INTERVAL_S`` of fix time (the roll's cells are summed then). On flat ground a
mounting yaw is left to the live estimate (:mod:`gateway.service.mounting_watch`, which
costs as much as an engine per sample): there it tilts nothing sent.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

from drivers.samples import Float3, GnssFix
from drivers.units import RAD_TO_DEG
from gateway.estimation.ins_tilt import InsTilt, RollCoupling, TiltEstimate
from gateway.estimation.solution import Solution

log = logging.getLogger(__name__)

#: An axis counts as off beyond this many of its 1-sigmas ...
SIGMAS = 3.0
#: ... plus this (deg), for the roll and pitch: the chassis itself leans on its tyres
#: against the ground it drives (a lifted rear implement pitches a tractor some 0.5 deg
#: nose-up, a heavy side load rolls it), which the IMU rightly measures and the ground's
#: slopes do not show ...
OFFSET_TOLERANCE_DEG = 0.5
#: ... and this for the pitch a mounting yaw makes of the roll: nothing of the chassis
#: couples them (a side slope's crabbing shows as an offset: the roll and the slip both
#: turn over with the way driven). The margin of the check of what goes out.
COUPLING_TOLERANCE_DEG = 0.1
#: The sigma is the scatter between blocks of driving (50 m of forward driving for pitch,
#: 20 m squares driven both ways for roll): with fewer, it is itself too rough to judge by
#: (with correct mountings the angles stayed within a quarter of the bound, docs/ROBUSTNESS.md).
MIN_BLOCKS = 5
#: The estimate is looked at this often (s of fix time).
CHECK_INTERVAL_S = 10.0
#: An engine's epochs count once it states roll/pitch within this (deg), or says its
#: accelerometer biases converged (what ``navgw calibrate`` takes as determined).
LEARNT_TILT_SIGMA_DEG = 0.15


@dataclass(frozen=True, slots=True)
class TiltOff:
    """One axis's mounting error as the drive shows it: the angle and its 1-sigma (deg), and
    how near the bound it is."""

    axis: str
    angle_deg: float
    sigma_deg: float
    ratio: float  # the error over the bound it is judged by: off beyond 1

    def text(self) -> str:
        """E.g. ``pitch 2.95 +/- 0.09 deg``."""
        return f"{self.axis} {self.angle_deg:+.2f} +/- {self.sigma_deg:.2f} deg"


class MountingCheck:
    """Fed each GNSS fix with the engine's solution after it; :attr:`off` once the drive
    has shown the mounting in effect tilted off the body's axes."""

    def __init__(self, antenna_lever_arm_m: Float3, mounting_sigma_deg: float = 0.0) -> None:
        """``mounting_sigma_deg``: the configured mounting's stated roll/pitch 1-sigma
        (``[vehicle] imu_mounting_sigma_deg``), already in the engine's stated accuracy and
        so in the roll's and pitch's sigmas here; the yaw's tilt is allowed it too."""
        self.tilt = InsTilt(antenna_lever_arm_m, max_tilt_sigma_deg=LEARNT_TILT_SIGMA_DEG)
        self.mounting_sigma_deg = mounting_sigma_deg
        self.found: tuple[TiltOff, ...] = ()  # the axes off at the last look that found any
        self._next_t: float | None = None
        self._tilt_sums = [0.0, 0.0, 0.0]  # roll, pitch, count of the solutions since

    @property
    def off(self) -> bool:
        """The drive has shown the mounting off (latched: the mounting does not change)."""
        return bool(self.found)

    def solution(self, sol: Solution) -> None:
        """A solution made for the bus: its roll and pitch go into the interval's mean."""
        if sol.roll_rad is not None and sol.pitch_rad is not None:
            sums = self._tilt_sums
            sums[0] += sol.roll_rad
            sums[1] += sol.pitch_rad
            sums[2] += 1.0

    def epoch(self, fix: GnssFix, sol: Solution) -> None:
        """One GNSS fix and the solution after it, with the mean roll and pitch sent since
        the last (:meth:`solution`); every CHECK_INTERVAL_S, the verdict."""
        roll_sum, pitch_sum, n = self._tilt_sums
        self._tilt_sums = [0.0, 0.0, 0.0]
        self.tilt.epoch(fix, sol, (roll_sum / n, pitch_sum / n) if n else None)
        if self._next_t is not None and fix.t < self._next_t:
            return
        self._next_t = fix.t + CHECK_INTERVAL_S
        found = tuple(off for off in self.judged() if off.ratio > 1.0)
        if found and not self.found:
            log.warning(
                "t=%.1f: the IMU mounting in effect is off the vehicle's axes (%s): the roll "
                "and pitch sent are the IMU's, not the vehicle's; NAVGW_STATUS degraded "
                "until restarted. Run navgw calibrate on a recording of this drive, set "
                "[vehicle] imu_mounting_rpy_deg and restart", fix.t,
                "; ".join(o.text() for o in found),
            )  # fmt: skip
        if found:
            self.found = found

    def judged(self) -> tuple[TiltOff, ...]:
        """The axes the drive so far can judge, each with its error against its bound."""
        tilt = self.tilt
        judged = (
            _off("roll", tilt.roll()),
            _off("pitch", tilt.pitch()),
            _yaw_off(tilt.roll_coupling(), self.mounting_sigma_deg),
        )
        return tuple(off for off in judged if off is not None)


def _off(axis: str, est: TiltEstimate) -> TiltOff | None:
    """The axis's error against ``SIGMAS`` of its sigma and the chassis's tolerance; None
    with too little driving to judge."""
    if est.angle_rad is None or est.blocks < MIN_BLOCKS or not math.isfinite(est.sigma_rad):
        return None
    angle, sigma = est.angle_rad * RAD_TO_DEG, est.sigma_rad * RAD_TO_DEG
    return TiltOff(axis, angle, sigma, abs(angle) / (SIGMAS * sigma + OFFSET_TOLERANCE_DEG))


def _yaw_off(fit: RollCoupling | None, stated_deg: float) -> TiltOff | None:
    """The mounting yaw: the pitch it carries at the roll driven against ``SIGMAS`` of its
    sigma and of the mounting's stated 1-sigma ``stated_deg``, plus the margin; None with
    too little driving to judge."""
    if fit is None or fit.segments < MIN_BLOCKS or not math.isfinite(fit.sigma_coupling):
        return None
    error_deg = abs(fit.coupling) * fit.roll_rms_rad * RAD_TO_DEG
    sigma_deg = fit.sigma_coupling * fit.roll_rms_rad * RAD_TO_DEG
    bound_deg = SIGMAS * (sigma_deg + stated_deg) + COUPLING_TOLERANCE_DEG
    yaw = math.asin(max(-1.0, min(1.0, -fit.coupling)))
    return TiltOff("yaw", yaw * RAD_TO_DEG, fit.sigma_coupling * RAD_TO_DEG, error_deg / bound_deg)
