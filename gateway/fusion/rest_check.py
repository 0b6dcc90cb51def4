"""Is a warm start's seed still the IMU's? The mean specific force and rate at the last stop
against the same means at the next start, on the same spot.

A vehicle stands still where it was parked when the gateway starts again. If it has not
moved, nothing has tilted it, and the IMU's biases carried over the restart, the IMU measures
at the start what it measured at the stop: the specific force of gravity in the same body
axes plus the same biases. A difference is a change of the biases (a MEMS IMU's turn-on bias
differs from one power-on to the next by an amount the ADIS16334 datasheet does not give) or
of the attitude (a tank filled while parked): either way the stored biases would tilt roll
and pitch by the difference over g while the engine stated their learned accuracy. So the
learned state is used only when both means agree within the seed's sigmas and their own
noise; its accelerometer sigmas grow by the difference found.

:class:`RestMean` follows the stretch at rest (GNSS speed below :data:`STILL_SPEED_MPS` or
its noise, the body rate below :data:`QUIET_RATE_RPS`) sample by sample;
:meth:`RestMean.record` gives it as a :class:`RestRecord` once it is :data:`MIN_REST_S`
long, which the state store keeps (:mod:`gateway.state`); :func:`check_seed` compares two of
them; :func:`drove_off` says when waiting for a rest at the start is over.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

from drivers.samples import Float3, GnssFix, ImuSample
from drivers.units import DEG_TO_RAD, MG_MPS2
from gateway.estimation.geodesy import LocalFrame
from gateway.estimation.gnss_error import fix_position_sigma_m, fix_velocity_sigma_mps
from gateway.estimation.solution import LearnedState

#: A rest this long (after SETTLE_S) gives the means (with 0.2 m/s^2 of engine vibration per
#: sample, the specific force's mean is good to 0.8 mg after 3 s at 204.8 Hz).
MIN_REST_S = 3.0
#: Standing: GNSS speed below this (m/s), or below SPEED_SIGMAS of the fix quality's speed
#: noise (single point: 0.1 m/s a axis) ...
STILL_SPEED_MPS = 0.1
SPEED_SIGMAS = 4.0
#: ... and the body rate, low-passed over RATE_LP_S, below this (rad/s): not turning, not
#: rocking. (Single samples at rest exceed it now and then: the ADIS16334's rate noise is
#: ~0.6 deg/s a sample at 204.8 Hz.)
QUIET_RATE_RPS = 2.0 * DEG_TO_RAD
RATE_LP_S = 0.1
#: Driving off: GNSS speed above this (m/s) and above DRIVING_SIGMAS of its noise.
DRIVING_SPEED_MPS = 0.5
DRIVING_SIGMAS = 6.0
#: The first second of a stretch is left out of its means: GNSS speed falls below
#: STILL_SPEED_MPS while the last of the braking goes on, and a vehicle rocks on its
#: suspension after it stops.
SETTLE_S = 1.0
#: The antenna within this of where it stood (m), beyond three sigma of the two positions:
#: a parked vehicle has not moved.
SAME_SPOT_M = 0.5
#: A mean that differs by more than this many sigma (the seed's, and the two means' own
#: noise) says the biases or the attitude changed.
CHECK_SIGMAS = 3.0


@dataclass(frozen=True)
class RestRecord:
    """A stretch at rest: where the antenna stood (deg, with its horizontal 1-sigma, m), the
    mean specific force (m/s^2) and rate (rad/s) in body axes, biases included, with the
    1-sigma of each mean from the samples' own spread, its end time (host clock, s) and
    length (s)."""

    t_s: float
    lat_deg: float
    lon_deg: float
    sigma_m: float
    f_b_mps2: Float3
    w_b_rps: Float3
    sigma_f_mps2: Float3
    sigma_w_rps: Float3
    duration_s: float


@dataclass(frozen=True)
class WarmSeed:
    """A learned state to start from and the rest it must be checked against (None: the
    store has none, and the seed cannot be checked)."""

    learned: LearnedState
    rest: RestRecord | None


class RestMean:
    """The current stretch at rest, and the last one of at least :data:`MIN_REST_S`."""

    def __init__(self) -> None:
        self.last: RestRecord | None = None  # the last stretch long enough, ended
        self._fix: GnssFix | None = None  # the last fix, while it says the vehicle stands
        self._sigma_m = 0.0  # its horizontal 1-sigma
        self._w_lp = [0.0, 0.0, 0.0]  # body rate low-passed over RATE_LP_S, while standing
        self._restart()

    def _restart(self) -> None:
        self._t_still_s: float | None = None  # when the stretch began (its means later)
        self._n = 0
        self._t0_s = self._t1_s = 0.0
        self._sum = [0.0] * 6  # f (3), w (3)
        self._sum_sq = [0.0] * 6

    def gnss(self, fix: GnssFix) -> None:
        """A fix: standing (a position, speed below :data:`STILL_SPEED_MPS`) or not."""
        sigma = fix_position_sigma_m(fix)
        standing = (
            fix.measures
            and fix.lat_deg is not None
            and fix.lon_deg is not None
            and sigma is not None
            and fix.sog_mps is not None
            and fix.sog_mps < max(STILL_SPEED_MPS, SPEED_SIGMAS * fix_velocity_sigma_mps(fix, 0.0))
        )
        if standing:
            assert sigma is not None
            self._fix, self._sigma_m = fix, math.hypot(sigma[0], sigma[1])
        else:
            self._end()
            self._fix = None
            self._w_lp = [0.0, 0.0, 0.0]

    def imu(self, sample: ImuSample) -> None:
        """A sample: part of the stretch at rest if quiet while a fix says standing."""
        if self._fix is None:
            return
        w, f = sample.w_ib_b, sample.f_ib_b
        lp, a = self._w_lp, sample.dt / (RATE_LP_S + sample.dt)
        for i in range(3):
            lp[i] += a * (w[i] - lp[i])
        if lp[0] * lp[0] + lp[1] * lp[1] + lp[2] * lp[2] >= QUIET_RATE_RPS * QUIET_RATE_RPS:
            self._end()
            return
        if self._t_still_s is None:
            self._t_still_s = sample.t
        if sample.t - self._t_still_s < SETTLE_S:
            return
        if self._n == 0:
            self._t0_s = sample.t
        self._t1_s = sample.t
        self._n += 1
        s, q = self._sum, self._sum_sq
        for i, x in enumerate((*f, *w)):
            s[i] += x
            q[i] += x * x

    def _end(self) -> None:
        """The stretch is over: kept as :attr:`last` if long enough."""
        current = self.current()
        if current is not None:
            self.last = current
        self._restart()

    def current(self) -> RestRecord | None:
        """The stretch going on, once it is :data:`MIN_REST_S` long, else None."""
        fix, n = self._fix, self._n
        if fix is None or n < 2 or self._t1_s - self._t0_s < MIN_REST_S:
            return None
        assert fix.lat_deg is not None and fix.lon_deg is not None
        mean = [x / n for x in self._sum]
        sd = [
            math.sqrt(max(0.0, q / n - m * m) / (n - 1))
            for q, m in zip(self._sum_sq, mean, strict=True)
        ]
        return RestRecord(
            t_s=self._t1_s,
            lat_deg=fix.lat_deg,
            lon_deg=fix.lon_deg,
            sigma_m=self._sigma_m,
            f_b_mps2=(mean[0], mean[1], mean[2]),
            w_b_rps=(mean[3], mean[4], mean[5]),
            sigma_f_mps2=(sd[0], sd[1], sd[2]),
            sigma_w_rps=(sd[3], sd[4], sd[5]),
            duration_s=self._t1_s - self._t0_s,
        )

    def record(self) -> RestRecord | None:
        """The stretch going on if long enough, else the last one that was."""
        return self.current() or self.last


def drove_off(fix: GnssFix) -> bool:
    """The fix says the vehicle is driving (not a standing receiver's speed noise)."""
    noise = DRIVING_SIGMAS * fix_velocity_sigma_mps(fix, 0.0)
    return fix.measures and fix.sog_mps is not None and fix.sog_mps >= max(DRIVING_SPEED_MPS, noise)


def check_seed(
    learned: LearnedState, then: RestRecord, now: RestRecord
) -> tuple[LearnedState | None, str]:
    """The seed to start from, or None, and why: ``now`` (the rest at this start) against
    ``then`` (the rest stored with ``learned``). Accepted, the accelerometer sigmas grow by
    the difference of the means (what is left of it is the seed's error, or a tilt)."""
    d_n, d_e, _ = LocalFrame((then.lat_deg, then.lon_deg, 0.0)).to_ned(
        now.lat_deg, now.lon_deg, 0.0
    )
    moved_m = math.hypot(d_n, d_e)
    if not moved_m <= SAME_SPOT_M + CHECK_SIGMAS * math.hypot(then.sigma_m, now.sigma_m):
        return None, (
            f"the vehicle stands {moved_m:.2f} m from where it stopped (within "
            f"{SAME_SPOT_M:g} m and the fixes' sigmas expected): the biases cannot be checked"
        )
    df = [a - b for a, b in zip(now.f_b_mps2, then.f_b_mps2, strict=True)]
    dw = [a - b for a, b in zip(now.w_b_rps, then.w_b_rps, strict=True)]
    off = [
        f"accel {axis} {d / MG_MPS2:+.2f} mg"
        for axis, d, s, s1, s2 in zip(
            "xyz", df, learned.sigma_a_mps2, now.sigma_f_mps2, then.sigma_f_mps2, strict=True
        )
        if abs(d) > CHECK_SIGMAS * math.sqrt(s * s + s1 * s1 + s2 * s2)
    ]
    off += [
        f"gyro {axis} {d / DEG_TO_RAD:+.4f} deg/s"
        for axis, d, s, s1, s2 in zip(
            "xyz", dw, learned.sigma_g_rps, now.sigma_w_rps, then.sigma_w_rps, strict=True
        )
        if abs(d) > CHECK_SIGMAS * math.sqrt(s * s + s1 * s1 + s2 * s2)
    ]
    if off:
        return None, (
            f"at rest on the same spot the IMU measures {', '.join(off)} off what it measured "
            f"at the last stop, beyond {CHECK_SIGMAS:g} sigma of the learned biases: its "
            "biases changed (a new power-on) or the vehicle's attitude did (a load)"
        )
    sa = learned.sigma_a_mps2
    grown = (math.hypot(sa[0], df[0]), math.hypot(sa[1], df[1]), math.hypot(sa[2], df[2]))
    return replace(learned, sigma_a_mps2=grown), (
        f"checked at rest on the same spot ({moved_m:.2f} m from the last stop): the IMU "
        f"measures what it did there within {max(abs(d) for d in df) / MG_MPS2:.2f} mg"
    )
