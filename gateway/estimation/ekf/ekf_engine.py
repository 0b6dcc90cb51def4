"""The EKF engine: 20-state loosely coupled GNSS/INS filter behind the Estimator protocol.

Per IMU sample (:meth:`EkfEngine.imu`): strapdown mechanisation of the IMU point and a
history row (for late GNSS epochs). Per GNSS epoch (:meth:`EkfEngine.gnss`): epoch time, then
alignment, reset, or the covariance prediction from the accumulated IMU sums, the fusion of
position, horizontal velocity and HDT of the epoch's instant, then the non-holonomic
constraint at the state of now (every ``nhc_interval_s``). Without an epoch for
``covariance_period_s`` (an outage, a slow receiver) the IMU path steps the covariance and
fuses the constraint itself. Pure code: no I/O, no clock; time comes from the samples.

Design choices (ALGORITHMS.md 3 leaves them to the implementer):

- State location: the INS state is the IMU point; antenna and reference point are reached
  through the lever arms (measurement models, read-out), so the mechanisation needs no
  lever-arm accelerations.
- Late epochs: a fix describes the epoch ``t_e`` (:mod:`gateway.estimation.epoch_clock`) and arrives
  later. The innovation and H are computed against the INS state interpolated from the
  history at ``t_e``; the correction is
  applied to the current state (and to the history, so that the next epoch is not double
  counted). Approximation: the error state is taken as constant over the delay (< 0.1 s:
  dv * delay is ~1 mm).
- Covariance runs at the GNSS epochs (10 Hz with an RTK receiver) on IMU sums
  (:func:`gateway.estimation.ekf.error_state.transition_matrix`), flushed before every
  update, and every ``covariance_period_s`` between epochs.
- GNSS position: the receiver's error is three Gauss-Markov states plus a white share
  (:mod:`gateway.estimation.gnss_error`, the model of the observer's position channel),
  restarted when the fix quality changes (a new receiver solution). RTK float and DGNSS are
  not averaged into false confidence, and RTK fixed is weighed by its own sigma.
- Epoch times: on a host clock that does not follow UTC the epochs are placed by their
  arrival less the configured receiver latency, whose error is a constant (0.1 s 1-sigma):
  a state (EPOCH), its estimate taken out of each epoch's time and its error in the
  position model (v_ant dtau), told from pitch (which the mast's lever arm also turns into
  a position offset along body x) as the speed changes. None on a host that follows UTC.
- Yaw: the non-holonomic constraint (zero lateral and vertical velocity of the reference
  point) ties yaw to the direction of travel whenever the vehicle moves, forwards or in
  reverse; HDT is fused when present. No COG pseudo-measurement is needed. Its vertical
  row allows the chassis its own pitch against its track (a state:
  :mod:`gateway.estimation.chassis`), which would otherwise be read as x accelerometer bias.
"""

from __future__ import annotations

import logging
import math
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from drivers.log_limit import LogLimiter
from drivers.samples import DEFAULT_GNSS_SIGMAS, FixQuality, Float3, GnssFix, ImuSample
from drivers.units import DEG_TO_RAD, GRAVITY_MPS2, wrap_pi
from gateway.estimation.attitude import (
    IDENTITY9,
    Mat9,
    cross3,
    dcm_from_rpy,
    dcm_mul,
    exp_so3,
    exp_so3_2nd,
    heading_rate_from_mat9,
    roll_pitch_from_specific_force,
    rpy_from_dcm,
    rpy_from_mat9,
    skew,
    to_mat9,
)
from gateway.estimation.bias_change import (
    WINDOW_S,
    BiasChange,
    CorrectionWindow,
    FoundWalk,
    bias_change_text,
    xy_reopened_text,
    z_reopened_text,
)
from gateway.estimation.chassis import CHASSIS_PITCH_SIGMA_RAD
from gateway.estimation.course_alignment import CourseAlignment, direction_known
from gateway.estimation.ekf.ekf_config import EkfConfig, EkfTuning
from gateway.estimation.ekf.error_state import (
    ATT,
    BA,
    BG,
    CHASSIS,
    EPOCH,
    FIX,
    N_STATES,
    POS,
    RATE_LP_TAU_S,
    VEL,
    Measurement,
    Strapdown,
    correct,
    fuse_heading,
    fuse_nonholonomic,
    fuse_position,
    fuse_velocity,
    fuse_zero_rate,
    heading_weights,
    predict,
    process_noise_psd,
    set_symmetrised,
    transition_matrix,
)
from gateway.estimation.ekf.ins_history import ROW_C, ROW_P, ROW_T, ROW_V, InsHistory
from gateway.estimation.engine_base import (
    HeldEpochs,
    ImuHealth,
    common_fields,
    dead_reckoning_output,
    fix_fields,
    gap_beyond_s,
    levelling_correction,
)
from gateway.estimation.epoch_clock import (
    DELAY_WINDOW_S,
    EpochClock,
    late_epoch_text,
)
from gateway.estimation.geodesy import LocalFrame
from gateway.estimation.gnss_error import (
    INNOVATION_PAIR_MAX_S,
    PositionNoise,
    VelocityNoise,
    fix_position_sigma_m,
    split_fix_variance,
)
from gateway.estimation.gnss_track import DRIFT_WINDOW_S, GnssTrack
from gateway.estimation.hdt_doubt import HdtDoubt, hdt_doubt_text
from gateway.estimation.heading_hint import HeadingHint
from gateway.estimation.imu_noise import ImuNoiseMeter
from gateway.estimation.levelling import ALIGN_LAG_S, WindowMotion
from gateway.estimation.lever_arm import (
    LEVER_RATE_HALF_WIDTH_S,
    along_body_x,
    centred_rate,
    centred_rate_velocity_sigma_mps,
    heading_from_antenna_course,
    lever_arm_position_ned,
    lever_arm_velocity_ned,
)
from gateway.estimation.solution import (
    MAX_IMU_STEP_S,
    NAVIGATING_POSITION_SHARE_M,
    Convergence,
    LearnedState,
    Mode,
    Solution,
    convergence_of,
    navigation_mode,
)
from gateway.estimation.temperature import TemperatureWalk

Array = npt.NDArray[np.float64]
log = logging.getLogger(__name__)

#: Tilt alignment accepts a non-quiet window after this long (vehicle never still).
ALIGN_TIMEOUT_S = 10.0
#: A rest window starts once the vehicle has been quiet and still this long, s: the braking
#: to a stop (GNSS speed lags it) and the rocking after it are not tilt (a window from the
#: stop on levelled 0.45 deg off, stated 0.03).
ALIGN_SETTLE_S = 1.0
ALIGN_MARK_S = 0.05  # the window's running sums kept this often, s, for that
#: A fix that says the vehicle stands vouches for rest this long after its receipt, s: the
#: next epoch of a 1 Hz receiver, with its jitter. Without a fix since, the vehicle may have
#: driven off: GNSS silent while parked (a stalled reader, a receiver's reset), the engine
#: re-levelled on quiet windows of the drive and took their acceleration for tilt: roll
#: 3 deg off with 0.6 stated, ALIGNING.
FIX_STILL_HOLD_S = 1.5
#: Earth rate, rad/s: part of the gyro mean at rest (mechanisation drops it, see
#: gateway.estimation.ekf.error_state).
EARTH_RATE_RPS = 7.292115e-5
#: Below this GNSS speed the receiver's course is unreliable (held): direction unknown.
COG_RELIABLE_SPEED_MPS = 0.1
#: How many times its noise the antenna's smooth horizontal acceleration must be for the
#: velocity's EPOCH column (:meth:`EkfEngine._antenna_accel_ned`); below, it is white.
ACCEL_COLUMN_SNR = 3.0


class AntennaAccel(NamedTuple):
    """The antenna's acceleration at an epoch (:meth:`EkfEngine._antenna_accel_ned`)."""

    column: Array | None  # smooth part, m/s^2 NED, for the velocity's EPOCH column
    sigma_white_mps2: float  # 1-sigma of the rest per horizontal axis, taken as white


#: The EPOCH state's walk, s^2/s: on a free-running host the epochs are placed by the least
#: receive delay over the last ``DELAY_WINDOW_S``, which the clock's drift (50 ppm: 3 ms
#: over that window) and the serial line's scheduling move.
EPOCH_WALK_S2_PER_S = 0.003**2 / DELAY_WINDOW_S

#: The non-holonomic constraint is due ``nhc_interval_s`` after the last to within this, s
#: (a 10 Hz receiver's epochs arrive 0.1 s apart give or take the serial line's jitter).
NHC_SLACK_S = 0.01
#: A zero-rate update's span is fused this long (s) after it ends, the mean rate since its
#: start checked (:meth:`EkfEngine._zero_rate`): within the history (``history_s``), and
#: long enough for the check to see a turn of 0.15 deg/s.
ZERO_RATE_CHECK_S = 2.0
#: The stated roll/pitch 1-sigma is at least the filter's own latest horizontal tilt
#: correction, decaying over this long, s (:meth:`EkfEngine._inject`).
TILT_STEP_TAU_S = 1.0


@dataclass
class EkfCounters:
    """Rejected and special updates since start (for status and tests)."""

    position_rejected: int = 0
    velocity_rejected: int = 0
    heading_rejected: int = 0
    nonholonomic_rejected: int = 0
    zero_rate_rejected: int = 0  # at rest, a mean z rate beyond the gate: the vehicle turned
    late_epochs: int = 0  # epoch older than the INS history: dropped
    resets: int = 0  # position/velocity re-initialised from GNSS
    bias_changes: int = 0  # x/y biases re-opened: a change beyond their in-run model


class EkfEngine:
    """Loosely coupled GNSS/INS error-state EKF (ALGORITHMS.md 3) behind the Estimator protocol."""

    def __init__(
        self,
        config: EkfConfig | None = None,
        clock: EpochClock | None = None,
        noise: ImuNoiseMeter | None = None,
    ) -> None:
        """``clock``: the epoch clock to use (one that outlives the engine keeps what it learnt
        of the host clock across a restart), else a new one from ``config``; ``noise``: the
        same for the IMU's noise measured at rest (a restart on the move has no rest)."""
        cfg = config if config is not None else EkfConfig()
        self.cfg = cfg
        self.counters = EkfCounters()
        self._log = LogLimiter(log)
        self._corrections = CorrectionWindow("tilt")  # recent attitude corrections: a bias change?
        self._heading_corrections = CorrectionWindow("heading")  # the same for the z bias
        self._ba_walk = FoundWalk()  # the x/y accelerometer bias walk tilt changes showed
        # the bias walks the IMU's temperature drives (:meth:`temperature`)
        self._temp = TemperatureWalk(
            cfg.gyro_bias_tempco_dps_per_c,
            cfg.accel_bias_tempco_mg_per_c,
            cfg.bias_correlation_time_s,
        )
        self._hdt_doubt = HdtDoubt()  # an HDT the courses contradicted
        self._t_hdt_used_s = -math.inf  # the last epoch whose HDT the filter took
        # turned at rest beyond the z bias since the last course, rad, over refused spans, s
        self._rest_turn = (0.0, 0.0)
        self._pending_turn_rad = 0.0  # turned in the rest spans not checked yet
        self._t_course_s: float | None = None  # the last epoch with a course
        self.clock = clock or EpochClock.of(cfg)
        self._l_ant_b = np.array(cfg.antenna_lever_arm_m, dtype=float)
        self._l_ant_m = float(np.linalg.norm(self._l_ant_b))
        self._l_imu_b = np.array(cfg.imu_lever_arm_m, dtype=float)
        self._l_imu_m = float(np.linalg.norm(self._l_imu_b))
        self._l_imu_b_f = tuple(float(x) for x in self._l_imu_b)
        self._l_imu_ant_b = self._l_ant_b - self._l_imu_b  # antenna relative to the IMU
        self._l_imu_ant_m = float(np.linalg.norm(self._l_imu_ant_b))  # its length
        self._tuning: EkfTuning | None = None
        self._config_tuning: EkfTuning | None = None  # the tuning as configured
        # the gyro and accelerometer noise excess the filter's tuning has taken so far
        self._excess_taken = (1.0, 1.0)
        # (receive time, under stationary_speed_mps) of the last fix with a speed: a fix
        # without one (a receiver with no fix yet, a GGA alone) says nothing of the motion
        self._speed_seen: tuple[float, bool] | None = None
        # lost IMU samples were bridged by one held sample: the INS position and velocity then
        # carry the unknown motion of the gap (0.3 m/s in a 0.5 s gap while braking), not
        # what P says; the next fix resets them (as after an outage)
        self._imu_gaps_at_reset = 0
        self._q_c = np.zeros(N_STATES)
        self._ins: Strapdown | None = None
        self._p: Array | None = None  # error covariance (20, 20); None until heading is known
        self._chassis_pitch_rad = 0.0  # the chassis's pitch against its track (CHASSIS)
        self._epoch_err_s = 0.0  # the epochs' placement error on the host clock (EPOCH)
        # the receiver's position error (FIX states): estimate, white and wandering variance
        self._fix_err_ned_m = np.zeros(3)
        self._fix_var_white_m2 = np.zeros(3)
        self._fix_var_wander_m2 = np.zeros(3)
        self._hist: InsHistory | None = None
        self._held = HeldEpochs()  # epochs ahead of the IMU
        self._imu = ImuHealth(self.cfg.imu_fault_s)  # timing, alarm, saturation, FAULT
        self._frame: LocalFrame | None = None  # local NED around the first position used
        self._t_s: float | None = None
        # alignment: mean specific force and rate over the current quiet window
        self._align_first_s: float | None = None
        self._win_t0_s: float | None = None
        self._win_sum = np.zeros(6)
        self._win_n = 0
        # a moving window's specific force in its first body frame, summed, and the rotation
        # from the current body frame to that one (the gyro's)
        self._win_f0 = [0.0, 0.0, 0.0]
        self._win_rot9: Mat9 = IDENTITY9
        # (t, sums, n, f0 sums) to level with
        self._win_marks: deque[tuple[float, Array, int, list[float]]] = deque()
        self._still_since_s: float | None = None  # when the fixes last began to say still
        self._align_w_lp: Float3 | None = None  # body rate low-passed (RATE_LP_TAU_S): quiet?
        self._noise = noise or ImuNoiseMeter()  # the IMU's white noise at rest, vibration too
        self._imu_dt_s = 0.0  # the IMU's sample period, s
        self._win_at_rest = True  # the window quiet (low-passed rate) and GNSS speed ~0
        self._t_levelled_s = 0.0  # end of the last window that set roll/pitch
        self._rest_bias_s = 0.0  # rest duration behind the gyro bias estimate, 0 if none
        self._win_motion = WindowMotion(self.cfg.gnss_vel_sigma_mps, self.cfg.stationary_speed_mps)
        self._vel_noise = VelocityNoise(self.cfg.gnss_vel_sigma_mps)  # from the innovations
        self._t_vel_noise_s: float | None = None  # the last epoch that fed it (for the rest feed)
        self._vel_innovation: tuple[float, float, float] | None = None  # t, z_n, z_e
        self._pos_noise = PositionNoise()  # the fixes' white noise, from the innovations
        #: quality, (t, z_n, z_e) of the last position innovation
        self._pos_innovation: tuple[int, tuple[float, float, float]] | None = None
        self._sigma_level_rad = 0.0  # tilt error of the window's own motion (levelling.py)
        # GNSS bookkeeping
        self._last_fix: GnssFix | None = None
        self._last_quality: FixQuality | None = None
        #: epoch time of the last GNSS velocity the filter's gate rejected: a drift of the
        #: receiver's positions off its velocity with none rejected over the drift window is
        #: the positions'; with some, the velocity's
        self._t_velocity_rejected_s: float | None = None
        self._t_accepted_rx_s: float | None = None  # receive time of the last accepted fix
        self._t_pos_epoch_s: float | None = None  # epoch of the last accepted position
        self._t_pos_rx_s: float | None = None  # receive time of the last fix with a position
        self._track = GnssTrack()  # the receiver's own track: glitch or filter off?
        self._courses = CourseAlignment(self.cfg.heading_gate_deg * DEG_TO_RAD)  # 1st heading
        self._t_nhc_s = -math.inf
        # the IMU path steps the covariance after this much time (s) without a step
        self._step_s = self.cfg.covariance_period_s
        # motion flags and IMU health
        self._reversing = False
        self._stationary = False
        # a warm start (:meth:`seed`): the biases' prior and its variance per axis (the gyro's
        # combined with the rest mean when there is one); None: the turn-on sigmas
        self._seed: LearnedState | None = None
        self._hint: HeadingHint | None = None  # the heading the last engine had, till aligned
        self._seed_var_g = np.zeros(3)
        self._rest_mean_g_rps: list[float] = []  # mean rate of the last window at rest
        # last epoch at rest before alignment: its time and the INS velocity then
        self._rest_epoch: tuple[float, Array] | None = None
        # forward (True) or reversing since that rest, once its velocity change told
        self._direction_since_rest: bool | None = None
        # epochs at rest since the last that was not, not yet zero-rate updated from, with
        # the z gyro bias estimate the rates before them were corrected with, rad/s
        self._rest_epochs: deque[tuple[float, float]] = deque()
        self._tilt_step: tuple[float, float] = (0.0, 0.0)  # latest tilt correction rad, at s

    # ======================================================================== prediction

    def imu(self, sample: ImuSample) -> None:
        """Propagate with one IMU sample (body frame, bias not yet removed)."""
        t = sample.t
        dt = self._imu.accept(sample)
        if dt is None:
            return
        w, f = sample.w_ib_b, sample.f_ib_b
        if self._tuning is None:
            self._tuning = self._config_tuning = EkfTuning.from_config(self.cfg, dt)
            self._imu_dt_s = dt
            self._q_c = process_noise_psd(self._tuning)
            self._hist = InsHistory(max(2, math.ceil(self.cfg.history_s / dt)))
        self._t_s = t
        if self._p is None:
            if dt > MAX_IMU_STEP_S and not self._win_at_rest:
                # a moving window's rotation across the gap is a guess (_bridge): a new
                # window. A rest window's mean (per sample) loses only the samples: a reader
                # losing 0.1 s in every 0.16 s (a starved host) had restarted it at every
                # gap and the engine never aligned.
                self._win_t0_s = None
            self._align_tilt(t, w, f, dt)
        ins = self._ins
        if ins is None:
            if self._hint is not None:
                self._hint.turn(w[2], dt)
            return
        if self._p is not None:
            still = self._gnss_says_still(t)
            if still or self._still_since_s is not None:
                self._measure_noise(t, w, f, still)  # a stop after the start
        ins.propagate(w, f, dt)
        if self._imu.timing.lost_s:
            self._bridge()
        assert self._hist is not None
        self._hist.append((t, *ins.p_ned_m, *ins.v_ned_mps, *ins.c_bn9, *ins.w_b_rps))
        if self._p is not None and ins.sum_dt_s >= self._step_s:
            self._predict()
            self._step_s = self.cfg.nhc_interval_s  # no epoch: step with the constraint
            if t - self._t_nhc_s >= self.cfg.nhc_interval_s - NHC_SLACK_S:
                self._fuse_nonholonomic(t)
        if self._held:  # (no generator per sample when none waits)
            for t_e, fix in self._held.due(t):
                self._fuse_epoch(fix, t_e)

    def _gnss_says_still(self, t: float) -> bool:
        """The vehicle stands at ``t`` as the last fix with a speed said, if within
        :data:`FIX_STILL_HOLD_S`. Before any: parked at power-up (after a restart as the old
        engine saw it) for the first levelling only; after it the motion is unknown (50 s
        without a fix from power-up, the vehicle driving off at 30 s: re-levelled on the
        drive, roll 3 deg off with 0.6 stated)."""
        seen = self._speed_seen
        if seen is None:
            return not self._win_motion.moving_before and self._ins is None
        t_fix, still = seen
        return still and t - t_fix <= FIX_STILL_HOLD_S

    def _measure_noise(self, t: float, w: Float3, f: Float3, still: bool) -> tuple[bool, float]:
        """Feed the noise meter with the sample at ``t`` where the vehicle is ``still`` (GNSS)
        and quiet (the body rate low-passed, :data:`RATE_LP_TAU_S`, under
        ``align_quiet_rate_dps``) since :data:`ALIGN_SETTLE_S`; else the meter's rest ends.
        Returns (quiet, s still). Before the filter runs and at every stop after: the
        process noise takes what it shows (:meth:`_noise_as_measured`)."""
        lp = self._align_w_lp or w
        dt = self._imu_dt_s
        a = dt / (RATE_LP_TAU_S + dt)
        lp = (lp[0] + a * (w[0] - lp[0]), lp[1] + a * (w[1] - lp[1]), lp[2] + a * (w[2] - lp[2]))
        self._align_w_lp = lp
        quiet = math.hypot(*lp) < self.cfg.align_quiet_rate_dps * DEG_TO_RAD
        if not still:
            self._still_since_s = None
        elif self._still_since_s is None:
            self._still_since_s = t
        still_s = 0.0 if self._still_since_s is None else t - self._still_since_s
        if quiet and still and still_s >= ALIGN_SETTLE_S:
            self._noise.add(w, f, dt)
        else:
            self._noise.restart()
        return quiet, still_s

    def _bridge(self) -> None:
        """The last sample closed a step that bridges lost samples (:class:`ImuTiming`):
        the attitude and velocity it held over them are uncertain by what
        :func:`bridged_sigma` says, body axes, which P takes in NED (covariance predicted to
        now first); before the filter runs, the levelled tilt's sigma takes it until the
        next levelling. With the white noise of the step's length alone, 0.8 s gaps left the
        tilt 3 deg off with 0.6 stated; levelled, not yet filtering, 0.9 deg off with 0.05
        stated."""
        assert self._ins is not None
        gap = self._imu.timing.bridged()
        if self._p is None:
            r = gap.rotation_rad
            self._sigma_level_rad = math.hypot(self._sigma_level_rad, max(r[0], r[1]))
            return
        self._predict()
        c = self._ins.c_bn
        self._p[ATT, ATT] += c @ np.diag(np.square(gap.rotation_rad)) @ c.T
        self._p[VEL, VEL] += c @ np.diag(np.square(gap.velocity_mps)) @ c.T

    def _predict(self) -> None:
        """Covariance prediction over the IMU samples since the last one."""
        assert self._ins is not None and self._p is not None
        t_s, dv_f, c_dt = self._ins.take_interval()
        if t_s > 0.0:
            decay = math.exp(-t_s / self.cfg.gnss_error_correlation_s)
            self._fix_err_ned_m *= decay
            q_c = self._q_c
            walk = 0.0 if self._t_s is None else self._ba_walk.psd_at(self._t_s)
            walk_g, walk_a = self._temp.gyro_rps2_per_s, self._temp.accel_mps4_per_s
            if walk or walk_g or walk_a:
                q_c = q_c.copy()
                q_c[BA.start : BA.start + 2] += walk
                q_c[BA] += walk_a
                q_c[BG] += walk_g
            predict(self._p, transition_matrix(t_s, dv_f, c_dt, decay), q_c, t_s)

    def _align_tilt(self, t: float, w: Float3, f: Float3, dt: float) -> None:
        """Roll/pitch from the mean specific force of a quiet window; gyro bias if at rest.

        Quiet = |w| low-passed (:data:`RATE_LP_TAU_S`) below ``align_quiet_rate_dps`` and, once
        GNSS speaks, speed below ``stationary_speed_mps``. The window grows while quiet and
        re-levels the INS every ``align_tilt_time_s`` until the heading is known, so alignment
        uses the last rest before the vehicle drives off. At rest the mean rate is the gyro bias
        plus Earth rate (at most 0.004 deg/s, left in its 1-sigma). If never quiet for
        ``ALIGN_TIMEOUT_S``, a moving window levels the INS (no gyro bias) and the filter
        finishes the job. A rest window starts :data:`ALIGN_SETTLE_S` after GNSS says still and
        levels with its samples up to :data:`ALIGN_LAG_S` ago: the stop before it and the
        pull-away after it, which GNSS reports late, are not in the mean. A moving window's
        attitude changes (a rough slope rocks the vehicle a degree within a second): its
        specific force is carried into its first body frame by the gyro, and its tilt from there
        to now.
        """
        if self._align_first_s is None:
            self._align_first_s = t
        still = self._gnss_says_still(t)
        # the rate low-passed: one sample's gyro noise (0.5 deg/s an axis) and engine
        # vibration passed the threshold sample by sample, so a parked vehicle on a rough
        # engine never had a quiet window (3x the simulator's vibration: pitch 5 deg off
        # open loop after 23 s parked, the heading then aligned 180 deg off)
        quiet, still_s = self._measure_noise(t, w, f, still)
        if not (quiet and still):
            if self._ins is not None or t - self._align_first_s < ALIGN_TIMEOUT_S:
                self._win_t0_s = None
                return
            self._win_at_rest = False
        elif self._win_t0_s is None and still_s < ALIGN_SETTLE_S:
            return
        if self._win_t0_s is None:
            self._win_t0_s = t
            self._win_sum[:] = 0.0
            self._win_n = 0
            self._win_marks.clear()
            self._win_at_rest = True
            self._win_motion.restart()
            self._win_f0 = [0.0, 0.0, 0.0]
            self._win_rot9 = IDENTITY9
        self._win_sum += (*f, *w)
        self._win_n += 1
        r, f0 = self._win_rot9, self._win_f0
        f0[0] += r[0] * f[0] + r[1] * f[1] + r[2] * f[2]
        f0[1] += r[3] * f[0] + r[4] * f[1] + r[5] * f[2]
        f0[2] += r[6] * f[0] + r[7] * f[1] + r[8] * f[2]
        b = self._seed.bias_g_rps if self._seed is not None else (0.0, 0.0, 0.0)
        self._win_rot9 = dcm_mul(
            r, exp_so3_2nd((w[0] - b[0]) * dt, (w[1] - b[1]) * dt, (w[2] - b[2]) * dt)
        )
        marks = self._win_marks
        if not marks or t - marks[-1][0] >= ALIGN_MARK_S:
            marks.append((t, self._win_sum.copy(), self._win_n, f0.copy()))
        while len(marks) > 1 and marks[1][0] <= t - ALIGN_LAG_S:
            marks.popleft()  # the first left is the newest at least ALIGN_LAG_S old
        t_end, win_sum, win_n, f0_sum = marks[0]
        span = t_end - self._win_t0_s
        if (
            t_end > t - ALIGN_LAG_S
            or span < self.cfg.align_tilt_time_s
            or t - self._t_levelled_s < self.cfg.align_tilt_time_s
        ):
            return
        mean = win_sum / win_n
        if self._win_at_rest:  # (the same mean as in the first frame, without the gyro's drift)
            roll, pitch = roll_pitch_from_specific_force(mean[:3])
        else:
            roll0, pitch0 = roll_pitch_from_specific_force([x / win_n for x in f0_sum])
            # (the rotation before this sample's: the INS propagates with it next)
            roll, pitch, _ = rpy_from_mat9(dcm_mul(to_mat9(dcm_from_rpy(roll0, pitch0, 0.0)), r))
        yaw = 0.0 if self._ins is None else rpy_from_dcm(self._ins.c_bn)[2]
        created = self._ins is None
        if self._ins is None:
            self._ins = Strapdown(dcm_from_rpy(roll, pitch, yaw))
        else:
            self._ins.c_bn9 = to_mat9(dcm_from_rpy(roll, pitch, yaw))
        if self._win_at_rest:
            self._ins.bias_g_rps = [float(x) for x in mean[3:]]
            self._rest_bias_s = span
            self._rest_mean_g_rps = self._ins.bias_g_rps
        # the window's motion, and the noise of its mean specific force (vibration: 0.08 deg
        # for a 1 s window)
        assert self._tuning is not None
        # (of the samples the window has: those lost in its gaps do not average)
        sampled_s = min(span, win_n * self._imu_dt_s)
        noise = math.sqrt(self._tuning.q_accel_m2_per_s3 / sampled_s) / GRAVITY_MPS2
        self._sigma_level_rad = math.hypot(self._win_motion.tilt_sigma_rad(), noise)
        if not self._win_at_rest:  # and the gyro bias over the window's rotation
            drift = self._levelled_gyro_bias_sigma_rps() * (t - self._win_t0_s)
            self._sigma_level_rad = math.hypot(self._sigma_level_rad, drift)
        self._t_levelled_s = t
        if self._seed is not None:
            self._apply_seed(self._seed)
        if created:
            # The rate low-pass (lever arms, rate of turn) starts from the rate of the moment,
            # not from rest: levelled in an 11 deg/s turn it sent 1.7 deg/s while ALIGNING. A
            # moving window's mean rate ended 0.5 s ago: entering a turn it sent 7.5 deg/s
            # off; the mean since the mark before the last (50-100 ms) is the rate now. At
            # rest without a seed the window's mean is the bias: exactly 0, as before.
            w_now = mean[3:]
            if not self._win_at_rest and len(marks) > 1:
                _, sums_then, n_then = marks[-2][:3]
                w_now = (self._win_sum[3:] - sums_then[3:]) / (self._win_n - n_then)
            bg = self._ins.bias_g_rps
            self._ins.w_b_lp_rps = (
                float(w_now[0]) - bg[0],
                float(w_now[1]) - bg[1],
                float(w_now[2]) - bg[2],
            )

    # ======================================================================= warm start

    def moving_before(self) -> None:
        """The vehicle was moving when this engine took over: see the protocol (and no rest
        window without a fix that says the vehicle stands)."""
        self._win_motion.moving_before = True

    def heading_before(self, hint: HeadingHint) -> None:
        """The heading the engine this one replaces had: see the protocol."""
        self._hint = hint

    def seed(self, learned: LearnedState, f_rest_b_mps2: Float3 | None = None) -> bool:
        """Start from learned biases (a warm start, or the engine this one replaces after an
        IMU gap): accepted until the filter starts (P exists once the heading is known).

        The INS takes the biases; the tilt levelled so far takes the accelerometer bias out
        (:func:`levelling_correction`), and every later levelling too (it levels again on
        every quiet window until then, so ``f_rest_b_mps2`` adds nothing); a gyro mean at rest
        is combined with the seed by their variances. At heading alignment P's bias blocks
        start from the seed's sigmas (not the turn-on ones), and the tilt's share of the
        accelerometer bias error with them.
        """
        if self._p is not None or self._seed is not None or not learned.is_valid():
            return False
        self._seed = learned
        if self._ins is not None:
            self._apply_seed(learned)
        return True

    def _apply_seed(self, s: LearnedState) -> None:
        """The seed on an INS just levelled from the mean specific force (bias 0 in it)."""
        ins = self._ins
        assert ins is not None
        ins.rotate(exp_so3(levelling_correction(ins.c_bn9, s.bias_a_mps2)))
        ins.bias_a_mps2 = [float(x) for x in s.bias_a_mps2]
        var_s = np.array(s.sigma_g_rps) ** 2
        bg_s = np.array(s.bias_g_rps)
        if self._rest_bias_s > 0.0:  # a mean rate at rest: combine the two
            assert self._tuning is not None
            var_r = self._tuning.q_gyro_rad2_per_s / self._rest_bias_s + EARTH_RATE_RPS**2
            bg = bg_s + var_s / (var_s + var_r) * (np.array(self._rest_mean_g_rps) - bg_s)
            self._seed_var_g = var_s * var_r / (var_s + var_r)
        else:
            bg, self._seed_var_g = bg_s, var_s
        ins.bias_g_rps = [float(x) for x in bg]

    def learned_state(self) -> LearnedState | None:
        """Bias estimates and their 1-sigma from P; before P, the seed (with the rest mean
        in the gyro's), or None."""
        ins, p = self._ins, self._p
        if p is None:
            s = self._seed
            if s is None or ins is None:
                return s
            sg = np.sqrt(self._seed_var_g)
            return LearnedState(
                bias_g_rps=(ins.bias_g_rps[0], ins.bias_g_rps[1], ins.bias_g_rps[2]),
                sigma_g_rps=(float(sg[0]), float(sg[1]), float(sg[2])),
                bias_a_mps2=s.bias_a_mps2,
                sigma_a_mps2=s.sigma_a_mps2,
            )
        assert ins is not None
        d = np.sqrt(np.diag(p))
        return LearnedState(
            bias_g_rps=(ins.bias_g_rps[0], ins.bias_g_rps[1], ins.bias_g_rps[2]),
            sigma_g_rps=(float(d[BG][0]), float(d[BG][1]), float(d[BG][2])),
            bias_a_mps2=(ins.bias_a_mps2[0], ins.bias_a_mps2[1], ins.bias_a_mps2[2]),
            sigma_a_mps2=(float(d[BA][0]), float(d[BA][1]), float(d[BA][2])),
        )

    # ======================================================================= corrections

    def temperature(self, t_s: float, temp_c: float) -> None:
        """The IMU's temperature at ``t_s`` (IMU_AUX, 1 Hz): while it moves, the biases
        walk faster (:mod:`gateway.estimation.temperature`), and so do P's."""
        self._temp.add(t_s, temp_c)

    def gnss(self, fix: GnssFix) -> None:
        """Correct with one GNSS epoch; it may arrive after IMU samples of later time.

        An epoch whose time is ahead of the last IMU sample waits until the IMU covers it.
        """
        self._last_fix = fix
        if fix.sog_mps is not None and fix.measures:
            self._speed_seen = (fix.t, fix.sog_mps < self.cfg.stationary_speed_mps)
        if self._p is None:  # (before a window too: the velocity at its start)
            self._win_motion.add(fix)
        if self._ins is None or not fix.measures:
            return
        t_e = self.clock.epoch_time(fix)
        if t_e is None:
            return
        t_e -= self._epoch_err_s  # placed late by the EPOCH estimate (a free-running host)
        if not self._held.hold(t_e, fix, self._t_s):
            self._fuse_epoch(fix, t_e)

    def _fuse_epoch(self, fix: GnssFix, t_e: float) -> None:
        """Align, reset or fuse one epoch against the INS state at its epoch time ``t_e``."""
        assert self._hist is not None
        row = self._hist.at(t_e)
        if row is None:
            if self._hist.full:  # not an epoch from before the engine started
                self.counters.late_epochs += 1
                self._log.warning(t_e, late_epoch_text(t_e, self._hist.oldest_s()), "late")
            return
        if self._p is None:
            if fix.sog_mps is not None and fix.sog_mps < self.cfg.stationary_speed_mps:
                self._rest_epoch = (t_e, row[ROW_V].copy())
                self._direction_since_rest = None
                self._measure_velocity_noise_at_rest(fix, t_e)
            self._align_heading(fix, t_e, row)
            return
        if self._hist.spacing(t_e) > MAX_IMU_STEP_S:
            return  # within an IMU gap: the history there is a straight line, no state
        self._predict()
        self._step_s = self.cfg.covariance_period_s  # the next epoch steps it, if in time
        self._track_epoch_error()
        p = self._p
        sig_pos = self._position_sigma(fix)
        if sig_pos is not None:
            self._set_fix_error_model(fix, sig_pos, restart=self._last_quality != fix.quality)
        self._last_quality = fix.quality
        p_ant = self._antenna_ned(fix) if sig_pos is not None else None
        if p_ant is not None and sig_pos is not None:
            self._t_pos_rx_s = fix.t
            p_ne = (float(p_ant[0]), float(p_ant[1]))
            self._track.add(
                t_e, p_ne, fix.vel_ne_mps, fix.horizontal_sigma_m, float(p_ant[2]),
                float(sig_pos[2]), int(fix.quality),
            )  # fmt: skip
        since = t_e - (self._t_pos_epoch_s if self._t_pos_epoch_s is not None else t_e)
        if sig_pos is not None and (
            (since > self.cfg.reset_outage_s and self._track.rejecting_since_s is None)
            or self._imu.timing.gaps != self._imu_gaps_at_reset
            or self._track.reset_due(t_e, self.cfg.reset_rejections, self.cfg.position_reset_s)
        ):
            self._reset_from_fix(fix, t_e, row)
            return
        c_e = row[ROW_C].reshape(3, 3)
        w_e, sig_lever = self._lever_rate(t_e, self._l_imu_ant_m)
        measurements: list[Measurement] = []
        m_pos: Measurement | None = None
        if sig_pos is not None and p_ant is not None:
            if self._track.drifting and not self._velocity_suspect(t_e):
                self._reject_position(t_e, self._track.drift_text(t_e))
            elif self._track.away:
                self._reject_position(t_e, self._track.away_text(t_e))
            else:
                m_pos = self._fuse_fix_position(row, c_e, w_e, p_ant, self._epoch_moves(fix))
                measurements.append(m_pos)
                self._measure_position_noise(fix, t_e, m_pos, sig_pos)
        if m_pos is None:  # (no position measured: the next innovation pairs with none)
            self._pos_innovation = None
        vel = self._gnss_velocity(fix)
        course = None
        if vel is not None:
            a_ant = self._antenna_accel_ned(t_e, c_e, w_e) if self._epoch_moves(fix) else None
            a_col, sigma_v = None, math.hypot(vel[1], sig_lever)
            if a_ant is not None:  # its smooth part in the EPOCH column, the rest white
                a_col = a_ant.column
                sigma_v = math.hypot(sigma_v, a_ant.sigma_white_mps2 * self._epoch_sigma_s())
            m_vel = fuse_velocity(row[ROW_V], c_e, w_e, self._l_imu_ant_b, vel[0], sigma_v, a_col)
            measurements.append(m_vel)
            self._measure_velocity_noise(fix, t_e, m_vel)
            sigma_course = math.hypot(vel[1], self._velocity_timing_sigma_mps(a_ant))
            course = self._course_residual(fix, t_e, row, w_e, sigma_course)
            if course is not None:
                self._fold_rest_turn()
        at_rest = fix.sog_mps is not None and fix.sog_mps < self.cfg.stationary_speed_mps
        if at_rest:
            self._noise_as_measured()
        if at_rest and not self._rest_epochs:  # (the last epoch was not at rest)
            self._forget_heading_corrections()
        if fix.heading_rad is not None:
            sigma_hdt = self.cfg.hdt_sigma_deg * DEG_TO_RAD
            if self._hdt_doubt.admits():
                measurements.append(fuse_heading(c_e, fix.heading_rad, sigma_hdt))
            elif course is not None:  # the HDT less the course, for the doubt's evidence
                off = wrap_pi(fix.heading_rad - math.atan2(c_e[1, 0], c_e[0, 0]) - course[0])
                self._hdt_doubt.add_course(
                    t_e, off, math.hypot(course[1], sigma_hdt), course[2], course[3]
                )
        measurements += self._zero_rate(fix, t_e)
        dx = np.zeros(N_STATES)
        accepted = False
        for m in measurements:
            ok = correct(p, dx, m, self.cfg.gate_sigma).accepted
            accepted |= ok
            if m.name == "position":
                if ok:
                    self._t_pos_epoch_s = t_e
                    self._track.accepted()
                else:
                    self._reject_position(
                        t_e,
                        f"GNSS position glitch at t={t_e:.3f}: beyond the filter's "
                        f"{self.cfg.gate_sigma:g}-sigma gate (quality {int(fix.quality)}); "
                        "position not used",
                    )
            elif not ok and m.name == "velocity":
                self.counters.velocity_rejected += 1
                self._t_velocity_rejected_s = t_e
            elif m.name == "velocity" and course is not None:
                self._heading_corrections.add_course(t_e, *course)
            elif not ok and m.name == "zero rate":
                self.counters.zero_rate_rejected += 1
            elif not ok:
                self.counters.heading_rejected += 1
            elif m.name == "heading":
                self._t_hdt_used_s = t_e
        if accepted:
            self._t_accepted_rx_s = fix.t
            self._inject(dx, t_e)
            self._watch_corrections(t_e)
        t = self._t_s
        assert t is not None  # (the history has rows)
        if t - self._t_nhc_s >= self.cfg.nhc_interval_s - NHC_SLACK_S:
            self._fuse_nonholonomic(t)  # 50 ms before now, however late the epoch

    def _zero_rate(self, fix: GnssFix, t_e: float) -> list[Measurement]:
        """Zero-rate updates (:func:`fuse_zero_rate`) at rest, one per span between two
        epochs whose speeds over ground were under ``stationary_speed_mps``, each taken
        ``ZERO_RATE_CHECK_S`` after its end: if the mean rate from its start to now is what
        the bias leaves (within ``gate_sigma`` of P's z-bias sigma and the noise's), the
        vehicle did not turn over it. A tractor inching round a full-lock turn is under that
        speed at 0.5 deg/s, which one epoch's mean (0.1 deg/s of noise) could not tell from
        a bias: learnt as one for the 1.5 s its first check took, it left the heading 0.5
        deg off 30 s later. A refused span is a turn or a z bias step, which a stop cannot
        tell apart: :meth:`_turn_or_step`.

        The history's rates were corrected with the z bias estimate of their time; the
        spans are fused seconds later, and what the bias has learnt since (the spans before
        this one) is taken off their mean. Without that, each span of a stop found the
        same rate again: after the bias re-opened (0.15 deg/s 1-sigma), a stop's spans
        took a +0.14 deg/s error as +0.37 and moved the heading 1.6 deg past the truth."""
        rest = self._rest_epochs
        if fix.sog_mps is None:
            # a position alone says nothing of the motion: the rest goes on (a receiver
            # sending GGA at 10 Hz and RMC at 1 Hz cut every stop into nothing: no zero-rate
            # update, the heading 8.6 deg off after 5 min parked, DEGRADED)
            return []
        self._pending_turn_rad = 0.0
        if fix.sog_mps >= self.cfg.stationary_speed_mps:
            rest.clear()
            return []
        hist, tun, p, ins = self._hist, self._tuning, self._p, self._ins
        assert hist is not None and tun is not None and p is not None and ins is not None
        b_z = ins.bias_g_rps[2]
        rest.append((t_e, b_z))
        out: list[Measurement] = []
        w_check_z = None
        while len(rest) > 1 and rest[1][0] <= t_e - ZERO_RATE_CHECK_S:
            (a, learnt_a), (b, learnt_b) = rest.popleft(), rest[0]
            if a < hist.oldest_s():
                continue
            w_check = hist.mean_rate(0.5 * (a + t_e), 0.5 * (t_e - a))
            w_check[2] -= b_z - 0.5 * (learnt_a + b_z)  # (the estimate's mean over the check)
            w_check_z = float(w_check[2])
            var = p[BG.start + 2, BG.start + 2] + tun.q_gyro_rad2_per_s / (t_e - a)
            if (
                float(np.linalg.norm(w_check)) >= self.cfg.stationary_rate_dps * DEG_TO_RAD
                or float(w_check[2]) ** 2 > self.cfg.gate_sigma**2 * var
            ):
                self.counters.zero_rate_rejected += 1
                self._turn_or_step(abs(float(w_check[2])), b - a)
                continue
            row = hist.at(b)
            assert row is not None  # (within the history, as a is)
            w_z = float(hist.mean_rate(0.5 * (a + b), 0.5 * (b - a))[2]) - (b_z - learnt_b)
            out.append(fuse_zero_rate(row[ROW_C].reshape(3, 3), w_z, b - a, tun.q_gyro_rad2_per_s))
        # the spans not checked yet: what they turned so far, at the last check's mean rate
        # (over them and one span more), or in a stop's first seconds at their own
        a, learnt_a = rest[0]
        if w_check_z is None and t_e > a >= hist.oldest_s():
            w_check_z = float(hist.mean_rate(0.5 * (a + t_e), 0.5 * (t_e - a))[2])
            w_check_z -= b_z - learnt_a
        if w_check_z is not None:
            self._pending_turn_rad = abs(w_check_z) * (t_e - a)
        return out

    def _turn_or_step(self, rate_rps: float, span_s: float) -> None:
        """At rest the gyro turned at ``rate_rps`` beyond what the z bias explains over
        ``span_s``: the vehicle turning on the spot, or the bias stepped and the heading
        drifts. The stated heading takes the turn (the spans of one stop add up, as a
        step's drift does), and the next course puts it, and the rate as a z bias, into
        P (:meth:`_fold_rest_turn`). A step of -0.2 deg/s as `steep-turns` seed 554
        stopped: every span refused, the heading drifted 0.2 deg/s through two stops and
        a short reverse, NAVIGATING up to 3 deg off for 12 s (582 frames) until courses in a
        turn showed it. The cost is a DEGRADED heading while a vehicle creeps round a turn
        under ``stationary_speed_mps`` (or stops in one), where nothing steers on it. Not
        into P at rest: there it let the zero velocity a creeping vehicle's fixes give
        below ``COG_RELIABLE_SPEED_MPS`` turn the heading (2.7 deg off after 30 s creeping
        round a full-lock turn)."""
        self._rest_turn = (self._rest_turn[0] + rate_rps * span_s, self._rest_turn[1] + span_s)

    def _fold_rest_turn(self) -> None:
        """A course again: what the stops' refused spans turned goes into P's heading, and
        their mean rate into P's z bias about the vertical (a step, if it was one, is then
        learnt from the courses; a turn on the spot leaves the bias where it was)."""
        turn, span = self._rest_turn
        if turn > 0.0:
            sigma = self._p_heading_sigma_rad()
            self._reopen_vertical(turn / span, math.sqrt(turn * (2.0 * sigma + turn)))
            self._rest_turn = (0.0, 0.0)

    def _course_residual(
        self, fix: GnssFix, t_e: float, row: Array, w_e: Array, sigma_v_mps: float
    ) -> tuple[float, float, float, float] | None:
        """The epoch's course of the reference point less the heading at ``row`` (before the
        epoch's correction; turned round when reversing), rad, its 1-sigma (the velocity's
        ``sigma_v_mps`` and the antenna lever arm's gyro noise, over the speed), the yaw rate
        ``w_e`` makes, rad/s, and the time since the last course, s, from
        ``cog_min_speed_mps``: the heading window's evidence
        (:meth:`CorrectionWindow.add_course`).

        The reference point's velocity is the antenna's less the whole lever-arm velocity
        C (w x l) in the heading held: a 3 m mast pitching on washboard ground (4 cm bumps
        every 1.5-4 m, 90-120 deg/s) moved the antenna backwards at 2 m/s while the
        vehicle drove forward at 3, and the antenna's course, taken as the body's x axis
        less only the lateral part (:func:`heading_from_antenna_course`, for an unknown
        heading), was 130-170 deg off: 11 % of the courses beyond 3 sigma, a z bias change
        found every 15 s (custom `field` seed 634, the EKF)."""
        vel = fix.vel_ne_mps
        if vel is None:
            return None
        c = to_mat9(row[ROW_C].reshape(3, 3))
        u_n, u_e, _ = lever_arm_velocity_ned(c, w_e, self._l_ant_b)
        v_n, v_e = vel[0] - u_n, vel[1] - u_e
        speed = math.hypot(v_n, v_e)
        if speed < self.cfg.cog_min_speed_mps:
            return None
        forward = along_body_x(float(row[ROW_V][0]), float(row[ROW_V][1]), c) >= 0.0
        course = math.atan2(v_e, v_n) + (0.0 if forward else math.pi)
        sig_lever = centred_rate_velocity_sigma_mps(self._arw(), self._l_ant_m)
        yaw_rate = c[6] * float(w_e[0]) + c[7] * float(w_e[1]) + c[8] * float(w_e[2])
        last, self._t_course_s = self._t_course_s, t_e
        return (
            wrap_pi(course - math.atan2(c[3], c[0])),
            math.hypot(sigma_v_mps, sig_lever) / speed,
            yaw_rate,
            0.0 if last is None else t_e - last,
        )

    def _lever_rate(self, t_e: float, lever_m: float) -> tuple[Array, float]:
        """Body rate at ``t_e`` for a lever-arm velocity, and that velocity's 1-sigma over a
        lever arm of ``lever_m``.

        From the history's means about ``t_e`` (:func:`centred_rate`: no lag, no loss of a
        rocking mast's rate; an epoch waits for the samples after it, :class:`HeldEpochs`);
        its gyro noise over the lever arm (:func:`centred_rate_velocity_sigma_mps`) is added
        to the velocity's sigma.
        """
        assert self._hist is not None and self._tuning is not None
        hist = self._hist
        arw = math.sqrt(self._tuning.q_gyro_rad2_per_s)
        w_e = np.array(centred_rate(lambda r: hist.mean_rate(t_e, r)))
        return w_e, centred_rate_velocity_sigma_mps(arw, lever_m)

    def _fuse_nonholonomic(self, t: float) -> None:
        """Zero lateral/vertical velocity of the reference point, at the state of
        :data:`LEVER_RATE_HALF_WIDTH_S` before ``t`` (now).

        The reference point's lever-arm velocity w x l takes the rate centred on that instant
        (:func:`centred_rate`, as the antenna's does), its gyro noise over the lever arm in
        the constraint's sigma. A rate from the past lags: the outputs' low-pass (50 ms)
        put up to 5 cm/s into the constraint on rough ground, which took it for pitch
        (steep-turns seed 61 of rough-slope: 0.3 deg off with 0.06 stated), and the mean of
        the last 20 ms, 12-15 ms behind, still read a rocking body's lateral lever-arm
        velocity, in phase with the roll, as vertical: a mean pitch error (+/-2 deg of roll
        at 2 Hz with the IMU 1 m up: +0.069 deg at 102.4 Hz, +0.052 at 204.8; centred,
        +0.036 and +0.032).
        """
        hist = self._hist
        assert self._p is not None and hist is not None
        self._t_nhc_s = t
        t_c = t - LEVER_RATE_HALF_WIDTH_S
        row = hist.at(t_c)
        if row is None or hist.spacing(t_c) > MAX_IMU_STEP_S:
            return  # the history does not reach back, or a gap: no state there
        w_c, sigma_lever = self._lever_rate(t_c, self._l_imu_m)
        m = fuse_nonholonomic(
            row[ROW_V],
            row[ROW_C].reshape(3, 3),
            w_c,
            -self._l_imu_b,
            math.hypot(self.cfg.nhc_sigma_mps, sigma_lever),
            self._chassis_pitch_rad,
        )
        dx = np.zeros(N_STATES)
        if correct(self._p, dx, m, self.cfg.gate_sigma).accepted:
            self._inject(dx, t_c)
        else:
            self.counters.nonholonomic_rejected += 1
        self._update_motion_flags()

    def _inject(self, dx: Array, t_e: float) -> None:
        """Feed the error estimate of time ``t_e`` back into the INS and its history; the
        error state is then 0.

        A velocity error at t_e has moved the position by dv (t - t_e) since: the current
        state and the later history rows take it (first order of the transition over the
        age). Without it, epochs that arrive seconds late (a loaded host) corrected the
        position by dp only, and the next epoch, compared with the shifted history, found the
        same error again: 8 m of error with epochs 4 s late in 2 s bursts, 0.x m with it.
        """
        assert self._ins is not None and self._hist is not None and self._t_s is not None
        p = self._p
        assert p is not None
        var_bg = max(p.item(BG.start, BG.start), p.item(BG.start + 1, BG.start + 1))
        self._corrections.add(
            t_e, float(dx[6]), float(dx[7]), self._p_tilt_sigma_rad(), math.sqrt(var_bg)
        )
        h_n, h_e = self._heading_weights()
        d_psi = h_n * float(dx[6]) + h_e * float(dx[7]) + float(dx[8])
        self._heading_corrections.add(
            t_e, d_psi, 0.0, self._p_heading_sigma_rad(), self._vertical_bias_sigma_rps()
        )
        rot = self._ins.inject(dx, max(0.0, self._t_s - t_e))
        self._hist.shift(dx[POS], dx[VEL], rot, t_e)
        self._fix_err_ned_m += dx[FIX]
        self._chassis_pitch_rad += float(dx[CHASSIS])
        self._epoch_err_s += float(dx[EPOCH])
        step = math.hypot(dx[ATT.start], dx[ATT.start + 1])
        if step > self._tilt_step_rad(self._t_s):
            self._tilt_step = (step, self._t_s)

    def _tilt_step_rad(self, t: float) -> float:
        """The latest horizontal tilt correction, decayed over :data:`TILT_STEP_TAU_S`: a
        floor of the stated roll/pitch sigma. A filter that has just moved its tilt by x was
        about x off a moment ago, whatever P says now. After a restart levelled in a turn
        (tilt sigma 4 deg), the first velocity epoch moved roll by 5 deg, overshooting to
        1.7 deg off, while P's sigma fell to 0.41 (slope-start seed 73, an IMU stall at
        40 s): the linear update does not hold for degrees of tilt in a 19 deg/s turn, and
        P does not know it. Converged, the corrections are hundredths of a degree, under
        P's own sigma."""
        step, t_step = self._tilt_step
        return step * math.exp(-(t - t_step) / TILT_STEP_TAU_S) if step else 0.0

    def _align_heading(self, fix: GnssFix, t_e: float, row: Array) -> None:
        """First heading from HDT, or at ``align_min_speed_mps`` from the antenna's courses
        of the last second (:class:`CourseAlignment`, each from ``cog_min_speed_mps`` on,
        its lever-arm velocity taken out, :func:`heading_from_antenna_course`), forward
        unless the INS's velocity change since the last epoch at rest points backwards along
        body x (taken as forward, a start reversing out of a shed aligned 180 deg off and the
        filter then read the deceleration as tilt: pitch 5.7 deg off, NAVIGATING).

        The INS yaw at ``t_e`` is turned onto the reference (history too, keeping the gyro
        motion since), position and velocity are set from the fix, and P starts: position
        from the fix sigma, velocity ``align_vel_sigma_mps``, tilt from the accelerometer
        turn-on bias plus gyro drift since levelling, yaw from the reference, biases from the
        turn-on sigmas (gyro from the rest mean if there was one).
        """
        sig_pos = self._position_sigma(fix)
        if sig_pos is None:
            return
        yaw_e = math.atan2(row[ROW_C][3], row[ROW_C][0])
        if fix.heading_rad is not None:
            target, sig_yaw = fix.heading_rad, self.cfg.hdt_sigma_deg * DEG_TO_RAD
        elif (course := self._course_offset(fix, t_e, row, yaw_e)) is not None:
            target, sig_yaw = yaw_e + course[0], course[1]
        else:
            return
        ins, hist, tun = self._ins, self._hist, self._tuning
        assert ins is not None and hist is not None and tun is not None
        rot = exp_so3((0.0, 0.0, target - yaw_e))
        ins.rotate(rot)  # and the velocity integrated in the old azimuth, rows too
        ins.v_ned_mps = [float(x) for x in rot @ np.array(ins.v_ned_mps)]
        self._hint = None
        self._courses.clear()
        hist.turn(to_mat9(rot), ins.p_ned_m)
        row_aligned = hist.at(t_e)
        assert row_aligned is not None
        self._p = np.zeros((N_STATES, N_STATES))
        tun = self._noise_as_measured()
        ins.take_interval()
        sig_bg = self._levelled_gyro_bias_sigma_rps()
        sig_ba = tun.sigma_bias_a0_mps2
        sig_tilt = self._levelled_tilt_sigma_rad(t_e)
        p = self._p
        p[BA, BA] = sig_ba**2 * np.eye(3)
        p[BG, BG] = sig_bg**2 * np.eye(3)
        p[ATT, ATT] = np.diag([sig_tilt**2, sig_tilt**2, sig_yaw**2])
        m = _tilt_of_accel_bias(ins.c_bn)
        if self._seed is None:
            p[ATT, ATT] += sig_ba**2 * m @ m.T
            p[ATT, BA] = sig_ba**2 * m
        else:  # the seed's sigmas per axis (the levelling took its bias out)
            var_ba = np.array(self._seed.sigma_a_mps2) ** 2
            p[BA, BA] = np.diag(var_ba)
            p[BG, BG] = np.diag(self._seed_var_g)
            p[ATT, ATT] += (m * var_ba) @ m.T
            p[ATT, BA] = m * var_ba
        p[BA, ATT] = p[ATT, BA].T
        p[CHASSIS, CHASSIS] = CHASSIS_PITCH_SIGMA_RAD**2
        self._chassis_pitch_rad = 0.0
        self._epoch_err_s = 0.0
        self._track_epoch_error()
        self._set_fix_error_model(fix, sig_pos, restart=True)
        self._set_from_fix(fix, t_e, row_aligned)
        self._last_quality = fix.quality
        self._t_accepted_rx_s = fix.t

    def _watch_corrections(self, t_e: float) -> None:
        """After an epoch's correction: beyond what the noise and P's gyro bias and tilt
        (heading) explain (:class:`CorrectionWindow`), the x/y (z) biases changed."""
        change = self._corrections.check(self._arw(), self._p_tilt_sigma_rad())
        if change is not None:
            self._bias_changed(t_e, change, self._reopen_xy)
        change = self._heading_corrections.check(self._arw(), self._p_heading_sigma_rad())
        if change is not None:
            if change.courses and t_e - self._t_hdt_used_s < WINDOW_S:
                self._doubt_hdt(t_e, change)
            self._bias_changed(t_e, change, self._reopen_z)

    def _doubt_hdt(self, t_e: float, change: BiasChange) -> None:
        """The courses left the heading an HDT steered (:mod:`gateway.estimation.hdt_doubt`):
        the HDT is doubted, and the heading and z bias re-open by the change as for any
        found first (the HDT's drift went into both), however soon after the last."""
        self._hdt_doubt.doubt()
        if change.again:
            self._reopen_z(change)
        self.counters.heading_rejected += 1
        self._log.warning(t_e, hdt_doubt_text(t_e, change.angle_rad), "hdt")

    def _bias_changed(
        self, t_e: float, change: BiasChange, reopen: Callable[[BiasChange], str]
    ) -> None:
        """A bias change (:mod:`gateway.estimation.bias_change`): ``reopen`` re-opens P and
        says what it did, unless the change came again; counted and logged. A tilt change,
        again or not, raises the x/y accelerometer bias walk for a while
        (:class:`FoundWalk`)."""
        if change.axis == "tilt":
            self._ba_walk.found(t_e, GRAVITY_MPS2 * change.angle_rad)
        if change.again:
            self._log.warning(t_e, bias_change_text(t_e, change, ""), "bias change")
            return
        reopened = reopen(change)
        self.counters.bias_changes += 1
        self._log.warning(t_e, bias_change_text(t_e, change, reopened), "bias change")

    def _reopen_attitude(self, j: Array, sigma: float) -> None:
        """P += sigma^2 J J' for the attitude error per unit change ``j`` (N_STATES, k; its
        ATT rows set), with the IMU position error it makes through the lever arm, the
        antenna being where the fixes say (as at a reset, :meth:`_set_from_fix`). Without
        the position term the next fix "observed" the tilt and took P's tilt back to 0.1
        deg while roll stayed 1.4 deg off."""
        p, ins = self._p, self._ins
        assert p is not None and ins is not None
        j[POS] = skew(ins.c_bn @ self._l_imu_ant_b) @ j[ATT]
        p += sigma * sigma * (j @ j.T)

    def _reopen_xy(self, change: BiasChange) -> str:
        """The x/y biases changed beyond their in-run model: P's gyro block re-opens by the
        window's rate, its accelerometer block by the tilt taken (as a specific force), and
        the tilt by as much (:meth:`_reopen_attitude`). The tilt and the bias re-open
        independently: as one quantity (as at levelling, the loop having taken the whole
        step into the tilt), a step found in the turn it came in put its rest into the
        other axis (-30 mg on x at 45 s of `short` seed 5: y 0.14 m/s^2 off with 0.03
        stated, 600 frames beyond). The unobserved-bias share of the stated tilt
        (:meth:`_unobserved_bias_var`) comes back with it."""
        p, ins = self._p, self._ins
        assert p is not None and ins is not None
        j = np.zeros((N_STATES, 2))  # tilt per unit x/y bias change
        j[ATT] = _tilt_of_accel_bias(ins.c_bn)[:, :2]
        sigma_a, sigma_g = GRAVITY_MPS2 * change.angle_rad, change.rate_rps
        self._reopen_attitude(j, sigma_a)
        for i in (BA.start, BA.start + 1):
            p[i, i] += sigma_a * sigma_a
        for i in (BG.start, BG.start + 1):
            p[i, i] += sigma_g * sigma_g
        sigma_ba = math.sqrt(max(p.item(BA.start, BA.start), p.item(BA.start + 1, BA.start + 1)))
        sigma_bg = math.sqrt(max(p.item(BG.start, BG.start), p.item(BG.start + 1, BG.start + 1)))
        return xy_reopened_text(sigma_ba, sigma_bg)

    def _reopen_z(self, change: BiasChange) -> str:
        """The z gyro bias changed beyond its in-run model: :meth:`_reopen_vertical` by the
        window's rate and the angle taken."""
        self._reopen_vertical(change.rate_rps, change.angle_rad)
        return z_reopened_text(self._vertical_bias_sigma_rps())

    def _reopen_vertical(self, rate_rps: float, angle_rad: float) -> None:
        """P's gyro bias about the vertical re-opens by ``rate_rps``, the heading by
        ``angle_rad`` (:meth:`_reopen_heading`)."""
        p, ins = self._p, self._ins
        assert p is not None and ins is not None
        u = ins.c_bn[2]  # the vertical in body axes
        p[BG, BG] += rate_rps**2 * np.outer(u, u)
        self._reopen_heading(angle_rad)

    def _reopen_heading(self, sigma_rad: float) -> None:
        """P's heading (about the vertical) re-opens by ``sigma_rad``
        (:meth:`_reopen_attitude`)."""
        j = np.zeros((N_STATES, 1))
        j[ATT.stop - 1, 0] = 1.0
        self._reopen_attitude(j, sigma_rad)

    def _forget_heading_corrections(self) -> None:
        """A stop: the heading window ends, and what it showed beyond P's heading stays in
        P until courses take it (aging out of the window through the stop, a z step's
        excess was forgotten)."""
        excess = self._heading_corrections.forget(self._arw(), self._p_heading_sigma_rad())
        if excess > 0.0:
            self._reopen_heading(excess)

    def _noise_as_measured(self) -> EkfTuning:
        """The white rate and acceleration noise the IMU showed at rest, where it is more
        than the config's (``[ekf] vibration_*``, :mod:`gateway.estimation.imu_noise`): the
        process noise of an installation on a rough engine. Set as the filter starts, and
        raised at every epoch at rest after (the noise measured since): with a dual-antenna
        heading the filter starts at the first epoch after levelling, before the meter has
        its samples, and a unit twice as noisy ran the whole run on its datasheet's noise, the
        tilt 0.35-0.44 deg off with 0.08 stated (`field` seed 613 of imu-noise-x2+hdt,
        509 frames beyond 0.1 deg + 3 sigma).

        Both bias walks are raised by the larger of the two ratios, as the observer's bias
        floors are: a unit noisier than its datasheet is not the datasheet's typical unit,
        and its stabilities are not known to be. By each sensor's own ratio, a unit twice as
        noisy in every figure kept the accelerometer's datasheet walk (its white noise is
        under ``vibration_accel_mps2``'s, so it showed no excess) while its in-run y bias
        wandered twice as far: 0.013 m/s^2 off with 0.006 stated, roll 1.3 times its sigma
        RMS (headland-reversing seed 560, imu-noise-x2)."""
        tun, base = self._tuning, self._config_tuning
        assert tun is not None and base is not None
        q_g, q_a = base.q_gyro_rad2_per_s, base.q_accel_m2_per_s3
        measured = self._noise_excess(base)
        r_g, r_a = (max(m, taken) for m, taken in zip(measured, self._excess_taken, strict=True))
        if (r_g, r_a) == self._excess_taken:
            return tun
        self._excess_taken = (r_g, r_a)
        log.info(
            "IMU noise at rest %.1f times (gyro) and %.1f times (accelerometer) [ekf]'s, "
            "engine vibration included: the filter's process noise raised to it",
            r_g,
            r_a,
        )
        r_unit = max(r_g, r_a)
        tun = replace(
            base,
            q_gyro_rad2_per_s=q_g * r_g * r_g,
            q_accel_m2_per_s3=q_a * r_a * r_a,
            q_bias_g_rad2_per_s3=base.q_bias_g_rad2_per_s3 * r_unit * r_unit,
            q_bias_a_m2_per_s5=base.q_bias_a_m2_per_s5 * r_unit * r_unit,
        )
        fix_q, epoch_q = self._q_c[FIX].copy(), self._q_c[EPOCH]
        self._tuning, self._q_c = tun, process_noise_psd(tun)
        self._q_c[FIX], self._q_c[EPOCH] = fix_q, epoch_q
        return tun

    def _course_offset(
        self, fix: GnssFix, t_e: float, row: Array, yaw_e: float
    ) -> tuple[float, float] | None:
        """The platform's azimuth error at ``t_e`` and its 1-sigma, rad, from the recent
        courses (:meth:`CourseAlignment.alignment`: at ``align_min_speed_mps``, or slower once
        they are good enough and the direction of travel is known); None before. Each
        course from ``cog_min_speed_mps`` on is added, its sigma the fix velocity's and the
        antenna lever arm's gyro noise over the speed."""
        vel = fix.vel_ne_mps
        speed = 0.0 if vel is None else math.hypot(*vel)
        measured = self._gnss_velocity(fix)
        if vel is None or measured is None or speed < self.cfg.cog_min_speed_mps:
            return None
        w_e, sig_lever = self._lever_rate(t_e, self._l_ant_m)
        if self._direction_since_rest is None:
            self._direction_since_rest = self._direction_from_rest(t_e, row)
        forward = self._forward_at(vel, row, w_e)
        course = heading_from_antenna_course(vel, row[ROW_C], w_e, self._l_ant_b, forward)
        a_ant = self._antenna_accel_ned(t_e, row[ROW_C].reshape(3, 3), w_e)
        sigma_v = math.hypot(measured[1], sig_lever, self._velocity_timing_sigma_mps(a_ant))
        self._courses.add(t_e, wrap_pi(course - yaw_e), sigma_v / speed)
        cfg = self.cfg
        known = self._hint is not None or self._direction_since_rest is not None
        arw = self._arw() * self._gyro_noise_excess()
        return self._courses.alignment(
            self._bias_z_sigma_rps(t_e),
            arw,
            speed,
            cfg.align_min_speed_mps,
            cfg.navigating_heading_sigma_deg,
            known,
            refined=True,
        )

    def _bias_z_sigma_rps(self, t_e: float) -> float:
        """z gyro bias 1-sigma at ``t_e`` before the filter runs: the seed's or the
        levelling's, and the in-run walk since the levelling (Q_bg dt), as much larger as
        the gyro noise measured at rest is than the tuning's. Without the walk
        the first heading took 12.8 mdeg/s through 590 s of planting at 0.5 m/s in which
        the bias wandered 0.08 deg/s (a unit twice as noisy, a 1 Hz receiver: `field`
        seed 578), and the courses' turn of the platform was stated that much too small."""
        assert self._tuning is not None
        bz_var = self._seed_var_g[2] if self._seed is not None else None
        sig_bz = math.sqrt(bz_var) if bz_var is not None else self._levelled_gyro_bias_sigma_rps()
        walk_s = max(0.0, t_e - self._t_levelled_s)
        walk = self._tuning.q_bias_g_rad2_per_s3 * walk_s
        return self._gyro_noise_excess() * math.sqrt(sig_bz * sig_bz + walk)

    def _forward_at(self, vel_ne_mps: tuple[float, float], row: Array, w_e: Array) -> bool:
        """Driving forward at ``row``, the antenna moving at ``vel_ne_mps``: as the heading
        the last engine had says, after a restart (:mod:`gateway.estimation.heading_hint`:
        it outranks the velocity change, which a tilt left by levelling while braking turns
        round), else :meth:`_forward_since_rest`."""
        if self._hint is None:
            return self._forward_since_rest()
        c = row[ROW_C]
        if_forward = heading_from_antenna_course(vel_ne_mps, c, w_e, self._l_ant_b, True)
        return self._hint.forward(if_forward, math.atan2(c[3], c[0]))

    def _forward_since_rest(self) -> bool:
        """Driving forward: as the velocity change since the last rest said once it could
        (:meth:`_direction_from_rest`; kept until the next rest, as the observer keeps it: the
        tilt's share of the change, g theta t, soon outgrows it; a planter with a 1 Hz
        receiver lost it 5 s after pulling away, before its courses gave a heading, and
        never aligned), else forward (at ``align_min_speed_mps``, as the observer: vehicles
        reverse slower, and the sign of a change within its noise is the noise's)."""
        return self._direction_since_rest is not False

    def _dv_x_since_rest(self, row: Array) -> float | None:
        """The INS velocity change along body x from the last epoch at rest to ``row``,
        m/s; None without one."""
        if self._rest_epoch is None:
            return None
        dv = row[ROW_V] - self._rest_epoch[1]
        c = to_mat9(row[ROW_C].reshape(3, 3))
        return along_body_x(float(dv[0]), float(dv[1]), c)

    def _direction_from_rest(self, t_e: float, row: Array) -> bool | None:
        """Forward (True) or reversing (False) at ``row`` (epoch time ``t_e``), before the
        heading is known, where the velocity change since the last rest tells them apart:
        beyond what the levelled tilt puts into it (:func:`direction_known`); else None."""
        dv_x = self._dv_x_since_rest(row)
        if dv_x is None or self._rest_epoch is None:
            return None
        since_s = t_e - self._rest_epoch[0]
        if not direction_known(dv_x, self._levelled_tilt_sigma_rad(t_e), since_s):
            return None
        return dv_x >= 0.0

    def _levelled_tilt_sigma_rad(self, t_e: float) -> float:
        """Roll/pitch 1-sigma at ``t_e`` before the filter runs: the levelling's and the gyro
        bias's drift since it."""
        return math.sqrt(self._bias_drift_var_rad2(t_e) + self._sigma_level_rad**2)

    def _bias_drift_var_rad2(self, t: float) -> float:
        """Tilt variance the gyro bias adds from levelling to ``t``: its sigma then times
        the time, and its in-run walk since, Q_bg dt^3 / 3. Without the walk a planter with
        a 1 Hz receiver, no heading for ten minutes, sent roll 4 deg off with 1.3 stated."""
        assert self._tuning is not None
        dt = max(0.0, t - self._t_levelled_s)
        bias_drift = self._levelled_gyro_bias_sigma_rps() * dt
        return bias_drift**2 + self._tuning.q_bias_g_rad2_per_s3 * dt**3 / 3.0

    def _gyro_noise_excess(self) -> float:
        """How many times the gyro noise measured at rest is the tuning's (>= 1; 1 once the
        filter has taken it, :meth:`_noise_as_measured`): the tilt sigma sent before the
        filter runs takes the rest mean's bias error, the ARW and the in-run walk as that
        much larger, as the observer takes them. A unit twice as noisy as its datasheet
        (robustness `imu-noise-x2`), a planter at 1 Hz, sent roll 3.4 deg off with 0.86
        stated before its first heading."""
        assert self._tuning is not None
        return self._noise_excess(self._tuning)[0]

    def _noise_excess(self, tun: EkfTuning) -> tuple[float, float]:
        """How many times the gyro and accelerometer noise measured at rest are ``tun``'s
        (:meth:`ImuNoiseMeter.excess`)."""
        dt = self._imu_dt_s
        sigma_g = math.sqrt(tun.q_gyro_rad2_per_s / dt)
        return self._noise.excess(sigma_g, math.sqrt(tun.q_accel_m2_per_s3 / dt))

    def _levelled_gyro_bias_sigma_rps(self) -> float:
        """Gyro bias 1-sigma before the filter runs: the seed's (x/y, with the rest mean's),
        else the rest mean's, else the turn-on one."""
        tun = self._tuning
        assert tun is not None
        if self._seed is not None:
            return math.sqrt(max(self._seed_var_g[0], self._seed_var_g[1]))
        if self._rest_bias_s > 0.0:
            return math.sqrt(tun.q_gyro_rad2_per_s / self._rest_bias_s + EARTH_RATE_RPS**2)
        return tun.sigma_bias_g0_rps

    def _sigma_tilt_rad(self) -> float | None:
        """Roll/pitch 1-sigma: from P once it runs, that of the worse horizontal tilt axis
        (one figure for both angles; the mean of the two hid a 0.24 deg roll axis behind a
        stated 0.19 on a straight, the accelerometer's y bias not yet told from roll);
        before, what levelling leaves (the accelerometer bias over g, the window's motion
        and noise, the gyro's drift since); with the IMU mounting's own 1-sigma (an
        estimated mounting is not exact)."""
        p, tun = self._p, self._tuning
        mounting_var = (self.cfg.imu_mounting_sigma_deg * DEG_TO_RAD) ** 2
        if p is not None:
            model = self._p_tilt_sigma_rad()
            excess = self._corrections.excess_rad(self._arw(), model)
            return math.sqrt(model * model + excess * excess + mounting_var)
        if self._ins is None or tun is None or self._t_s is None:
            return None
        var_ba = tun.sigma_bias_a0_mps2**2
        if self._seed is not None:
            var_ba = max(self._seed.sigma_a_mps2[0], self._seed.sigma_a_mps2[1]) ** 2
        return math.sqrt(
            (var_ba + self._unobserved_bias_var(var_ba)) / GRAVITY_MPS2**2
            + self._sigma_level_rad**2
            + self._drift_var_rad2(self._t_s)
            + mounting_var
        )

    def _p_tilt_sigma_rad(self) -> float:
        """The filter's roll/pitch 1-sigma: P's worse horizontal tilt axis with the
        unobserved share of the accelerometer bias, or the latest tilt step if more."""
        p = self._p
        assert p is not None
        a, b, d = p.item(6, 6), p.item(6, 7), p.item(7, 7)
        worse = 0.5 * (a + d) + math.sqrt(0.25 * (a - d) ** 2 + b * b)  # larger eigenvalue
        step = self._tilt_step_rad(self._t_s) if self._t_s is not None else 0.0
        bx, by = BA.start, BA.start + 1
        var_ba = max(p.item(bx, bx), p.item(by, by))
        unobserved = self._unobserved_bias_var(var_ba) / GRAVITY_MPS2**2
        return math.sqrt(max(worse + unobserved, step * step))

    def _unobserved_bias_var(self, var_ba: float) -> float:
        """Variance, (m/s^2)^2, of a turn-on accelerometer bias beyond P0's (``[ekf]
        accel_bias_sigma_covered_mps2``) that a filter whose x/y bias variance is ``var_ba``
        (P's, or a seed's: the learned state carries P) has not yet observed.

        A linear filter's estimate of a constant keeps the fraction r = P / P0 of its true
        value unlearnt; drawn from the wider spread, the bias leaves r^2 (sigma_c^2 -
        sigma_0^2) more error than P says, and until the heading changes that is tilt (C b_a
        and g phi are one quantity). Seed 000's example bias, 0.2 m/s^2 (here on y, 40 times
        P0's sigma), had roll 1.36 deg off with 0.30 stated from the start's rest to the
        first turn (field seed 1: 1094 frames beyond 0.1 deg + 3 sigma; none now); a warm
        start from a run that never turned stated the seed's 0.29 deg, parked.

        The spread covered is as much wider as the unit is noisier than its config
        (:meth:`_unit_noise_excess`), as the observer's turn-on prior is: a unit twice as
        noisy as its datasheet with 0.22/0.24 m/s^2 of x/y bias (2.4 sigma of 0.1) sent
        roll 1.05 deg off with 0.30 stated in its first U-turn (`float-spells` seed 612 of
        gnss-20hz+imu-noise-x2, 63 frames beyond 0.1 deg + 3 sigma).
        """
        tun = self._tuning
        assert tun is not None
        var0 = tun.sigma_bias_a0_mps2**2
        covered = self.cfg.accel_bias_sigma_covered_mps2 * self._unit_noise_excess()
        extra = covered * covered - var0
        if extra <= 0.0:
            return 0.0
        r = min(1.0, var_ba / var0)
        return r * r * extra

    def _unit_noise_excess(self) -> float:
        """How many times noisier than its config the unit is, the larger of gyro and
        accelerometer (>= 1): at rest before the filter runs (:class:`ImuNoiseMeter`), the
        ratio the filter took once it runs (:meth:`_noise_as_measured`)."""
        if self._p is not None:
            return max(self._excess_taken)
        assert self._tuning is not None
        return max(self._noise_excess(self._tuning))

    def _drift_var_rad2(self, t: float) -> float:
        """Tilt variance the gyro adds from levelling to ``t``, while roll/pitch go out
        before the filter runs: its bias's drift and its white noise's random walk (at rest
        after a restart the INS walked 0.08 deg in a second, the bias alone said 0.003). P
        starts from the bias's drift alone: with the walk too, epochs 4 s late in bursts
        (tests/test_busy_host_inputs.py) took the filter through a run of rejections and
        resets to 8.5 m off, 0.8 m without."""
        assert self._tuning is not None
        dt = max(0.0, t - self._t_levelled_s)
        drift = self._bias_drift_var_rad2(t) + self._tuning.q_gyro_rad2_per_s * dt
        return drift * self._gyro_noise_excess() ** 2

    def _reset_from_fix(self, fix: GnssFix, t_e: float, row: Array) -> None:
        """Recovery after a long outage or a run of rejections: position/velocity from GNSS.

        Attitude and biases are kept; position and velocity restart from the fix with their
        cross-covariances dropped (the old ones described a state that was just replaced).
        Logged once per cause per 10 s: an overloaded gateway bridges a gap every few seconds.
        """
        self.counters.resets += 1
        cause = (
            "positions rejected"
            if self._track.rejecting_since_s is not None
            else "an IMU gap"
            if self._imu.timing.gaps != self._imu_gaps_at_reset
            else "an outage"
        )
        self._log.warning(
            t_e, f"GNSS position at t={t_e:.3f}: position and velocity reset to it ({cause})", cause
        )
        self._set_from_fix(fix, t_e, row)
        self._last_quality = fix.quality
        self._t_accepted_rx_s = fix.t

    def _set_fix_error_model(self, fix: GnssFix, sig_pos: Array, restart: bool) -> None:
        """The white and wandering parts of this fix's error (:func:`split_fix_variance`:
        the configured share, or what the receiver's track shows where more) and the
        wander's driving noise; ``restart``: a new quality is a new receiver solution, its
        error independent of everything so far (FIX rows of P reset)."""
        p = self._p
        assert p is not None
        sig_ne = (float(sig_pos[0]), float(sig_pos[1]))
        quality = int(fix.quality)
        seen = max(
            self._track.noise.white_share(quality, sig_ne),
            self._pos_noise.white_share(quality, sig_ne),
        )
        for i in range(3):
            self._fix_var_white_m2[i], self._fix_var_wander_m2[i] = split_fix_variance(
                float(sig_pos[i]), self.cfg.gnss_white_share, seen
            )
        self._q_c[FIX] = 2.0 * self._fix_var_wander_m2 / self.cfg.gnss_error_correlation_s
        if restart:
            p[FIX, :] = 0.0
            p[:, FIX] = 0.0
            p[FIX, FIX] = np.diag(self._fix_var_wander_m2)
            self._fix_err_ned_m[:] = 0.0

    def _set_from_fix(self, fix: GnssFix, t_e: float, row: Array) -> None:
        """INS position/velocity from the fix at ``t_e``, moved to now by the INS's motion
        since; P rows reset.

        The new errors are the fix's, carried through the lever arm with the attitude and
        gyro bias of the moment: dp = -b - w + [C l]x phi + v_ant dtau, dv = -e_v +
        [C (w x l)]x phi - C [l]x dbg (the measurement models read backwards). Both
        correlations are kept: position and fix-error states start correlated, so that a fix
        of the same solution does not count twice; dropping the attitude term let the next
        fixes of an RTK solution "observe" roll through a 2 m lever arm on a straight line
        (0.3 deg of roll error reported as 0.12 deg)."""
        ins, hist, p = self._ins, self._hist, self._p
        assert ins is not None and hist is not None and p is not None and self._t_s is not None
        c_e = row[ROW_C].reshape(3, 3)
        l_b = self._l_imu_ant_b
        c_l = c_e @ l_b
        p_imu = self._antenna_ned(fix) - c_l
        vel = self._gnss_velocity(fix)
        v_ne = vel[0] if vel is not None else np.zeros(2)
        w_e = self._lever_rate(t_e, self._l_imu_ant_m)[0]
        v_lever = c_e @ cross3(w_e, l_b)
        v_imu = np.array([v_ne[0], v_ne[1], 0.0]) - v_lever
        # NMEA has no vertical velocity: the reference point's, a wheeled vehicle's (along
        # its body x, :func:`fuse_nonholonomic`), with the IMU's lever-arm velocity. Zero was
        # 0.6 m/s off at 4 m/s on a 9 deg slope, and the first constraint took it for pitch.
        v_rot_imu = c_e @ cross3(w_e, self._l_imu_b)
        fwd_n, fwd_e, fwd_d = c_e[:, 0]
        u = ((v_imu[0] - v_rot_imu[0]) * fwd_n + (v_imu[1] - v_rot_imu[1]) * fwd_e) / (
            fwd_n**2 + fwd_e**2
        )
        v_imu[2] = fwd_d * u + v_rot_imu[2]
        # the fix is the antenna dtau before t_e (the INS's velocity for its vertical)
        v_ant = v_imu + v_lever
        # the INS's own motion since t_e carried on (as a fused epoch's correction is): with a
        # constant velocity over the age, an epoch 4 s late in a pull-away set 1.5 m/s where
        # the vehicle did 3, and the next epochs were rejected as glitches
        age_s = self._t_s - t_e
        dp = p_imu - row[ROW_P]
        dv = v_imu - row[ROW_V]
        ins.p_ned_m = [float(x) for x in np.array(ins.p_ned_m) + dp + dv * age_s]
        ins.v_ned_mps = [float(x) for x in np.array(ins.v_ned_mps) + dv]
        hist.shift(dp, dv, IDENTITY9, t_e)
        for s in (POS, VEL, FIX):
            p[s, :] = 0.0
            p[:, s] = 0.0
        # (dp, dv) = m (phi, dbg) + the fix's own errors
        m = np.zeros((6, N_STATES))
        m[3:6, ATT] = skew(v_lever)
        m[3:6, BG] = -c_e @ skew(l_b)
        # the vertical one through C: d(C b) = -[C b]x phi, and C (w x l_imu) through dbg
        m[5, ATT] = -skew(v_imu)[2]
        m[5, BG] = (c_e @ skew(self._l_imu_b))[2]
        m[0:3, ATT] = skew(c_l) + age_s * m[3:6, ATT]
        m[0:3, BG] = age_s * m[3:6, BG]
        if self._epoch_moves(fix):
            m[0:3, EPOCH] = v_ant
            a_ant = self._antenna_accel_ned(t_e, c_e, w_e)
            if a_ant is not None and a_ant.column is not None:  # (the velocity's a_ant dtau)
                m[3:5, EPOCH] = a_ant.column[:2]
        pv = slice(POS.start, VEL.stop)
        cross = m @ p
        p[pv, :] = cross
        p[:, pv] = cross.T
        p[pv, pv] = cross @ m.T
        wander = np.diag(self._fix_var_wander_m2)
        p[POS, POS] += np.diag(self._fix_var_white_m2) + wander
        p[POS, FIX] = -wander
        p[FIX, POS] = -wander
        p[FIX, FIX] = wander
        self._fix_err_ned_m[:] = 0.0
        self._pos_innovation = None  # (a state set from a fix: no innovation to change from)
        p[VEL, VEL] += self.cfg.align_vel_sigma_mps**2 * np.eye(3)
        set_symmetrised(p, p.copy())  # (m P m^T and the levelling's terms, rounded apart)
        self._t_pos_epoch_s = t_e
        self._imu_gaps_at_reset = self._imu.timing.gaps
        self._track.accepted()

    def _antenna_ned(self, fix: GnssFix) -> Array:
        """Antenna position in the local NED frame (origin: the first position used)."""
        assert fix.lat_deg is not None and fix.lon_deg is not None and fix.alt_m is not None
        if self._frame is None:
            self._frame = LocalFrame((fix.lat_deg, fix.lon_deg, fix.alt_m))
        return np.array(self._frame.to_ned(fix.lat_deg, fix.lon_deg, fix.alt_m))

    def _velocity_suspect(self, t_e: float) -> bool:
        """Did the filter's gate reject a GNSS velocity within the drift window before
        ``t_e``? A drift of the positions off the velocity is then the velocity's: RMC
        speed 0.3 m/s high (or its course 3 deg off) with the positions right is rejected
        against the state, while a drifting solution's right velocity never is."""
        t_rej = self._t_velocity_rejected_s
        return t_rej is not None and t_e - t_rej <= DRIFT_WINDOW_S

    def _fuse_fix_position(
        self, row: Array, c_e: Array, w_e: Array, p_ant: Array, moves: bool
    ) -> Measurement:
        """The fix's antenna position as a measurement of the state at its epoch (``row``,
        body rate ``w_e``); the antenna's velocity for its EPOCH column if the epoch time
        ``moves`` it (:meth:`_epoch_moves`)."""
        l_b = self._l_imu_ant_b
        return fuse_position(
            row[ROW_P],
            c_e,
            l_b,
            p_ant,
            np.sqrt(self._fix_var_white_m2),
            self._fix_err_ned_m,
            row[ROW_V] + c_e @ cross3(w_e, l_b) if moves else np.zeros(3),
        )

    def _epoch_moves(self, fix: GnssFix) -> bool:
        """Does an epoch-time error move this fix: has the receiver a course (a speed from
        ``COG_RELIABLE_SPEED_MPS``)? Parked, the INS's velocity and acceleration at the
        epoch are their own noise, which the residual shares (the INS's position and
        velocity there): as EPOCH columns they took the epoch time to -108 ms with 14
        stated (18 true) in 40 s parked, aligned on HDT, and the pull-away's positions
        went 0.2 m off NAVIGATING (field seed 632, `host-clock-free+hdt`)."""
        sog = fix.sog_mps
        return fix.vel_ne_mps is not None and sog is not None and sog >= COG_RELIABLE_SPEED_MPS

    def _epoch_sigma_s(self) -> float:
        """1-sigma of the epoch times, s: the EPOCH state's once the filter runs (what it has
        learnt of them), the clock's before."""
        p = self._p
        return self.clock.epoch_sigma_s if p is None else math.sqrt(p.item(EPOCH, EPOCH))

    def epoch_time_error(self) -> tuple[float, float] | None:
        """What the filter has learnt of the epochs' placement on a host clock that does not
        follow UTC: the configured receiver latency's error (the true latency less it), s,
        and its 1-sigma; None on a host that follows UTC, or before the filter runs."""
        if self._p is None or self.clock.epoch_sigma_s == 0.0:
            return None
        return self._epoch_err_s, self._epoch_sigma_s()

    def _track_epoch_error(self) -> None:
        """The EPOCH state as the clock knows the epochs' times: on a host clock that does
        not follow UTC, a constant of the clock's ``epoch_sigma_s`` (the configured receiver
        latency's error), walking as the least receive delay it is placed by may move
        (:data:`EPOCH_WALK_S2_PER_S`); on one that does, none (estimate and P's row cleared
        when the clock finds it follows UTC)."""
        p = self._p
        assert p is not None
        sigma_s = self.clock.epoch_sigma_s
        if sigma_s == 0.0:
            if p.item(EPOCH, EPOCH) > 0.0 or self._epoch_err_s:
                p[EPOCH, :] = 0.0
                p[:, EPOCH] = 0.0
                self._epoch_err_s = 0.0
            self._q_c[EPOCH] = 0.0
            return
        if p.item(EPOCH, EPOCH) == 0.0:
            p[EPOCH, EPOCH] = sigma_s * sigma_s
        self._q_c[EPOCH] = EPOCH_WALK_S2_PER_S

    def _reject_position(self, t_e: float, why: str) -> None:
        """The fix's position is not used: counted, told to the track, logged (rate-limited)."""
        self.counters.position_rejected += 1
        self._track.rejected(t_e)
        self._log.warning(t_e, why, "glitch")

    def _position_sigma(self, fix: GnssFix) -> Array | None:
        """Position 1-sigma NED (3,) of the fix (:func:`fix_position_sigma_m`: GST when
        sent, else the quality's default scaled by HDOP and the age of corrections)."""
        sig = fix_position_sigma_m(fix)
        if fix.lat_deg is None or fix.lon_deg is None or fix.alt_m is None or sig is None:
            return None
        return np.maximum(np.array(sig), 1e-3)

    def _measure_velocity_noise(self, fix: GnssFix, t_e: float, m: Measurement) -> None:
        """Feed the receiver's velocity noise (:class:`VelocityNoise`) with the change of an
        RTK fixed epoch's velocity innovation since the last: two fixes' errors and the
        filter's share of both innovations (2 H P H^T, taken out). The change, not the
        innovation: a velocity 0.3 m/s off for 20 s was the receiver's noise in it, weighed
        so, fused, and the positions went 1.75 m off (tests/test_gnss_glitches.py)."""
        if (
            fix.quality != FixQuality.RTK_FIXED
            or fix.vel_ne_mps is None
            or fix.sog_mps is None
            or fix.sog_mps < COG_RELIABLE_SPEED_MPS
        ):
            self._vel_innovation = None
            return
        now = (t_e, float(m.z[0]), float(m.z[1]))
        last, self._vel_innovation = self._vel_innovation, now
        self._t_vel_noise_s = t_e
        change = self._innovation_change(last, now, m)
        if change is not None:
            (var_n, var_e), interval_s = change
            self._vel_noise.add(var_n, var_e, interval_s)

    def _measure_position_noise(
        self, fix: GnssFix, t_e: float, m: Measurement, sig_pos: Array
    ) -> None:
        """Feed the fixes' white noise (:class:`PositionNoise`, per quality) with the change
        of the position innovation since the last epoch of the same quality: two fixes'
        white errors and the filter's share of both innovations (2 H P H^T, taken out). The
        track measures it on steps of 0.25 s or less; a 1 Hz receiver whose 2 cm are white
        from epoch to epoch was weighed by the configured share, and the filter took its
        noise for tilt (6 frames 0.31 deg off with 0.07 stated: `field` seed 840,
        `gnss-1hz+pos-white`). The change, not the innovation: a fix's wander, or a jump
        the filter has not yet followed, is no white noise."""
        quality = int(fix.quality)
        now = (t_e, float(m.z[0]), float(m.z[1]))
        last, self._pos_innovation = self._pos_innovation, (quality, now)
        change = self._innovation_change(last[1] if last and last[0] == quality else None, now, m)
        if change is not None:
            fix_var_m2 = 0.5 * (float(sig_pos[0]) ** 2 + float(sig_pos[1]) ** 2)
            self._pos_noise.add(quality, change[0], change[1], fix_var_m2)

    def _innovation_change(
        self, last: tuple[float, float, float] | None, now: tuple[float, float, float],
        m: Measurement,
    ) -> tuple[tuple[float, float], float] | None:  # fmt: skip
        """The change of ``m``'s horizontal innovation ``now`` since ``last`` (each epoch
        time s, north, east) as a sample of the receiver's white variance per axis: half its
        square (two fixes' errors) less the filter's share of one innovation (H P H^T's
        diagonal); and the interval, s. None unless the two epochs are a pair (within
        :data:`INNOVATION_PAIR_MAX_S`)."""
        if last is None or not 0.0 < now[0] - last[0] <= INNOVATION_PAIR_MAX_S:
            return None
        assert self._p is not None
        hph = m.h @ self._p @ m.h.T
        dz_n, dz_e = now[1] - last[1], now[2] - last[2]
        var_ne = (0.5 * dz_n * dz_n - hph.item(0, 0), 0.5 * dz_e * dz_e - hph.item(1, 1))
        return var_ne, now[0] - last[0]

    def _measure_velocity_noise_at_rest(self, fix: GnssFix, t_e: float) -> None:
        """Feed the receiver's velocity noise with an RTK fixed epoch at rest before the
        heading is known: the speed over ground is the fix's velocity error (its square 2
        sigma_v^2; the speeds under the rest test only, so somewhat less), which the first
        courses are then weighed with (at 5 cm/s weighed as 2 cm/s, the first heading went
        out 3 deg off NAVIGATING: `steep-turns` seed 820 with a 5 Hz receiver)."""
        if fix.quality != FixQuality.RTK_FIXED or fix.sog_mps is None:
            return
        last, self._t_vel_noise_s = self._t_vel_noise_s, t_e
        if last is not None and t_e > last:
            half = 0.5 * fix.sog_mps * fix.sog_mps
            self._vel_noise.add(half, half, t_e - last)

    def _gnss_velocity(self, fix: GnssFix) -> tuple[Array, float] | None:
        """Horizontal antenna velocity (2,) and its 1-sigma, from SOG/COG.

        Below ``COG_RELIABLE_SPEED_MPS`` (or without a course) the direction is unknown: the
        measurement becomes v = 0 with SOG added to its sigma.
        """
        if fix.sog_mps is None or int(fix.quality) not in DEFAULT_GNSS_SIGMAS:
            return None
        sigma = max(self._vel_noise.sigma_mps(), DEFAULT_GNSS_SIGMAS[int(fix.quality)][2])
        vel = fix.vel_ne_mps
        if vel is None or fix.sog_mps < COG_RELIABLE_SPEED_MPS:
            return np.zeros(2), math.hypot(sigma, fix.sog_mps)
        return np.array(vel), sigma

    def _antenna_accel_ned(self, t_e: float, c_e: Array, w_e: Array) -> AntennaAccel | None:
        """The antenna's acceleration at ``t_e`` while the epochs' times are uncertain (None
        on a UTC host): what a velocity placed dtau off is off by, a_ant dtau.

        Its smooth part, m/s^2 NED: the INS's over the history's +/- h
        (:data:`LEVER_RATE_HALF_WIDTH_S`, an epoch waits for it, :class:`HeldEpochs`) and
        the lever arm's centripetal C (w x (w x l)); the EPOCH column while its horizontal
        is :data:`ACCEL_COLUMN_SNR` times its noise, sqrt(q_a / 2 h), or more. The rest is
        white: that noise, the lever arm's C (dw x l) from the rate's change between the
        means of the two halves, and a smooth part too small for the column. A 3 m mast
        rocking on bumps moves its top at metres per second squared, but dw over 0.05 s is
        noisy, 0.15 m/s^2 on a 2 m mast (2 q_g / h^3 |l|^2, vibration in) with outliers
        past 0.4: in the column, the pull-away's changes of acceleration it seemed to show
        told the epoch time from a velocity error (0.3 m off, NAVIGATING, 6 cm stated).
        Under its noise it is noise, which shares the INS's velocity at ``t_e`` with the
        residual: in the column it moved the epoch time at a steady speed as it did parked
        (:meth:`_epoch_moves`). (The fixes' velocity differences were noisier still: 0.4
        m/s^2.)"""
        if self._epoch_sigma_s() == 0.0:
            return None
        hist, h, tun = self._hist, LEVER_RATE_HALF_WIDTH_S, self._tuning
        assert hist is not None and tun is not None
        before, after = hist.at(t_e - h), hist.at(t_e + h)
        if before is None or after is None:
            return None
        a_imu = (after[ROW_V] - before[ROW_V]) / (after[ROW_T] - before[ROW_T])
        l_b = self._l_imu_ant_b
        half = 0.5 * h
        w_dot = (hist.mean_rate(t_e + half, half) - hist.mean_rate(t_e - half, half)) / h
        r_n, r_e, _ = (c_e @ cross3(w_dot, l_b)).tolist()
        var_noise = tun.q_accel_m2_per_s3 / (2.0 * h)
        smooth = a_imu + c_e @ cross3(w_e, cross3(w_e, l_b))
        s_n, s_e, _ = smooth.tolist()
        var_smooth = s_n * s_n + s_e * s_e
        if var_smooth >= ACCEL_COLUMN_SNR**2 * var_noise:
            return AntennaAccel(smooth, math.sqrt(r_n * r_n + r_e * r_e + var_noise))
        return AntennaAccel(None, math.sqrt(r_n * r_n + r_e * r_e + var_noise + var_smooth))

    def _velocity_timing_sigma_mps(self, a_ant: AntennaAccel | None) -> float:
        """1-sigma of a GNSS velocity's timing error, m/s: the antenna's horizontal
        acceleration ``a_ant`` (:meth:`_antenna_accel_ned`, both parts) times the epochs'
        time sigma (0 on a UTC host). For a velocity used outside the filter."""
        if a_ant is None:
            return 0.0
        a_n, a_e = (0.0, 0.0) if a_ant.column is None else a_ant.column[:2].tolist()
        return math.hypot(a_n, a_e, a_ant.sigma_white_mps2) * self._epoch_sigma_s()

    def _update_motion_flags(self) -> None:
        """Stationary and reversing from the reference-point body velocity (hysteresis)."""
        ins = self._ins
        assert ins is not None
        c0, c1, c2, c3, c4, c5, c6, c7, c8 = ins.c_bn9
        vn, ve, vd = ins.v_ned_mps
        wx, wy, wz = ins.w_b_lp_rps
        lx, ly, lz = self._l_imu_b_f
        # C^T v - w x l_imu, body
        u = c0 * vn + c3 * ve + c6 * vd - (wy * lz - wz * ly)
        v = c1 * vn + c4 * ve + c7 * vd - (wz * lx - wx * lz)
        w = c2 * vn + c5 * ve + c8 * vd - (wx * ly - wy * lx)
        cfg = self.cfg
        self._stationary = (
            math.sqrt(u * u + v * v + w * w) < cfg.stationary_speed_mps
            and math.sqrt(wx * wx + wy * wy + wz * wz) < cfg.stationary_rate_dps * DEG_TO_RAD
        )
        if u < -cfg.reverse_detect_speed_mps:
            self._reversing = True
        elif u > cfg.reverse_detect_speed_mps:
            self._reversing = False

    # ========================================================================= read-out

    @property
    def origin_lla(self) -> Array | None:
        """Origin (lat deg, lon deg, height m) of the local NED frame, None before a fix."""
        return self._frame.origin_lla if self._frame is not None else None

    def bias_sigma(self) -> tuple[Array, Array] | None:
        """1-sigma of the gyro (rad/s) and accelerometer (m/s^2) bias estimates, (3,) each."""
        if self._p is None:
            return None
        d = np.sqrt(np.diag(self._p))
        return d[BG].copy(), d[BA].copy()

    def navigation_covariance(self) -> Array | None:
        """Covariance (9, 9) of the reference point's position, velocity and attitude error.

        p_ref = p - C l_imu, v_ref = v - C (w x l_imu): J P J^T with the lever-arm Jacobian.
        """
        ins, p = self._ins, self._p
        if ins is None or p is None:
            return None
        c_bn = ins.c_bn
        w_b = np.array(ins.w_b_lp_rps)
        j = np.zeros((9, N_STATES))
        j[0:3, POS] = np.eye(3)
        j[0:3, ATT] = skew(c_bn @ self._l_imu_b)
        j[3:6, VEL] = np.eye(3)
        j[3:6, ATT] = skew(c_bn @ cross3(w_b, self._l_imu_b))
        j[3:6, BG] = -c_bn @ skew(self._l_imu_b)
        j[6:9, ATT] = np.eye(3)
        return np.asarray(j @ p @ j.T)

    def reference_state(self) -> tuple[Array, Array, Array] | None:
        """Reference point NED position (3,), velocity (3,) and C_bn (3, 3); None if unknown."""
        ref = self._reference_point()
        if ref is None:
            return None
        assert self._ins is not None
        return np.array(ref[0]), np.array(ref[1]), self._ins.c_bn

    def _reference_point(self) -> tuple[Float3, Float3] | None:
        """Reference point NED position and velocity, p - C l_imu and v - C (w x l_imu), in
        plain floats (50 times a second); None if unknown."""
        ins = self._ins
        if ins is None or self._p is None:
            return None
        dn, de, dd = lever_arm_position_ned(ins.c_bn9, self._l_imu_b_f)
        un, ue, ud = lever_arm_velocity_ned(ins.c_bn9, ins.w_b_lp_rps, self._l_imu_b_f)
        p, v = ins.p_ned_m, ins.v_ned_mps
        return (p[0] - dn, p[1] - de, p[2] - dd), (v[0] - un, v[1] - ue, v[2] - ud)

    def solution(self) -> Solution:
        """The current solution at the time of the last IMU sample."""
        fix = self._last_fix
        ins = self._ins
        if ins is None:
            return Solution(
                mode=Mode.INITIALISING, is_ekf=True, **common_fields(self._t_s, fix, self._imu)
            )
        c9 = ins.c_bn9
        roll, pitch, yaw = rpy_from_mat9(c9)
        w_b = ins.w_b_lp_rps
        coasting_s = self._coasting_s()
        send, within = self._dead_reckoning_output(coasting_s)
        mode = self._mode(coasting_s, within)
        nav = self._reference_point() if send else None  # (None until P, i.e. a frame, exists)
        lat = lon = alt = None
        vel = None
        if nav is not None and self._frame is not None:
            lat, lon, alt = self._frame.to_lla(*nav[0])
            vel = nav[1]
        p = self._p
        bg, ba = ins.bias_g_rps, ins.bias_a_mps2
        quality, sats, hdop, age, geoid, station, talker = fix_fields(fix)
        imu, t = self._imu, self._t_s
        assert t is not None  # a sample came: the INS levelled on it
        # positional, in the field order (keywords cost a third of the solution's build)
        return Solution(
            t, mode, roll, pitch, yaw if p is not None else None,
            heading_rate_from_mat9(c9, w_b),  # output only
            lat, lon, alt, vel, (bg[0], bg[1], bg[2]), (ba[0], ba[1], ba[2]),
            self._sigma_tilt_rad(),
            quality, sats, hdop, age, geoid, station, talker,
            p is not None and coasting_s == 0.0 and fix is not None
            and fix.measures,  # gnss_ok
            imu.ok, imu.alarm, self._reversing, self._stationary, coasting_s > 0.0,
            True, self._convergence(coasting_s),  # is_ekf, convergence
        )  # fmt: skip

    def _convergence(self, coasting_s: float) -> Convergence:
        """Bias learning flags from the 1-sigmas in P; learning is frozen without P and while
        coasting."""
        p, cfg = self._p, self.cfg
        if p is None:
            return convergence_of(False, False, False, True)
        i, j = BA.start, BG.start
        var_ax, var_ay, var_gx, var_gy, var_gz = (
            p.item(i, i), p.item(i + 1, i + 1), p.item(j, j), p.item(j + 1, j + 1),
            p.item(j + 2, j + 2),
        )  # fmt: skip
        return convergence_of(
            math.sqrt(max(var_gx, var_gy)) < cfg.gyro_xy_converged_dps * DEG_TO_RAD,
            math.sqrt(var_gz) < cfg.gyro_z_converged_dps * DEG_TO_RAD,
            math.sqrt(max(var_ax, var_ay)) < cfg.accel_xy_converged_mps2,
            coasting_s > 0.0,
        )

    def _coasting_s(self) -> float:
        """Time without an accepted fix, or without a position (:func:`gap_beyond_s`),
        beyond ``gnss_timeout_s`` counts as coasting, else 0."""
        timeout = self.cfg.gnss_timeout_s
        return max(
            gap_beyond_s(self._t_s, self._t_accepted_rx_s, timeout),
            gap_beyond_s(self._t_s, self._t_pos_rx_s, timeout),
        )

    def _dead_reckoning_output(self, coasting_s: float) -> tuple[bool, bool]:
        """(position sent, within COASTING's accuracy): :func:`dead_reckoning_output` with the
        horizontal position 1-sigma of the covariance (the INS position's: the fix-error states
        describe fixes, and none come in an outage)."""
        p = self._p
        if coasting_s <= 0.0 or p is None:
            return True, True
        sigma_h = math.sqrt(p[POS.start, POS.start] + p[POS.start + 1, POS.start + 1])
        return dead_reckoning_output(coasting_s, sigma_h, self.cfg)

    def _mode(self, coasting_s: float, coast_within_accuracy: bool) -> Mode:
        return navigation_mode(
            fault=self._imu.fault,
            aligned=self._p is not None,
            coasting=coasting_s > 0.0,
            coast_within_accuracy=coast_within_accuracy,
            imu_alarm=self._imu.alarm,
            fix=self._last_fix,
            navigating_fix_qualities=self.cfg.navigating_fix_qualities,
            imu_gap=self._imu.timing.degraded(),
            gnss_glitch=self._t_s is not None and self._track.doubtful(self._t_s),
            heading_within_accuracy=self._heading_sigma_rad()
            <= self.cfg.navigating_heading_sigma_deg * DEG_TO_RAD,
            position_within_accuracy=self._epoch_share_m() <= NAVIGATING_POSITION_SHARE_M,
        )

    def _epoch_share_m(self) -> float:
        """The epoch time's share of the position's horizontal 1-sigma, m: the speed times
        the EPOCH state's 1-sigma (0 on a UTC host). After a free-running host's alignment
        it is the speed times the receiver latency's error; on a pull-away the epoch time
        and a velocity error look alike until the acceleration changes (0.1 s at 2.2 m/s,
        0.2 m off with 10 cm in P: NAVIGATING said 1-2 cm)."""
        p, ins = self._p, self._ins
        if p is None or ins is None:
            return 0.0
        var_t = p.item(EPOCH, EPOCH)
        if var_t == 0.0:
            return 0.0
        vn, ve, _ = ins.v_ned_mps
        return math.hypot(vn, ve) * math.sqrt(var_t)

    def _heading_sigma_rad(self) -> float:
        """The heading's 1-sigma, rad: P's (:meth:`_p_heading_sigma_rad`) and what the
        gyro turned at rest beyond the z bias (:meth:`_turn_or_step`; the spans not checked
        yet with what they turned so far), with what the recent
        heading corrections show beyond it (:meth:`CorrectionWindow.excess_rad`); pi
        before P."""
        if self._p is None or self._ins is None:
            return math.pi
        model = self._p_heading_sigma_rad()
        excess = self._heading_corrections.excess_rad(self._arw(), model)
        return math.hypot(model + self._rest_turn[0] + self._pending_turn_rad, excess)

    def _heading_weights(self) -> tuple[float, float]:
        """:func:`heading_weights` of the INS's attitude."""
        assert self._ins is not None
        c = self._ins.c_bn9
        return heading_weights(c[0], c[3], c[6])

    def _p_heading_sigma_rad(self) -> float:
        """The heading's 1-sigma from P (:func:`heading_weights`), rad."""
        p = self._p
        assert p is not None
        h_n, h_e = self._heading_weights()
        var = _quadratic_form(p, ATT.start, (h_n, h_e, 1.0))
        return math.sqrt(max(var, 0.0))

    def _vertical_bias_sigma_rps(self) -> float:
        """P's gyro bias 1-sigma about the vertical (what turns the heading), rad/s."""
        p, ins = self._p, self._ins
        assert p is not None and ins is not None
        c = ins.c_bn9
        return math.sqrt(max(_quadratic_form(p, BG.start, (c[6], c[7], c[8])), 0.0))

    def _arw(self) -> float:
        """The gyro's white rate noise (as measured at rest, if more), rad/sqrt(s): what
        :class:`CorrectionWindow` weighs the corrections with."""
        tun = self._tuning
        assert tun is not None
        return math.sqrt(tun.q_gyro_rad2_per_s)


def _quadratic_form(p: Array, i0: int, u: tuple[float, float, float]) -> float:
    """u' P[i0:i0+3, i0:i0+3] u in plain floats (a 3-vector's variance, per solution)."""
    a, b, c = u
    return (
        a * a * p.item(i0, i0)
        + b * b * p.item(i0 + 1, i0 + 1)
        + c * c * p.item(i0 + 2, i0 + 2)
        + 2.0
        * (a * b * p.item(i0, i0 + 1) + a * c * p.item(i0, i0 + 2) + b * c * p.item(i0 + 1, i0 + 2))
    )


def _tilt_of_accel_bias(c_bn: Array) -> Array:
    """M with tilt error = M dba, NED, of a platform levelled on the mean specific force:
    levelling makes the tilt error and the accelerometer bias error one quantity,
    C dba = g (-phi_E, phi_N, .)."""
    m = np.zeros((3, 3))
    m[0] = c_bn[1] / GRAVITY_MPS2
    m[1] = -c_bn[0] / GRAVITY_MPS2
    return m
