"""Accuracy of an engine against simulator truth: recording a solution trace and its metrics.

One place for every number the accuracy benchmark, the plots and the tests report, so that
they cannot disagree. :func:`record` feeds any :class:`gateway.estimation.solution.Estimator` from
an
input stream (normally :class:`gateway.offline.log_inputs.LogInputs`, the path replay and live use
take) and keeps the solution at a fixed decimation; the rest are pure functions from a
:class:`Trace` and a :class:`sim_bus.truth.Truth` (or plain arrays) to numbers.

Errors are estimate minus truth. Angles are wrapped to [-pi, pi). The reference-point error
"from attitude" is the horizontal part of (C_true - C_est) l_ant: the error terrain
compensation makes for a perfect antenna position, which isolates it from GNSS noise.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from drivers.samples import GnssFix, ImuAux, ImuSample
from drivers.units import wrap_pi
from gateway.estimation.attitude import dcm_from_rpy_array
from gateway.estimation.geodesy import lla_to_ned
from gateway.estimation.solution import Estimator, Solution
from gateway.fusion.fusion_core import BusFrame, FusionCore
from sim_bus.truth import Truth

Array = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]

#: On runs without a convergence flag (or where it never rises), metrics start here, s.
DEFAULT_CONVERGED_AFTER_S = 600.0
#: After a degraded span (float, DGNSS, single point, outage) this long counts as recovery.
RECOVERY_S = 30.0
#: Cold start: roll/pitch are judged from this long after the run start ...
COLD_START_JUDGED_FROM_S = 60.0
#: ... for this long.
COLD_START_WINDOW_S = 60.0
#: Warm start (issue 17): roll and pitch count as within a limit when their RMS over this
#: long is (one sample's error is mostly the tilt loop's ARW noise, 0.05 deg 1-sigma) ...
START_RMS_WINDOW_S = 10.0
#: ... for every window starting within this long (20 s in all); a bias must stay within
#: its limit this long.
START_HOLD_S = 10.0
BIAS_HOLD_S = 10.0
#: GGA qualities (drivers.samples.FixQuality values) of the spans reported apart.
RTK_FIXED, RTK_FLOAT, OUTAGE = 4, 5, 0


@dataclass
class Trace:
    """An engine's solution at the recorded instants; NaN where the engine knew nothing.

    ``t`` (n,) host-clock s; ``rpy_rad`` (n, 3); ``ref_lla`` (n, 3) reference point lat deg,
    lon deg, height m; ``bias_g_rps``, ``bias_a_mps2`` (n, 3) body FRD; ``gyro_xy_converged``,
    ``accel_xy_converged`` (n,) the engine's own convergence flags.
    """

    t: Array
    rpy_rad: Array
    ref_lla: Array
    bias_g_rps: Array
    bias_a_mps2: Array
    gyro_xy_converged: BoolArray
    accel_xy_converged: BoolArray

    @classmethod
    def from_solutions(cls, solutions: list[Solution]) -> Trace:
        """Columns of a list of solutions (None -> NaN)."""
        nan3 = (math.nan, math.nan, math.nan)

        def vec(x: object) -> tuple[float, float, float]:
            return nan3 if x is None else tuple(float(v) for v in x)  # type: ignore[return-value,attr-defined]

        def num(x: float | None) -> float:
            return math.nan if x is None else x

        return cls(
            t=np.array([s.t for s in solutions]),
            rpy_rad=np.array(
                [(num(s.roll_rad), num(s.pitch_rad), num(s.yaw_rad)) for s in solutions]
            ).reshape(-1, 3),
            ref_lla=np.array(
                [(num(s.lat_deg), num(s.lon_deg), num(s.alt_m)) for s in solutions]
            ).reshape(-1, 3),
            bias_g_rps=np.array([vec(s.bias_g_rps) for s in solutions]).reshape(-1, 3),
            bias_a_mps2=np.array([vec(s.bias_a_mps2) for s in solutions]).reshape(-1, 3),
            gyro_xy_converged=np.array([s.convergence.gyro_xy for s in solutions], dtype=bool),
            accel_xy_converged=np.array([s.convergence.accel_xy for s in solutions], dtype=bool),
        )


def record(
    engine: Estimator, inputs: Iterable[ImuSample | ImuAux | GnssFix], every: int = 10
) -> Trace:
    """Feed ``inputs`` to ``engine`` in order; keep the solution after every ``every``-th
    IMU sample (10: about 20 Hz at 204.8 Hz); IMU_AUX gives the IMU's temperature, as the
    fusion core does."""
    solutions: list[Solution] = []
    n = 0
    for item in inputs:
        if isinstance(item, ImuSample):
            engine.imu(item)
            n += 1
            if n % every == 0:
                solutions.append(engine.solution())
        elif isinstance(item, GnssFix):
            engine.gnss(item)
        else:
            engine.temperature(item.t, item.temp_c)
    return Trace.from_solutions(solutions)


def record_core(
    core: FusionCore, inputs: Iterable[ImuSample | ImuAux | GnssFix | BusFrame], every: int = 10
) -> Trace:
    """:func:`record` through a fusion core (IMU_AUX included: a warm start is the core's),
    before its address claim (so it encodes nothing)."""
    solutions: list[Solution] = []
    n = 0
    for item in inputs:
        for _ in core.on_input(item):
            pass
        if isinstance(item, ImuSample):
            n += 1
            if n % every == 0:
                solutions.append(core.solution())
    return Trace.from_solutions(solutions)


# ================================================================== truth at the trace times


@dataclass
class TruthAt:
    """Truth interpolated at trace instants (n,): attitude, reference point, biases."""

    t: Array
    rpy_rad: Array
    pos_ned_m: Array
    bias_g_rps: Array
    bias_a_mps2: Array
    stationary: BoolArray


def truth_at(truth: Truth, t: Array) -> TruthAt:
    """Linear interpolation of the truth columns at ``t`` (yaw unwrapped first)."""
    t = np.asarray(t, dtype=float)

    def interp(col: Array) -> Array:
        return np.stack([np.interp(t, truth.t, c) for c in col.T], axis=-1)

    rpy = truth.rpy_rad.copy()
    rpy[:, 2] = np.unwrap(rpy[:, 2])
    i = np.clip(np.searchsorted(truth.t, t), 0, len(truth) - 1)
    return TruthAt(
        t=t,
        rpy_rad=interp(rpy),
        pos_ned_m=interp(truth.pos_ned_m),
        bias_g_rps=interp(truth.bias_g_rps),
        bias_a_mps2=interp(truth.bias_a_mps2),
        stationary=truth.stationary[i],
    )


# ======================================================================== pure metrics


def rms(x: npt.ArrayLike) -> float:
    """Root mean square over the finite values (NaN if none)."""
    a = np.asarray(x, dtype=float)
    a = a[np.isfinite(a)]
    return float(np.sqrt(np.mean(a * a))) if a.size else math.nan


def max_abs(x: npt.ArrayLike) -> float:
    """Largest |x| over the finite values (NaN if none)."""
    a = np.asarray(x, dtype=float)
    a = a[np.isfinite(a)]
    return float(np.max(np.abs(a))) if a.size else math.nan


def attitude_error_rad(rpy_est_rad: npt.ArrayLike, rpy_true_rad: npt.ArrayLike) -> Array:
    """Roll, pitch, yaw error (n, 3), estimate minus truth, wrapped."""
    return wrap_pi(np.asarray(rpy_est_rad, dtype=float) - np.asarray(rpy_true_rad, dtype=float))


def lever_arm_error_h_m(
    rpy_est_rad: npt.ArrayLike, rpy_true_rad: npt.ArrayLike, lever_arm_b_m: npt.ArrayLike
) -> Array:
    """|horizontal part of (C_true - C_est) l| (n,), m: the reference-point error that the
    attitude error alone causes (terrain compensation with a perfect antenna position)."""
    l_b = np.asarray(lever_arm_b_m, dtype=float)
    d = (dcm_from_rpy_array(rpy_true_rad) - dcm_from_rpy_array(rpy_est_rad)) @ l_b
    return np.asarray(np.hypot(d[:, 0], d[:, 1]))


def horizontal_error_m(ned_est_m: npt.ArrayLike, ned_true_m: npt.ArrayLike) -> Array:
    """Horizontal distance (n,) between two NED position tracks, m."""
    d = np.asarray(ned_est_m, dtype=float) - np.asarray(ned_true_m, dtype=float)
    return np.asarray(np.hypot(d[:, 0], d[:, 1]))


def cross_track_error_m(
    ned_est_m: npt.ArrayLike, ned_true_m: npt.ArrayLike, yaw_true_rad: npt.ArrayLike
) -> Array:
    """Signed horizontal error across the true heading (n,), m, right positive: the error an
    autosteer acts on (along-track error moves the implement along its own line)."""
    d = np.asarray(ned_est_m, dtype=float) - np.asarray(ned_true_m, dtype=float)
    yaw = np.asarray(yaw_true_rad, dtype=float)
    return np.asarray(-np.sin(yaw) * d[:, 0] + np.cos(yaw) * d[:, 1])


def first_time(t: npt.ArrayLike, flag: npt.ArrayLike) -> float | None:
    """First ``t`` from which ``flag`` stays true to the end, or None if it ends false."""
    t_a = np.asarray(t, dtype=float)
    f = np.asarray(flag, dtype=bool)
    if f.size == 0 or not f[-1]:
        return None
    false_idx = np.flatnonzero(~f)
    return float(t_a[false_idx[-1] + 1] if false_idx.size else t_a[0])


def window_rms(t: npt.ArrayLike, x: npt.ArrayLike, window_s: float) -> Array:
    """RMS of ``x`` over [t_i, t_i + window_s] for each i (n,); NaN where the window runs
    past the end or holds a NaN (an unknown value is not within any limit)."""
    t_a, x_a = np.asarray(t, dtype=float), np.asarray(x, dtype=float)
    if t_a.size == 0:
        return np.zeros(0)
    bad = ~np.isfinite(x_a)
    sq = np.concatenate(([0.0], np.cumsum(np.where(bad, 0.0, x_a * x_a))))
    nbad = np.concatenate(([0], np.cumsum(bad)))
    end = np.searchsorted(t_a, t_a + window_s, side="right")
    start = np.arange(len(t_a))
    n = end - start
    out = np.sqrt((sq[end] - sq[start]) / np.maximum(n, 1))
    out[(nbad[end] - nbad[start] > 0) | (t_a + window_s > t_a[-1])] = np.nan
    return np.asarray(out)


def settle_time(t: npt.ArrayLike, ok: npt.ArrayLike, hold_s: float) -> float | None:
    """Time from ``t[0]`` to the first instant from which ``ok`` holds for ``hold_s`` (the
    whole hold inside the record); None if never."""
    t_a, ok_a = np.asarray(t, dtype=float), np.asarray(ok, dtype=bool)
    if t_a.size == 0:
        return None
    bad = np.concatenate(([0], np.cumsum(~ok_a)))
    end = np.searchsorted(t_a, t_a + hold_s, side="right")
    good = (bad[end] == bad[np.arange(len(t_a))]) & (t_a + hold_s <= t_a[-1])
    first = np.flatnonzero(good)
    return float(t_a[first[0]] - t_a[0]) if first.size else None


@dataclass
class StartAccuracy:
    """How soon after a start the solution is accurate (s from the first recorded instant;
    None: not within the record): roll and pitch RMS over :data:`START_RMS_WINDOW_S` within
    ``tilt_limit`` for :data:`START_HOLD_S`; the x/y accelerometer bias errors within
    ``accel_limit`` for :data:`BIAS_HOLD_S`."""

    attitude_s: float | None
    accel_bias_s: float | None


def start_accuracy(
    trace: Trace,
    truth: Truth,
    tilt_limit_rad: float = math.radians(0.1),
    accel_limit_mps2: float = 0.01,
) -> StartAccuracy:
    """:class:`StartAccuracy` of ``trace`` against ``truth`` (issue 17's warm start)."""
    tr = truth_at(truth, trace.t)
    att = attitude_error_rad(trace.rpy_rad, tr.rpy_rad)
    tilt_ok = (window_rms(trace.t, att[:, 0], START_RMS_WINDOW_S) <= tilt_limit_rad) & (
        window_rms(trace.t, att[:, 1], START_RMS_WINDOW_S) <= tilt_limit_rad
    )
    d_ba = np.abs(trace.bias_a_mps2[:, :2] - tr.bias_a_mps2[:, :2])
    accel_ok = np.all(d_ba <= accel_limit_mps2, axis=1)  # NaN compares False
    return StartAccuracy(
        attitude_s=settle_time(trace.t, tilt_ok, START_HOLD_S),
        accel_bias_s=settle_time(trace.t, accel_ok, BIAS_HOLD_S),
    )


# ============================================================================ the report


@dataclass(frozen=True)
class Accuracy:
    """One engine on one run. Angles rad, rates rad/s, m/s^2, m; times s from the run start.

    Bias errors are estimate minus truth over the converged part (RMS, and the final value);
    attitude and position errors are over the converged part too (RMS and max). NaN where
    the engine gives no such output (e.g. an AHRS estimates no accelerometer bias).
    """

    converged_from_s: float
    gyro_xy_converged_s: float | None
    accel_xy_converged_s: float | None
    bias_g_final_rps: Array  # (3,)
    bias_g_rms_rps: Array  # (3,)
    bias_a_final_mps2: Array  # (3,)
    bias_a_rms_mps2: Array  # (3,)
    rpy_rms_rad: Array  # (3,)
    rpy_max_rad: Array  # (3,)
    ref_h_rms_m: float
    ref_h_max_m: float
    ref_from_att_h_rms_m: float
    ref_from_att_h_max_m: float


def evaluate(
    trace: Trace,
    truth: Truth,
    antenna_lever_arm_m: npt.ArrayLike,
    converged_from_s: float | None = None,
) -> Accuracy:
    """All metrics of ``trace`` against ``truth``.

    The converged part starts at ``converged_from_s`` (s from the first truth sample) if
    given, else where both x/y convergence flags of the engine have risen for good, else at
    :data:`DEFAULT_CONVERGED_AFTER_S` (clipped to half the recorded run for short runs).
    """
    t0 = float(truth.t[0])
    tr = truth_at(truth, trace.t)
    g_s = first_time(trace.t, trace.gyro_xy_converged)
    a_s = first_time(trace.t, trace.accel_xy_converged)
    if converged_from_s is None:
        both = first_time(trace.t, trace.gyro_xy_converged & trace.accel_xy_converged)
        run_s = float(trace.t[-1]) - t0 if len(trace.t) else 0.0
        converged_from_s = (
            both - t0 if both is not None else min(DEFAULT_CONVERGED_AFTER_S, 0.5 * run_s)
        )
    sel = trace.t - t0 >= converged_from_s
    att = attitude_error_rad(trace.rpy_rad, tr.rpy_rad)[sel]
    d_bg = (trace.bias_g_rps - tr.bias_g_rps)[sel]
    d_ba = (trace.bias_a_mps2 - tr.bias_a_mps2)[sel]
    ref = lla_to_ned(trace.ref_lla, truth.origin_lla)
    pos_h = horizontal_error_m(ref, tr.pos_ned_m)[sel]
    att_h = lever_arm_error_h_m(trace.rpy_rad, tr.rpy_rad, antenna_lever_arm_m)[sel]
    last3 = np.full(3, math.nan)

    def final(x: Array) -> Array:
        return x[-1] if len(x) else last3

    return Accuracy(
        converged_from_s=float(converged_from_s),
        gyro_xy_converged_s=None if g_s is None else g_s - t0,
        accel_xy_converged_s=None if a_s is None else a_s - t0,
        bias_g_final_rps=final(d_bg),
        bias_g_rms_rps=np.array([rms(c) for c in d_bg.T]),
        bias_a_final_mps2=final(d_ba),
        bias_a_rms_mps2=np.array([rms(c) for c in d_ba.T]),
        rpy_rms_rad=np.array([rms(c) for c in att.T]),
        rpy_max_rad=np.array([max_abs(c) for c in att.T]),
        ref_h_rms_m=rms(pos_h),
        ref_h_max_m=max_abs(pos_h),
        ref_from_att_h_rms_m=rms(att_h),
        ref_from_att_h_max_m=max_abs(att_h),
    )


@dataclass(frozen=True)
class SpanAccuracy:
    """Reference-point cross-track error by GNSS condition, one engine on one run, m; and
    the cold-start tilt. NaN where the run has no such span (or no position was output).

    ``fixed_rms_m``: RTK fixed in the converged part, outside the recovery windows;
    ``float_rms_m``: during RTK float; ``coarse_rms_m``: during DGNSS and single point;
    ``outage_rms_m``: during outages; ``outage_end_max_m``: worst |error| of the last position
    output in each outage (its end, or where the engine stops outputting one);
    ``recovery_rms_m``: the :data:`RECOVERY_S` after each degraded span;
    ``cold_start_tilt_max_rad``: worst roll or pitch error over the
    :data:`COLD_START_WINDOW_S` from :data:`COLD_START_JUDGED_FROM_S` after the run start.
    """

    fixed_rms_m: float
    float_rms_m: float
    coarse_rms_m: float
    outage_rms_m: float
    outage_end_max_m: float
    recovery_rms_m: float
    cold_start_tilt_max_rad: float


def evaluate_spans(
    trace: Trace,
    truth: Truth,
    schedule: Sequence[tuple[float, float, int]],
    converged_from_s: float,
) -> SpanAccuracy:
    """:class:`SpanAccuracy` of ``trace``; ``schedule``: the receiver's (start s, end s,
    GGA quality) spans from the run start, RTK fixed outside them (later ones win)."""
    t0 = float(truth.t[0])
    t_rel = trace.t - t0
    tr = truth_at(truth, trace.t)
    ref = lla_to_ned(trace.ref_lla, truth.origin_lla)
    xt = cross_track_error_m(ref, tr.pos_ned_m, tr.rpy_rad[:, 2])
    quality = np.full(len(t_rel), RTK_FIXED)
    recovering = np.zeros(len(t_rel), dtype=bool)
    ends: list[float] = []
    for start, end, q in schedule:
        quality[(t_rel >= start) & (t_rel < end)] = int(q)
        if int(q) != RTK_FIXED:
            recovering |= (t_rel >= end) & (t_rel < end + RECOVERY_S)
    for start, end, q in schedule:
        inside = np.flatnonzero((t_rel >= start) & (t_rel < end) & np.isfinite(xt))
        if int(q) == OUTAGE and inside.size:
            ends.append(abs(float(xt[inside[-1]])))
    recovering &= quality == RTK_FIXED
    coarse = (quality != RTK_FIXED) & (quality != RTK_FLOAT) & (quality != OUTAGE)
    fixed = (quality == RTK_FIXED) & ~recovering & (t_rel >= converged_from_s)
    window = (t_rel >= COLD_START_JUDGED_FROM_S) & (
        t_rel < COLD_START_JUDGED_FROM_S + COLD_START_WINDOW_S
    )
    tilt = attitude_error_rad(trace.rpy_rad, tr.rpy_rad)[window, :2]
    return SpanAccuracy(
        fixed_rms_m=rms(xt[fixed]),
        float_rms_m=rms(xt[quality == RTK_FLOAT]),
        coarse_rms_m=rms(xt[coarse]),
        outage_rms_m=rms(xt[quality == OUTAGE]),
        outage_end_max_m=max(ends) if ends else math.nan,
        recovery_rms_m=rms(xt[recovering]),
        cold_start_tilt_max_rad=max_abs(tilt),
    )
