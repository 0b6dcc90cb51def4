"""The observer engine: Tereshkov observer + heading channel + gates + reference-point navigation.

Implements :class:`gateway.estimation.solution.Estimator`. Per IMU sample
(:meth:`ObserverEngine.imu`):
strapdown prediction of the platform DCM and biases (observer), then the reference-point
velocity and position, then a time-stamped history row (running integral of f_p, platform
heading, cumulative heading correction) so that a GNSS epoch arriving late can be compared with
exactly the IMU interval it describes. Per GNSS epoch (:meth:`ObserverEngine.gnss`): epoch time,
lever-arm velocities, stationarity, tilt correction (eq. 3), learning gates, heading channel,
position blend. Pure code: no I/O, no clock; time comes from the samples.

Choices the papers leave open (ALGORITHMS.md 1) are documented at the method that makes them.
"""

from __future__ import annotations

import logging
import math
from bisect import bisect_left
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from operator import itemgetter
from typing import Literal

from drivers.log_limit import LogLimiter
from drivers.samples import DEFAULT_GNSS_SIGMAS, FixQuality, Float3, GnssFix, ImuSample
from drivers.units import DEG_TO_RAD, GRAVITY_MPS2, MG_MPS2, SQRT_SECONDS_PER_HOUR, wrap_pi
from gateway.estimation.attitude import (
    IDENTITY9,
    Mat9,
    dcm_from_rpy,
    dcm_mul,
    exp_so3_2nd,
    exp_so3_9,
    heading_rate_from_mat9,
    roll_pitch_from_specific_force,
    rpy_from_mat9,
    to_mat9,
)
from gateway.estimation.bias_change import (
    BiasChange,
    CorrectionWindow,
    bias_change_text,
    xy_reopened_text,
    z_reopened_text,
)
from gateway.estimation.course_alignment import (
    DIRECTION_SIGMAS,
    CourseAlignment,
    direction_known,
)
from gateway.estimation.ekf.ekf_config import GM_ALLAN_FLOOR
from gateway.estimation.engine_base import (
    HeldEpochs,
    ImuHealth,
    common_fields,
    dead_reckoning_output,
    fix_fields,
    gap_beyond_s,
    levelling_correction,
    seeded_exponent,
)
from gateway.estimation.epoch_clock import EpochClock, late_epoch_text
from gateway.estimation.geodesy import LocalFrame
from gateway.estimation.gnss_error import (
    VelocityNoise,
    displacement_sigma_m,
    fix_position_sigma_m,
    fix_velocity_ne_mps,
    fix_velocity_sigma_mps,
)
from gateway.estimation.gnss_track import GnssTrack
from gateway.estimation.hdt_doubt import HdtDoubt, hdt_doubt_text
from gateway.estimation.heading_hint import HeadingHint
from gateway.estimation.imu_noise import ImuNoiseMeter, vibration_per_sample
from gateway.estimation.levelling import ALIGN_LAG_S, WindowMotion
from gateway.estimation.lever_arm import (
    along_body_x,
    antenna_velocity_along_body_x,
    centred_rate,
    centred_rate_velocity_sigma_mps,
    heading_from_antenna_course,
    lever_arm_position_ned,
    lever_arm_velocity_ned,
    reference_from_antenna,
    velocity_at,
)
from gateway.estimation.observer.accel_bias_filter import (
    GYRO_BIAS_SIGMA0_RPS,
    NIS_WINDOW_S,
    AccelBiasFilter,
    BiasFilterNoise,
    TrackEpoch,
)
from gateway.estimation.observer.coast_budget import CoastBudget
from gateway.estimation.observer.ground_constraint import (
    GROUND_TILT_RAD,
    GroundPeriod,
    GroundResidual,
)
from gateway.estimation.observer.hdt_screen import HdtScreen
from gateway.estimation.observer.heading_channel import HeadingChannel, HeadingSource
from gateway.estimation.observer.observer_config import ObserverConfig
from gateway.estimation.observer.position_channel import PositionChannel
from gateway.estimation.observer.rest_window import RestWindow
from gateway.estimation.observer.tereshkov import TereshkovObserver
from gateway.estimation.observer.tilt_loop import MAX_TAU_FACTOR, TiltLoop
from gateway.estimation.solution import (
    MAX_IMU_STEP_S,
    NAVIGATING_POSITION_SHARE_M,
    LearnedState,
    Mode,
    Solution,
    convergence_of,
    navigation_mode,
)
from gateway.estimation.temperature import TemperatureWalk

#: Interval of the log line that the epoch time's share holds NAVIGATING back, s: a standing
#: condition of the installation (a free-running host clock), not an event.
EPOCH_SHARE_LOG_S = 600.0
#: How long the epoch time's share holds NAVIGATING back after the speed let it go, s: what
#: the turns put into the heading (its courses' w dtau) and the tilt (a dtau in the tilt
#: loop's velocities) decays over several of the loops' time constants (4-16 s).
EPOCH_SHARE_HOLD_S = 60.0
#: History kept for late GNSS epochs, samples (5 s at 204.8 Hz): latency + one interval.
HISTORY_LEN = 1024
#: Tilt alignment accepts a non-quiet window after this long (vehicle never still/straight).
ALIGN_TIMEOUT_S = 10.0
#: Time constant of the running estimate of the tilt-residual noise (roll/pitch sigma).
E_NOISE_TAU_S = 10.0
#: Rate of turn output: mean body rate over this long before the last sample.
OUTPUT_RATE_WINDOW_S = 0.05
#: History rows searched first for a time (:meth:`ObserverEngine._history_at`).
RECENT_ROWS = 64
#: Height loop time constant, s: GNSS gives no vertical velocity, so the height (a double
#: integrator) needs a firm loop whatever the fix's sigma: weighed by a float fix's 0.4 m, it
#: drifted 60 m in a float spell.
HEIGHT_LOOP_TAU_S = 0.3
#: Velocity variance per horizontal axis of a position set without a velocity, m^2/s^2: a
#: field vehicle's speed is unknown to a few m/s; the next epoch's velocity takes over.
UNKNOWN_VELOCITY_VAR_M2PS2 = 9.0
#: Before the heading is known, how long after a rest the tilt loop runs on the speed along
#: body x in the direction taken leaving the rest, s (a wheeled vehicle reverses only
#: through a stop); after it each epoch checks the direction against the inertial velocity
#: (:meth:`ObserverEngine._direction_holds`).
BODY_X_LOOP_S = 5.0
#: A speed beyond this many sigma of the fix's velocity noise is creeping, not standing still.
CREEP_SIGMAS = 3.0
#: Gaps in the IMU stream are differenced across by eq. (3) while this many 1-sigma of the
#: velocity error their bridging may have made fit in the glitch gate (alone, never a glitch).
GAP_SIGMAS_IN_GATE = 3.0
#: Body rate for the stationarity test: mean over this long before the epoch.
STATIONARY_RATE_WINDOW_S = 0.2
#: Residual bias levels after convergence (seed 000, section 4): floors of the sigma model.
GYRO_BIAS_FLOOR_RPS = 0.01 * DEG_TO_RAD
ACCEL_BIAS_FLOOR_MPS2 = 0.01
#: Floor of the z accelerometer bias sigma once learnt from RTK heights (the product's own
#: extension, :meth:`ObserverEngine._learn_accel_bias_z`): 1.1-1.9 mg RMS measured after
#: 240 s on steep-turns seeds 1-3 (docs/ACCURACY.md), with margin.
ACCEL_BIAS_Z_FLOOR_MPS2 = 0.003
#: The x/y accelerometer bias estimate tells the size of the turn-on bias once the learning
#: exponent has taken out this much of it (:meth:`ObserverEngine._sigma_ba_mps2`).
SHOWN_BIAS_MIN_LEARNT = 0.2
#: The accel-bias filter's inconsistency re-opens the x/y biases once it states them within
#: this share of the turn-on sigma: before, re-opening them would change nothing.
REOPEN_ARMED_SHARE = 0.5
#: The IMU noise measured at rest is logged when its excess over the config's has changed by
#: more than this (relative) since it was last logged: it is measured again at every stop.
NOISE_TOLD_CHANGE = 0.25

# History row: a plain tuple (one per IMU sample, so no object overhead), read by these names:
# time; integral of f_p N, E, D (m/s); platform heading psi; cumulative heading correction;
# integral of the bias-corrected body rate x, y, z (rad); integral of the platform's slope
# N, E (s: the height per metre north and east that no velocity along body z gives).
_Row = tuple[float, float, float, float, float, float, float, float, float, float, float]
_T, _SF, _PSI, _HC, _WI = 0, slice(1, 4), 4, 5, slice(6, 9)
_SF_N, _SF_E, _SF_D, _WI_X, _WI_Y, _WI_Z, _GI_N, _GI_E = 1, 2, 3, 6, 7, 8, 9, 10
_row_time = itemgetter(_T)


log = logging.getLogger(__name__)


@dataclass
class ObserverCounters:
    """GNSS epochs not used as they came (for the logs and tests)."""

    position_rejected: int = 0  # position residual beyond the gate: a glitch
    position_resets: int = 0  # rejected for ``position_reset_s``: reset to the GNSS
    late_epochs: int = 0  # epoch older than the IMU history: dropped
    bias_changes: int = 0  # x/y biases re-opened: a change beyond their in-run model
    hdt_rejected: int = 0  # HDT off the gyro's turn since the last one used: a jump


class ObserverEngine:
    """Tereshkov observer engine (ALGORITHMS.md 1, 2, 4) behind the Estimator protocol."""

    def __init__(
        self,
        config: ObserverConfig | None = None,
        clock: EpochClock | None = None,
        noise: ImuNoiseMeter | None = None,
    ) -> None:
        """``clock``: the epoch clock to use (one that outlives the engine keeps what it learnt
        of the host clock across a restart), else a new one from ``config``; ``noise``: the
        same for the IMU's noise measured at rest."""
        cfg = config if config is not None else ObserverConfig()
        self.cfg = cfg
        self._l_ant_f = tuple(float(x) for x in cfg.antenna_lever_arm_m)
        self._heading = HeadingChannel(cfg)
        self._hdt_screen = HdtScreen(cfg)  # HDT's jumps against the gyro's turn
        self._hdt_doubt = HdtDoubt()  # an HDT the courses contradicted
        self.clock = clock or EpochClock.of(cfg)
        self._observer: TereshkovObserver | None = None
        # tilt alignment
        self._align_sum = [0.0] * 6  # sums of w_b and f_b over the window
        self._align_n = 0
        self._align_t0_s: float | None = None
        self._align_rot9 = IDENTITY9  # the body's turn since the window ended
        self._align_sigma_rad = 0.0  # the window's motion as GNSS said at its end
        self._align_first_s: float | None = None
        self._align_motion = WindowMotion(cfg.gnss_vel_sigma_mps, cfg.stationary_speed_mps)
        # tilt error of levelling on a moving window, or of a coast, decaying with the loop
        self._sigma_level_rad = 0.0
        self._sigma_level_held = 0.0  # the part of it in the loop's low-pass (TiltLoop.decay)
        self._turned_s = -math.inf  # the last closed-loop epoch that was turning, s
        # the tilt the accel-bias filter's recent corrections left, N/E, m/s^2 (_filter_epoch)
        self._ba_tilt_ne = (0.0, 0.0)
        self._ba_tilt_held_ne = (0.0, 0.0)
        self._heading_aligned = False
        # IMU-time state and history
        self._t_s: float | None = None
        self._sf = [0.0, 0.0, 0.0]  # running integral of f_p, m/s
        self._wi = [0.0, 0.0, 0.0]  # running integral of w_b, rad
        self._gi = [0.0, 0.0]  # running integral of the platform's slope N, E, s
        self._hc_rad = 0.0  # running integral of the heading control rate
        self._w_pz_rps = 0.0
        self._hist: deque[_Row] = deque(maxlen=HISTORY_LEN)
        self._held = HeldEpochs()  # epochs ahead of the IMU
        # reference-point navigation (NED around the first fix)
        self._p_ned_m = [0.0, 0.0, 0.0]
        self._v_ned_mps = [0.0, 0.0, 0.0]
        self._nav_valid = False
        self._frame: LocalFrame | None = None  # local NED around the first fix
        self._t_height_epoch_s: float | None = None  # last epoch whose height was used
        self._position = PositionChannel(cfg.gnss_error_correlation_s, cfg.gnss_white_share)
        self._t_position_s = 0.0  # epoch time the position channel was predicted to
        self._sf_position_ne = (0.0, 0.0)  # the f_p integral (north, east) then, m/s
        self._l_imu_f = tuple(float(x) for x in cfg.imu_lever_arm_m)
        self._l_imu_ant_m = math.dist(self._l_ant_f, self._l_imu_f)  # antenna to IMU, m
        self._courses = CourseAlignment(cfg.heading_gate_deg * DEG_TO_RAD)
        # the constant terms of the roll/pitch variance (_sigma_tilt_rad)
        arw = cfg.gyro_arw_deg_per_sqrt_h * DEG_TO_RAD / SQRT_SECONDS_PER_HOUR
        self._gyro_arw = arw  # rad/sqrt(s), the white rate noise measured where it is more
        self._tilt_loop = TiltLoop(cfg.tau_s, cfg.second_order_tilt_loop)
        self._tilt_loop.set_imu_noise(arw, 0.0)
        # while coasting, on the wheeled-vehicle constraint: a loop of its own, so that what
        # the GNSS loop still owes waits for GNSS (spent on the constraint, it moved pitch by
        # the last epochs' along-track residual: `outages` reference point 8 % worse)
        self._ground_loop = TiltLoop(cfg.tau_s, cfg.second_order_tilt_loop)
        self._ground_loop.set_imu_noise(arw, 0.0)
        self._rest = RestWindow(arw)  # the specific force of a stop (_level_at_rest)
        self._noise = noise or ImuNoiseMeter()  # the IMU's white noise at rest, vibration too
        self._imu_dt_s = 0.0  # the IMU's sample period, s
        self._floor_scale = 1.0  # the residual bias floors, for the noise measured
        self._noise_told = 1.0  # the noise excess last logged
        self._gap_end_s = -math.inf  # IMU time of the last gap that ended eq. (3)'s chain
        self._gap_dv_var = 0.0  # (m/s)^2 the gaps bridged since the last difference base put in
        self._accel_psd = 0.0  # the accelerometer's white noise, (m/s^2)^2/Hz, as measured
        self._mounting_var = (cfg.imu_mounting_sigma_deg * DEG_TO_RAD) ** 2
        self._v_imu_ned_mps = [0.0, 0.0, 0.0]  # IMU-point velocity while coasting
        # IMU-point minus reference-point velocity, C (w_b x l_imu), at the last velocity
        # reset: the velocity state integrates the IMU point's f_p since then
        self._lever_v_ned_mps = (0.0, 0.0, 0.0)
        # since the last epoch (t, (C l_imu) N/E then, that lever velocity N/E): the
        # horizontal position the lever arm's rotation has put into the state since
        self._lever_anchor: tuple[float, float, float, float, float] | None = None
        # GNSS bookkeeping
        self._last_fix: GnssFix | None = None
        self._t_vel_rx_s: float | None = None  # receive time of the last usable velocity
        self._t_pos_rx_s: float | None = None  # receive time of the last fix with a position
        self._prev_epoch: tuple[float, float, float, _Row] | None = None  # t, vN, vE at IMU
        self._stationary = False  # at rest and not turning (status bit, zero-rate update)
        self._at_rest = False  # reference point not moving (turning on the spot allowed)
        self._rest_row: _Row | None = None  # history row of the last epoch at rest
        self._forward: bool | None = None  # direction of travel since that rest
        self._forward_known = False  # ... beyond what a tilt error could make of it
        # the last epoch the tilt loop closed on the speed along body x: its row and the IMU's
        # velocity N/E it took (:meth:`_direction_holds`)
        self._body_x_last: tuple[_Row, float, float] | None = None
        self._held_forward: bool | None = None  # ... under a held course, since the last stop
        self._direction_pending = False  # ... not found yet: the epoch gives no velocity
        # reference point at the last still epoch, N and E, m: the fix's 1-sigma, time, quality
        self._stop_ne_m: tuple[float, float, float, float, int] | None = None
        self._t_velocity_s: float | None = None  # last epoch that gave a velocity
        # history row where the rest window began, and _turned_rad then
        self._zero_rate_start: tuple[_Row, float] | None = None
        self._turned_rad = 0.0  # sum of the platform's heading steps (_turn_platform)
        self._prev_rest_row: _Row | None = None  # newest row when last levelled at rest
        self._rest_last_row: _Row | None = None  # newest row at the last epoch at rest
        self._coasting = False  # GNSS velocity timed out: platform open loop
        # epoch time the tilt loop was left open with velocity flowing (moving before the
        # heading is known, glitches rejected): it drifts as in a coast (:meth:`_open_s`)
        self._t_open_s: float | None = None
        self._coast_budget: CoastBudget | None = None  # error sources as the outage began
        self._ground = GroundResidual()  # what the coast's constraint takes out: roll's e
        # learning gates and convergence bookkeeping
        self._learn_ok_since_s: float | None = None
        self._g_learn = 0.0  # integral of dt / tau_g while learning
        self._t_bg_learnt_s: float | None = None  # when the x/y gyro biases last learnt
        self._a_learn = 0.0  # integral of w_z^2 / (omega_a (1 + (w_z tau)^2)) dt while learning
        # where the x/y accelerometer bias learning started: estimate, its 1-sigma (None:
        # the turn-on spread, :meth:`_turn_on_ba_mps2`), exponent (a cold start's zeros
        # and turn-on sigma; a seed's): :meth:`_sigma_ba_mps2`
        self._ba_origin: tuple[float, float, float | None, float] = (0.0, 0.0, None, 0.0)
        self._az_learn_s = 0.0  # time the z accelerometer bias has learnt on RTK heights
        self._lever_vd_prev_mps: float | None = None  # (C (w x l_imu))_d at the last learning
        self._e_var_mps4 = 0.0  # running variance of one horizontal e component
        self._vel_noise = VelocityNoise(cfg.gnss_vel_sigma_mps)  # the receiver's, from e
        self._epoch_interval_s = 0.1  # last closed-loop GNSS interval
        self._t_last_epoch_s: float | None = None
        self._control_until_s: float | None = None  # IMU time the epoch's control rates end
        self._control_from_s = 0.0  # IMU time they began
        self._control_period_s = 0.0  # the epoch period they are meant for
        self._rejecting_since_s: float | None = None  # epoch time glitches began, if ongoing
        # the loop's recent tilt control: a bias change?
        self._corrections = CorrectionWindow("tilt")
        # IMU health
        self._imu = ImuHealth(cfg.imu_fault_s)  # timing, alarm, saturation, FAULT
        self.counters = ObserverCounters()
        self._log = LogLimiter(log)
        self._epoch_log = LogLimiter(log, EPOCH_SHARE_LOG_S)  # (a standing condition)
        self._t_epoch_share_beyond_s: float | None = None  # (_epoch_time_within_accuracy)
        self._track = GnssTrack()  # the receiver's own track: glitch or engine off?
        self._seed: LearnedState | None = None  # what a warm start gave (:meth:`seed`)
        # the x/y accelerometer biases from a filter instead of eq. (12), if configured
        self._ba_filter = (
            AccelBiasFilter(cfg.tau_s) if cfg.accel_bias_filter and cfg.estimate_biases else None
        )
        self._hint: HeadingHint | None = None  # the heading the last engine had, till aligned
        # the bias walks the IMU's temperature drives (:meth:`temperature`)
        self._temp = TemperatureWalk(
            cfg.gyro_bias_tempco_dps_per_c,
            cfg.accel_bias_tempco_mg_per_c,
            cfg.bias_correlation_time_s,
        )

    # ======================================================================== prediction

    def imu(self, sample: ImuSample) -> None:
        """Propagate with one IMU sample (body frame, bias not yet removed)."""
        t = sample.t
        dt = self._imu.accept(sample)
        if dt is None:
            return
        w, f = sample.w_ib_b, sample.f_ib_b
        self._t_s = t
        if self._stationary:  # the sample period is needed only where the noise is taken
            self._imu_dt_s = sample.dt
            self._noise.add(w, f, sample.dt)
        obs = self._observer
        if obs is None:
            self._imu_dt_s = sample.dt
            if self._hint is not None:
                self._hint.turn(w[2], dt)
            self._align_tilt(t, w, f, dt)
            return
        if self._control_until_s is not None and t > self._control_until_s:
            self._end_control()
        if self._imu.timing.lost_s:
            self._bridge(sample, dt)
        fpn, fpe, fpd = obs.propagate(w, f, dt)
        c = obs.c_bp9
        if self._coasting:
            self._coast_on_the_ground(fpn, fpe, fpd, dt, c, obs.w_b_rps)
        else:
            self._propagate_navigation(fpn, fpe, fpd, dt)
        self._hc_rad += self._w_pz_rps * dt
        sf = self._sf
        wi = self._wi
        w_b = obs.w_b_rps
        wi[0] += w_b[0] * dt
        wi[1] += w_b[1] * dt
        wi[2] += w_b[2] * dt
        gi = self._gi
        dt_up = dt / c[8]
        gi[0] += c[2] * dt_up
        gi[1] += c[5] * dt_up
        self._hist.append(
            (
                t, sf[0], sf[1], sf[2], math.atan2(c[3], c[0]), self._hc_rad,
                wi[0], wi[1], wi[2], gi[0], gi[1],
            )
        )  # fmt: skip
        if (
            not self._coasting
            and self._t_vel_rx_s is not None
            and t - self._t_vel_rx_s > self.cfg.gnss_timeout_s
        ):
            self._enter_coasting()
        if self._held:  # (no generator per sample when none waits)
            for t_e, fix in self._held.due(t):
                self._correct(fix, t_e)

    def _bridge(self, sample: ImuSample, dt: float) -> None:
        """``sample`` closes a step of ``dt`` that bridges lost samples (:class:`ImuTiming`):
        the rotation it holds over them is uncertain by what :func:`bridged_sigma` says,
        which the stated tilt takes (decaying with tau as the loop removes it), and the
        heading channel's and accel-bias filter's variances too. A gap (beyond
        MAX_IMU_STEP_S) ends the heading's bias interval (its drift is no bias's), and it
        ends the chain of eq. (3)'s differences once the velocity error the gaps since the
        last base may have put in the specific-force integral is beyond a third of the
        glitch gate (a held sample's vibration over 0.5 s is 0.2 m/s: a glitch, then applied
        clipped once it persisted, and the tilt went 0.7 deg off). Shorter gaps, which alone
        never make a glitch, are differenced across: a reader losing 0.1 s in every 0.16 s
        (a starved host) had ended every chain, and with the loop never closed the tilt
        drifted with the unlearnt gyro bias, 3 deg in 25 s at rest."""
        gap = self._imu.timing.bridged()
        assert self._observer is not None
        r = gap.rotation_rad
        sigma_tilt = max(r[0], r[1])
        self._sigma_level_rad = math.hypot(self._sigma_level_rad, sigma_tilt)
        long = dt > MAX_IMU_STEP_S
        self._heading.bridged(r[2], restart=long)
        if self._ba_filter is not None:
            self._ba_filter.bridge(sample.t, self._observer.c_bp9, sigma_tilt, new_chain=long)
        if long:
            v = gap.velocity_mps
            self._gap_dv_var += v[0] * v[0] + v[1] * v[1]
            gate_mps = self._glitch_dv_mps(self._epoch_interval_s)
            if (GAP_SIGMAS_IN_GATE * GAP_SIGMAS_IN_GATE) * self._gap_dv_var > gate_mps**2:
                self._gap_end_s = sample.t
            self._hdt_screen.restart(sample.t)

    def _propagate_navigation(self, fpn: float, fpe: float, fpd: float, dt: float) -> None:
        """Reference-point velocity and position from a = f_p + g; f_p integral for eq. (3).

        f_p is the IMU point's: since the last velocity reset the state has integrated the
        IMU point's motion less its lever-arm velocity then, and the position what the lever
        arm's rotation moved the IMU point since (:meth:`_lever_drift_ne`), which each
        epoch and the output take out (horizontally; the height loop takes the vertical).
        Per epoch, not per sample: it telescopes, C l_imu now against then.
        """
        sf = self._sf
        sf[0] += fpn * dt
        sf[1] += fpe * dt
        sf[2] += fpd * dt
        v = self._v_ned_mps
        p = self._p_ned_m
        v[0] += fpn * dt
        v[1] += fpe * dt
        v[2] += (fpd + GRAVITY_MPS2) * dt
        p[0] += v[0] * dt
        p[1] += v[1] * dt
        p[2] += v[2] * dt

    def _lever_drift_ne(self, c: Mat9, t: float) -> tuple[float, float]:
        """The horizontal position the IMU lever arm's rotation has put into the state since
        the last epoch, m: the integral of C (w x l_imu) - its value then, which is
        C l_imu now - C l_imu then - (C (w x l_imu) then) (t - then). At 1 Hz a headland
        turn's 19 deg/s moved the IMU point (0.5 m ahead) 0.17 m/s against the reference
        point within an epoch interval: the reference point went out up to 0.24 m off with
        RTK fixes (robustness `gnss-1hz` seed 41). Zero while coasting: the coast integrates
        the IMU point and constrains it as such."""
        a = self._lever_anchor
        if a is None:
            return (0.0, 0.0)
        t_a, cln_a, cle_a, lvn_a, lve_a = a
        cln, cle, _ = lever_arm_position_ned(c, self._l_imu_f)
        return (cln - cln_a - lvn_a * (t - t_a), cle - cle_a - lve_a * (t - t_a))

    def _lever_velocity_change_ne(self, c: Mat9, w_b: Float3) -> tuple[float, float]:
        """The IMU lever arm's horizontal velocity C (w x l_imu) now less its value at the
        last epoch: what the state's velocity has of it (0 while coasting)."""
        a = self._lever_anchor
        if a is None:
            return (0.0, 0.0)
        vn, ve, _ = lever_arm_velocity_ned(c, w_b, self._l_imu_f)
        return (vn - a[3], ve - a[4])

    def _platform(self) -> Mat9:
        """The platform's attitude now, C_b^n (row major)."""
        assert self._observer is not None
        return self._observer.c_bp9

    def _settle_lever(self, c: Mat9, velocity_reset: bool) -> None:
        """Take :meth:`_lever_drift_ne` out of the position (at an epoch, or the coast's
        start) and start anew from now: with the lever velocity of the epoch's fix after a
        velocity reset, else with the old one (the state goes on integrating from it)."""
        t = self._t_s
        a = self._lever_anchor
        if t is None or (a is None and not velocity_reset):
            return
        dn, de = self._lever_drift_ne(c, t)
        self._p_ned_m[0] -= dn
        self._p_ned_m[1] -= de
        lever = self._lever_v_ned_mps if velocity_reset or a is None else (a[3], a[4], 0.0)
        cln, cle, _ = lever_arm_position_ned(c, self._l_imu_f)
        self._lever_anchor = (t, cln, cle, lever[0], lever[1])

    def _coast_on_the_ground(
        self,
        fpn: float,
        fpe: float,
        fpd: float,
        dt: float,
        c: Mat9,
        w_b: tuple[float, float, float],
    ) -> None:
        """Dead reckoning without GNSS velocity, under the wheeled-vehicle constraints.

        The reference point (on the ground, between the wheels) neither slips sideways nor
        leaves the ground: its body velocity is (u, 0, 0). Only u is left to the inertial
        solution, so a tilt error (g theta, 0.01 m/s^2 for 0.06 deg) no longer grows a
        lateral velocity error: cross-track error comes from the heading error alone.
        The IMU point is integrated (f_p is its specific force) and constrained to the body
        velocity (u, 0, 0) + w_b x l_imu, so the lever arm's rotation terms do not leak into
        u (projecting the reference velocity instead kept the centripetal w^2 l_x of a turn
        and dropped its rotation: 0.4 m/s of forward error after a 10 s headland turn). A
        hard constraint: true sideslip and bounce are below a few cm/s on firm ground.
        """
        self._sf[0] += fpn * dt
        self._sf[1] += fpe * dt
        self._sf[2] += fpd * dt
        vi = self._v_imu_ned_mps
        vn = vi[0] + fpn * dt
        ve = vi[1] + fpe * dt
        vd = vi[2] + (fpd + GRAVITY_MPS2) * dt
        lx, ly, lz = self._l_imu_f
        wx, wy, wz = w_b
        # lever-arm velocity w_b x l_imu (body); forward speed of the IMU point u + lever x
        lev_x, lev_y, lev_z = wy * lz - wz * ly, wz * lx - wx * lz, wx * ly - wy * lx
        u_imu = c[0] * vn + c[3] * ve + c[6] * vd
        for i in range(3):
            vi[i] = c[3 * i] * u_imu + c[3 * i + 1] * lev_y + c[3 * i + 2] * lev_z
        if dt > MAX_IMU_STEP_S:  # a bridged gap's velocity is no roll's: a new period
            self._correct_tilt_on_the_ground(None, self._ground.restart() + dt)
        else:
            period = self._ground.add(vn - vi[0], ve - vi[1], wz, dt)
            if period is not None:
                self._correct_tilt_on_the_ground(period, period.span_s)
        u = u_imu - lev_x
        v, p = self._v_ned_mps, self._p_ned_m
        for i in range(3):
            v[i] = c[3 * i] * u
            p[i] += v[i] * dt

    def _correct_tilt_on_the_ground(self, period: GroundPeriod | None, span_s: float) -> None:
        """Eq. (3) on the wheeled-vehicle constraint's residual over the last ``span_s``
        (:mod:`.ground_constraint`), in a loop of its own with the tau for the constraint's
        noise; open where the forward speed's error would read as roll, and after a gap
        (``period`` None). The accel-bias filter, open while coasting, is told the turn the
        control gave the platform over the span."""
        obs = self._observer
        budget = self._coast_budget
        assert obs is not None and budget is not None
        if self._ba_filter is not None:
            w = obs.w_p_rps
            self._ba_filter.rotate((-w[0] * span_s, -w[1] * span_s, 0.0))
        sigma_u_mps = budget.sigma_u_mps(self._coasting_s())
        if period is None or sigma_u_mps * abs(period.w_z_rps) > GRAVITY_MPS2 * GROUND_TILT_RAD:
            obs.open_tilt_loop()
            return
        u_ne = self._ground_loop.control(
            period.e_ne_mps2, span_s, span_s, self.cfg.ground_sigma_mps
        )
        obs.correct_tilt(*u_ne)

    def _align_tilt(self, t: float, w: Float3, f: Float3, dt: float) -> None:
        """Roll/pitch from the mean specific force over a quiet window, yaw 0 until COG/HDT.

        Quiet = |mean w| over the window below ``align_quiet_rate_dps`` (still, or straight
        at constant speed, where the mean f_b is -g as well; the mean, because gyro noise and
        engine vibration exceed the threshold sample by sample). A turning window is dropped,
        unless the engine has tried for ``ALIGN_TIMEOUT_S``: then it is taken as is and the
        tilt loop (tau) finishes the job. The window levels :data:`ALIGN_LAG_S` after it
        ends, turned by the gyro since: GNSS reports a pull-away an epoch and its latency
        after the IMU feels it, so the window's motion (:class:`WindowMotion`) is known
        only then. Levelled at once, a window that ended 0.6 s into a gentle pull-away from
        a stop took it for rest: pitch 0.39 deg off with 0.08 stated (an engine restarted
        after an IMU stall at the stop, steep-turns seed 421).
        """
        if self._align_first_s is None:
            self._align_first_s = t
        if self._align_t0_s is None:
            self._align_t0_s = t
            self._align_sum = [0.0] * 6
            self._align_n = 0
            self._align_rot9 = IDENTITY9
            self._align_motion.restart()
        if t - self._align_t0_s < self.cfg.align_tilt_time_s:
            s = self._align_sum
            for i in range(3):
                s[i] += w[i]
                s[3 + i] += f[i]
            self._align_n += 1
            self._align_sigma_rad = self._align_motion.tilt_sigma_rad()  # as GNSS says so far
            return
        b = self._seed.bias_g_rps if self._seed is not None else (0.0, 0.0, 0.0)
        self._align_rot9 = dcm_mul(
            self._align_rot9,
            exp_so3_2nd((w[0] - b[0]) * dt, (w[1] - b[1]) * dt, (w[2] - b[2]) * dt),
        )
        if t - self._align_t0_s < self.cfg.align_tilt_time_s + ALIGN_LAG_S:
            return
        s, n = self._align_sum, self._align_n
        quiet = math.hypot(s[0], s[1], s[2]) / n < self.cfg.align_quiet_rate_dps * DEG_TO_RAD
        if not quiet and t - self._align_first_s < ALIGN_TIMEOUT_S:
            self._align_t0_s = None
            return
        roll, pitch = roll_pitch_from_specific_force((s[3] / n, s[4] / n, s[5] / n))
        # (the larger: a window's motion over the fixes up to its end and over those since)
        self._sigma_level_rad = max(self._align_sigma_rad, self._align_motion.tilt_sigma_rad())
        self._sigma_level_held = 0.0
        self._tilt_loop.clear()
        self._observer = TereshkovObserver(
            self.cfg.tau_s,
            self._tau_g_s(),
            self.cfg.omega_a_dps * DEG_TO_RAD,
            dcm_mul(to_mat9(dcm_from_rpy(roll, pitch, 0.0)), self._align_rot9),
        )
        self._observer.learn_accel = self._ba_filter is None
        if self._seed is not None:
            self._apply_seed(self._observer, self._seed)
        self._noise_as_measured()  # at a restart on the move: what the last engine measured
        if self._t_vel_rx_s is None:
            # no GNSS velocity yet (a receiver without a fix at power-up): the tilt loop is
            # open from here, the tilt drifting with the unlearnt gyro bias. Unstated, 50 s
            # without a fix from power-up drifted pitch 4 deg parked with 0.85 stated.
            self._t_open_s = t

    # ======================================================================= warm start

    def moving_before(self) -> None:
        """The vehicle was moving when this engine took over: see the protocol."""
        self._align_motion.moving_before = True

    def heading_before(self, hint: HeadingHint) -> None:
        """The heading the engine this one replaces had: see the protocol."""
        self._hint = hint

    def seed(self, learned: LearnedState, f_rest_b_mps2: Float3 | None = None) -> bool:
        """Start from learned biases (a warm start, or the engine this one replaces after an
        IMU gap): accepted until the observer begins to learn on its own (the learning
        hold-off after the first usable epochs), refused without bias estimation.

        The biases replace the turn-on guess (the z gyro bias through the heading channel's
        KF, as an observation of its sigma); the learning exponents are set to what the
        sigma model needs to say the seed's sigmas, so the convergence flags and the roll/pitch
        sigma (NAVGW_STATUS bytes 5, 7) state the seed's accuracy, no better. A tilt already
        levelled takes the accelerometer bias out (:func:`levelling_correction`); with the
        mean specific force of the rest going on, it is levelled again on that instead.

        Why again: the tilt loop has run on the turn-on gyro bias since the levelling, and
        its PI response to the b_g tau it built up (0.1 deg/s for 3 s: 0.3 deg) outlasts the
        seed by 20-40 s (steep-turns seed 12, parked at 11 deg of roll). At rest the tilt is
        what the mean specific force less the seeded bias says, to the bias's sigma / g.
        """
        obs = self._observer
        started = self._g_learn > 0.0 or self._a_learn > 0.0 or (obs is not None and obs.learn)
        started |= self._seed is not None
        if started or not self.cfg.estimate_biases or not learned.is_valid():
            return False
        self._seed = learned
        self._end_rest()
        if obs is not None:
            self._apply_seed(obs, learned)
            if f_rest_b_mps2 is not None:
                ba, f = learned.bias_a_mps2, f_rest_b_mps2
                minus_f_true = (ba[0] - f[0], ba[1] - f[1], ba[2] - f[2])  # -(f - b_a)
                self._rotate_platform(levelling_correction(obs.c_bp9, minus_f_true))
        return True

    def _apply_seed(self, obs: TereshkovObserver, s: LearnedState) -> None:
        ba = obs.ba_hat_mps2
        dba = (s.bias_a_mps2[0] - ba[0], s.bias_a_mps2[1] - ba[1], s.bias_a_mps2[2] - ba[2])
        self._rotate_platform(
            levelling_correction(obs.c_bp9, (float(dba[0]), float(dba[1]), float(dba[2])))
        )
        obs.set_biases(s.bias_g_rps, s.bias_a_mps2)
        kf = self._heading.kf
        kf.update(s.bias_g_rps[2] - kf.x_rps, s.sigma_g_rps[2] ** 2)
        obs.set_gyro_bias_z(self._heading.bg_z_rps)
        cfg = self.cfg
        self._g_learn = seeded_exponent(
            cfg.gyro_bias_sigma0_dps * DEG_TO_RAD, max(s.sigma_g_rps[0], s.sigma_g_rps[1])
        )
        sigma_a = max(s.sigma_a_mps2[0], s.sigma_a_mps2[1])
        self._a_learn = seeded_exponent(cfg.accel_bias_sigma0_mps2, sigma_a)
        self._ba_origin = (s.bias_a_mps2[0], s.bias_a_mps2[1], sigma_a, self._a_learn)
        self._az_learn_s = cfg.accel_bias_z_tau_s * seeded_exponent(
            cfg.accel_bias_sigma0_mps2, s.sigma_a_mps2[2]
        )

    def learned_state(self) -> LearnedState | None:
        """Bias estimates with the sigmas the observer states for them: x/y from the learning
        exponents (floored at the paper's residual level), z gyro from the heading channel's
        KF, z accelerometer from the time its height loop has learnt it."""
        obs = self._observer
        if obs is None:
            return self._seed
        bg, ba = obs.bg_hat_rps, obs.ba_hat_mps2
        sg, sa = self._sigma_bg_rps(), self._sigma_ba_mps2()
        return LearnedState(
            bias_g_rps=(float(bg[0]), float(bg[1]), float(bg[2])),
            sigma_g_rps=(sg, sg, self._heading.kf.sigma_rps),
            bias_a_mps2=(float(ba[0]), float(ba[1]), float(ba[2])),
            sigma_a_mps2=(sa, sa, self._sigma_baz_mps2()),
        )

    # ======================================================================= corrections

    def temperature(self, t_s: float, temp_c: float) -> None:
        """The IMU's temperature at ``t_s`` (IMU_AUX, 1 Hz): while it moves, the biases
        walk faster (:mod:`gateway.estimation.temperature`): the z gyro bias filter's walk
        and the accelerometer-bias filter's take it, and eq. (11) follows the x/y gyro
        biases faster (:meth:`_tau_g_s`)."""
        temp = self._temp
        temp.add(t_s, temp_c)
        self._heading.kf.q_temp_rps2_per_s = temp.gyro_rps2_per_s
        if self._ba_filter is not None:
            self._ba_filter.temp_walk = (temp.gyro_rps2_per_s, temp.accel_mps4_per_s)
        if self._observer is not None:
            self._observer.tau_g_s = self._tau_g_s()

    def _tau_g_s(self) -> float:
        """Eq. (11)'s time constant now: the paper's for the in-run wander's walk q0, and
        sqrt(q0 / (q0 + q_T)) of it while the temperature's walk q_T adds to it (a PI loop's
        integral gain goes as the square root of the walk it follows, a Kalman filter's
        does; its tilt error on a bias ramp r is r tau tau_g), but never below the tilt
        loop's longest time constant: the PI loop's damping, sqrt(tau_g / tau) / 2, stays
        at 1/2 or more."""
        cfg = self.cfg
        q_t = self._temp.gyro_rps2_per_s
        if not q_t:
            return cfg.tau_g_s
        q0 = self._heading.kf.q_wander_rps2_per_s
        shortest = min(cfg.tau_g_s, MAX_TAU_FACTOR * cfg.tau_s)
        return max(cfg.tau_g_s * math.sqrt(q0 / (q0 + q_t)), shortest)

    def gnss(self, fix: GnssFix) -> None:
        """Correct with one GNSS epoch; it may arrive after IMU samples of later time.

        An epoch whose time is ahead of the last IMU sample (zero or under-stated latency)
        waits until the IMU has covered it, so e and the heading residual always compare
        quantities of the same instant.
        """
        self._last_fix = fix
        if self._observer is None:  # (before a window too: the velocity at its start)
            self._align_motion.add(fix)
        if self._observer is None or not fix.measures:
            return
        t_e = self.clock.epoch_time(fix)
        if t_e is not None and not self._held.hold(t_e, fix, self._t_s):
            self._correct(fix, t_e)

    def _correct(self, fix: GnssFix, t_e: float) -> None:
        """All corrections of one epoch at epoch time ``t_e`` (<= the last IMU time)."""
        obs = self._observer
        assert obs is not None
        row = self._history_at(t_e)
        c_bn = obs.c_bp9
        if row is None:
            self._prev_epoch = None
            self._update_gates(t_e, ok=False)
            self._correct_position(fix, t_e, row, c_bn, None)
            return
        w_lever = self._lever_rate(t_e, row)
        c_e = self._attitude_at(row, c_bn)
        v_ant = self._antenna_velocity(fix, t_e, row, c_e, w_lever)
        if v_ant is None:
            if self._direction_pending:
                # skipped as a rejected epoch is: the next difference spans it, so what the
                # last epochs at rest took for zero velocity (the pull-away had begun) is
                # taken back by it, and the gates stay as they are; no longer at rest once
                # the speed is beyond the stationary speed (below it, one epoch's noise
                # tail must not end a stop's means)
                if fix.sog_mps is None or fix.sog_mps >= self.cfg.stationary_speed_mps:
                    self._at_rest = self._stationary = False
                    self._end_rest()
                self._update_gates(t_e, ok=None)
            elif fix.sog_mps is not None:
                self._prev_epoch = None
                self._update_gates(t_e, ok=False)
            # else a position without a velocity (a receiver sending GGA at 10 Hz and RMC and
            # VTG at 1 Hz): the epochs with one go on as if it were not there, the difference
            # chain, the control period and the gates (ending the chain at each, the tilt
            # loop never closed: no heading in 16 minutes)
            self._correct_position(fix, t_e, row, c_e, None)
            return
        w_still = self._mean_rate(t_e - STATIONARY_RATE_WINDOW_S, row)
        v_ref = velocity_at(v_ant, c_e, w_lever, self._l_ant_f, (0.0, 0.0, 0.0))
        v_imu = velocity_at(v_ant, c_e, w_lever, self._l_ant_f, self._l_imu_f)
        speed_ref = math.hypot(v_ref[0], v_ref[1])
        if self._coasting:
            # the coast's open-loop drift is still in the tilt: it decays with the loop from
            # here (it went from 0.61 deg stated to 0.09 at once, 0.43 deg off: outages 31)
            self._close_open_span(self._open_s(fix.t))
        self._t_vel_rx_s = fix.t
        self._coasting = False
        # at rest in translation: v = 0 is then a velocity reference in any azimuth, so the
        # tilt loop and x/y gyro learning need no heading and no rate test (a large gyro bias
        # must not keep the loop open: 0.5 deg/s per axis tilts 2 deg in 4 s open loop)
        self._at_rest = speed_ref < self.cfg.stationary_speed_mps
        rate_limit = self.cfg.stationary_rate_dps * DEG_TO_RAD + 3.0 * self._sigma_bg_rps()
        self._stationary = self._at_rest and math.hypot(*w_still) < rate_limit
        self._hold_control(t_e)
        # Before the heading is known, creeping under the stationary speed is no velocity
        # reference: its direction may be a course the receiver holds from before the stop
        # (the simulator's, u-blox's below 0.1 m/s), and v = 0 is not the velocity either.
        # Closed on it, a pull-away after a restart kicked pitch 0.2 deg as the held course
        # turned, 0.39 deg off with 0.09 stated (steep-turns seed 7, stalls): the loop stays
        # open for those epochs, until the speed along body x takes over.
        sigma_v = fix_velocity_sigma_mps(fix, self._gnss_vel_sigma_mps())
        creeping = speed_ref > CREEP_SIGMAS * sigma_v
        rest_reference = self._at_rest and (self._heading_aligned or not creeping)
        v_tilt, closed = (v_imu[0], v_imu[1]), self._heading_aligned or rest_reference
        if not self._heading_aligned:
            self._direction_from_hint(fix, v_ant, c_e, w_lever, row)
            along_x = self._velocity_along_body_x(fix, t_e, c_e, w_lever, row)
            if along_x is not None:
                v_tilt, closed = along_x, True
        track = (
            self._track_epoch(fix, c_e, v_ref, row)
            if self._heading_aligned and self._ba_filter is not None
            else None
        )
        sigma_v_imu = math.hypot(sigma_v, self._lever_sigma_mps())
        glitch = self._correct_tilt(t_e, v_tilt[0], v_tilt[1], row, closed, sigma_v_imu, track)
        if not closed:
            # moving before the heading and the direction of travel are known: the velocity is
            # in the receiver's azimuth, not the platform's, so no base for eq. (3)'s next
            # difference either (0.18 deg of tilt once the direction became known)
            self._prev_epoch = None
        # Learning goes on at rest: the tilt loop is closed there too (v = 0 is the best
        # velocity reference there is), the control rate still equals the x/y gyro bias
        # (eq. 15), and eq. (12) moves no accelerometer bias without a yaw rate. Freezing it
        # let the tilt settle at b_g tau during every stop, then an 8 s hold-off after it.
        self._update_gates(
            t_e,
            ok=(
                int(fix.quality) in self.cfg.learning_fix_qualities
                and not glitch
                and (self._heading_aligned or self._at_rest)
                and not self._imu.upset
            ),
        )
        self._zero_rate_update(t_e, row)
        self._level_at_rest(t_e, (v_ref[0], v_ref[1]))
        self._imu.upset = False
        # (before the heading is found C's yaw is arbitrary, and so was v_ref's lever-arm part)
        cog_ref = (
            math.atan2(v_ref[1], v_ref[0]) % (2.0 * math.pi)
            if self._heading_aligned
            else heading_from_antenna_course(
                v_ant, c_e, w_lever, self._l_ant_f, forward=self._forward is not False
            )
        )
        yaw_rate = c_bn[6] * w_still[0] + c_bn[7] * w_still[1] + c_bn[8] * w_still[2]
        aligned = self._heading_aligned
        self._correct_heading(t_e, row, cog_ref, speed_ref, fix.heading_rad, yaw_rate, c_bn[8])
        if not aligned and self._heading_aligned:
            # The heading was found: the reference point (antenna - C l_ant) and its velocity
            # stood in an arbitrary azimuth until now (0.84 m off with a 0.5 m lever arm
            # turned by 115 deg); they start again, from this fix, in the heading found.
            c_e = self._attitude_at(row, obs.c_bp9)
            v_ref = velocity_at(v_ant, c_e, w_lever, self._l_ant_f, (0.0, 0.0, 0.0))
            v_imu = velocity_at(v_ant, c_e, w_lever, self._l_ant_f, self._l_imu_f)
            self._nav_valid = False
            self._prev_epoch = None  # its velocity and f_p integral were in the old azimuth
        self._lever_v_ned_mps = (v_imu[0] - v_ref[0], v_imu[1] - v_ref[1], v_imu[2] - v_ref[2])
        # A glitch's velocity is not the reference point's either: one epoch's RMC speed 5 kn
        # off had set it, and the position went out 0.43 m off (field seed 7, 300 s). Only
        # where the gate had this fix's noise (RTK fixed): it has the RTK figure, so a noisier
        # quality's epochs are "glitches" by their noise alone, and left without the velocity
        # DGNSS spells drifted (cross-track 6.8 -> 15.6 cm on float-spells)
        rejected = glitch and self._velocity_rejected(t_e) and sigma_v <= self._gnss_vel_sigma_mps()
        self._correct_position(fix, t_e, row, c_e, None if rejected else (v_ref[0], v_ref[1]))

    def _hold_control(self, t_e: float) -> None:
        """The control rates this epoch sets are meant for one epoch period (time since the
        previous epoch), as eq. (3)'s discrete form and the heading gain assume. The next
        epoch normally replaces them; if it does not come, both loops open after 1.5 periods
        (the half period covers receive jitter and the IMU sample granularity: exactly one
        period cut off ~2 % of every correction at 204.8 Hz, roll 0.092 -> 0.093 deg on
        field). Held until the next epoch instead, the last rates before an outage ran on to
        the GNSS timeout: 15 periods of one noisy correction, 1.2 deg of roll and pitch at the
        start of a 20 s outage after a DGNSS spell."""
        last = self._t_last_epoch_s
        period_s = t_e - last if last is not None else 0.0
        if not 0.0 < period_s <= self.cfg.max_gnss_interval_s:
            period_s = self._epoch_interval_s
        assert self._t_s is not None and self._observer is not None
        if self._control_until_s is not None:
            # The previous epoch's rates are still on: what is left of its period is applied
            # at once, so each epoch corrects for its full period. Epochs that reach the
            # engine in a burst (a loaded host) otherwise replaced each other's rates unused:
            # one correction in twenty, and the tilt loop all but open.
            left = self._control_left_s(self._t_s)
            if left > 0.0:
                self._observer.apply_control(left)
                self._hc_rad += self._w_pz_rps * left
        self._control_from_s, self._control_period_s = self._t_s, period_s
        self._control_until_s = self._t_s + 1.5 * period_s

    def _end_control(self) -> None:
        """The epoch's period is over and no new epoch has come: both loops open."""
        obs = self._observer
        assert obs is not None
        last = self._t_last_epoch_s
        self._set_tilt_open(self._t_s if last is None else last + 1.5 * self._control_period_s)
        obs.set_heading_rate(0.0)
        self._w_pz_rps = 0.0
        self._control_until_s = None

    def _zero_rate_update(self, t_e: float, row: _Row) -> None:
        """At rest, every ``gyro_z_window_s`` the mean body z rate is the residual z-gyro bias
        (heading channel KF): a 20 s stop pins it to ARW / sqrt(20 s) = 0.007 deg/s, where
        course-over-ground heading could not observe it at all. The vehicle has not turned
        over the window, so the platform's yaw is held where it was at its start: its drift
        (less the steps applied meanwhile) is turned back. Without the hold a 10 min stop
        left the heading 0.7 deg off, the gyro's random walk. Not where a heading reference
        corrected it meanwhile (HDT at rest): that had taken part of the drift out already,
        and the hold took it twice (0.9 deg the other way after a cold start)."""
        if not (self._stationary and self.cfg.estimate_biases) or self._imu.upset:
            self._zero_rate_start = None
            return
        start = self._zero_rate_start
        if start is None or t_e - start[0][_T] < self.cfg.gyro_z_window_s:
            if start is None:
                self._zero_rate_start = (row, self._turned_rad)
                self._heading.rest_began()
            return
        row0, turned0 = start
        self._zero_rate_start = (row, self._turned_rad)
        window_s = t_e - row0[_T]
        if self._heading.observe_zero_rate(t_e, (row[_WI_Z] - row0[_WI_Z]) / window_s, window_s):
            assert self._observer is not None
            self._observer.set_gyro_bias_z(self._heading.bg_z_rps)
            if row[_HC] == row0[_HC]:  # no heading control meanwhile
                self._turn_platform(
                    -(wrap_pi(row[_PSI] - row0[_PSI]) - (self._turned_rad - turned0))
                )
                self._heading.held()
        self._heading.rest_began()

    def _level_at_rest(self, t_e: float, v_ref_ne_mps: tuple[float, float]) -> None:
        """Standing still, the tilt is the stop's mean specific force less the accelerometer
        bias (:mod:`gateway.estimation.observer.rest_window`). Once that mean is better than
        the tilt loop's tilt (its own noise, the gyro's ARW through tau, 0.05 deg: 3 s of
        samples with this engine vibration; sooner where a levelling on a moving window left
        more in it), the platform is levelled on it every epoch and the loop, which would
        add the ARW and the x/y gyro bias error times tau (eq. 10), stays open. The x/y gyro
        biases are learnt from what the control rate converges to at rest (eq. 15), the mean
        bias-corrected body rate, directly (:meth:`_observe_gyro_bias_at_rest`). The
        product's own extension of seed 000; the stated sigma keeps the loop's terms.
        """
        obs = self._observer
        assert obs is not None and self._t_s is not None
        if not (self._stationary and self.cfg.estimate_biases) or self._imu.upset:
            self._end_rest()
            return
        self._noise_as_measured()
        row, last = self._hist[-1], self._rest_last_row
        self._rest_last_row = row
        f_b: Float3 | None = None
        if last is not None and row[_T] > last[_T]:
            # the mean f_b - b_a since the last epoch: C^T of the mean f_p (C holds still at
            # rest: the levelling turns it at the epochs, between which the chunks lie)
            d, c = row[_T] - last[_T], obs.c_bp9
            sn, se, sd = ((row[i] - last[i]) / d for i in (_SF_N, _SF_E, _SF_D))
            f_b = (
                c[0] * sn + c[3] * se + c[6] * sd,
                c[1] * sn + c[4] * se + c[7] * sd,
                c[2] * sn + c[5] * se + c[8] * sd,
            )
        level = self._rest.epoch(t_e, self._t_s, f_b, (row[_WI_X], row[_WI_Y]), v_ref_ne_mps)
        if (
            level is None
            or level.sigma_tilt_rad**2 >= self._noise_tilt_var + self._sigma_level_rad**2
        ):
            self._prev_rest_row = None
            return
        f = level.f_b_mps2  # bias-corrected: level on -f
        self._rotate_platform(levelling_correction(obs.c_bp9, (-f[0], -f[1], -f[2])))
        self._set_tilt_open(t_e)
        # what a levelling on a moving window, a coast or an open loop left in the tilt is
        # gone with it
        self._t_open_s = None
        if level.sigma_tilt_rad < self._sigma_level_rad:
            self._sigma_level_rad, self._sigma_level_held = level.sigma_tilt_rad, 0.0
        self._ba_tilt_ne = self._ba_tilt_held_ne = (0.0, 0.0)
        # eq. (3)'s differences start again after the stop: the corrections they would have
        # made here are not made, so the next ones must not telescope onto them (the first
        # 0.2 s of a pull-away are still "at rest", and before the heading is known their
        # velocity is in another azimuth than the body-x speed that follows: 0.12 deg)
        self._prev_epoch = None
        prev = self._prev_rest_row
        observed = False
        if prev is not None and row[_T] > prev[_T] and obs.learn:
            observed = True
            d = row[_T] - prev[_T]
            w_res = ((row[_WI_X] - prev[_WI_X]) / d, (row[_WI_Y] - prev[_WI_Y]) / d)
            self._observe_gyro_bias_at_rest(w_res, d)
        self._prev_rest_row = row
        if self._ba_filter is not None:
            sigma_bg = self._sigma_bg_rps() if observed else None
            self._ba_filter.level(
                t_e, obs.c_bp9, filter_biases(obs), level.sigma_tilt_rad, sigma_bg
            )

    def _noise_as_measured(self) -> None:
        """The IMU's white noise as measured at rest (:mod:`gateway.estimation.imu_noise`),
        where it is beyond the config's datasheet figures and ``vibration_*``, else those:
        the gyro's ARW in the stated tilt, its coast drift, the zero-rate update and the
        stop's rotation test, the accelerometer's noise in the stop's mean, and the residual
        bias floors in proportion to the larger of the two excesses (a linear observer's
        steady-state error is in proportion to the noise that drives it). Three times the
        simulator's vibration left the accelerometer x bias 0.03 m/s^2 off after a turn,
        against the 0.01 floor: 0.46 deg of pitch with 0.09 stated (field seed 94)."""
        cfg, dt = self.cfg, self._imu_dt_s
        arw = cfg.gyro_arw_deg_per_sqrt_h * DEG_TO_RAD / SQRT_SECONDS_PER_HOUR
        vrw = cfg.accel_vrw_mps_per_sqrt_h / SQRT_SECONDS_PER_HOUR
        sigma_a = math.hypot(  # a sample
            vrw / math.sqrt(dt), vibration_per_sample(cfg.vibration_accel_mps2, dt)
        )
        sigma_g = math.hypot(
            arw / math.sqrt(dt), vibration_per_sample(cfg.vibration_gyro_dps * DEG_TO_RAD, dt)
        )
        r_g, r_a = self._noise.excess(sigma_g, sigma_a)
        if abs(max(r_g, r_a) / self._noise_told - 1.0) > NOISE_TOLD_CHANGE:
            self._noise_told = max(r_g, r_a)
            log.info(
                "IMU noise at rest %.1f times (gyro) and %.1f times (accelerometer) the "
                "config's, engine vibration included: the stated accuracy follows it",
                r_g,
                r_a,
            )
        self._gyro_arw = arw * r_g
        self._floor_scale = max(r_g, r_a)
        self._accel_psd = (sigma_a * r_a) ** 2 * dt
        self._rest.set_noise(self._gyro_arw, self._accel_psd)
        self._heading.set_noise(self._gyro_arw, self._floor_scale)
        for loop in (self._tilt_loop, self._ground_loop):
            loop.set_imu_noise(self._gyro_arw, self._accel_psd)
        if self._ba_filter is not None:
            self._ba_filter.noise = self._bias_filter_noise()

    def _observe_gyro_bias_at_rest(self, w_res_rps: tuple[float, float], d_s: float) -> None:
        """At rest the mean bias-corrected body rate x/y over ``d_s`` is the gyro bias error
        plus the mean of the ARW (variance ARW^2 / d): a scalar Kalman update of each axis
        from the sigma the engine states, which then states the result (a zero-rate update,
        as the heading channel's for z). A cold 0.1 deg/s is 0.007 deg/s after a 20 s stop,
        where eq. (11)'s loop (tau_g 40 s) would have left 60 % of it."""
        obs = self._observer
        assert obs is not None
        p = self._sigma_bg_rps() ** 2
        k = p / (p + self._gyro_arw**2 / d_s)
        bg = obs.bg_hat_rps
        obs.set_biases((bg[0] + k * w_res_rps[0], bg[1] + k * w_res_rps[1], bg[2]), obs.ba_hat_mps2)
        sigma0 = self.cfg.gyro_bias_sigma0_dps * DEG_TO_RAD
        self._g_learn = max(self._g_learn, seeded_exponent(sigma0, math.sqrt((1.0 - k) * p)))
        self._t_bg_learnt_s = self._t_s

    def _end_rest(self) -> None:
        """The stop is over (or its means are, as the biases they were corrected with were
        replaced by a seed)."""
        self._rest.stop()
        self._noise.restart()
        self._prev_rest_row = self._rest_last_row = None

    def _antenna_velocity(
        self, fix: GnssFix, t_e: float, row: _Row, c_e: Mat9, w_lever: Float3
    ) -> Float3 | None:
        """The antenna velocity (NED, m/s) an epoch gives, or None: the receiver's, but below
        ``course_hold_speed_mps`` with the heading known, its speed along body x.

        Why: a receiver holds or blanks its course over ground at low speed (u-blox below
        0.1 m/s, static hold and low-speed course filters further up), so a vehicle that
        stops and reverses reports its speed along the course it came in on. The tilt loop
        read twice the acceleration of the reversing start: with a receiver holding its
        course below 0.5 m/s, roll 1.3 deg off with 0.18 stated (headland-reversing seed 91,
        462 frames). A wheeled vehicle's antenna moves along body x plus the lever arm's
        rotation (:func:`antenna_velocity_along_body_x`); forward or reversing is what the
        engine's own velocity says, the last epoch's carried on by f_p to this one (the
        antenna's, with the mast's rocking). Where that and the fix's speed are both within
        :data:`DIRECTION_SIGMAS` of the velocity noise (and under ``stationary_speed_mps``),
        the reference point is taken as still (v = 0 is then within that of the truth in
        any direction). A speed beyond the noise is motion even under the stationary speed:
        taken as still, a 0.08 m/s creep went out as 0.0 m/s, and the pull-away's epochs
        at 0.09-0.11 m/s started eq. (3)'s differences 0.1 m/s off, 0.1 / (g tau) of tilt
        (0.35 deg of pitch with 0.085 stated: outages seed 41 with a 20 Hz receiver).

        Faster, the direction is the one found since that stop (a wheeled vehicle reverses
        only through one): from the reference point's displacement since it, once beyond
        :data:`DIRECTION_SIGMAS` of the two fixes' noise (:func:`displacement_sigma_m`: a
        few cm with RTK), or from that velocity, once beyond those sigmas of the fix's
        velocity noise and of the drift the tilt puts into it since the last epoch that gave
        one. Until then the epoch gives no velocity. Why: a pull-away's first epochs carry a
        few cm/s (the stop's last epoch set the velocity to zero), while the mast's rocking
        and the engine's vibration put 0.02 m/s into the antenna's velocity; the sign of
        that noise, taken as reversing, held itself (the epoch's velocity is the next one's
        start): pitch 1.3 deg off with 0.15 stated as field seed 95 drove off at three times
        the simulator's vibration.

        Before the heading is known, a receiver that has not moved yet gives SOG only: a
        speed below ``stationary_speed_mps`` is then zero velocity (the tilt loop still
        levels the platform at rest before the first drive), a faster one no velocity
        (:func:`fix_velocity_ne_mps`).
        """
        sog = fix.sog_mps
        cfg = self.cfg
        self._direction_pending = False
        if sog is None:  # a position alone: the stop and the direction as they were
            return None
        if sog >= cfg.course_hold_speed_mps or not (self._heading_aligned and self._nav_valid):
            self._held_forward = self._stop_ne_m = None
            self._t_velocity_s = t_e
            vel = fix_velocity_ne_mps(fix, cfg.stationary_speed_mps)
            return None if vel is None else (vel[0], vel[1], 0.0)
        v, sf = self._v_ned_mps, self._sf
        v_e = (v[0] - (sf[0] - row[_SF_N]), v[1] - (sf[1] - row[_SF_E]), 0.0)
        v_ant_e = velocity_at(v_e, c_e, w_lever, (0.0, 0.0, 0.0), self._l_ant_f)
        u_ant = along_body_x(v_ant_e[0], v_ant_e[1], c_e)
        sigma = math.hypot(
            fix_velocity_sigma_mps(fix, self._gnss_vel_sigma_mps()), cfg.dr_velocity_floor_mps
        )
        # the inertial velocity's error since the last epoch gave one: the tilt's, g theta t
        since_s = 0.0 if self._t_velocity_s is None else max(0.0, t_e - self._t_velocity_s)
        sigma_u = math.hypot(sigma, GRAVITY_MPS2 * self._sigma_tilt_rad(0.0) * since_s)
        p_ref = self._reference_ne_m(fix, c_e)
        sigma_ned = self._fix_sigma_m(fix)
        sigma_p = sigma_ned[0]
        # (the engine's velocity within its own error since the last epoch that gave one:
        # after an outage at a stop it had drifted with the tilt, g theta t, beyond the
        # fix's noise, and no epoch at the stop was still again, nor moving: the velocity
        # never reset and the position ran off, 80 m in a minute, until the vehicle drove)
        if abs(u_ant) < DIRECTION_SIGMAS * sigma_u and sog < min(
            cfg.stationary_speed_mps, DIRECTION_SIGMAS * sigma
        ):
            # the latest still epoch's: the stop's first may be the braking's last cm
            if p_ref is not None:
                self._stop_ne_m = (p_ref[0], p_ref[1], sigma_p, t_e, int(fix.quality))
            self._held_forward = None
            self._t_velocity_s = t_e
            vn, ve, _ = lever_arm_velocity_ned(c_e, w_lever, self._l_ant_f)
            return (vn, ve, 0.0)
        moved_x = None
        if p_ref is not None and self._stop_ne_m is not None:
            stop_n, stop_e, sigma_stop, t_stop, quality = self._stop_ne_m
            moved_x = along_body_x(p_ref[0] - stop_n, p_ref[1] - stop_e, c_e)
            sigma_x = displacement_sigma_m(
                sigma_stop,
                sigma_p,
                t_e - t_stop,
                cfg.gnss_white_share,
                cfg.gnss_error_correlation_s if quality == int(fix.quality) else None,
                self._track.noise.white_share(int(fix.quality), sigma_ned[:2]),
            )
            if abs(moved_x) < DIRECTION_SIGMAS * sigma_x:
                moved_x = None
        if moved_x is not None and self._held_forward is None:
            self._held_forward = moved_x >= 0.0
        elif abs(u_ant) >= DIRECTION_SIGMAS * sigma_u:
            self._held_forward = u_ant >= 0.0
        elif self._held_forward is None:
            self._direction_pending = True
            return None
        self._t_velocity_s = t_e
        vn, ve = antenna_velocity_along_body_x(sog, c_e, w_lever, self._l_ant_f, self._held_forward)
        return (vn, ve, 0.0)

    def _reference_ne_m(self, fix: GnssFix, c_bn: Mat9) -> tuple[float, float] | None:
        """The reference point's horizontal position of ``fix`` (local NED, m), or None."""
        if fix.lat_deg is None or fix.lon_deg is None or fix.alt_m is None or self._frame is None:
            return None
        p_ant = self._frame.to_ned(fix.lat_deg, fix.lon_deg, fix.alt_m)
        p_ref = reference_from_antenna(p_ant, c_bn, self._l_ant_f)
        return p_ref[0], p_ref[1]

    def _history_at(self, t_s: float) -> _Row | None:
        """History row interpolated at ``t_s``; None if older than the history."""
        hist = self._hist
        if not hist or t_s < hist[0][_T]:
            return None
        if t_s >= hist[-1][_T]:
            return hist[-1]
        # Most lookups are within the last ~0.3 s: search those rows first (the same index).
        lo = len(hist) - RECENT_ROWS
        if lo <= 0 or not hist[lo][_T] < t_s:
            lo = 0
        i = bisect_left(hist, t_s, lo, key=_row_time)
        a, b = hist[i - 1], hist[i]
        u = (t_s - a[_T]) / (b[_T] - a[_T])
        psi = (a[_PSI] + u * wrap_pi(b[_PSI] - a[_PSI])) % (2.0 * math.pi)
        _, a1, a2, a3, _, a5, a6, a7, a8, a9, a10 = a
        _, b1, b2, b3, _, b5, b6, b7, b8, b9, b10 = b
        return (
            t_s,
            a1 + u * (b1 - a1),
            a2 + u * (b2 - a2),
            a3 + u * (b3 - a3),
            psi,
            a5 + u * (b5 - a5),
            a6 + u * (b6 - a6),
            a7 + u * (b7 - a7),
            a8 + u * (b8 - a8),
            a9 + u * (b9 - a9),
            a10 + u * (b10 - a10),
        )

    def _attitude_at(self, row: _Row, c_bn: Mat9) -> Mat9:
        """C_b^n at the time of ``row``: the current C turned back by the body rotation since
        (integral of w_b from the history; the platform control rate is negligible over the
        ~0.1 s of receiver latency). A bump rolls the mast by ~0.5 deg in 70 ms."""
        last = self._hist[-1]
        return dcm_mul(
            c_bn,
            exp_so3_9(row[_WI_X] - last[_WI_X], row[_WI_Y] - last[_WI_Y], row[_WI_Z] - last[_WI_Z]),
        )

    def _lever_rate(self, t_e: float, row: _Row) -> Float3:
        """Body rate at epoch time ``t_e`` for the lever-arm velocities (``row`` the history
        at ``t_e``), from the history's means about it (:func:`centred_rate`; the epoch
        waits for the samples after it: :class:`HeldEpochs`). A window cut on one side lags:
        5 ms for a receiver 40 ms late, 3.5 cm/s of a 3 m mast rocking +/-1.5 deg at 1.5 Hz,
        which the accel-bias filter took for y bias (rocking +/-2 deg at 2 Hz through four
        U-turns: roll/pitch 0.18 deg RMS, 0.49 at worst)."""
        return centred_rate(lambda r: self._mean_rate(t_e - r, self._history_at(t_e + r) or row))

    def _lever_sigma_mps(self) -> float:
        """1-sigma of the antenna-to-IMU lever-arm velocity from :meth:`_lever_rate`'s gyro
        noise, m/s: 0.6 cm/s on a 2 m lever arm at the ADIS16334's ARW, more on a noisier
        unit, and the velocity chain of the accel-bias filter must know it (an IMU twice as
        noisy as its datasheet learnt its x bias 0.02 m/s^2 off without it)."""
        return centred_rate_velocity_sigma_mps(self._gyro_arw, self._l_imu_ant_m)

    def _ant_lever_sigma_mps(self) -> float:
        """1-sigma of the antenna's lever-arm velocity about the reference point from
        :meth:`_lever_rate`'s gyro noise, m/s: what it adds to a course's noise."""
        return centred_rate_velocity_sigma_mps(self._gyro_arw, math.hypot(*self._l_ant_f))

    def _mean_rate(self, t0_s: float, row: _Row) -> Float3:
        """Mean bias-corrected body rate over [t0_s, row time], from the history, rad/s."""
        row0 = self._history_at(t0_s)
        if row0 is None or row[_T] <= row0[_T]:
            obs = self._observer
            return obs.w_b_rps if obs is not None else (0.0, 0.0, 0.0)
        span = row[_T] - row0[_T]
        return (
            (row[_WI_X] - row0[_WI_X]) / span,
            (row[_WI_Y] - row0[_WI_Y]) / span,
            (row[_WI_Z] - row0[_WI_Z]) / span,
        )

    def _velocity_along_body_x(
        self, fix: GnssFix, t_e: float, c_e: Mat9, w_lever: Float3, row: _Row
    ) -> tuple[float, float] | None:
        """Before the heading is known: the IMU's horizontal velocity in the platform's own
        azimuth, from the GNSS speed along body x (a wheeled vehicle does not slip sideways),
        from a rest on while the direction holds (:meth:`_direction_holds`); None at rest,
        or when not known.

        Why: at rest the tilt loop takes v = 0 and closes in any azimuth; leaving it, the
        loop opened until the course gave the heading (1 m/s). The rest epochs of the pull
        away (GNSS speed still under ``stationary_speed_mps``, the vehicle already rolling)
        had their acceleration read as tilt, and the epoch that would have taken it back was
        one of the open ones: 0.27 deg of pitch for 3 s as the warm start of steep-turns
        seed 12 drove off. Closed on the speed along x, the velocity differences telescope
        through the pull-away as they do once the heading is known. Forward or reversing is
        what the inertial velocity change along x since the rest says, once it is beyond
        :data:`DIRECTION_SIGMAS` of what the tilt left by a levelling on a moving window puts
        into it (:meth:`_direction_tilt_rad`); until then the loop stays open, and the
        heading's alignment at ``align_min_speed_mps`` takes the vehicle as driving forward
        (as the EKF does: vehicles reverse slower, and the sign of a change within its noise
        is the noise's).
        """
        if self._at_rest:
            self._rest_row, self._forward, self._forward_known = row, None, False
            self._body_x_last = None
            return None
        rest = self._rest_row
        if rest is None or fix.sog_mps is None:
            self._body_x_last = None
            return None
        since_s = t_e - rest[_T]
        if not self._forward_known:
            dn, de = row[_SF_N] - rest[_SF_N], row[_SF_E] - rest[_SF_E]
            dv_x = along_body_x(dn, de, c_e)
            self._forward_known = direction_known(dv_x, self._direction_tilt_rad(since_s), since_s)
            if not self._forward_known:
                return None
            self._forward = dv_x >= 0.0
        if since_s > BODY_X_LOOP_S and not self._direction_holds(fix, row, c_e):
            self._body_x_last = None
            return None
        vn, ve = antenna_velocity_along_body_x(
            fix.sog_mps, c_e, w_lever, self._l_ant_f, self._forward is not False
        )
        v_imu = velocity_at((vn, ve, 0.0), c_e, w_lever, self._l_ant_f, self._l_imu_f)
        self._body_x_last = (row, v_imu[0], v_imu[1])
        return v_imu[0], v_imu[1]

    def _direction_tilt_rad(self, since_s: float) -> float:
        """The tilt error, 1-sigma, whose g theta t may turn the inertial velocity change
        along body x ``since_s`` after a rest round (:func:`direction_known`).

        At rest the tilt loop has made the mean horizontal f_p zero, whatever the
        accelerometer bias, but not what a levelling on a moving window left (a restart
        levelled while braking, 1.4 deg of pitch left after 3 s at rest: 0.08 m/s in the
        0.3 s to the first epoch, with 0.1 m/s of true speed; decided there, the heading
        aligned 180 deg off for good and the tilt went 13 deg off: steep-turns seed 94
        with a stall at 160 s), nor an x/y gyro bias not yet learnt: the loop holds the
        tilt b_g tau off with f_p's mean g b_g tau, and from the rest on, open until the
        direction is known, the tilt drifts b_g t (the change's mean tilt: half that).
        Without the bias, a unit with 0.58 deg/s on y (3 sigma of a noisy unit's spread,
        `slope-start` seed 612 of imu-noise-x2+fast-wide) 4.5 s at rest from a cold start
        read its pull-away as a reversal, closed the loop on it (pitch 4 deg off with 1.3
        stated) and aligned the heading 180 deg off, NAVIGATING."""
        bias_tilt = self._sigma_bg_rps() * (self._tilt_loop.tau_now_s + 0.5 * since_s)
        return math.sqrt(self._sigma_level_rad**2 + self._noise_tilt_var + bias_tilt**2)

    def _direction_holds(self, fix: GnssFix, row: _Row, c_e: Mat9) -> bool:
        """Past :data:`BODY_X_LOOP_S` after a rest, with the heading still unknown: may the
        tilt loop go on closing on the speed along body x? Yes while the last epoch closed
        it: the direction is then the IMU velocity that epoch took, carried on by f_p, where
        that is beyond :data:`DIRECTION_SIGMAS` of the fix's noise and the drift the tilt
        puts into it (a reversal with no epoch at rest, a 1 Hz receiver's), else the one
        held (a wheeled vehicle reverses only through a stop).

        Why: a vehicle under ``align_min_speed_mps`` may drive on for minutes before its
        courses give the heading; open loop, a planter at 0.5 m/s with a unit twice as noisy
        as its datasheet and a 1 Hz receiver (`field` seed 578) drifted 6 deg in tilt in
        the 130 s to its first turn, stated, but its dead reckoning ran off the fixes and
        never aligned."""
        last = self._body_x_last
        if last is None:
            return False
        prow, vn, ve = last
        u = along_body_x(vn + row[_SF_N] - prow[_SF_N], ve + row[_SF_E] - prow[_SF_E], c_e)
        sigma = math.hypot(
            fix_velocity_sigma_mps(fix, self._gnss_vel_sigma_mps()),
            self._lever_sigma_mps(),
            GRAVITY_MPS2 * self._sigma_tilt_rad(0.0) * (row[_T] - prow[_T]),
        )
        if abs(u) >= DIRECTION_SIGMAS * sigma:
            self._forward = u >= 0.0
        return True

    def _direction_from_hint(
        self, fix: GnssFix, v_ant: Float3, c_e: Mat9, w_lever: Float3, row: _Row
    ) -> None:
        """Before the heading is known, after a restart: forward or reversing from the
        heading the last engine had (:mod:`gateway.estimation.heading_hint`), once the
        course is the vehicle's (over ``course_hold_speed_mps``, not held from before a stop).
        It outranks the velocity change along body x, which a tilt left by levelling while
        braking turns round."""
        hint = self._hint
        if (
            hint is None
            or self._at_rest
            or fix.sog_mps is None
            or fix.sog_mps < self.cfg.course_hold_speed_mps
        ):
            return
        if_forward = heading_from_antenna_course(v_ant, c_e, w_lever, self._l_ant_f, forward=True)
        self._forward = hint.forward(if_forward, row[_PSI])
        self._forward_known = True

    def _track_epoch(self, fix: GnssFix, c_e: Mat9, v_ref: Float3, row: _Row) -> TrackEpoch | None:
        """The reference point's height and velocity at the epoch, with the attitude
        ``c_e``, and the platform's slope integral of ``row``, for the accel-bias filter's
        climb-angle measurement of pitch; None without a height."""
        if fix.alt_m is None:
            return None
        l_ant = self._l_ant_f
        v_n, v_e = v_ref[0], v_ref[1]
        return TrackEpoch(
            fix.alt_m + c_e[6] * l_ant[0] + c_e[7] * l_ant[1] + c_e[8] * l_ant[2],
            self._fix_sigma_m(fix)[2],
            (v_n, v_e),
            (v_n * c_e[0] + v_e * c_e[3]) / math.hypot(c_e[0], c_e[3]),
            (row[_GI_N], row[_GI_E]),
            (int(fix.quality), fix.reference_station_id),
        )

    def _correct_tilt(
        self,
        t_e: float,
        v_imu_n: float,
        v_imu_e: float,
        row: _Row,
        closed: bool,
        sigma_v: float,
        track: TrackEpoch | None,
    ) -> bool:
        """Eq. (3) over exactly the GNSS interval (``sigma_v`` the fix's velocity 1-sigma,
        m/s; ``track`` for the accel-bias filter); returns True for a glitch.

        e = (v_k - v_{k-1}) / T - mean f_p over [t_{k-1}, t_k], horizontal (the -g term has no
        horizontal part). The velocity is moved from the antenna to the IMU with both lever
        arms first, so that it describes the point whose specific force is measured. Before the
        heading is known the horizontal f_p is in an arbitrary azimuth, so the loop is closed
        (``closed``) only while at rest (v = 0 in any azimuth) or on the speed along body x
        in the platform's azimuth (:meth:`_velocity_along_body_x`). A velocity mismatch |e| T beyond
        :meth:`_glitch_dv_mps` is a glitch: the loop stays open for the interval (no attitude
        kick) and learning is gated (hold-off after it). Glitches that last
        ``glitch_persist_s`` are the platform's error, not the GNSS's (a velocity step cancels
        in the differences after one new base): e is then used again, clipped to the gate, so
        a platform tilted beyond the gate recovers.

        A rejected epoch is skipped, not made the base of the next difference: the next e
        spans the last accepted epoch to it, and its control rate, held for one epoch period,
        is scaled by interval / period. The gate is that of one period however long the span:
        a velocity step is rejected until the span exceeds ``max_gnss_interval_s`` and a new
        base starts after it. So the applied tilt corrections still telescope to
        (v_last - v_first) / (g tau), one velocity error, however many epochs are rejected.
        Differencing against a rejected epoch instead made noisy spells (single-point GNSS,
        8 cm/s: e ~1.1 m/s^2 against a 1.5 m/s^2 gate) a random walk of 1-2 deg in tilt.
        """
        obs = self._observer
        assert obs is not None
        prev = self._prev_epoch
        current = (t_e, v_imu_n, v_imu_e, row)
        interval_s = 0.0 if prev is None else t_e - prev[0]
        if (
            prev is None
            or not 0.0 < interval_s <= self.cfg.max_gnss_interval_s
            or prev[0] < self._gap_end_s  # the interval spans a chain-ending gap
        ):
            self._prev_epoch, self._gap_dv_var = current, 0.0
            self._leave_open(t_e)
            return False
        _, vn_prev, ve_prev, prow = prev
        e_n = (v_imu_n - vn_prev) / interval_s - (row[_SF_N] - prow[_SF_N]) / interval_s
        e_e = (v_imu_e - ve_prev) / interval_s - (row[_SF_E] - prow[_SF_E]) / interval_s
        last = self._t_last_epoch_s
        period_s = interval_s if last is None else min(interval_s, max(t_e - last, 1e-3))
        mismatch_mps, gate_mps = math.hypot(e_n, e_e) * interval_s, self._glitch_dv_mps(period_s)
        glitch = mismatch_mps > gate_mps
        if not glitch:
            self._rejecting_since_s = None
        else:
            if self._rejecting_since_s is None:
                self._rejecting_since_s = t_e
            if self._velocity_rejected(t_e):
                self._leave_open(t_e)
                return True
            # rejected this long: the platform is off, not the GNSS; correct, clipped
            e_n, e_e = e_n * gate_mps / mismatch_mps, e_e * gate_mps / mismatch_mps
            if self._ba_filter is not None:
                self._ba_filter.lose_tilt(t_e, obs.c_bp9)
        self._prev_epoch, self._gap_dv_var = current, 0.0
        if not closed:
            self._leave_open(t_e)
            return False
        if self._t_open_s is not None:
            self._close_open_span(t_e - self._t_open_s)
        u_ne = self._tilt_loop.control((e_n, e_e), interval_s, period_s, sigma_v)
        obs.correct_tilt(*u_ne)
        self._watch_corrections(t_e, u_ne, period_s)
        if self._ba_filter is not None and not glitch:
            self._filter_epoch(t_e, (e_n, e_e), u_ne, (row, prow), interval_s, sigma_v, track)
        self._sigma_level_rad, self._sigma_level_held = self._tilt_loop.decay(
            self._sigma_level_rad, self._sigma_level_held, interval_s
        )
        self._epoch_interval_s = interval_s
        a = min(1.0, interval_s / E_NOISE_TAU_S)
        self._e_var_mps4 += a * (0.5 * (e_n * e_n + e_e * e_e) - self._e_var_mps4)
        fix = self._last_fix
        if fix is not None and fix.quality == FixQuality.RTK_FIXED:
            # the mismatch e T is two fixes' velocity errors: 2 sigma_v^2 a component
            dv_n, dv_e = e_n * interval_s, e_e * interval_s
            self._vel_noise.add(0.5 * dv_n * dv_n, 0.5 * dv_e * dv_e, interval_s)
        return glitch

    def _filter_epoch(
        self,
        t_e: float,
        e_ne: tuple[float, float],
        u_ne: tuple[float, float],
        rows: tuple[_Row, _Row],
        interval_s: float,
        sigma_v: float,
        track: TrackEpoch | None,
    ) -> None:
        """Feed the accel-bias filter the epoch's e and the e the loop applies from it
        (``u_ne``; it starts with learning), with the fix's velocity 1-sigma and the track,
        and apply the x/y bias correction it returns."""
        obs, flt = self._observer, self._ba_filter
        assert obs is not None and flt is not None
        biases = filter_biases(obs)
        row, prow = rows
        # the mean rate over the loop's tau (at least the epoch interval): what turns the
        # tilt of a bias error faster than the loop follows. One sample's noise is 0.5-1
        # deg/s of ARW, which beyond 2 deg/s once in 8 s kept the filter from starting on
        # an IMU twice the datasheet's noise (its x bias never learnt: pitch 1.6 deg off,
        # 0.46 stated); an epoch's mean still caught the yaw a rough field's bumps rock
        # the body by (+-4 deg/s at 6 m/s), and the filter never started (`short` seed
        # 547 of fast-wide+rough-slope: roll 0.75 deg off all run, 3,681 frames beyond)
        span_s = min(max(self._tilt_loop.tau_now_s, interval_s), row[_T] - self._hist[0][_T])
        w_z = self._mean_rate(row[_T] - span_s, row)[2]
        if abs(w_z) >= self.cfg.align_quiet_rate_dps * DEG_TO_RAD:
            self._turned_s = t_e
        if not flt.started:
            # It starts with the platform levelled on the biases (x = -C_h db): not in a
            # turn, nor before the loop has followed the tilt a bias error turns with the
            # body (learning_holdoff_s, 2 tau). Started mid-turn, an engine restarted on the
            # move read the bias's turning tilt as y bias and sent roll 0.8 deg off with
            # 0.23 stated (`short` seed 3, 1.2 s without IMU at 44.5 s).
            if not obs.learn or t_e - self._turned_s < self.cfg.learning_holdoff_s:
                return
            flt.start(obs.c_bp9, self._ba_origin_sigma_mps2(), biases, self._bias_filter_noise())
        f_p = ((row[_SF_N] - prow[_SF_N]) / interval_s, (row[_SF_E] - prow[_SF_E]) / interval_s)
        db = flt.epoch(t_e, e_ne, u_ne, f_p, obs.c_bp9, biases, sigma_v, obs.learn, track)
        obs.add_accel_bias_xy(*db)
        sigma0, learnt = self._turn_on_ba_mps2(), flt.sigma_mps2
        if learnt < REOPEN_ARMED_SHARE * sigma0 and flt.inconsistent():
            # the residual is not that of the biases the filter holds learnt: re-opened to
            # the turn-on spread, so the stated tilt covers them and turns learn them again
            flt.reopen(sigma0, 0.0, obs.c_bp9, absorbed=False)
            flt.walk.found(t_e, sigma0)
            flt.clear_window()
            self.counters.bias_changes += 1
            self._log.warning(
                t_e,
                f"IMU bias change at t={t_e:.3f}: the tilt loop's residual over "
                f"{NIS_WINDOW_S:g} s is beyond what the learnt x/y accelerometer biases "
                f"({learnt:.3f} m/s^2 1-sigma) explain; re-opened to {sigma0:.3f} m/s^2, "
                "the roll/pitch accuracy sent with them, and learnt again in the next turns",
                "bias change",
            )
        # The tilt a bias error holds (b / g) moves by what is learnt of it, and the loop
        # follows with its tau: until then the platform is off by the sum of the recent
        # corrections, N/E, decaying with the loop (a first turn with seed 000's 0.2 m/s^2
        # learnt it in two seconds and stated 0.39 deg while roll was still 1.17 deg off).
        c, decay = obs.c_bp9, self._tilt_loop.decay
        (n, e), (n_held, e_held) = self._ba_tilt_ne, self._ba_tilt_held_ne
        n, n_held = decay(n, n_held, interval_s)
        e, e_held = decay(e, e_held, interval_s)
        self._ba_tilt_ne = (n + c[0] * db[0] + c[1] * db[1], e + c[3] * db[0] + c[4] * db[1])
        self._ba_tilt_held_ne = (n_held, e_held)

    def _watch_corrections(self, t_e: float, u_ne: tuple[float, float], period_s: float) -> None:
        """The tilt the loop's control turns the platform by over the coming period (eq.
        3: w_p = (-u_E, u_N) / (tau g), u the e applied) into :class:`CorrectionWindow`;
        beyond what the noise and the stated bias and tilt sigmas explain, the biases
        changed. Only while the learning gates are open: a fix not good enough to learn
        biases from is no evidence that they changed (gnss-outage seed 3, single point: 1.0
        deg of corrections in 5 s from its 8 cm/s velocities)."""
        obs = self._observer
        assert obs is not None
        if not obs.learn:
            self._corrections.clear()
            return
        k = period_s / (self.cfg.tau_s * GRAVITY_MPS2)
        corrections = self._corrections
        sigma_tilt = math.sqrt(self._model_tilt_var(0.0))
        corrections.add(t_e, -u_ne[1] * k, u_ne[0] * k, sigma_tilt, self._sigma_bg_rps())
        change = corrections.check(self._gyro_arw, sigma_tilt)
        if change is not None:
            self._bias_changed(t_e, change, self._reopen_xy)

    def _doubt_hdt(self, t_e: float, change: BiasChange, c22: float) -> None:
        """The courses left the heading an HDT steered (:mod:`gateway.estimation.hdt_doubt`):
        the HDT is doubted, and the heading and z bias re-open by the change as for any
        found first (the HDT's drift went into both), however soon after the last."""
        self._hdt_doubt.doubt()
        if change.again:
            self._heading.reopen(change, c22)
        self.counters.hdt_rejected += 1
        self._log.warning(t_e, hdt_doubt_text(t_e, change.angle_rad), "hdt")

    def _bias_changed(
        self, t_e: float, change: BiasChange, reopen: Callable[[BiasChange], str]
    ) -> None:
        """A bias change (:mod:`gateway.estimation.bias_change`): ``reopen`` re-opens the
        biases and says what it did, unless the change came again; counted and logged. A tilt
        change, again or not, raises the accel-bias filter's x/y bias walk for a while
        (:class:`gateway.estimation.bias_change.FoundWalk`)."""
        if change.axis == "tilt" and self._ba_filter is not None:
            self._ba_filter.walk.found(t_e, self._reopened_ba_mps2(change))
        if change.again:
            self._log.warning(t_e, bias_change_text(t_e, change, ""), "bias change")
            return
        reopened = reopen(change)
        self.counters.bias_changes += 1
        self._log.warning(t_e, bias_change_text(t_e, change, reopened), "bias change")

    def _reopen_xy(self, change: BiasChange) -> str:
        """The x/y biases changed beyond their in-run model: their sigmas re-open, the
        accelerometer's to the turn-on spread or the tilt taken (as a specific force) if
        more, the gyro's to the window's rate, so what goes out states it and learning
        takes the new biases."""
        obs = self._observer
        assert obs is not None
        cfg = self.cfg
        sigma_a = self._reopened_ba_mps2(change)
        sigma_g = max(self._sigma_bg_rps(), change.rate_rps)
        flt = self._ba_filter
        if flt is not None and flt.started:
            flt.reopen(sigma_a, sigma_g, obs.c_bp9)
        else:
            ba = obs.ba_hat_mps2
            self._ba_origin = (ba[0], ba[1], sigma_a, self._a_learn)
        self._g_learn = min(
            self._g_learn, seeded_exponent(cfg.gyro_bias_sigma0_dps * DEG_TO_RAD, sigma_g)
        )
        return xy_reopened_text(sigma_a, sigma_g)

    def _reopened_ba_mps2(self, change: BiasChange) -> float:
        """The x/y accelerometer bias 1-sigma a tilt ``change`` re-opens: the turn-on spread,
        or the tilt taken as a specific force if more."""
        return max(self._turn_on_ba_mps2(), GRAVITY_MPS2 * change.angle_rad)

    def _reopened_z(self, change: BiasChange) -> str:
        """What the heading channel re-opened on a z bias change
        (:meth:`HeadingChannel.correct` does it)."""
        return z_reopened_text(self._heading.kf.sigma_rps)

    def _bias_filter_noise(self) -> BiasFilterNoise:
        """The accel-bias filter's noise: the IMU's white noise as measured where it is more
        than the config's (:meth:`_noise_as_measured`), and the in-run wander of [imu] and
        the gyro bias prior scaled as the stated floors are, by the larger excess (as the
        EKF raises its bias walks): a unit noisier than its datasheet is not the
        datasheet's typical unit, and its stabilities are not known to be. With the
        datasheet's wander, a unit twice as noisy in every figure had its x/y gyro biases
        0.015-0.025 deg/s off against the filter's 0.010, and a U-turn on a 6 m/s run read
        their tilt as x accelerometer bias: 0.04 m/s^2 off with 0.011 stated, pitch
        0.55 deg off with 0.15 stated (steep-turns seed 614, fast-wide+imu-noise-x2+hdt)."""
        cfg, scale = self.cfg, self._floor_scale
        return BiasFilterNoise(
            accel_psd=self._accel_psd,
            arw_rad_per_sqrt_s=self._gyro_arw,
            accel_bias_sigma_mps2=cfg.accel_bias_stability_mg * MG_MPS2 / GM_ALLAN_FLOOR * scale,
            gyro_bias_sigma_rps=cfg.gyro_bias_stability_dps * DEG_TO_RAD / GM_ALLAN_FLOOR * scale,
            bias_correlation_s=cfg.bias_correlation_time_s,
            gyro_bias_sigma0_rps=GYRO_BIAS_SIGMA0_RPS * scale,
        )

    def _velocity_rejected(self, t_e: float) -> bool:
        """The epoch at ``t_e`` is in a spell of velocity glitches younger than
        ``glitch_persist_s``: its velocity is the receiver's error, used by no loop."""
        since = self._rejecting_since_s
        return since is not None and t_e - since < self.cfg.glitch_persist_s

    def _glitch_dv_mps(self, period_s: float) -> float:
        """Largest velocity-change mismatch over one epoch period that is not a glitch: white
        GNSS velocity noise (the difference of two 2-D errors, Rayleigh with scale sqrt(2)
        sigma_v) plus a specific-force mismatch ``e_gate_mps2``. The noise part does not
        shrink with the period, so a 20 Hz receiver is not half rejected, nor does a 1 Hz
        receiver get a gate 10 times wider than its noise."""
        cfg = self.cfg
        noise_mps = cfg.glitch_sigma * math.sqrt(2.0) * self._gnss_vel_sigma_mps()
        return noise_mps + cfg.e_gate_mps2 * period_s

    def _set_tilt_open(self, t_s: float | None) -> None:
        """The tilt loop opens (at epoch time ``t_s``: until then its control was on). What
        its low-pass still owes waits for the loop to close (:mod:`.tilt_loop`)."""
        obs = self._observer
        assert obs is not None
        obs.open_tilt_loop()
        if self._ba_filter is not None and t_s is not None:
            self._ba_filter.open(t_s, obs.c_bp9)

    def _leave_open(self, t_e: float) -> None:
        """The epoch at ``t_e`` leaves the tilt loop open: the open span starts, if new."""
        self._set_tilt_open(t_e)
        if self._t_open_s is None:
            self._t_open_s = t_e

    def _close_open_span(self, open_s: float) -> None:
        """The loop closes after ``open_s`` open (a coast, or epochs that left it open): the
        drift of that span stays in the stated tilt and decays with the loop from here."""
        self._sigma_level_rad = math.hypot(self._sigma_level_rad, self._coast_drift_rad(open_s))
        self._t_open_s = None

    def _open_s(self, t_s: float) -> float:
        """How long the tilt loop has run open at ``t_s``: through a coast
        (:meth:`_coasting_s`) or since an epoch left it open on the move (before the heading
        is known, one that gave no speed along body x: the direction of travel not known,
        after a restart on the move). Unstated, a vehicle driving on under
        ``align_min_speed_mps`` with its loop open drifted roll 1.9 deg off in 100 s with
        the 0.59 deg stated at levelling."""
        since = 0.0 if self._t_open_s is None else max(0.0, t_s - self._t_open_s)
        return max(self._coasting_s(), since)

    def _rotate_platform(self, phi_rad: Float3) -> None:
        """C <- exp([phi]x) C (a levelling): the accel-bias filter's tilt error moves with it."""
        assert self._observer is not None
        self._observer.rotate(phi_rad)
        self._tilt_loop.clear()
        if self._ba_filter is not None:
            self._ba_filter.rotate(phi_rad)

    def _turn_platform(self, dpsi_rad: float) -> None:
        """C <- Rz(dpsi) C (a heading step): the accel-bias filter's tilt error turns with it;
        the HDT screen's gyro heading breaks (the history's rows up to now keep the old)."""
        assert self._observer is not None and self._t_s is not None
        self._turned_rad += dpsi_rad
        self._observer.rotate_about_vertical(dpsi_rad)
        self._tilt_loop.rotate_about_vertical(dpsi_rad)
        self._hdt_screen.restart(self._t_s)
        if self._ba_filter is not None:
            self._ba_filter.rotate_about_vertical(dpsi_rad)

    def _enter_coasting(self) -> None:
        """GNSS velocity timed out: platform runs open loop (w_p = 0), learning frozen."""
        obs = self._observer
        assert obs is not None
        self._set_tilt_open(self._t_last_epoch_s)
        obs.set_heading_rate(0.0)
        obs.learn = False
        self._w_pz_rps = 0.0
        self._settle_lever(obs.c_bp9, velocity_reset=False)
        self._lever_anchor = None  # the coast integrates the IMU point as such
        self._coasting = True
        self._ground.restart()
        self._ground_loop.clear()
        self._held_forward = self._stop_ne_m = None
        self._end_rest()
        sigma_v = self._fix_sigma_v()
        self._coast_budget = CoastBudget(
            sigma_p0_m=math.hypot(*self._position.sigma_ne_m()),
            sigma_v0_mps=math.hypot(sigma_v, self.cfg.dr_velocity_floor_mps),
            sigma_a_mps2=GRAVITY_MPS2 * self._sigma_tilt_rad(0.0),
            sigma_bg_rps=self._sigma_bg_rps(),
            arw_rad_per_sqrt_s=self._gyro_arw,
            sigma_psi_rad=self._heading.sigma_psi_rad,
            sigma_bz_rps=self._heading.kf.sigma_rps,
        )
        for i in range(3):
            self._v_imu_ned_mps[i] = self._v_ned_mps[i] + self._lever_v_ned_mps[i]
        self._prev_epoch = None
        self._learn_ok_since_s = None

    def _update_gates(self, t_e: float, ok: bool | None) -> None:
        """Bias learning on only after all gates have been open for ``learning_holdoff_s``
        (``ok`` None: the epoch says nothing of them, they stay as they are).

        Also accumulates the convergence exponents: t / tau_g (gyro x/y) and the integral
        of w_z^2 / (omega_a (1 + (w_z tau)^2)) (accelerometer x/y). Eq. (12) learns from the
        control rate, and in a turn the bias error turns with the body at w_z: the tilt loop
        (first order, tau) follows the tilt it causes with a lag, and only the quadrature
        part of its response, w_z / (1 + (w_z tau)^2), moves the estimate towards the truth.
        The paper's rate w_z^2 / omega_a is the limit w_z tau << 1; with it the stated sigma
        fell 2-3 times faster than the bias error (slope-start seed 21: 0.09 deg of tilt
        stated while 0.3-0.4 deg off, 9 % of the attitude frames beyond 3 sigma; now none).
        """
        obs = self._observer
        assert obs is not None
        interval_s = 0.0 if self._t_last_epoch_s is None else t_e - self._t_last_epoch_s
        self._t_last_epoch_s = t_e
        if obs.learn and 0.0 < interval_s <= self.cfg.max_gnss_interval_s:
            self._g_learn += interval_s / self.cfg.tau_g_s
            self._t_bg_learnt_s = t_e
            row = self._history_at(t_e)
            wz = obs.w_b_rps[2] if row is None else self._mean_rate(t_e - interval_s, row)[2]
            omega_a = self.cfg.omega_a_dps * DEG_TO_RAD
            tau = self._tilt_loop.tau_now_s
            self._a_learn += wz * wz * interval_s / (omega_a * (1.0 + (wz * tau) ** 2))
        if ok is None:
            return
        if not (ok and self.cfg.estimate_biases):
            self._learn_ok_since_s = None
            obs.learn = False
            return
        if self._learn_ok_since_s is None:
            self._learn_ok_since_s = t_e
        obs.learn = t_e - self._learn_ok_since_s >= self.cfg.learning_holdoff_s

    def _correct_heading(
        self,
        t_e: float,
        row: _Row,
        cog_ref_rad: float,
        speed_ref_mps: float,
        hdt_rad: float | None,
        yaw_rate_rps: float,
        c_bn_dd: float,
    ) -> None:
        """First heading alignment, then the heading channel (ALGORITHMS.md 2).

        Alignment takes HDT, or the first reference-point course at ``align_min_speed_mps``,
        forward unless the vehicle left its last rest reversing (:meth:`_velocity_along_body_x`:
        taken as forward, backing out of a shed aligned 180 deg off and sent that heading,
        NAVIGATING, for as long as it reversed). The heading channel's bias KF learns under
        the same gates as the observer. An HDT off the gyro's turn since the last one used is
        not used (:mod:`gateway.estimation.observer.hdt_screen`).
        """
        obs = self._observer
        assert obs is not None
        cfg = self.cfg
        if not self._heading_aligned:
            self._heading.predict_bias(t_e)
            if hdt_rad is not None:
                target, sigma = hdt_rad, cfg.hdt_sigma_deg * DEG_TO_RAD
            elif speed_ref_mps >= cfg.cog_min_speed_mps:
                sigma_v = math.hypot(self._gnss_vel_sigma_mps(), self._ant_lever_sigma_mps())
                self._courses.add(t_e, wrap_pi(cog_ref_rad - row[_PSI]), sigma_v / speed_ref_mps)
                found = self._courses.alignment(
                    self._heading.kf.sigma_rps,
                    self._gyro_arw,
                    speed_ref_mps,
                    cfg.align_min_speed_mps,
                    cfg.navigating_heading_sigma_deg,
                    self._forward_known,
                )
                if found is None:
                    return
                target, sigma = row[_PSI] + found[0], found[1]
            else:
                return
            # yaw at t_e is psi_e; move it onto the reference, keep the gyro motion since t_e
            self._turn_platform(wrap_pi(target - row[_PSI]))
            self._courses.clear()
            self._heading_aligned = True
            self._hint = None
            self._heading.aligned(sigma)
            self._heading.reversing = self._forward is False and hdt_rad is None
            return
        doubted_hdt = hdt_rad if hdt_rad is not None and not self._hdt_doubt.admits() else None
        if doubted_hdt is not None:
            hdt_rad = None
        screen = self._hdt_screen
        if hdt_rad is not None and not screen.screen(
            t_e, row[_PSI], hdt_rad, row[_HC], self._heading.kf.sigma_rps,
            self._heading.sigma_psi_rad,
        ):  # fmt: skip
            self.counters.hdt_rejected += 1
            self._log.warning(t_e, screen.text(t_e), "hdt")
            hdt_rad = None
        # the heading at t_e with the control applied since (the last epoch's, applied after
        # t_e): what is left of the residual. From the row's heading alone, each epoch took
        # the part of the last correction applied after t_e again, and the gain had to be
        # capped at T / 2 s (one epoch late): aligned 3.7 deg off on a course at
        # 1.4 m/s, it took 2 s to come within 1.7 deg, NAVIGATING (slope-start seed 540).
        psi_e = row[_PSI] - (self._hc_rad - row[_HC])
        ref = self._heading.select_reference(
            t_e, psi_e, cog_ref_rad, speed_ref_mps, hdt_rad, yaw_rate_rps, self._stationary,
            self._gnss_vel_sigma_mps(), self.clock.epoch_sigma_s,
        )  # fmt: skip
        corr = self._heading.correct(
            t_e, psi_e, ref, self._hc_rad, c_bn_dd, obs.learn, yaw_rate_rps,
            self._control_period_s,
        )  # fmt: skip
        course = self._heading.course
        if doubted_hdt is not None and course is not None:
            self._hdt_doubt.add_course(
                t_e, wrap_pi(doubted_hdt - course.psi_rad),
                math.hypot(course.sigma_rad, cfg.hdt_sigma_deg * DEG_TO_RAD), yaw_rate_rps,
                self._epoch_interval_s,
            )  # fmt: skip
        if corr.step_rad:
            self._turn_platform(corr.step_rad)
        if corr.change is not None:
            if corr.change.courses and ref is not None and ref.source is HeadingSource.HDT:
                self._doubt_hdt(t_e, corr.change, c_bn_dd)
            self._bias_changed(t_e, corr.change, self._reopened_z)
        self._w_pz_rps = corr.w_pz_rps
        obs.set_heading_rate(corr.w_pz_rps)
        obs.set_gyro_bias_z(self._heading.bg_z_rps)

    def _correct_position(
        self,
        fix: GnssFix,
        t_e: float,
        row: _Row | None,
        c_bn: Mat9,
        v_ref_ne: tuple[float, float] | None,
    ) -> None:
        """Reference point = antenna - C l_ant (full 3-D), weighed into the propagated state.

        The propagated state at t_e is reconstructed from the f_p integral in the history:
        v(t_e) = v_now - (S_f(now) - S_f(t_e)) - g (now - t_e), p(t_e) by the trapezoid.
        Horizontal velocity is reset to the GNSS one at t_e (plus the inertial change since);
        the horizontal residual is weighed by the position channel's Kalman gain (the fix's
        sigma against the dead-reckoning error since the last fix, :meth:`_predict_position`);
        vertical velocity, which GNSS does not give, comes from the height residual
        (second-order loop, alpha-beta with beta = alpha^2 / 4, alpha = 2 T / tau_h with
        :data:`HEIGHT_LOOP_TAU_S`, at most 1).

        The corrections (dp, dv) are made at t_e and reach the current state through the age
        a = now - t_e: p_now += dp + dv a, v_now += dv. Adding dv to the velocity without its
        a dv to the position made the next epoch's back-propagated p(t_e) wrong by a dv, which
        the vertical loop fed back with gain beta a per epoch: on a loaded host, where epochs
        reach the engine seconds late and in bursts, the height diverged to 1e15 m and the
        output position to the antipode of the field.
        """
        if fix.lat_deg is None or fix.lon_deg is None or fix.alt_m is None or self._t_s is None:
            return
        self._t_pos_rx_s = fix.t
        if self._frame is None:
            self._frame = LocalFrame((fix.lat_deg, fix.lon_deg, fix.alt_m))
        p_ant = self._frame.to_ned(fix.lat_deg, fix.lon_deg, fix.alt_m)
        sigma_ned = self._fix_sigma_m(fix)
        self._track.add(
            t_e, (p_ant[0], p_ant[1]), fix.vel_ne_mps, fix.horizontal_sigma_m, p_ant[2],
            sigma_ned[2], int(fix.quality),
        )  # fmt: skip
        p_ref = reference_from_antenna(p_ant, c_bn, self._l_ant_f)
        p, v, sf = self._p_ned_m, self._v_ned_mps, self._sf
        if row is None:
            if len(self._hist) == HISTORY_LEN:  # not an epoch from before the engine started
                self.counters.late_epochs += 1
                self._log.warning(t_e, late_epoch_text(t_e, self._hist[0][_T]), "late")
            return
        channel = self._position
        channel.set_fix(
            fix.quality, sigma_ned, self._track.noise.white_share(int(fix.quality), sigma_ned[:2])
        )
        var_v = self._fix_velocity_var(fix)
        if not self._nav_valid:
            age = self._t_s - t_e
            vn, ve = v_ref_ne if v_ref_ne is not None else (0.0, 0.0)
            self._v_ned_mps = [vn, ve, 0.0]
            self._p_ned_m = [p_ref[0] + vn * age, p_ref[1] + ve * age, p_ref[2]]
            channel.reset(var_v if v_ref_ne is not None else UNKNOWN_VELOCITY_VAR_M2PS2)
            self._nav_valid = True
            self._t_height_epoch_s = self._t_position_s = t_e
            self._sf_position_ne = (row[_SF_N], row[_SF_E])
            self._lever_anchor = None
            self._settle_lever(self._platform(), velocity_reset=True)
            return
        self._settle_lever(self._platform(), velocity_reset=False)
        age = self._t_s - row[_T]
        v_e = [
            v[0] - (sf[0] - row[_SF_N]),
            v[1] - (sf[1] - row[_SF_E]),
            v[2] - (sf[2] - row[_SF_D]) - GRAVITY_MPS2 * age,
        ]
        dp = [p_ref[i] - (p[i] - 0.5 * (v[i] + v_e[i]) * age) for i in range(3)]
        self._predict_position(t_e, row)
        # the time since the height was last corrected: the loop's velocity correction is
        # the height residual over it (capped at an epoch interval, a span of rejected
        # heights made it 20 times too large; at 1 Hz each reset then tripled the vertical
        # velocity error, and with the horizontal rejected on, the height reached 1e102 m)
        since_s = t_e - (self._t_height_epoch_s or t_e)
        interval_s = min(since_s, self.cfg.max_gnss_interval_s)
        verdict = self._gate_position(fix, t_e, dp)
        # a position rejected for its horizontal part (a jump, a drift) whose height agrees:
        # the height loop keeps it (open, the height ran 18 m off in a minute's rejections)
        height_only = verdict == "reject" and abs(dp[2]) <= self._height_gate_m(t_e)
        corr = [0.0, 0.0, 0.0]
        k_d = height_loop_gain(since_s)
        if verdict == "use":
            corr[2] = k_d * dp[2]
        elif height_only:
            channel.height_taken()
            corr[2] = k_d * dp[2]
        elif verdict == "reset":
            channel.reset()
            corr, k_d = [dp[0], dp[1], dp[2]], 1.0
        # The velocity: the fix's against the inertial one, both the reference point's (the
        # state integrates the IMU point less the lever-arm velocity of its last anchor, the
        # fix's is taken at this epoch's), weighed by the channel with the position
        shift = (0.0, 0.0)
        dzv = None
        if v_ref_ne is not None:
            a = self._lever_anchor
            lever = self._lever_v_ned_mps
            shift = (lever[0], lever[1]) if a is None else (lever[0] - a[3], lever[1] - a[4])
            dzv = (v_ref_ne[0] - (v_e[0] - shift[0]), v_ref_ne[1] - (v_e[1] - shift[1]))
        c_p, c_v = channel.update(dp if verdict == "use" else None, dzv, var_v)
        corr[0] += c_p[0]
        corr[1] += c_p[1]
        dv = [c_v[0] - shift[0], c_v[1] - shift[1], 0.0]
        if since_s > 0.0:
            # alpha-beta form of the critically damped loop: beta = alpha^2 / 4 (alpha * the
            # correction alpha dz) stays stable with alpha <= 1 whatever the epoch interval
            dv[2] = 0.25 * k_d / since_s * corr[2]
        for i in range(3):
            p[i] += corr[i] + dv[i] * age
            v[i] += dv[i]
        if v_ref_ne is not None:
            self._settle_lever(self._platform(), velocity_reset=True)
        if verdict != "reject" or height_only:
            self._t_height_epoch_s = t_e
        learn = verdict == "use" and fix.quality == FixQuality.RTK_FIXED and interval_s > 0.0
        self._learn_accel_bias_z(dv[2] if learn and v_ref_ne else None, interval_s, c_bn)

    def _learn_accel_bias_z(self, dv_d_mps: float | None, interval_s: float, c_bn: Mat9) -> None:
        """The z accelerometer bias from the height loop (the product's own extension: seed
        000 has no vertical channel; docs/ACCURACY.md, "z accelerometer bias").

        The loop's velocity corrections make up for the vertical acceleration the inertial
        propagation gets wrong: their mean rate is the vertical part of the accelerometer
        error, C_dz b_az (x/y errors project c_dx, c_dy: below 0.2 mg on a 10 deg slope with
        the paper's 0.01 m/s^2). Low-passed over ``accel_bias_z_tau_s`` it is an integral
        term of the height loop, which makes it third order, far slower than its 0.3 s.
        Why: the z bias is what C f_b puts on the horizontal on a slope, b_az sin(tilt):
        5 mg on a 10 deg side slope reads as 0.05 deg of roll, which no turn separates (it
        turns with the slope, not the body). Only on RTK fixed heights (a float spell's
        0.4 m would make it noise), never while the IMU is upset (``dv_d_mps`` None: not
        this epoch).

        The height is the reference point's, the specific force the IMU's: the loop also
        makes up for the change of the IMU lever arm's vertical velocity (C (w x l_imu))_d,
        which is added back so that the mean is the bias's alone. It telescopes over a turn
        (on steep-turns seeds 1-3 it moved the z bias error by under 0.2 mg); what swings the
        estimate in turns and three-point turns is the loop's own velocity error, up to
        0.1 m/s over a crest, divided by ``accel_bias_z_tau_s`` (docs/ACCURACY.md).
        """
        lever_vd, prev = self._lever_v_ned_mps[2], self._lever_vd_prev_mps
        self._lever_vd_prev_mps = None if dv_d_mps is None else lever_vd
        obs = self._observer
        c_dz = c_bn[8]
        if dv_d_mps is None or prev is None or obs is None or c_dz < 0.5:
            return
        if not self.cfg.estimate_biases or self._imu.upset:
            return
        tau = self.cfg.accel_bias_z_tau_s
        dv = dv_d_mps + (lever_vd - prev)
        obs.set_accel_bias_z(obs.ba_hat_mps2[2] - dv / (tau * c_dz))
        self._az_learn_s += interval_s

    def _fix_sigma_m(self, fix: GnssFix) -> tuple[float, float, float]:
        """The fix's position 1-sigma NED (:func:`fix_position_sigma_m`); a quality without
        a typical figure (PPS, simulation) is taken as single-point."""
        sigma = fix_position_sigma_m(fix)
        if sigma is not None:
            return sigma
        h, d, _ = DEFAULT_GNSS_SIGMAS[int(FixQuality.GNSS)]
        return (h, h, d)

    def _predict_position(self, t_e: float, row: _Row) -> None:
        """Grow the position channel's variances over the dead reckoning since its last
        epoch (``row`` the history at ``t_e``).

        The inertial velocity's error per horizontal axis walks with the platform's
        acceleration error (g times :meth:`_platform_tilt_var`'s sigma, and what the loop's
        recent corrections show beyond the model, as the stated tilt has it), correlated over
        the tilt loop's time constant tau: as white noise of density 2 (g sigma)^2 tau,
        which over an epoch shorter than tau is more than the tilt's own (g sigma T)^2.
        Each epoch adds the heading's error times the inertial velocity change since the
        last (a turn's change rotated by sigma_psi) and what the IMU lever arm's velocity,
        taken from the gyro at each epoch, puts in twice (now and at the last epoch).
        """
        interval_s = t_e - self._t_position_s
        if interval_s <= 0.0:
            return
        self._t_position_s = t_e
        sf_n, sf_e = self._sf_position_ne
        self._sf_position_ne = (row[_SF_N], row[_SF_E])
        turned = self._heading.sigma_psi_at(t_e) * math.hypot(row[_SF_N] - sf_n, row[_SF_E] - sf_e)
        var_v = turned * turned + 2.0 * self._lever_sigma_mps() ** 2
        self._position.predict(interval_s, self._velocity_walk_q(), var_v)

    def _velocity_walk_q(self) -> float:
        """Density of the inertial velocity's walk per horizontal axis, m^2/s^3
        (:meth:`_predict_position`)."""
        excess = self._corrections.excess_rad(self._gyro_arw, math.sqrt(self._model_tilt_var(0.0)))
        var_a = GRAVITY_MPS2**2 * (self._platform_tilt_var(0.0) + excess * excess)
        return 2.0 * var_a * self._tilt_loop.tau_now_s

    def _fix_velocity_var(self, fix: GnssFix) -> float:
        """Variance per horizontal axis of the fix's reference-point velocity, m^2/s^2: the
        fix's (:func:`fix_velocity_sigma_mps`), ``dr_velocity_floor_mps`` and the antenna
        lever arm's rate noise."""
        sigma_v = fix_velocity_sigma_mps(fix, self._gnss_vel_sigma_mps())
        floor, lever = self.cfg.dr_velocity_floor_mps, self._ant_lever_sigma_mps()
        return sigma_v * sigma_v + floor * floor + lever * lever

    def _height_gate_m(self, t_e: float) -> float:
        """The height residual's gate at epoch ``t_e``: ``glitch_sigma`` x its 1-sigma +
        ``position_gate_m``. The 1-sigma has, with the height's and the fix's, what the z
        accelerometer bias not yet learnt puts into the residual: the height loop's lag at
        the epoch interval T (:func:`height_loop_lag_m`: at 1 Hz four times the bias in
        metres), and its open drift b s^2 / 2 over the heights rejected since the last
        taken. Without it a unit twice as noisy as its datasheet, its z bias 0.25 m/s^2
        (2.5 sigma of its spread), had its first heights 0.84 m off against a 0.83 m gate
        on a 1 Hz receiver; rejected, the height ran open to -900 m and every position was
        withheld (`steep-turns` seed 600, `imu-noise-x2+gnss-1hz`)."""
        interval_s = self._position.interval_s
        open_s = max(0.0, t_e - (self._t_height_epoch_s or t_e) - interval_s)
        sigma_baz = self._sigma_baz_mps2()
        lag_m = height_loop_lag_m(sigma_baz, interval_s) + 0.5 * sigma_baz * open_s * open_s
        sigma_m = math.hypot(self._position.vertical_innovation_sigma_m(), lag_m)
        return self.cfg.glitch_sigma * sigma_m + self.cfg.position_gate_m

    def _gate_position(
        self, fix: GnssFix, t_e: float, dp: list[float]
    ) -> Literal["use", "reject", "reset"]:
        """Use, reject (a glitch) or reset to the position whose horizontal residual is ``dp``.

        Gate: the innovation (the residual less the fix error the channel carries) beyond
        ``glitch_sigma`` x its 1-sigma as the channel predicts it (the fix's sigma and the
        dead-reckoning error since the last position used) + ``position_gate_m``, or the
        height residual beyond the same of the height's (an RTK height 5 m off went out in
        129029, NAVIGATING, through the height loop). A glitch
        is counted, logged at a limited rate, and not weighed in (the velocity still is); the
        mode is DEGRADED meanwhile.
        The engine resets to the GNSS after ``reset_rejections`` if the receiver's track is
        continuous (the engine is off), else after ``position_reset_s`` (it moved for good:
        a new base station, a datum change); see :mod:`gateway.estimation.gnss_track`.
        """
        cfg, track, channel = self.cfg, self._track, self._position
        gate_m = cfg.glitch_sigma * channel.horizontal_innovation_sigma_m() + cfg.position_gate_m
        residual_m = channel.horizontal_innovation_m(dp)
        gate_d_m = self._height_gate_m(t_e)
        within = residual_m <= gate_m and abs(dp[2]) <= gate_d_m
        if within and not track.drifting and not track.away:
            track.accepted()
            return "use"
        if track.reset_due(t_e, cfg.reset_rejections, cfg.position_reset_s):
            self.counters.position_resets += 1
            log.warning(
                "GNSS position %.2f m from the dead-reckoned one for %d epochs at t=%.3f: "
                "position reset to it", residual_m, track.rejections, t_e,
            )  # fmt: skip
            track.accepted()
            return "reset"
        track.rejected(t_e)
        self.counters.position_rejected += 1
        self._log.warning(
            t_e,
            track.drift_text(t_e)
            if track.drifting
            else track.away_text(t_e)
            if within
            else f"GNSS position glitch at t={t_e:.3f}: {residual_m:.2f} m from the "
            f"dead-reckoned position, gate {gate_m:.2f} m; height {dp[2]:+.2f} m off, gate "
            f"{gate_d_m:.2f} m (quality {int(fix.quality)}); position not used",
            "glitch",
        )
        return "reject"

    # ========================================================================= read-out

    def solution(self) -> Solution:
        """The current solution at the time of the last IMU sample."""
        fix = self._last_fix
        obs = self._observer
        if obs is None:
            return Solution(mode=Mode.INITIALISING, **common_fields(self._t_s, fix, self._imu))
        c9 = obs.c_bp9
        roll, pitch, yaw = rpy_from_mat9(c9)
        coasting_s = max(  # the position's (:func:`gap_beyond_s`)
            self._coasting_s(), gap_beyond_s(self._t_s, self._t_pos_rx_s, self.cfg.gnss_timeout_s)
        )
        gnss_ok = (
            fix is not None and fix.measures and self._t_vel_rx_s is not None and coasting_s == 0.0
        )
        lat = lon = alt = None
        vel = None
        send, within = self._dead_reckoning_output(coasting_s)
        # the reference point is antenna - C l_ant: not known before the heading is
        if self._nav_valid and self._heading_aligned and self._frame is not None and send:
            p, v = self._p_ned_m, self._v_ned_mps
            dn, de = self._lever_drift_ne(c9, self._t_s or 0.0)
            lat, lon, alt = self._frame.to_lla(p[0] - dn, p[1] - de, p[2])
            dvn, dve = self._lever_velocity_change_ne(c9, obs.w_b_rps)
            vel = (v[0] - dvn, v[1] - dve, v[2])
        k = self.cfg.converged_time_constants
        convergence = convergence_of(
            self._g_learn >= k,
            self._heading.kf.sigma_rps < self.cfg.gyro_z_converged_dps * DEG_TO_RAD,
            self._accel_xy_converged(k),
            not obs.learn,
        )
        quality, sats, hdop, age, geoid, station, talker = fix_fields(fix)
        imu, t = self._imu, self._t_s
        assert t is not None  # a sample came: the observer levelled on it
        # positional, in the field order (keywords cost a third of the solution's build)
        return Solution(
            t, self._mode(coasting_s, within),
            roll, pitch,
            wrap_pi(yaw - self._heading_to_turn_rad(t)) if self._heading_aligned else None,
            self._yaw_rate_rps(c9),
            lat, lon, alt, vel, obs.bg_hat_rps, obs.ba_hat_mps2,
            self._sigma_tilt_rad(self._open_s(t)),
            quality, sats, hdop, age, geoid, station, talker,
            gnss_ok, imu.ok, imu.alarm,  # gnss_ok, imu_ok, imu_alarm
            self._heading.reversing, self._stationary, coasting_s > 0.0,  # ... coasting
            False, convergence,  # is_ekf, convergence
        )  # fmt: skip

    def _accel_xy_converged(self, k: float) -> bool:
        """Learnt k time constants of eq. (12); with the filter, its sigma at the residual
        level seed 000 reports after convergence (the stated sigma's floor)."""
        flt = self._ba_filter
        if flt is None:
            return self._a_learn >= k
        return flt.started and flt.sigma_mps2 <= ACCEL_BIAS_FLOOR_MPS2 * self._floor_scale

    def _yaw_rate_rps(self, c9: Mat9) -> float | None:
        """Rate of turn (:func:`heading_rate_from_mat9`), w_b averaged over the last
        ``OUTPUT_RATE_WINDOW_S`` (a single ADIS16334 sample is 0.5 deg/s noisy). Output only
        (no state depends on it), so plain floats, not numpy."""
        hist = self._hist
        if not hist or hist[-1][_T] - hist[0][_T] < OUTPUT_RATE_WINDOW_S:
            return None  # not yet a window: one sample's noise (1.6 deg/s seen) is no rate
        last = hist[-1]
        w = self._mean_rate(last[_T] - OUTPUT_RATE_WINDOW_S, last)
        return heading_rate_from_mat9(c9, w)

    def _coasting_s(self) -> float:
        """Time since usable GNSS velocity stopped, 0 while it flows (receive-time clock)."""
        if self._t_s is None or self._t_vel_rx_s is None or not self._coasting:
            return 0.0
        return max(0.0, self._t_s - self._t_vel_rx_s)

    def _dead_reckoning_output(self, coasting_s: float) -> tuple[bool, bool]:
        """(position sent, within COASTING's accuracy): :func:`dead_reckoning_output` with the
        1-sigma of :class:`CoastBudget`, or, while velocities still come and only positions
        do not (the GGA lost, RMC and VTG through), the position channel's grown over the
        time since its last epoch at the inertial velocity's walk: the channel takes no
        velocity without a position, so the state dead-reckons on its own. Without that,
        40 s of GGA lost on `short` seed 11 sent 1,043 positions COASTING up to metres off
        (beyond 3 x ``coast_sigma_m``), with no budget to withhold them."""
        if coasting_s <= 0.0:
            return True, True
        budget = self._coast_budget
        if self._coasting and budget is not None:
            v = self._v_ned_mps
            sigma_h = budget.sigma_h_m(coasting_s, math.hypot(v[0], v[1]))
        else:
            tau = (self._t_s or self._t_position_s) - self._t_position_s
            sigma_h = self._position.sigma_h_after_m(tau, self._velocity_walk_q())
        return dead_reckoning_output(coasting_s, sigma_h, self.cfg)

    def _mode(self, coasting_s: float, coast_within_accuracy: bool) -> Mode:
        return navigation_mode(
            fault=self._imu.fault,
            aligned=self._heading_aligned,
            coasting=coasting_s > 0.0,
            coast_within_accuracy=coast_within_accuracy,
            imu_alarm=self._imu.alarm,
            fix=self._last_fix,
            navigating_fix_qualities=self.cfg.navigating_fix_qualities,
            imu_gap=self._imu.timing.degraded(),
            gnss_glitch=self._t_s is not None and self._track.doubtful(self._t_s),
            heading_within_accuracy=self._t_s is not None
            and self._heading.sigma_psi_at(self._t_s)
            <= self.cfg.navigating_heading_sigma_deg * DEG_TO_RAD,
            position_within_accuracy=self._epoch_time_within_accuracy(),
        )

    def _epoch_time_within_accuracy(self) -> bool:
        """Is the epoch time's share of the position's horizontal 1-sigma, the speed times
        the epochs' time 1-sigma (the clock's: 0 on a UTC host, `[gnss]
        receiver_latency_sigma_s` on a free-running one), within
        :data:`NAVIGATING_POSITION_SHARE_M`, and has it been for
        :data:`EPOCH_SHARE_HOLD_S`? The observer has no state for it: a receiver 68 ms
        later than the configured latency put every fix 0.2 m behind the vehicle at 3 m/s
        and the heading 1.8 deg off after turns, NAVIGATING (field seed 635, free host, 100
        ms receiver); what the turns left in the heading and the tilt outlasts the speed
        (stopped, a 150 ms receiver's heading was 1.6 deg off: steep-turns seed 636). Only
        while GNSS velocities are in use: driving without a fix, no epoch moves anything
        (and the clock knows no date yet). Logged when it holds NAVIGATING back."""
        sigma_s, t = self.clock.epoch_sigma_s, self._t_s
        if sigma_s == 0.0 or t is None:
            return True
        vn, ve, _ = self._v_ned_mps
        speed = math.hypot(vn, ve)
        in_use = self._t_vel_rx_s is not None and not self._coasting
        if in_use and speed * sigma_s > NAVIGATING_POSITION_SHARE_M:
            self._t_epoch_share_beyond_s = t
            self._epoch_log.warning(
                t,
                f"GNSS epochs placed by their receive time (the host clock not known to "
                f"follow UTC), known to {sigma_s * 1000:.0f} ms ([gnss] receiver_latency_sigma_s): "
                f"at {speed:.1f} m/s beyond RTK class, DEGRADED; sync the host clock (NTP, "
                "PPS, gpsd), measure the latency (navgw calibrate on a recorded drive gives "
                "both keys), or run the EKF (it learns the error)",
                "epoch share",
            )
        last = self._t_epoch_share_beyond_s
        return last is None or t - last >= EPOCH_SHARE_HOLD_S

    def _control_left_s(self, t_s: float) -> float:
        """What is left at ``t_s`` of the period the last epoch's control rates are for, s."""
        return max(0.0, self._control_period_s - (t_s - self._control_from_s))

    def _heading_to_turn_rad(self, t_s: float) -> float:
        """What the last epoch's heading correction has still to turn the platform at
        ``t_s``, rad: it is a rate over the epoch's period (a 1 Hz receiver's over the
        second after it), while the heading channel's variance is the corrected heading's.
        The heading sent is the corrected one (0.46 deg at 1 Hz while the z-gyro bias is
        learnt, with 0.28 stated)."""
        return self._w_pz_rps * self._control_left_s(t_s)

    def _sigma_bg_rps(self) -> float:
        """x/y gyro bias 1-sigma: the turn-on sigma decaying with the learning exponent, and
        the in-run walk since the biases last learnt (the datasheet's, as the heading
        channel's z bias walks). Without the walk a planter at 0.4-0.6 m/s with a unit twice
        as noisy as its datasheet (`field` seed 577, 1 Hz), its loop open for minutes before
        the first heading, stated 18.7 mdeg/s for 200 s in which its y bias wandered 0.08
        deg/s, and its pitch went 3.2 deg off with 1.02 stated."""
        sigma0 = self.cfg.gyro_bias_sigma0_dps * DEG_TO_RAD
        base = max(sigma0 * math.exp(-self._g_learn), GYRO_BIAS_FLOOR_RPS * self._floor_scale)
        if self._t_bg_learnt_s is None or self._t_s is None:
            return base
        unlearnt_s = max(0.0, self._t_s - self._t_bg_learnt_s)
        return math.sqrt(base * base + self._heading.kf.q_rps2_per_s * unlearnt_s)

    def _sigma_ba_mps2(self) -> float:
        """x/y accelerometer bias 1-sigma: the turn-on sigma (or the seed's) decaying with
        the exponent, or more where the estimate shows a bias beyond it.

        Eq. (12) takes out the fraction 1 - e^-a of the error e0 it started with (a being
        the exponent learnt since), so the estimate has moved by e0 (1 - e^-a) and e0 e^-a
        is left: (b_hat - b_hat0) e^-a / (1 - e^-a). For an error within the starting
        sigma that is within sigma0 e^-a; for seed 000's 0.2 m/s^2 against the 0.1 of the
        turn-on model it is twice as much, and a sigma that decayed from 0.1 stated half
        the error left (headland-reversing seed 117 restarted: 1.06 deg off with 0.32
        stated). Looked at once the estimate has moved a fifth of the way
        (``SHOWN_BIAS_MIN_LEARNT``): before, its noise would be the bias shown."""
        flt = self._ba_filter
        if flt is not None and flt.started:
            return max(flt.sigma_mps2, ACCEL_BIAS_FLOOR_MPS2 * self._floor_scale)
        bx0, by0, _, a0 = self._ba_origin
        sigma0 = self._ba_origin_sigma_mps2()
        # with the filter configured, nothing learns them before it starts (eq. 12 is
        # off): turns then took the sigma down with the exponent while the bias stayed
        # (roll 0.75 deg off with 0.12 stated, the filter kept from starting on rough ground)
        left = 1.0 if flt is not None else math.exp(a0 - self._a_learn)
        sigma = sigma0 * left
        obs = self._observer
        if obs is not None and 1.0 - left >= SHOWN_BIAS_MIN_LEARNT:
            ba = obs.ba_hat_mps2
            shown = max(abs(ba[0] - bx0), abs(ba[1] - by0))
            sigma = max(sigma, shown * left / (1.0 - left))
        return max(sigma, ACCEL_BIAS_FLOOR_MPS2 * self._floor_scale)

    def _ba_origin_sigma_mps2(self) -> float:
        """The x/y accelerometer bias 1-sigma where its learning started: a seed's or a
        bias change's, else the turn-on spread."""
        sigma0 = self._ba_origin[2]
        return self._turn_on_ba_mps2() if sigma0 is None else sigma0

    def _turn_on_ba_mps2(self) -> float:
        """The accelerometer's turn-on bias spread, 1-sigma: the config's, as much larger as
        the IMU's noise measured at rest is than the config's (as the residual floors and
        the gyro bias prior of the accel-bias filter are: :meth:`_noise_as_measured`). A
        unit that noisy is taken as that much worse a grade. Why: twice as noisy as its
        datasheet (robustness `imu-noise-x2`, whose turn-on spread is doubled too), a
        planter's x bias of 0.24 m/s^2 (2.4 sigma of the config's 0.1) went unlearnt for
        an hour without a heading, roll and pitch 1.3-2.0 deg off with 0.54-0.65 stated
        (`field` seed 591, 5,990 frames beyond 0.1 deg + 3 sigma)."""
        return self.cfg.accel_bias_sigma0_mps2 * self._floor_scale

    def _sigma_baz_mps2(self) -> float:
        """z accelerometer bias 1-sigma: the turn-on sigma (or the seed's) decaying with
        the low-pass of :meth:`_learn_accel_bias_z`, floored."""
        sigma0 = self._turn_on_ba_mps2()
        decay = math.exp(-self._az_learn_s / self.cfg.accel_bias_z_tau_s)
        return max(sigma0 * decay, ACCEL_BIAS_Z_FLOOR_MPS2 * self._floor_scale)

    def _coast_drift_rad(self, open_s: float) -> float:
        """1-sigma of the tilt's open-loop drift after ``open_s`` (a coast, :meth:`_open_s`):
        the x/y gyro bias's b_g t and the ARW's random walk ARW sqrt(t) (0.067 deg after 4 s:
        left out, an outage on seed 95 of `outages` drifted 0.3 deg in 7 s with 0.04
        stated)."""
        return math.hypot(self._sigma_bg_rps() * open_s, self._gyro_arw * math.sqrt(open_s))

    def _sigma_tilt_rad(self, open_s: float) -> float:
        """Roll/pitch 1-sigma: :meth:`_model_tilt_var`'s, and what the loop's recent tilt
        corrections show beyond it (:meth:`CorrectionWindow.excess_rad`: a bias change
        building, before it is one)."""
        var = self._model_tilt_var(open_s)
        sigma = math.sqrt(var)
        excess = self._corrections.excess_rad(self._gyro_arw, sigma)
        return math.sqrt(var + excess * excess) if excess else sigma

    @property
    def _noise_tilt_var(self) -> float:
        """Steady roll/pitch variance from the IMU's white noise through the tilt loop."""
        return self._tilt_loop.noise_tilt_var()

    def _gnss_vel_sigma_mps(self) -> float:
        """The RTK velocity 1-sigma per axis the fixes are weighed with, m/s: the config's,
        or the receiver's where more (:class:`VelocityNoise`, from eq. 3's mismatches)."""
        return self._vel_noise.sigma_mps()

    def _fix_sigma_v(self) -> float:
        """The last fix's horizontal velocity 1-sigma per axis, at least RTK's, m/s."""
        fix, sigma_rtk = self._last_fix, self._gnss_vel_sigma_mps()
        return sigma_rtk if fix is None else fix_velocity_sigma_mps(fix, sigma_rtk)

    def _model_tilt_var(self, open_s: float) -> float:
        """Roll/pitch variance from the observer's physics (seed 000, eqs. 3, 8, 10): the
        sum of the squares of:
        - the IMU's white noise through the tilt loop: gyro ARW sqrt(tau / 2) first order,
          ARW sqrt(5 tau / 8) second order, and the accelerometer's, white on e
          (:mod:`.tilt_loop`);
        - GNSS velocity noise: e is a velocity *difference* over T, so its integral telescopes
          and the tilt sees one velocity error, not a random walk: sigma_v / (g tau), second
          order times sqrt(2 T / tau), with sigma_v^2 = var(e) T^2 / 2 from the running
          variance of e (white velocity noise differenced at 10 Hz is 0.28 m/s^2 on e but only
          0.03 deg of tilt through the paper's loop);
        - residual gyro bias times tau (steady tilt b_g tau, eq. 10) and accelerometer bias
          over g (eq. 8), each decaying from its initial 1-sigma with the learning exponent
          down to the paper's residual level;
        - the z accelerometer bias as C f_b puts it on the horizontal, b_az sin(tilt) / g;
        - open-loop drift while coasting or left open (:meth:`_coast_drift_rad`);
        - the tilt error of levelling on a moving window (:mod:`gateway.estimation.levelling`)
          or of the last coast's drift, decaying with the loop while it is closed;
        - the tilt the accel-bias filter's recent corrections left, until the loop follows;
        - the IMU mounting's own roll/pitch 1-sigma (an estimated mounting is not exact).
        """
        g = GRAVITY_MPS2
        obs = self._observer
        c = obs.c_bp9 if obs is not None else (0.0,) * 9
        sin2_tilt = c[2] * c[2] + c[5] * c[5]  # body z's horizontal part, squared
        return (
            self._platform_tilt_var(open_s)
            + (self._sigma_ba_mps2() / g) ** 2
            + sin2_tilt * (self._sigma_baz_mps2() / g) ** 2
            + self._mounting_var
        )

    def _platform_tilt_var(self, open_s: float) -> float:
        """The part of :meth:`_model_tilt_var` that is an error of the platform's specific
        force, which the velocities are integrated with: not the accelerometer biases' and
        the mounting's, which the loop's tilt makes up for (it turns the platform until C f
        agrees with the GNSS velocities: an x/y bias error delta_b leaves the tilt
        delta_b / g off the truth and the acceleration right)."""
        tau = self._tilt_loop.tau_now_s
        sigma_bg = self._sigma_bg_rps()
        sigma_v = math.sqrt(0.5 * self._e_var_mps4) * self._epoch_interval_s
        return (
            self._noise_tilt_var
            + self._tilt_loop.velocity_tilt_sigma(sigma_v, self._epoch_interval_s) ** 2
            + (sigma_bg * tau) ** 2
            + self._coast_drift_rad(open_s) ** 2
            + self._sigma_level_rad**2
            + (math.hypot(*self._ba_tilt_ne) / GRAVITY_MPS2) ** 2
        )


def filter_biases(obs: TereshkovObserver) -> tuple[float, float, float, float, float]:
    """The bias estimates the accel-bias filter follows: b_a x, y, z and b_g x, y."""
    ba, bg = obs.ba_hat_mps2, obs.bg_hat_rps
    return (ba[0], ba[1], ba[2], bg[0], bg[1])


def height_loop_gain(since_s: float) -> float:
    """The height loop's alpha for a residual ``since_s`` after the last height taken:
    2 T / :data:`HEIGHT_LOOP_TAU_S`, at most 1 (its beta is alpha^2 / 4, critically
    damped)."""
    return min(1.0, 2.0 * since_s / HEIGHT_LOOP_TAU_S) if since_s > 0.0 else 1.0


def height_loop_lag_m(accel_mps2: float, interval_s: float) -> float:
    """The height residual the loop settles at under a constant vertical acceleration
    error ``accel_mps2`` with heights ``interval_s`` apart: a T^2 / beta, the velocity
    correction beta e / T per epoch making up a T (0.09 a at 10 Hz, 4 a at 1 Hz)."""
    alpha = height_loop_gain(interval_s)
    return accel_mps2 * interval_s * interval_s / (0.25 * alpha * alpha)
