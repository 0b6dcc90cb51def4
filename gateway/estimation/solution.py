"""The estimator interface and the solution every engine (observer, EKF) produces.

Engines are plain classes fed timestamped samples (no I/O, no clock of their own), so the
live service, replay and tests run the same code; the engine is a config choice.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass, field
from enum import IntEnum
from itertools import product
from typing import Protocol

from drivers.samples import FixQuality, Float3, GnssFix, ImuSample
from gateway.estimation.heading_hint import HeadingHint


class Mode(IntEnum):
    """Navigation mode, NAVGW_STATUS byte 2 (SPEC 4)."""

    INITIALISING = 0
    ALIGNING = 1
    NAVIGATING = 2
    COASTING = 3  # inertial only through a GNSS outage
    DEGRADED = 4
    FAULT = 5


@dataclass(frozen=True, slots=True)
class Convergence:
    """Estimator flags, NAVGW_STATUS byte 5."""

    gyro_xy: bool = False
    gyro_z: bool = False
    accel_xy: bool = False
    learning_frozen: bool = False


#: Every Convergence there is (frozen: shared), by its flags in field order.
_CONVERGENCE = {flags: Convergence(*flags) for flags in product((False, True), repeat=4)}


def convergence_of(
    gyro_xy: bool, gyro_z: bool, accel_xy: bool, learning_frozen: bool
) -> Convergence:
    """The Convergence of these flags (one of sixteen, not a new object 50 times a second)."""
    return _CONVERGENCE[gyro_xy, gyro_z, accel_xy, learning_frozen]


@dataclass(slots=True)
class Solution:
    """Corrected attitude and reference-point navigation at time ``t`` (host clock, s).

    A quantity the engine does not know yet is None (sent as "not available", never as a
    made-up zero). Position and velocity are of the vehicle reference point, not the antenna.

    A value: never changed once built, a changed copy is ``dataclasses.replace``. Not
    ``frozen`` only for speed: one is built 50 times a second, and a frozen dataclass's
    ``__init__`` (``object.__setattr__`` per field) costs four times as much.
    """

    t: float
    mode: Mode
    roll_rad: float | None = None
    pitch_rad: float | None = None
    yaw_rad: float | None = None  # true heading, [0, 2 pi)
    yaw_rate_rps: float | None = None  # bias-corrected rate of turn, clockwise positive
    lat_deg: float | None = None
    lon_deg: float | None = None
    alt_m: float | None = None  # ellipsoidal height; of unknown datum without geoid_sep_m
    vel_ned_mps: tuple[float, float, float] | None = None
    bias_g_rps: Float3 | None = None  # gyro bias estimate, body FRD
    bias_a_mps2: Float3 | None = None  # accelerometer bias estimate, body FRD
    sigma_tilt_rad: float | None = None  # roll/pitch 1-sigma
    fix_quality: FixQuality | None = None  # of the last GNSS fix used
    num_sats: int | None = None
    hdop: float | None = None
    age_s: float | None = None
    geoid_sep_m: float | None = None  # at the antenna, metres away: the reference point's too
    reference_station_id: int | None = None  # as the receiver sent it
    talker: str | None = None  # GGA talker id: the satellite systems of the fix
    gnss_ok: bool = False
    imu_ok: bool = False
    imu_alarm: bool = False
    reversing: bool = False
    stationary: bool = False
    coasting: bool = False  # GNSS timed out: a position sent is dead reckoning
    is_ekf: bool = False
    convergence: Convergence = Convergence()

    @property
    def cog_sog(self) -> tuple[float, float] | None:
        """Reference-point course over ground (rad, true, [0, 2 pi)) and speed (m/s)."""
        if self.vel_ned_mps is None:
            return None
        vn, ve, _ = self.vel_ned_mps
        return math.atan2(ve, vn) % (2.0 * math.pi), math.hypot(vn, ve)


#: A share of the reference point's horizontal 1-sigma, m, beyond the fix's own (an RTK
#: fix's 1-2 cm), that NAVIGATING allows: the tilt's over the antenna lever arm (1 deg on a
#: 3 m mast), the epoch time's over the speed (a free-running host's). 5 cm leaves 3 sigma
#: within 15 cm.
NAVIGATING_POSITION_SHARE_M = 0.05
#: An IMU sample stands for at most this long (the samples lost before it included) without
#: making the solution DEGRADED: 10 samples at 204.8 Hz.
MAX_IMU_STEP_S = 0.05
#: DEGRADED this long after a longer gap: the rotation over the gap was guessed from the
#: rates at its end, and the tilt loop (tau 4 s) needs about this long to remove the error.
IMU_GAP_DEGRADED_S = 5.0
#: The samples before a gap whose spread tells what bridging it may have missed: 1 s at
#: 204.8 Hz (the rocking of a vehicle on rough ground, 0.3-1 Hz, and the sensor noise).
GAP_SPREAD_SAMPLES = 205
#: A step longer than this many sample periods bridged lost samples (the sample clock is
#: exact: a lost sample makes a step of two periods).
BRIDGED_STEP = 1.5


@dataclass(frozen=True, slots=True)
class GapSigma:
    """What bridging a gap in the IMU stream may have put in the solution, 1-sigma per body
    axis: the rotation, rad, and the velocity, m/s."""

    rotation_rad: Float3
    velocity_mps: Float3


@dataclass
class ImuTiming:
    """The time each IMU sample closes, and the gaps in the stream (both engines)."""

    t_s: float | None = None  # time of the last sample that moved time on
    gaps: int = 0  # steps longer than MAX_IMU_STEP_S
    degraded_until_s: float = -math.inf
    recent: deque[ImuSample] = field(default_factory=lambda: deque(maxlen=GAP_SPREAD_SAMPLES))
    lost_s: float = 0.0  # the span of lost samples the last step bridged (0: none lost)

    def step(self, sample: ImuSample) -> float:
        """Seconds ``sample`` closes: the time since the previous sample, so the samples lost
        between are bridged with this sample's rate and specific force (integrating only the
        nominal period never applied their rotation: 9 deg of yaw with 5 % of the frames
        lost); the nominal period for the first one. Not positive if time went back."""
        self.recent.append(sample)
        if self.t_s is None:
            self.t_s = sample.t
            return sample.dt
        dt = sample.t - self.t_s
        if dt > 0.0:
            self.t_s = sample.t
        self.lost_s = dt - sample.dt if dt > BRIDGED_STEP * sample.dt else 0.0
        if dt > MAX_IMU_STEP_S:
            self.gaps += 1
            self.degraded_until_s = sample.t + IMU_GAP_DEGRADED_S
        return dt

    def bridged(self) -> GapSigma:
        """What the last step may have missed over the :attr:`lost_s` it bridged."""
        return bridged_sigma(self.recent, self.lost_s)

    def degraded(self) -> bool:
        """A gap in the IMU stream ended less than IMU_GAP_DEGRADED_S ago."""
        return self.t_s is not None and self.t_s < self.degraded_until_s


def bridged_sigma(samples: Sequence[ImuSample], bridged_s: float) -> GapSigma:
    """The error of holding one sample's rate and specific force over ``bridged_s`` of lost
    samples, from how ``samples`` (those before the loss and the one that bridges it) move.

    Over the lost span the true value went its own way from the one held, by about what the
    stream moves in half that span: the root-mean-square difference of samples that far
    apart (sqrt(2) sigma for white noise and vibration; less for the vehicle's rocking over
    a short span, as much over a long one), integrated over the span. Taken as white noise
    of the span's length instead, a 0.5 s gap left the tilt 0.4 deg off with 0.1 deg stated
    5 s after it; and half the samples lost, eight at a time (no gap, steps of 44 ms),
    0.4-0.6 deg with 0.1-0.16 stated.
    """
    n = len(samples)
    if n < 2:
        return GapSigma((0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    lag = min(n - 1, max(1, round(0.5 * bridged_s / samples[-1].dt)))

    def moved(axis: int, rate: bool) -> float:
        v = [(s.w_ib_b if rate else s.f_ib_b)[axis] for s in samples]
        return bridged_s * math.sqrt(
            sum((v[i + lag] - v[i]) ** 2 for i in range(n - lag)) / (n - lag)
        )

    return GapSigma(
        (moved(0, True), moved(1, True), moved(2, True)),
        (moved(0, False), moved(1, False), moved(2, False)),
    )


def navigation_mode(
    *,
    fault: bool,
    aligned: bool,
    coasting: bool,
    imu_alarm: bool,
    coast_within_accuracy: bool = True,
    fix: GnssFix | None,
    navigating_fix_qualities: tuple[int, ...],
    imu_gap: bool = False,
    gnss_glitch: bool = False,
    heading_within_accuracy: bool = True,
    position_within_accuracy: bool = True,
) -> Mode:
    """The mode every engine reports, in order of precedence: FAULT (IMU data unusable),
    ALIGNING (no attitude/heading yet), COASTING (GNSS velocity timed out, the dead-reckoned
    position still ``coast_within_accuracy`` and the heading ``heading_within_accuracy``;
    DEGRADED beyond), DEGRADED (IMU alarm, a recent gap in the IMU stream, GNSS positions
    rejected as glitches, the heading's 1-sigma beyond NAVIGATING's, a share of the
    reference point's beyond :data:`NAVIGATING_POSITION_SHARE_M` (not
    ``position_within_accuracy``), or a fix quality outside ``navigating_fix_qualities``),
    else NAVIGATING."""
    if fault:
        return Mode.FAULT
    if not aligned:
        return Mode.ALIGNING
    if coasting:
        within = coast_within_accuracy and heading_within_accuracy
        return Mode.COASTING if within else Mode.DEGRADED
    if imu_alarm or imu_gap or gnss_glitch or not heading_within_accuracy:
        return Mode.DEGRADED
    if not position_within_accuracy:
        return Mode.DEGRADED
    if fix is None or int(fix.quality) not in navigating_fix_qualities:
        return Mode.DEGRADED
    return Mode.NAVIGATING


@dataclass(frozen=True, slots=True)
class LearnedState:
    """What an engine has learned of its IMU, to start another engine from (a warm start, or
    a restart after an IMU gap): the bias estimates, body FRD, and their 1-sigma per axis.

    Each sigma is the honest 1-sigma of the estimate as it stands (an engine seeded with it
    reports it back until it has learned better), never a hope. The engines take it as it
    is: growing a stored state by its age and the temperature change is the caller's job
    (:mod:`gateway.state`).
    """

    bias_g_rps: Float3  # gyro bias, rad/s
    sigma_g_rps: Float3
    bias_a_mps2: Float3  # accelerometer bias, m/s^2
    sigma_a_mps2: Float3

    def is_valid(self) -> bool:
        """Every number finite and every sigma positive (what an engine may be seeded with)."""
        values = (*self.bias_g_rps, *self.sigma_g_rps, *self.bias_a_mps2, *self.sigma_a_mps2)
        sigmas = (*self.sigma_g_rps, *self.sigma_a_mps2)
        return all(math.isfinite(v) for v in values) and all(s > 0.0 for s in sigmas)


class Estimator(Protocol):
    """What the fusion loop needs from an engine: feed samples, read the solution."""

    def imu(self, sample: ImuSample) -> None:
        """Propagate with one IMU sample (samples arrive in time order)."""

    def gnss(self, fix: GnssFix) -> None:
        """Correct with one GNSS epoch (may arrive after IMU samples of later time)."""

    def temperature(self, t_s: float, temp_c: float) -> None:
        """The IMU's temperature at ``t_s`` (IMU_AUX, in time order with the samples): its
        rate adds to the bias walks (:mod:`gateway.estimation.temperature`)."""

    def solution(self) -> Solution:
        """The current solution, at the time of the last IMU sample."""


class LearningEstimator(Estimator, Protocol):
    """An estimator that learns its IMU's biases and can start from what it learned before
    (both engines; the comparison baselines of the demo need not)."""

    def seed(self, learned: LearnedState, f_rest_b_mps2: Float3 | None = None) -> bool:
        """Start from ``learned`` (biases and their 1-sigma) instead of the turn-on guess;
        False (nothing changed) if the engine has already begun to learn on its own, or
        ``learned`` is not valid. Without a seed the engine behaves exactly as before.
        ``f_rest_b_mps2``: the mean specific force (body, bias included) over the rest the
        vehicle is standing in now, if any: the level with the seeded accelerometer bias."""

    def learned_state(self) -> LearnedState | None:
        """The biases learned so far with their honest 1-sigma; None before the engine has
        any (not yet levelled and not seeded)."""

    def moving_before(self) -> None:
        """The engine takes over from one that saw the vehicle moving (a restart after an
        IMU gap): without GNSS velocity (an outage) its levelling window is of unknown
        motion, not a parked vehicle's."""

    def heading_before(self, hint: HeadingHint) -> None:
        """The engine takes over from one that knew the heading (a restart after an IMU gap):
        ``hint`` decides forward or reversing at its first course over ground."""
