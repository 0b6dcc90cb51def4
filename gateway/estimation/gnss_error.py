"""The receiver's position error by fix quality: its sigma, and its white and wandering parts.

One model for both engines (the observer's position channel and the EKF's fix-error states):
RTK float, DGNSS and single-point errors are not white. Multipath and atmosphere residuals
wander over tens of seconds, so a fix error is first-order Gauss-Markov (a correlation time)
plus a small white share. A filter that took it as white would average a minute of float
fixes to sigma^2 / N, believe it, and follow the wander.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from drivers.samples import CORRECTED_QUALITIES, DEFAULT_GNSS_SIGMAS, GnssFix

#: HDOP the quality's default sigmas (no GST) describe; a larger HDOP scales them up.
NOMINAL_HDOP = 1.0
#: Corrections up to this old are normal (1 Hz RTCM over a radio link with drop-outs).
NOMINAL_AGE_S = 5.0
#: Beyond it the corrected solution degrades: its sigma grows by this share per second
#: (ionosphere and orbit decorrelation: an RTK fix 20 s old is ~1.75x as uncertain).
AGE_GROWTH_PER_S = 0.05


def fix_position_sigma_m(fix: GnssFix) -> tuple[float, float, float] | None:
    """Position 1-sigma north, east, down of ``fix``: GST when sent; else the quality's
    default (:data:`drivers.samples.DEFAULT_GNSS_SIGMAS`) scaled by HDOP above
    :data:`NOMINAL_HDOP` and grown with the age of corrections beyond :data:`NOMINAL_AGE_S`."""
    sig = fix.position_sigma_m
    if sig is None or fix.sigma_n_m is not None:
        return sig
    scale = 1.0
    if fix.hdop is not None and fix.hdop > NOMINAL_HDOP:
        scale = fix.hdop / NOMINAL_HDOP
    if fix.quality in CORRECTED_QUALITIES and fix.age_s is not None and fix.age_s > NOMINAL_AGE_S:
        scale *= 1.0 + AGE_GROWTH_PER_S * (fix.age_s - NOMINAL_AGE_S)
    return (sig[0] * scale, sig[1] * scale, sig[2] * scale)


#: Time constant of :class:`VelocityNoise`'s running mean, s.
VELOCITY_NOISE_TAU_S = 10.0
#: ... in which an epoch counts for at most this long, s (a 5 Hz receiver's interval): one
#: after an outage is one epoch, and a 1 Hz receiver's are measured over 50 s.
VELOCITY_NOISE_MAX_S = 0.2
#: Two velocities further apart than this, s, are not a pair whose difference is their
#: white errors (a 1 Hz receiver's epochs and their jitter).
INNOVATION_PAIR_MAX_S = 1.5
#: What lever arms, the IMU's noise and the epochs' timing add to the residuals besides the
#: receiver's velocity noise, as a share of the configured sigma: taken out in quadrature
#: (`field` at RTK's 2 cm/s shows 1.8-2.4 cm/s in the observer's, the first minute less).
VELOCITY_MODEL_SHARE = 0.75
#: A residual counts up to this many of the running 1-sigma (a pull-away's first epoch, a
#: clipped glitch: no noise).
VELOCITY_CLIP_SIGMAS = 4.0


@dataclass
class VelocityNoise:
    """The receiver's horizontal velocity 1-sigma per axis as its RTK fixes show it, where
    that is beyond the configured ``config_mps``. NMEA states no velocity accuracy; a
    receiver of 5 cm/s (u-blox F9P's datasheet figure) weighed at 2 cm/s had the observer's
    accel-bias filter learn its noise as biases (roll 1.2 deg off with 0.36 stated,
    `steep-turns` seed 815) and the EKF take a first heading 3 deg off from its courses."""

    config_mps: float
    _var_m2ps2: float = 0.0

    def add(self, var_n_m2ps2: float, var_e_m2ps2: float, interval_s: float) -> None:
        """One epoch's residuals, as an unbiased sample of the variance on each axis (e.g.
        half a velocity difference's square), ``interval_s`` since the last that fed it."""
        clip = VELOCITY_CLIP_SIGMAS**2 * max(self._var_m2ps2, self.config_mps**2)
        mean = 0.5 * (min(var_n_m2ps2, clip) + min(var_e_m2ps2, clip))
        weight = min(interval_s, VELOCITY_NOISE_MAX_S) / VELOCITY_NOISE_TAU_S
        self._var_m2ps2 += weight * (mean - self._var_m2ps2)

    def sigma_mps(self) -> float:
        """The 1-sigma to weigh RTK fixes' velocities with: the config's, or what the
        residuals show less :data:`VELOCITY_MODEL_SHARE` of it in quadrature where more."""
        config = self.config_mps
        seen2 = self._var_m2ps2 - (VELOCITY_MODEL_SHARE * config) ** 2
        return math.sqrt(seen2) if seen2 > config * config else config


def fix_velocity_sigma_mps(fix: GnssFix, floor_mps: float) -> float:
    """Horizontal velocity 1-sigma per axis: the quality's default, at least ``floor_mps``."""
    row = DEFAULT_GNSS_SIGMAS.get(int(fix.quality))
    return max(floor_mps, row[2]) if row is not None else floor_mps


def fix_velocity_ne_mps(fix: GnssFix, stationary_speed_mps: float) -> tuple[float, float] | None:
    """Horizontal antenna velocity of ``fix`` (N, E, m/s) from SOG and COG, or None. A speed
    under ``stationary_speed_mps`` without a course is a vehicle standing still: a receiver
    gives no course before it has moved, and u-blox's NMEA blanks it below 0.1 m/s. A faster
    one without a course is no velocity."""
    vel = fix.vel_ne_mps
    if vel is None and fix.sog_mps is not None and fix.sog_mps < stationary_speed_mps:
        return (0.0, 0.0)
    return vel


def split_fix_variance(
    sigma_m: float, white_share: float, seen_share: float
) -> tuple[float, float]:
    """(white, wandering) variance of a fix error of 1-sigma ``sigma_m``: ``white_share`` of
    the sigma is independent from epoch to epoch (or ``seen_share`` where more: what the
    receiver's track shows, :class:`PositionNoise`), the configured rest is the Gauss-Markov
    wander (which no step of the track shows, so a white receiver keeps it)."""
    s2 = sigma_m * sigma_m
    w2 = white_share * white_share
    return max(w2, seen_share * seen_share) * s2, (1.0 - w2) * s2


def displacement_sigma_m(
    sigma_a_m: float,
    sigma_b_m: float,
    dt_s: float,
    white_share: float,
    correlation_s: float | None,
    seen_share: float,
) -> float:
    """1-sigma of the difference of two fixes' positions on one axis, ``dt_s`` apart: their
    white parts add, their wanders (:func:`split_fix_variance`) cancel as far as they are
    still correlated (exp(-dt / ``correlation_s``); None: two solutions of different kinds,
    no common wander). An RTK position moves by a few mm from one epoch to the next however
    far it is off (a white receiver's, ``seen_share``, by its white noise)."""
    white_a, wander_a = split_fix_variance(sigma_a_m, white_share, seen_share)
    white_b, wander_b = split_fix_variance(sigma_b_m, white_share, seen_share)
    rho = 0.0 if correlation_s is None else math.exp(-dt_s / correlation_s)
    var = white_a + white_b + wander_a + wander_b - 2.0 * rho * math.sqrt(wander_a * wander_b)
    return math.sqrt(max(var, 0.0))


#: Steps of the receiver's track at most this long, s, show its positions' white noise in
#: their miss of where its velocities led: at 4 Hz and up a turn's trapezoid error is
#: millimetres and the velocities' noise adds sigma_v dt / sqrt(2) per axis to the miss
#: (5 cm/s at 5 Hz: 0.7 cm; taken as the positions', which errs wide). A 1 or 2 Hz
#: receiver's steps are the configured share's.
POSITION_NOISE_MAX_STEP_S = 0.25
#: Time constant of :class:`PositionNoise`'s running mean, s (a plain mean before it).
POSITION_NOISE_TAU_S = 10.0
#: A miss counts up to this many of its running 1-sigma, or of the fix's sigma where more
#: (a step the track did not take for a jump is no noise beyond it).
POSITION_CLIP_SIGMAS = 4.0


@dataclass
class PositionNoise:
    """The white part of the receiver's horizontal position error per axis, per fix quality,
    as the fixes show it: :class:`gateway.estimation.gnss_track.GnssTrack` feeds it each
    short step's miss of its velocities' trapezoid (two positions' white errors), the EKF
    the change of its position innovation from one epoch to the next (which a 1 Hz
    receiver's steps, too long for the track, still show).

    The engines split a fix's sigma into a white part and a wander by a configured share
    (0.3: an RTK solution moves by millimetres from one epoch to the next, its multipath
    and atmosphere wander). A receiver whose 2 cm are white from epoch to epoch had the
    EKF gate out a third of its RTK fixes at 5 sigma of the white share and flap between
    NAVIGATING and DEGRADED a few times a second (`short` seed 5); where the fixes show
    more white noise than the share, the engines take theirs."""

    #: fix quality: (white variance m^2 per axis, time it has been measured over s)
    _var_m2: dict[int | None, tuple[float, float]] = field(default_factory=dict)

    def add(
        self, quality: int | None, var_ne_m2: tuple[float, float], interval_s: float,
        fix_var_m2: float,
    ) -> None:  # fmt: skip
        """One sample of the white variance on each axis (north, east; unbiased, e.g. half
        the square of the difference of two positions' white errors), ``interval_s`` since
        the last, of fixes whose error variance is ``fix_var_m2`` per axis."""
        var, span_s = self._var_m2.get(quality, (0.0, 0.0))
        # clipped at POSITION_CLIP_SIGMAS of its sigma, or of the fix's where more
        clip = POSITION_CLIP_SIGMAS**2 * max(var, fix_var_m2)
        sample = 0.5 * (min(var_ne_m2[0], clip) + min(var_ne_m2[1], clip))
        span_s += interval_s
        var += interval_s / min(span_s, POSITION_NOISE_TAU_S) * (sample - var)
        self._var_m2[quality] = (var, span_s)

    def white_share(self, quality: int | None, sigma_ne_m: tuple[float, float]) -> float:
        """The white 1-sigma the fixes of ``quality`` show, as a share of a fix's per-axis
        sigma (``sigma_ne_m``, north and east); 0 before any sample, or where the samples
        (the filter's share taken out of each) average below zero."""
        var = max(self._var_m2.get(quality, (0.0, 0.0))[0], 0.0)
        axis2 = 0.5 * (sigma_ne_m[0] ** 2 + sigma_ne_m[1] ** 2)
        return math.sqrt(var / axis2) if axis2 > 0.0 else 0.0
