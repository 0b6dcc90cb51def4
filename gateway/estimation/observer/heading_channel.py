"""Heading channel and z-gyro bias Kalman filter (ALGORITHMS.md section 2, seed 001).

The yaw of the platform DCM is propagated by the gyros; per GNSS epoch it is pulled toward the
best heading reference available (smallest 1-sigma): HDT at any speed, the course of the
reference point (lever-arm corrected) at speed, or a configured AB-line bearing while driving
along it. Reversing (course about 180 deg from heading) is detected with hysteresis and then the
reversed course is the reference, so there is no 180 deg jump and no backwards pull.

The correction is a vertical control rate w_pz = K r / T, r = psi_hat - psi_ref, applied to
the DCM by the observer over the next interval T. K is the gain of a scalar Kalman filter of
the heading error: its variance grows with the gyro's ARW (ARW^2 T) and the z-bias
uncertainty, and each reference shrinks it by its sigma (COG: sigma_v / speed, so 0.4 deg at
3 m/s and 1.1 deg at 1 m/s). In steady state this is a time constant sigma_ref sqrt(T) / ARW
(COG at 3 m/s: 3.6 s, at 1 m/s: 11 s) instead of a fixed 2 s that let the COG noise of low
speed straight into the heading; after alignment or a long gap it is fast. The z bias is a
consider state of that filter (Schmidt): the heading error's covariance with the bias error
grows by sigma_bz^2 T an epoch and shrinks with each reference and each bias update, and the
variance grows by 2 T of it + (sigma_bz T)^2. Taken as white noise an epoch, the bias's part
was (sigma_bz T)^2 alone, where an unlearnt bias b holds the heading b times the time
constant off: 1.6 deg with 0.12 stated while reversing at 1 m/s after a z bias step.
The rate is applied after the epoch's time (the epoch reaches the engine late), so
the residual is taken from the heading at the epoch with the corrections applied since: no
correction is taken twice, and K needs no cap.

The z-gyro bias follows seed 001: the heading drift the gyro would have had without
correction over an interval T is an observation of the residual bias (about the vertical;
divided by C[2,2] for the body z axis) and feeds a scalar Kalman filter with F = 1, H = 1
and the process noise of the datasheet's in-run wander (a Gauss-Markov process of sigma
stability / 0.6174 and time constant tau, driven by white noise of PSD 2 sigma^2 / tau, as
the EKF has it). The drift is the slope of a weighted least-squares line through the
uncorrected residuals u = r + integral of w_pz of every epoch of the interval. Its variance
is the fit's for the reference's noise (white at the epochs for a course from Doppler
velocity; for HDT and an AB line, whose errors last longer than an epoch, that of the two
ends) plus the gyro's angular random walk in the heading, 6 ARW^2 / (5 T) for a line fit to
a random walk; the slope is the bias's weighted mean over the interval, not its value at the
end (:meth:`GyroZBiasKf.update_slope`). An interval of course lasts until the random walk,
not the course's noise, is the larger part (about 11 s at 3 m/s, 6 s at 6 m/s, 60-130 s at
0.5 m/s; at least ``gyro_z_window_s``). Epochs without a reference (a course under its
speed) leave it running: the uncorrected heading's drift goes on across them. It ends where
that drift stops being the bias's: the gates closed, an IMU gap, a heading held or set, a
zero-rate update (a new bias), a change of source. The bias's variance grows with the
wander every epoch, observed or not.
Before, the drift was the difference of the interval's two ends over 5 s, and the filter
took the intervals as independent where they shared their ends: it stated three times the
error it had on a steady course, and with its hand-set random walk (a third of the
datasheet's) it trailed the wandering bias in a run, 2-3 times as far off as the EKF's
(0.020 against 0.008 deg/s RMS on `outages` seed 510), its heading 1.6 deg off after a
60 s outage. At rest the mean bias-corrected z rate over a window is a direct observation
of the residual bias (zero-rate update, :meth:`HeadingChannel.observe_zero_rate`), with
variance ARW^2 / T.

A step of the z bias (a shock to the unit) is far beyond that wander, and the filter, its
sigma at the wander's 8 mdeg/s, took a third of +0.2 deg/s in 40 s while the heading stated
0.06-0.14 deg stood 0.9-1.3 deg off (`short` seed 5). The heading corrections the channel
applies over 5 s are watched as the tilt's are (:mod:`gateway.estimation.bias_change`):
beyond what the ARW, the bias's sigma and the stated heading at both ends explain, the
excess is in the stated heading, and a change re-opens the bias to the window's rate and
restarts its interval, so the next interval's drift is all after the change.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import Enum

from drivers.units import DEG_TO_RAD, SQRT_SECONDS_PER_HOUR, wrap_pi
from gateway.estimation.bias_change import BiasChange, CorrectionWindow
from gateway.estimation.ekf.ekf_config import GM_ALLAN_FLOOR
from gateway.estimation.line_fit import LineSums
from gateway.estimation.observer.observer_config import ObserverConfig

#: Variance of a drift line's slope about the bias at its end, per (bias walk PSD x interval):
#: the integral over [0, 1] of (3 x^2 - 2 x^3)^2, the square of the slope's cumulative weight.
WANDER_IN_SLOPE = 13.0 / 35.0

#: Course-vs-heading difference above which the vehicle is reversing, below which forward.
REVERSE_ENTER_RAD = 135.0 * DEG_TO_RAD
REVERSE_LEAVE_RAD = 45.0 * DEG_TO_RAD


class HeadingSource(Enum):
    """Where a heading reference came from."""

    HDT = "hdt"
    COG = "cog"
    COG_REVERSED = "cog_reversed"
    AB_LINE = "ab_line"

    @property
    def white(self) -> bool:
        """Whether its error is white at the epochs: a course from Doppler velocity; a dual
        antenna's multipath and a driver's hold of an AB line last longer."""
        return self in (HeadingSource.COG, HeadingSource.COG_REVERSED)


@dataclass(frozen=True, slots=True)
class HeadingReference:
    """One heading observation: true heading (rad), its 1-sigma (rad) and source."""

    psi_rad: float
    sigma_rad: float
    source: HeadingSource


@dataclass(frozen=True, slots=True)
class HeadingCorrection:
    """What the observer applies: vertical control rate (rad/s) and a direct yaw step (rad);
    and a z bias change the corrections showed (for the log), if any."""

    w_pz_rps: float = 0.0
    step_rad: float = 0.0
    change: BiasChange | None = None


class GyroZBiasKf:
    """Scalar Kalman filter of seed 001: x = z gyro bias (rad/s), F = 1, H = 1."""

    def __init__(self, sigma0_rps: float, walk_rps_per_sqrt_s: float) -> None:
        self.x_rps = 0.0
        self.p_rps2 = sigma0_rps**2
        self.q_wander_rps2_per_s = walk_rps_per_sqrt_s**2  # the in-run wander's walk
        self.q_temp_rps2_per_s = 0.0  # the walk a moving temperature adds (the engine's)

    @property
    def q_rps2_per_s(self) -> float:
        """The bias's random walk, Q, (rad/s)^2 / s."""
        return self.q_wander_rps2_per_s + self.q_temp_rps2_per_s

    def predict(self, dt_s: float) -> None:
        """Random-walk bias: P += Q dt."""
        self.p_rps2 += self.q_rps2_per_s * dt_s

    def update(self, innovation_rps: float, r_rps2: float) -> None:
        """Fuse an observation z with z - x = ``innovation_rps`` and variance ``r_rps2``."""
        k = self.p_rps2 / (self.p_rps2 + r_rps2)
        self.x_rps += k * innovation_rps
        self.p_rps2 *= 1.0 - k

    def update_slope(self, innovation_rps: float, r_rps2: float, walk_rps2: float) -> None:
        """Fuse a drift line's slope (innovation and variance as :meth:`update`) over an
        interval in which the bias wandered by ``walk_rps2`` = Q T (in P already). The slope
        is the bias weighted 6 s (T - s) / T^3 over the interval, not the bias at its end:
        its error about that is (13/35) Q T in variance (:data:`WANDER_IN_SLOPE`), shared
        with the wander since the interval began by Q T / 2. Taken as the bias now, the
        130 s intervals of slow courses (0.5 m/s) stated 7 mdeg/s where they had 11."""
        cross = self.p_rps2 - 0.5 * walk_rps2
        s = max(self.p_rps2 - (1.0 - WANDER_IN_SLOPE) * walk_rps2, 0.0) + r_rps2
        k = cross / s
        self.x_rps += k * innovation_rps
        self.p_rps2 -= k * cross

    @property
    def sigma_rps(self) -> float:
        """1-sigma of the bias estimate, rad/s."""
        return math.sqrt(self.p_rps2)


@dataclass
class _BiasWindow:
    """The heading-residual interval of one bias observation: a least-squares line through
    its epochs' uncorrected residuals u (rad) against the time since ``t0_s``, weighted by
    1 / sigma^2 of each reference."""

    t0_s: float
    u0_rad: float  # the first epoch's u, subtracted to keep the sums small
    sigma0_rad: float
    source: HeadingSource
    sums: LineSums = field(default_factory=LineSums)

    def __post_init__(self) -> None:
        self.add(self.t0_s, self.u0_rad, self.sigma0_rad)  # the first epoch is on the line

    def add(self, t_s: float, u_rad: float, sigma_rad: float) -> None:
        """One epoch's uncorrected residual and its reference's 1-sigma."""
        self.sums.add(1.0 / sigma_rad**2, t_s - self.t0_s, u_rad - self.u0_rad)

    def drift(self, t_s: float, u_rad: float, sigma_rad: float) -> tuple[float, float]:
        """Drift rate (rad/s) over the interval up to this epoch and its variance from the
        references' noise: the line's slope, its variance the fit's for white noise, else
        that of the two ends."""
        interval_s = t_s - self.t0_s
        if not self.source.white or self.sums.det <= 0.0:
            sigma = max(self.sigma0_rad, sigma_rad)
            return (u_rad - self.u0_rad) / interval_s, 2.0 * (sigma / interval_s) ** 2
        return self.sums.line()[1], self.sums.w / self.sums.det


class HeadingChannel:
    """Selects heading references, produces the heading control rate, estimates z-gyro bias."""

    def __init__(self, cfg: ObserverConfig) -> None:
        self.cfg = cfg
        wander_rps = cfg.gyro_bias_stability_dps * DEG_TO_RAD / GM_ALLAN_FLOOR
        self._walk_rps_per_sqrt_s = wander_rps * math.sqrt(2.0 / cfg.bias_correlation_time_s)
        self.kf = GyroZBiasKf(cfg.gyro_z_bias_sigma0_dps * DEG_TO_RAD, self._walk_rps_per_sqrt_s)
        self._arw = cfg.gyro_arw_deg_per_sqrt_h * DEG_TO_RAD / SQRT_SECONDS_PER_HOUR
        self.reversing = False
        self._t_kf_s: float | None = None
        self._window: _BiasWindow | None = None
        self._ab_dwell_since_s: float | None = None
        self._rejected_since_s: float | None = None
        self._t_last_s: float | None = None  # previous correction epoch
        self._p_psi_rad2 = math.pi**2  # heading error variance (unknown until aligned)
        self._p_psi_bz = 0.0  # its covariance with the z bias error that turns it, rad^2/s
        self._p_rest = (math.pi**2, 0.0)  # the two at the start of the window at rest
        self._corrections = CorrectionWindow("heading")  # recent control: a z bias change?
        self._course: HeadingReference | None = None  # the epoch's course, if one
        self._reopened = False  # a change re-opened the bias, not yet learnt on a full line

    # ------------------------------------------------------------------ reference choice

    def select_reference(
        self,
        t_s: float,
        psi_hat_rad: float,
        cog_ref_rad: float | None,
        speed_ref_mps: float,
        hdt_rad: float | None,
        yaw_rate_rps: float,
        stationary: bool,
        vel_sigma_mps: float,
        epoch_sigma_s: float = 0.0,
    ) -> HeadingReference | None:
        """Best heading reference at epoch ``t_s`` (smallest sigma), or None: hold on gyro.

        ``cog_ref_rad`` and ``speed_ref_mps`` are of the reference point (lever-arm
        corrected); ``psi_hat_rad`` is the platform heading at the same instant. A course's
        sigma is the velocity's 1-sigma ``vel_sigma_mps`` over the speed, with the yaw rate
        times the epoch time's 1-sigma ``epoch_sigma_s`` (0 on a UTC host): the course of an
        epoch placed dtau late is the heading w dtau before.
        """
        cfg = self.cfg
        candidates: list[HeadingReference] = []
        self._course = None
        if hdt_rad is not None:
            candidates.append(
                HeadingReference(hdt_rad, cfg.hdt_sigma_deg * DEG_TO_RAD, HeadingSource.HDT)
            )
        if stationary:
            self.reversing = False
        elif cog_ref_rad is not None and speed_ref_mps > cfg.reverse_detect_speed_mps:
            d = abs(wrap_pi(psi_hat_rad - cog_ref_rad))
            if d > REVERSE_ENTER_RAD:
                self.reversing = True
            elif d < REVERSE_LEAVE_RAD:
                self.reversing = False
            in_band = d > REVERSE_ENTER_RAD if self.reversing else d < REVERSE_LEAVE_RAD
            if in_band and speed_ref_mps > cfg.cog_min_speed_mps:
                sigma = math.hypot(vel_sigma_mps / speed_ref_mps, yaw_rate_rps * epoch_sigma_s)
                if self.reversing:
                    psi = (cog_ref_rad + math.pi) % (2.0 * math.pi)
                    self._course = HeadingReference(psi, sigma, HeadingSource.COG_REVERSED)
                else:
                    self._course = HeadingReference(cog_ref_rad, sigma, HeadingSource.COG)
                candidates.append(self._course)
        ab = self._ab_line_reference(t_s, psi_hat_rad, yaw_rate_rps, stationary)
        if ab is not None:
            candidates.append(ab)
        return min(candidates, key=lambda c: c.sigma_rad) if candidates else None

    def _ab_line_reference(
        self, t_s: float, psi_hat_rad: float, yaw_rate_rps: float, stationary: bool
    ) -> HeadingReference | None:
        """The AB-line bearing (either direction) after a dwell along it, else None."""
        cfg = self.cfg
        if cfg.ab_line_bearing_deg is None:
            return None
        bearing = cfg.ab_line_bearing_deg * DEG_TO_RAD
        if abs(wrap_pi(psi_hat_rad - bearing)) > math.pi / 2:
            bearing = (bearing + math.pi) % (2.0 * math.pi)
        along = (
            not stationary
            and abs(wrap_pi(psi_hat_rad - bearing)) < cfg.ab_line_window_deg * DEG_TO_RAD
            and abs(yaw_rate_rps) < cfg.ab_line_max_rate_dps * DEG_TO_RAD
        )
        if not along:
            self._ab_dwell_since_s = None
            return None
        if self._ab_dwell_since_s is None:
            self._ab_dwell_since_s = t_s
        if t_s - self._ab_dwell_since_s < cfg.ab_line_min_time_s:
            return None
        return HeadingReference(
            bearing % (2.0 * math.pi), cfg.ab_line_sigma_deg * DEG_TO_RAD, HeadingSource.AB_LINE
        )

    # ---------------------------------------------------------------------- correction

    def correct(
        self,
        t_s: float,
        psi_hat_rad: float,
        ref: HeadingReference | None,
        hc_rad: float,
        c22: float,
        learn: bool,
        yaw_rate_rps: float,
        period_s: float,
    ) -> HeadingCorrection:
        """Heading correction for epoch ``t_s``; also one z-bias KF step per full interval.

        ``psi_hat_rad`` is the platform heading at ``t_s`` with every correction applied so
        far, ``hc_rad`` their sum (integral of w_pz, so psi_hat + hc is the uncorrected
        heading), ``c22`` = C[2, 2] (body z vs vertical), the vehicle turning at
        ``yaw_rate_rps``. ``learn`` False (gates closed) restarts the bias interval. The
        rate is the step over ``period_s``, the time the engine holds it for.
        """
        interval_s = 0.0 if self._t_last_s is None else t_s - self._t_last_s
        self._t_last_s = t_s
        self._predict_heading_variance(interval_s)
        self.predict_bias(t_s)
        if ref is None:
            self._rejected_since_s = None
            self._forget_corrections(self.sigma_psi_rad)
            return HeadingCorrection()
        r = wrap_pi(psi_hat_rad - ref.psi_rad)
        if abs(r) > self.cfg.heading_gate_deg * DEG_TO_RAD:
            self._window = None
            if self._rejected_since_s is None:
                self._rejected_since_s = t_s
            if t_s - self._rejected_since_s >= self.cfg.heading_realign_s:
                self._rejected_since_s = None
                self.aligned(ref.sigma_rad)
                return HeadingCorrection(step_rad=-r)
            return HeadingCorrection()
        self._rejected_since_s = None
        sigma_bz_rps = self.kf.sigma_rps
        if learn:
            self._observe_bias(t_s, r, hc_rad, ref, c22)
        else:
            self._window = None
        if not 0.0 < interval_s <= self.cfg.max_gnss_interval_s:
            # The first reference after a gap: weighed by its sigma as any other (a fixed
            # T / 2 s took half of one course's noise at 1 Hz: 2.2 deg of a pull-away's
            # course at 0.6 m/s, 2 deg off NAVIGATING with 0.3 stated for 4 s); not watched,
            # its interval being no epoch's.
            self._corrections.clear()
            self._match_gap_residual(r, ref.sigma_rad)
            return HeadingCorrection(w_pz_rps=r * self._gain(ref.sigma_rad) / period_s)
        sigma_rad = self.sigma_psi_rad
        step_rad = r * self._gain(ref.sigma_rad)
        course = self._course_evidence(ref, r, psi_hat_rad, yaw_rate_rps, interval_s)
        change = self._watch_corrections(
            t_s, (step_rad, sigma_rad), course, sigma_bz_rps, c22, learn
        )
        return HeadingCorrection(w_pz_rps=step_rad / period_s, change=change)

    @property
    def course(self) -> HeadingReference | None:
        """The last epoch's course as a heading reference (turned round when reversing),
        if it had one."""
        return self._course

    def _course_evidence(
        self,
        ref: HeadingReference,
        r: float,
        psi_hat_rad: float,
        yaw_rate_rps: float,
        interval_s: float,
    ) -> tuple[float, float, float, float] | None:
        """The epoch's course less the heading, its sigma, the yaw rate and the interval, for
        the window (:meth:`CorrectionWindow.add_course`): the reference's if a course (``r``
        the heading less it), else, under an HDT, the course's beside it. The HDT's screen
        tells its jumps from the gyro's turn; one that drifts (0.2 deg/s for a minute:
        multipath on an antenna) passes it epoch by epoch, and the observer followed it 12
        deg off, NAVIGATING (custom `field` seed 669 with HDT): the courses say so."""
        if ref.source.white:
            return -r, ref.sigma_rad, yaw_rate_rps, interval_s
        course = self._course
        if ref.source is not HeadingSource.HDT or course is None:
            return None
        return wrap_pi(course.psi_rad - psi_hat_rad), course.sigma_rad, yaw_rate_rps, interval_s

    def _watch_corrections(
        self,
        t_s: float,
        step: tuple[float, float],
        course: tuple[float, float, float, float] | None,
        sigma_bz_rps: float,
        c22: float,
        learn: bool,
    ) -> BiasChange | None:
        """The correction of the heading and the sigma stated before it (``step``, rad),
        a course less the heading, its sigma, the yaw rate and the epoch interval
        (``course``, :meth:`CorrectionWindow.add_course`; None for HDT or an AB line,
        whose errors last longer than an epoch), the z
        bias at ``sigma_bz_rps`` (before this epoch's bias update), into the window (while
        the gates are open: a fix not good enough to learn from is no evidence,
        :meth:`_forget_corrections`). On a change (:mod:`gateway.estimation.bias_change`)
        found first, :meth:`reopen`."""
        window = self._corrections
        if not learn:
            self._forget_corrections(step[1])
            return None
        window.add(t_s, step[0], 0.0, step[1], sigma_bz_rps)
        if course is not None:
            window.add_course(t_s, *course)
        change = window.check(self._arw, self.sigma_psi_rad)
        if change is not None and not change.again:
            self.reopen(change, c22)
        return change

    def reopen(self, change: BiasChange, c22: float) -> None:
        """A change: the z bias re-opens to the window's rate (about the vertical, so over
        ``c22`` for body z) and its interval restarts; the heading's variance takes the
        angle turned."""
        self.kf.p_rps2 = max(self.kf.p_rps2, (change.rate_rps / c22) ** 2)
        self._p_psi_rad2 = max(self._p_psi_rad2, change.angle_rad**2)
        self._window = None
        self._reopened = True

    def _forget_corrections(self, sigma_rad: float) -> None:
        """The window ends (the gates closed, or the references stopped: a stop): what it
        showed beyond the heading stated at ``sigma_rad`` stays in the heading's variance
        until references take it. A z step found in a U-turn at 1.5 m/s, stated 0.5 deg
        beyond, aged out of the window through the stop after it, and the vehicle
        reversed saying NAVIGATING 2.9 deg off."""
        self._p_psi_rad2 += self._corrections.forget(self._arw, sigma_rad) ** 2

    def _match_gap_residual(self, r_rad: float, sigma_ref_rad: float) -> None:
        """The first reference after a gap (an outage): a residual beyond 3 sigma of the
        heading's and the reference's is the heading's error, which the gap's growth did not
        cover (a z bias step in the outage): its variance becomes r^2 - sigma_ref^2, so the
        heading states it and the next references take it at once. `outages` seed 551 with
        -0.2 deg/s at its outage's start came out 2.1 deg off with 0.15 stated, 4.4 sigma of
        one course at 2.5 m/s, and said NAVIGATING 2.0 deg off until its corrections showed
        it (27 frames)."""
        r2, ref2 = r_rad * r_rad, sigma_ref_rad * sigma_ref_rad
        if r2 > 9.0 * (self._p_psi_rad2 + ref2):
            self._p_psi_rad2 = r2 - ref2

    def _gain(self, sigma_ref_rad: float) -> float:
        """Kalman gain of one heading reference (module docstring); updates the variance and
        the covariance with the z bias, which it does not correct (a consider state)."""
        k = self._p_psi_rad2 / (self._p_psi_rad2 + sigma_ref_rad**2)
        self._p_psi_rad2 *= 1.0 - k
        self._p_psi_bz *= 1.0 - k
        return k

    @property
    def sigma_psi_rad(self) -> float:
        """Heading 1-sigma as of the last reference (pi until aligned), rad."""
        return math.sqrt(self._p_psi_rad2)

    def sigma_psi_at(self, t_s: float) -> float:
        """Heading 1-sigma at ``t_s``: the last epoch's grown over the time since, rad (an
        outage's heading is as uncertain as the gyro made it, not as the last fix left it),
        with what the recent corrections show beyond it
        (:meth:`~gateway.estimation.bias_change.CorrectionWindow.excess_rad`)."""
        gap_s = 0.0 if self._t_last_s is None else max(t_s - self._t_last_s, 0.0)
        var = self._p_psi_rad2 + self._heading_growth_rad2(gap_s)
        excess = self._corrections.excess_rad(self._arw, math.sqrt(var))
        return math.sqrt(var + excess * excess)

    def _heading_growth_rad2(self, gap_s: float) -> float:
        """Heading error variance added over ``gap_s`` without a reference: ARW^2 gap + the
        z bias error's turn, 2 gap P_psi,bz + gap^2 sigma_bz^2."""
        return (
            self._arw**2 * gap_s + 2.0 * gap_s * self._p_psi_bz + (self.kf.sigma_rps * gap_s) ** 2
        )

    def _predict_heading_variance(self, gap_s: float) -> None:
        """Heading error variance and its covariance with the z bias grown over ``gap_s``."""
        self._p_psi_rad2 += self._heading_growth_rad2(gap_s)
        self._p_psi_bz += gap_s * self.kf.p_rps2

    def predict_bias(self, t_s: float) -> None:
        """The z bias's variance grown by its in-run wander up to ``t_s``, every epoch (the
        engine's before the heading is known too): the heading's growth, the corrections'
        check and the first alignment's courses take its sigma as of now. Grown only
        when an observation came, it stayed at a stop's 8 mdeg/s through 260 s of planting
        at 0.4-0.5 m/s without one while the bias wandered 0.03 deg/s, and the heading,
        1.6 deg off, stated 0.46 (`field` seed 575, planter speeds, IMU mounted rotated);
        before the heading, 12.8 mdeg/s through 590 s in which the bias wandered 0.08
        deg/s, and the courses aligned it 1.7 deg off with 0.5 stated (seed 578, a unit
        twice as noisy, a 1 Hz receiver)."""
        if self._t_kf_s is not None and t_s > self._t_kf_s:
            self.kf.predict(t_s - self._t_kf_s)
        if self._t_kf_s is None or t_s > self._t_kf_s:
            self._t_kf_s = t_s

    def _bias_updated(self, p_before_rps2: float) -> None:
        """The z bias KF took an observation: what of its error the heading error shared
        shrinks with it (by P after / P before, 1 - K)."""
        ratio = self.kf.p_rps2 / p_before_rps2 if p_before_rps2 > 0.0 else 0.0
        self._p_psi_bz *= ratio
        self._p_rest = (self._p_rest[0], self._p_rest[1] * ratio)

    def bridged(self, sigma_rad: float, restart: bool) -> None:
        """Lost IMU samples were bridged, turning the heading by an error of ``sigma_rad``
        1-sigma: the variance takes it, and after a gap (``restart``) the bias interval
        restarts (the heading's drift over it is no longer the z bias's)."""
        if restart:
            self._window = None
        self._p_psi_rad2 += sigma_rad**2

    def aligned(self, sigma_rad: float) -> None:
        """Heading was just set directly (alignment, realignment) to a reference of
        ``sigma_rad``: restart the bias interval, the corrections' window and the heading
        variance."""
        self._window = None
        self._corrections.clear()
        self._p_psi_rad2 = sigma_rad**2
        self._p_psi_bz = 0.0

    def set_noise(self, arw_rps_per_sqrt_s: float, scale: float) -> None:
        """The gyro's ARW as measured at rest, and how much noisier than its config the IMU
        is (>= 1): its in-run wander taken as that much larger too, as the engine's bias
        floors are. A unit twice as noisy as its datasheet (robustness `imu-noise-x2`) came
        out of a 60 s outage 2.7 deg off with 0.56 stated, NAVIGATING half a second later."""
        self._arw = arw_rps_per_sqrt_s
        self.kf.q_wander_rps2_per_s = (self._walk_rps_per_sqrt_s * scale) ** 2

    def rest_began(self) -> None:
        """A window at rest starts: its heading variance is what a hold at its end keeps."""
        self._p_rest = (self._p_psi_rad2, self._p_psi_bz)

    def held(self) -> None:
        """The caller held the heading where it was at the window's start (the gyro's drift
        over it, random walk and bias error alike, taken out): its variance is the start's."""
        self._window = None  # the heading turned back: the drift line breaks here
        if self._p_rest[0] < self._p_psi_rad2:
            self._p_psi_rad2, self._p_psi_bz = self._p_rest

    def observe_zero_rate(self, t_s: float, mean_w_z_rps: float, window_s: float) -> bool:
        """Zero-rate update at rest: the mean bias-corrected body z rate over ``window_s``
        is the residual z bias, variance ARW^2 / window (engine vibration averages out).

        True if taken: then the vehicle has not turned (the caller may hold the heading,
        :meth:`held`). Refused beyond ``glitch_sigma`` of the bias's and the mean's sigma: a
        turn on the spot, or creeping round a tight turn under the stationary speed."""
        self.predict_bias(t_s)
        r = self._arw**2 / window_s
        if mean_w_z_rps**2 > self.cfg.glitch_sigma**2 * (self.kf.p_rps2 + r):
            return False
        p_before = self.kf.p_rps2
        self.kf.update(mean_w_z_rps, r)
        self._bias_updated(p_before)
        self._window = None  # the gyro integrated with the old bias before, the new after
        return True

    def _observe_bias(
        self, t_s: float, r_rad: float, hc_rad: float, ref: HeadingReference, c22: float
    ) -> None:
        """Seed 001: residual bias = the uncorrected heading's drift over the interval (the
        slope of its epochs, module docstring)."""
        u = r_rad + hc_rad
        w = self._window
        if w is None or w.source is not ref.source:
            self._window = _BiasWindow(t_s, u, ref.sigma_rad, ref.source)
            return
        w.add(t_s, u, ref.sigma_rad)
        interval_s = t_s - w.t0_s
        if interval_s < self.cfg.gyro_z_window_s:
            return
        drift_rps, r_ref = w.drift(t_s, u, ref.sigma_rad)
        r_arw = 1.2 * self._arw**2 / interval_s
        r_rps2 = (r_ref + r_arw) / c22**2
        if ref.source.white and r_ref > r_arw:
            # the course's noise still the larger part: a longer line averages it; but a
            # bias re-opened by a change is taken as soon as the line knows it better (at
            # 1 m/s the course's noise is the larger part for 34 s: re-opened to 0.64 deg/s
            # after a -0.3 deg/s step, the bias was not learnt in 25 s of reversing, the
            # heading 1.6 deg off with 0.5 stated)
            if not (self._reopened and r_rps2 < self.kf.p_rps2):
                return
        else:
            self._reopened = False
        p_before = self.kf.p_rps2
        self.kf.update_slope(drift_rps / c22, r_rps2, self.kf.q_rps2_per_s * interval_s)
        self._bias_updated(p_before)
        self._window = _BiasWindow(t_s, u, ref.sigma_rad, ref.source)

    @property
    def bg_z_rps(self) -> float:
        """z-gyro bias estimate, body, rad/s."""
        return self.kf.x_rps
