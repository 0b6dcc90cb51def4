"""The IMU mounting from an ordinary drive: the rotation from the IMU samples' axes to the body.

The samples an engine sees are already turned by the configured mounting (SPEC 5, the IMU
driver), so what is estimated here is the residual rotation C (v_b = C v_samples) between
those axes and the true body axes; :func:`total_mounting_rpy_deg` composes it with the
configured mounting into the line to paste. What a wheeled vehicle tells apart, where an
accelerometer bias would hide a mounting tilt:

- yaw: it moves along its own x axis, so the IMU's forward axis is the one whose work
  matches the GNSS energy (:mod:`.work_windows`, :mod:`.forward_axis`; forward driving with
  RTK fixes, turns both ways or a side slope driven both ways);
- pitch: an engine fed the samples holds the IMU axes' pitch once turns have taught it the
  accelerometer biases; the track's RTK slope is the body's
  (:mod:`gateway.estimation.ins_tilt`);
- roll: the engine's roll, averaged over the same ground driven both ways (the same);
- coarse roll and pitch, for any mounting error: it turns about its own z axis
  (:mod:`.turn_axis`). Bumps tilt the body during turns, so this is good to a few tenths of
  a degree; the engine is trusted only once the samples are within ``fine_range_deg`` of the
  body (``needs_rerun`` otherwise: run again with the mounting found, as ``navgw calibrate``
  does).

Fed IMU samples and GNSS fixes in time order (O(1) memory but the bounded map of ground
cells), like the engines, so that the service can run it beside them. Each axis comes with
its 1-sigma and, while that is above ``max_sigma_deg``, the manoeuvre still missing.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from drivers.samples import GnssFix, ImuSample
from drivers.units import RAD_TO_DEG
from gateway.calibration.forward_axis import ForwardAxisFit, perpendicular_x
from gateway.calibration.imu_intervals import ImuIntervals, Vec3
from gateway.calibration.turn_axis import TurnAxisFit
from gateway.calibration.work_windows import WorkWindows
from gateway.estimation.attitude import dcm_from_rpy_deg, rpy_from_dcm
from gateway.estimation.epoch_clock import EpochClock
from gateway.estimation.ins_tilt import InsTilt, TiltEstimate
from gateway.estimation.observer.observer_config import ObserverConfig
from gateway.estimation.observer.observer_engine import ObserverEngine

TURN_BOTH_WAYS = (
    "turn both ways: U-turns or circles to the left and to the right (they teach the "
    "accelerometer biases)"
)
SAME_LINE = "drive the same line in both directions"
DRIVE_FORWARD = "drive forward at working speed (above 1 m/s) with an RTK fixed solution"
MORE_LATERAL = "turn both ways at working speed, or drive across a side slope both ways"
AXES = ("roll", "pitch", "yaw")


@dataclass(frozen=True)
class CalibrationConfig:
    """What the calibration is told, and when an axis counts as determined. ``observer``
    is the engine it runs for the IMU axes' tilt; its lever arms and GNSS timing (SPEC 5)
    serve the whole calibration."""

    observer: ObserverConfig = field(default_factory=ObserverConfig)
    max_sigma_deg: float = 0.15  # an axis with a larger 1-sigma is not determined
    fine_range_deg: float = 1.5  # the engine's tilt is used within this of the body's axes
    min_distance_m: float = 40.0  # least driving per axis (forward; both ways for roll)
    gyro_window_s: float = 1.0  # gyro means over this long (turn axis)
    work_window_s: float = 2.0  # work and energy over this long (forward axis)
    cell_m: float = 4.0  # ground cells of the roll both ways


@dataclass(frozen=True)
class MountingResult:
    """The rotation from the samples' axes to the body's (roll, pitch, yaw, ZYX, deg, as
    SPEC 5's mounting; None when nothing could be estimated), each axis's 1-sigma (deg, inf
    if unknown) and the manoeuvres it still needs (none once determined). ``needs_rerun``:
    the samples were too far off the body for the fine tilt; run again with this mounting."""

    rpy_deg: Vec3 | None
    sigma_deg: Vec3
    missing: tuple[tuple[str, ...], tuple[str, ...], tuple[str, ...]]
    needs_rerun: bool
    turned_right_deg: float
    turned_left_deg: float
    forward_m: float  # forward driving with usable fixes (m)
    both_ways_m: float  # ground driven both ways (the lesser way, m)

    @property
    def determined(self) -> bool:
        """Every axis within its sigma bound, from samples near enough the body."""
        return self.rpy_deg is not None and not self.needs_rerun and not any(self.missing)

    @property
    def manoeuvres(self) -> list[str]:
        """The missing manoeuvres, each once, in axis order."""
        return list(dict.fromkeys(m for axis in self.missing for m in axis))


class MountingEstimator:
    """Fed every IMU sample and GNSS fix of a drive, in time order."""

    def __init__(self, config: CalibrationConfig | None = None) -> None:
        self.config = cfg = config or CalibrationConfig()
        obs = cfg.observer
        self.clock = EpochClock.of(obs)
        self.intervals = ImuIntervals()
        self.turns = TurnAxisFit(cfg.gyro_window_s)
        self.work = WorkWindows(obs.antenna_lever_arm_m, obs.imu_lever_arm_m, cfg.work_window_s)
        self.forward = ForwardAxisFit()
        self.engine = ObserverEngine(obs)  # for the IMU axes' tilt
        self.tilt = InsTilt(
            obs.antenna_lever_arm_m, cfg.cell_m, max_tilt_sigma_deg=cfg.max_sigma_deg
        )

    def imu(self, sample: ImuSample) -> None:
        """One IMU sample (in the axes of the configured mounting)."""
        self.intervals.add(sample)
        self.turns.add(sample)
        self.engine.imu(sample)

    def gnss(self, fix: GnssFix) -> None:
        """One GNSS epoch, after the IMU samples up to its receipt."""
        t_s = self.clock.epoch_time(fix)
        window = None if t_s is None else self.work.add(t_s, fix, self.intervals.cut(t_s))
        if window is not None:
            self.forward.add(window)
        self.engine.gnss(fix)
        self.tilt.epoch(fix, self.engine.solution())

    def result(self) -> MountingResult:
        """The estimate so far."""
        cfg = self.config
        axis = self.turns.fit()
        n = axis.n_imu if axis is not None else np.array([0.0, 0.0, 1.0])
        forward = self.forward.fit(n)
        m = forward.m_imu if forward is not None else perpendicular_x(n)
        if axis is None and forward is None:
            coarse = None
        else:
            roll, pitch, yaw = rpy_from_dcm(np.vstack((m, np.cross(n, m), n)))
            coarse = (roll * RAD_TO_DEG, pitch * RAD_TO_DEG, _wrap_deg(yaw * RAD_TO_DEG))
        needs_rerun = coarse is not None and max(abs(a) for a in coarse) > cfg.fine_range_deg
        yaw_sigma = forward.sigma_rad * RAD_TO_DEG if forward is not None else math.inf
        roll_fine, pitch_fine = self.tilt.roll(), self.tilt.pitch()
        yaw_missing = () if yaw_sigma <= cfg.max_sigma_deg else (MORE_LATERAL,)
        missing = (
            self._tilt_missing(roll_fine, SAME_LINE),
            self._tilt_missing(pitch_fine, DRIVE_FORWARD),
            yaw_missing if forward is not None else (DRIVE_FORWARD,),
        )
        if coarse is None or needs_rerun:  # the engine's tilt is not to be trusted yet
            tilt_sigma = (
                np.sqrt(np.diag(axis.tilt_cov_rad2)) if axis is not None else [math.inf] * 2
            )
            rpy = coarse
            sigma = (tilt_sigma[0] * RAD_TO_DEG, tilt_sigma[1] * RAD_TO_DEG, yaw_sigma)
        else:
            rpy = (_angle(roll_fine, coarse[0]), _angle(pitch_fine, coarse[1]), coarse[2])
            sigma = (roll_fine.sigma_rad * RAD_TO_DEG, pitch_fine.sigma_rad * RAD_TO_DEG, yaw_sigma)
        return MountingResult(
            rpy,
            sigma,
            missing,
            needs_rerun,
            self.turns.turned_right_rad * RAD_TO_DEG,
            self.turns.turned_left_rad * RAD_TO_DEG,
            pitch_fine.driven_m,
            roll_fine.driven_m,
        )

    def _tilt_missing(self, estimate: TiltEstimate, drive: str) -> tuple[str, ...]:
        """What a roll or pitch from the engine still needs: the engine to learn its biases,
        and ``drive`` while too little of it went in."""
        enough = self.config.min_distance_m
        if not self.tilt.learnt:
            return (TURN_BOTH_WAYS,) if estimate.driven_m >= enough else (TURN_BOTH_WAYS, drive)
        if (
            estimate.distance_m < enough
            or estimate.sigma_rad * RAD_TO_DEG > self.config.max_sigma_deg
        ):
            return (drive,)
        return ()


def _angle(estimate: TiltEstimate, coarse_deg: float) -> float:
    """The engine's angle in degrees where it has one, else the coarse one."""
    return coarse_deg if estimate.angle_rad is None else estimate.angle_rad * RAD_TO_DEG


def _wrap_deg(angle_deg: float) -> float:
    """Angle in (-180, 180] deg."""
    wrapped = (angle_deg + 180.0) % 360.0 - 180.0
    return 180.0 if wrapped == -180.0 else wrapped


def total_mounting_rpy_deg(
    configured_rpy_deg: npt.ArrayLike, residual_rpy_deg: npt.ArrayLike
) -> Vec3:
    """The mounting to configure (SPEC 5, deg) when the samples, already turned by
    ``configured_rpy_deg``, are off the body by ``residual_rpy_deg``: C = C_res C_conf."""
    c = dcm_from_rpy_deg(residual_rpy_deg) @ dcm_from_rpy_deg(configured_rpy_deg)
    roll, pitch, yaw = rpy_from_dcm(c)
    return (roll * RAD_TO_DEG, pitch * RAD_TO_DEG, _wrap_deg(yaw * RAD_TO_DEG))
