"""A tiny exact test-motion generator for the estimator unit tests.

The reference point moves on the level plane through segments of constant longitudinal
acceleration and constant yaw rate (straight, circles, stops, reversing: speed may be negative)
with a constant roll and pitch (but a roll rocking or the chassis's pitch stepping, whose
angular acceleration the IMU's lever arm is not given: keep the IMU at the reference point
there); position, velocity and acceleration are closed-form, so IMU and GNSS streams are exact
to floating point. IMU values of the sample closing [t - dt, t] are
evaluated at the interval midpoint (second-order accurate, like an averaging IMU); GNSS epochs
are exact at their epoch time and arrive ``latency_s`` later on the host clock.

    motion = Motion([Segment(60.0), Segment(60.0, yaw_rate_rps=0.3)], v0_mps=3.0)
    imu = imu_stream(motion, bias_g_rps=(0.01, 0, 0))
    fixes = gnss_stream(motion, antenna_lever_arm_m=(0, 0, -3))
    run(engine, imu, fixes)
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, replace

import numpy as np
import numpy.typing as npt

from drivers.samples import FixQuality, GnssFix, ImuSample
from drivers.units import DEG_TO_RAD, GRAVITY_MPS2, SQRT_SECONDS_PER_HOUR
from gateway.estimation.geodesy import ned_to_lla
from gateway.estimation.solution import Estimator, Solution

Array = npt.NDArray[np.float64]
ORIGIN_LLA = np.array([52.2, 10.5, 80.0])
IMU_DT_S = 4.0 / 819.2
#: The ADIS16334 datasheet's gyro angular random walk (2 deg/sqrt(h)) as white noise per
#: sample, rad/s: ``imu_stream``'s ``noise_g_rps`` for a unit as its datasheet says.
GYRO_ARW_PER_SAMPLE_RPS = 2.0 * DEG_TO_RAD / SQRT_SECONDS_PER_HOUR / math.sqrt(IMU_DT_S)
T0_S = 1_700_000_000.0  # host clock (UTC seconds) at motion time 0


@dataclass(frozen=True)
class Segment:
    """``duration_s`` of constant longitudinal acceleration and yaw rate."""

    duration_s: float
    accel_mps2: float = 0.0
    yaw_rate_rps: float = 0.0


@dataclass(frozen=True)
class ChassisStep:
    """The chassis pitching by ``d_rad`` on its tyres against its track (an implement lifted
    or lowered), a raised-cosine ramp of ``ramp_s`` from motion time ``t_s``."""

    t_s: float
    d_rad: float
    ramp_s: float = 2.0


@dataclass(frozen=True)
class Motion:
    """Segments driven from speed ``v0_mps`` and heading ``yaw0_rad`` at constant roll/pitch.

    Speeds and accelerations are horizontal; the vehicle moves along its body x axis, as a
    wheeled one does, so with pitch it climbs (or descends) tan(pitch - chassis pitch) per
    metre (the chassis's own pitch against its track: a load, a lifted implement). Roll may
    rock about the reference point: roll + rock sin(2 pi rock_hz (t - rock_from_s)) from
    rock_from_s on. ``chassis_steps`` pitch
    the body and the chassis together about the reference point, the track unchanged."""

    segments: Sequence[Segment]
    v0_mps: float = 0.0
    yaw0_rad: float = 0.0
    roll_rad: float = 0.0
    pitch_rad: float = 0.0
    rock_rad: float = 0.0  # amplitude of a roll rocking about the reference point (rough ground)
    rock_hz: float = 0.0
    rock_from_s: float = 0.0  # the rocking starts here (rough ground begins; parked, none)
    chassis_pitch_rad: float = 0.0
    chassis_steps: Sequence[ChassisStep] = ()

    @property
    def duration_s(self) -> float:
        return float(sum(s.duration_s for s in self.segments))


@dataclass(frozen=True)
class State:
    """True state at times t (n,): reference point NED, attitude, body rates."""

    p_ned_m: Array  # (n, 3)
    v_ned_mps: Array  # (n, 3)
    a_ned_mps2: Array  # (n, 3)
    yaw_rad: Array  # (n,)
    c_bn: Array  # (n, 3, 3)
    w_b_rps: Array  # (n, 3)


def _int_v_cos_sin(v0: Array, a: Array, psi0: Array, w: Array, tau: Array) -> tuple[Array, Array]:
    """Exact integrals over [0, tau] of (v0 + a s) cos(psi0 + w s) and ... sin(...)."""
    small = np.abs(w) < 1e-12
    ws = np.where(small, 1.0, w)
    psi = psi0 + w * tau
    v = v0 + a * tau
    n_turn = (v * np.sin(psi) - v0 * np.sin(psi0)) / ws + a * (np.cos(psi) - np.cos(psi0)) / ws**2
    e_turn = -(v * np.cos(psi) - v0 * np.cos(psi0)) / ws + a * (np.sin(psi) - np.sin(psi0)) / ws**2
    dist = v0 * tau + 0.5 * a * tau**2
    return (
        np.where(small, dist * np.cos(psi0), n_turn),
        np.where(small, dist * np.sin(psi0), e_turn),
    )


def state_at(motion: Motion, t: npt.ArrayLike) -> State:
    """Exact state at motion times ``t`` (s from the start; clamped to the motion)."""
    tt = np.clip(np.atleast_1d(np.asarray(t, dtype=float)), 0.0, motion.duration_s)
    seg = motion.segments
    starts = np.concatenate(([0.0], np.cumsum([s.duration_s for s in seg])))
    acc = np.array([s.accel_mps2 for s in seg])
    rate = np.array([s.yaw_rate_rps for s in seg])
    v0 = np.zeros(len(seg))
    psi0 = np.zeros(len(seg))
    p0 = np.zeros((len(seg), 2))
    d0 = np.zeros(len(seg))  # distance driven (horizontal, signed) at each segment's start
    v, psi, p, d = motion.v0_mps, motion.yaw0_rad, np.zeros(2), 0.0
    for k, s in enumerate(seg):
        v0[k], psi0[k], p0[k], d0[k] = v, psi, p, d
        d += v * s.duration_s + 0.5 * s.accel_mps2 * s.duration_s**2
        dn, de = _int_v_cos_sin(
            np.array(v),
            np.array(s.accel_mps2),
            np.array(psi),
            np.array(s.yaw_rate_rps),
            np.array(s.duration_s),
        )
        p = p + [float(dn), float(de)]
        v += s.accel_mps2 * s.duration_s
        psi += s.yaw_rate_rps * s.duration_s
    i = np.clip(np.searchsorted(starts, tt, side="right") - 1, 0, len(seg) - 1)
    tau = tt - starts[i]
    dn, de = _int_v_cos_sin(v0[i], acc[i], psi0[i], rate[i], tau)
    vel = v0[i] + acc[i] * tau
    yaw = psi0[i] + rate[i] * tau
    cy, sy = np.cos(yaw), np.sin(yaw)
    r, th = motion.roll_rad, motion.pitch_rad
    down = -math.tan(th - motion.chassis_pitch_rad)  # down per metre driven
    dist = d0[i] + v0[i] * tau + 0.5 * acc[i] * tau**2
    n = len(tt)
    p_ned = np.stack((p0[i, 0] + dn, p0[i, 1] + de, down * dist), axis=1)
    v_ned = np.stack((vel * cy, vel * sy, down * vel), axis=1)
    a_ned = np.stack(
        (acc[i] * cy - vel * rate[i] * sy, acc[i] * sy + vel * rate[i] * cy, down * acc[i]),
        axis=1,
    )
    w_rock = 2.0 * math.pi * motion.rock_hz
    rocking = motion.rock_rad * (tt >= motion.rock_from_s)
    roll = r + rocking * np.sin(w_rock * (tt - motion.rock_from_s))
    pitch, pitch_rate = np.full(n, th), np.zeros(n)
    for step in motion.chassis_steps:
        u = np.clip((tt - step.t_s) / step.ramp_s, 0.0, 1.0)
        pitch += 0.5 * step.d_rad * (1.0 - np.cos(math.pi * u))
        ramping = (u > 0.0) & (u < 1.0)
        pitch_rate += ramping * 0.5 * step.d_rad * math.pi / step.ramp_s * np.sin(math.pi * u)
    sr, cr, sp, cp = np.sin(roll), np.cos(roll), np.sin(pitch), np.cos(pitch)
    c_bn = np.empty((n, 3, 3))
    c_bn[:, 0] = np.stack((cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr), axis=1)
    c_bn[:, 1] = np.stack((sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr), axis=1)
    c_bn[:, 2] = np.stack((-sp, cp * sr, cp * cr), axis=1)
    # Euler kinematics: w_b = (roll rate - yaw rate sin(pitch), pitch rate cos(roll) + ...)
    w_b = rate[i][:, None] * np.stack((-sp, sr * cp, cr * cp), axis=1)
    w_b[:, 0] += rocking * w_rock * np.cos(w_rock * (tt - motion.rock_from_s))
    w_b[:, 1] += pitch_rate * cr
    w_b[:, 2] -= pitch_rate * sr
    return State(p_ned, v_ned, a_ned, yaw % (2 * math.pi), c_bn, w_b)


def imu_stream(
    motion: Motion,
    imu_lever_arm_m: npt.ArrayLike = (0.0, 0.0, 0.0),
    bias_g_rps: npt.ArrayLike = (0.0, 0.0, 0.0),
    bias_a_mps2: npt.ArrayLike = (0.0, 0.0, 0.0),
    noise_g_rps: float = 0.0,
    noise_a_mps2: float = 0.0,
    seed: int = 0,
    dt_s: float = IMU_DT_S,
) -> list[ImuSample]:
    """IMU samples over the motion, body FRD, with constant biases and white noise; the
    IMU at ``imu_lever_arm_m`` from the reference point feels its centripetal and tangential
    acceleration (the latter as the mean over the sample: the rate's change over it)."""
    n = int(motion.duration_s / dt_s)
    t = (np.arange(n) + 1) * dt_s
    st = state_at(motion, t - 0.5 * dt_s)
    l_imu = np.asarray(imu_lever_arm_m, dtype=float)
    g = np.array([0.0, 0.0, GRAVITY_MPS2])
    f_n = st.a_ned_mps2 - g
    f_b = np.einsum("nji,nj->ni", st.c_bn, f_n)
    f_b += np.cross(st.w_b_rps, np.cross(st.w_b_rps, l_imu))
    if l_imu.any():
        w_dot = (state_at(motion, t).w_b_rps - state_at(motion, t - dt_s).w_b_rps) / dt_s
        f_b += np.cross(w_dot, l_imu)
    rng = np.random.default_rng(seed)
    w_b = st.w_b_rps + np.asarray(bias_g_rps) + noise_g_rps * rng.standard_normal((n, 3))
    f_b = f_b + np.asarray(bias_a_mps2) + noise_a_mps2 * rng.standard_normal((n, 3))
    return [
        ImuSample(
            t=T0_S + t_k, dt=dt_s, w_ib_b=(w[0], w[1], w[2]), f_ib_b=(f[0], f[1], f[2]), seq=k % 256
        )
        for k, (t_k, w, f) in enumerate(zip(t.tolist(), w_b.tolist(), f_b.tolist(), strict=True))
    ]


def gnss_stream(
    motion: Motion,
    antenna_lever_arm_m: npt.ArrayLike = (0.0, 0.0, 0.0),
    rate_hz: float = 10.0,
    latency_s: float = 0.0,
    vel_noise_mps: float = 0.0,
    hdt: bool = False,
    quality: FixQuality = FixQuality.RTK_FIXED,
    seed: int = 1,
) -> list[GnssFix]:
    """GNSS epochs of the antenna: position (LLA), SOG/COG, optional HDT, exact + noise."""
    n = int(motion.duration_s * rate_hz)
    t = np.arange(1, n + 1) / rate_hz
    st = state_at(motion, t)
    l_ant = np.asarray(antenna_lever_arm_m, dtype=float)
    p_ant = st.p_ned_m + np.einsum("nij,j->ni", st.c_bn, l_ant)
    v_ant = st.v_ned_mps + np.einsum("nij,nj->ni", st.c_bn, np.cross(st.w_b_rps, l_ant))
    v_ant[:, :2] += vel_noise_mps * np.random.default_rng(seed).standard_normal((n, 2))
    lla = ned_to_lla(p_ant, ORIGIN_LLA)
    fixes = []
    for k in range(n):
        vn, ve = float(v_ant[k, 0]), float(v_ant[k, 1])
        fixes.append(
            GnssFix(
                t=T0_S + float(t[k]) + latency_s,
                t_utc=T0_S + float(t[k]),
                quality=quality,
                lat_deg=float(lla[k, 0]),
                lon_deg=float(lla[k, 1]),
                alt_m=float(lla[k, 2]),
                geoid_sep_m=47.0,  # as a receiver with a geoid model sends it
                num_sats=20,
                hdop=0.7,
                sog_mps=math.hypot(vn, ve),
                cog_rad=math.atan2(ve, vn) % (2 * math.pi),
                heading_rad=float(st.yaw_rad[k]) if hdt else None,
            )
        )
    return fixes


def with_gyro_offset(
    samples: list[ImuSample], t0_s: float, t1_s: float, dw_b_rps: tuple[float, float, float]
) -> list[ImuSample]:
    """Fault or bias step: add ``dw_b_rps`` (body) to the gyro of samples with motion time
    in [t0, t1)."""
    dx, dy, dz = dw_b_rps
    return [
        replace(s, w_ib_b=(s.w_ib_b[0] + dx, s.w_ib_b[1] + dy, s.w_ib_b[2] + dz))
        if t0_s <= s.t - T0_S < t1_s
        else s
        for s in samples
    ]


def with_velocity_offset(
    fixes: list[GnssFix], t0_s: float, t1_s: float, dv_ne_mps: tuple[float, float]
) -> list[GnssFix]:
    """Glitch: add ``dv_ne_mps`` to the velocity of epochs with motion time in [t0, t1)."""
    out = []
    for f in fixes:
        ve = f.vel_ne_mps
        if ve is not None and f.t_utc is not None and t0_s <= f.t_utc - T0_S < t1_s:
            vn, vel_e = ve[0] + dv_ne_mps[0], ve[1] + dv_ne_mps[1]
            f = replace(
                f, sog_mps=math.hypot(vn, vel_e), cog_rad=math.atan2(vel_e, vn) % (2 * math.pi)
            )
        out.append(f)
    return out


def with_course_held(fixes: list[GnssFix], below_mps: float, blank: bool = False) -> list[GnssFix]:
    """A receiver that holds its last course over ground while SOG is under ``below_mps``
    (none before the first course above it), or with ``blank`` gives none there, as
    receivers do at low speed."""
    out, held = [], None
    for f in fixes:
        if f.sog_mps is not None and f.sog_mps >= below_mps:
            held = f.cog_rad
        else:
            f = replace(f, cog_rad=None if blank else held)
        out.append(f)
    return out


def run(
    engine: Estimator,
    imu: list[ImuSample],
    fixes: list[GnssFix],
    every: int = 0,
    on_sample: Callable[[ImuSample], None] | None = None,
) -> None:
    """Feed both streams in host-time order (:func:`fed`).

    ``on_sample`` is called after every ``every``-th IMU sample (if ``every`` > 0).
    """
    for k, s in fed(engine, imu, fixes):
        if on_sample is not None and every > 0 and k % every == 0:
            on_sample(s)


def solutions(
    engine: Estimator, imu: list[ImuSample], fixes: list[GnssFix], every: int = 41
) -> list[tuple[float, Solution]]:
    """:func:`run`, keeping the engine's solution with its motion time after every
    ``every``-th IMU sample."""
    out: list[tuple[float, Solution]] = []
    for k, s in fed(engine, imu, fixes):
        if k % every == 0:
            out.append((motion_time(s.t), engine.solution()))
    return out


def fed(
    engine: Estimator, imu: list[ImuSample], fixes: list[GnssFix]
) -> Iterator[tuple[int, ImuSample]]:
    """Both streams into ``engine`` in host-time order (a fix after the IMU samples stamped
    before it); yields each IMU sample, with its index, once the engine has taken it."""
    j = 0
    for k, s in enumerate(imu):
        while j < len(fixes) and fixes[j].t <= s.t:
            engine.gnss(fixes[j])
            j += 1
        engine.imu(s)
        yield k, s


def motion_time(sample_t: float) -> float:
    """Host time of a sample -> motion time (s from the start)."""
    return sample_t - T0_S
