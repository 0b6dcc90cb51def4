"""Lever-arm algebra for terrain compensation (ALGORITHMS.md section 4).

A point P fixed on the body at ``lever_arm_b`` (body FRD, metres, relative to the vehicle
reference point R) has position p_P = p_R + C_b^n l and velocity v_P = v_R + C_b^n (w_b x l).
Full 3-D rotation, no lateral-only h*sin(roll) shortcut. Plain floats: the observer runs
these every GNSS epoch, where numpy's per-call cost was most of the work. ``c_bn`` is C_b^n
as 9 row-major floats (:data:`~gateway.estimation.attitude.Mat9`) or a (3, 3) array.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np
import numpy.typing as npt

from gateway.estimation.attitude import Mat9, to_mat9

Vec3 = tuple[float, float, float]

#: A 3-vector argument: floats, or a (3,) array (analysis and tests).
Vec = Sequence[float] | npt.NDArray[np.float64]

#: Half width of the window of body rates, centred on a GNSS epoch, whose mean is the rate in
#: the antenna's lever-arm velocity C (w x l), s. Centred: no lag (bumps rock a 3 m mast at
#: 0.3-2 Hz; swaying 0.3 m/s at 1 Hz, 25 ms of lag cost 5 cm/s). Both engines hold
#: an epoch until the IMU has covered this much after it (:class:`~gateway.estimation.
#: engine_base.HeldEpochs`).
LEVER_RATE_HALF_WIDTH_S = 0.05
#: (fraction of the half width, weight) of the centred means that make :func:`centred_rate`:
#: they sum to 1 and their r^2 / 3 (a quadratic's share in a mean over +/- r) to 0, so a
#: rate's curvature cancels; of such weights these leave the least white noise.
_CENTRED_RATE_TERMS = ((1.0, -17.0 / 28.0), (2.0 / 3.0, 36.0 / 28.0), (1.0 / 3.0, 9.0 / 28.0))
#: White gyro noise of :func:`centred_rate` over that of the one mean over the half width
#: (1.56): two means over +/- r_i, +/- r_j share the samples of the narrower, so their
#: covariance is the wider's variance, 1 / max(r_i, r_j) in units of the full window's.
LEVER_RATE_NOISE_GAIN = math.sqrt(
    sum(a * b / max(r, q) for r, a in _CENTRED_RATE_TERMS for q, b in _CENTRED_RATE_TERMS)
)


def centred_rate(mean_rate: Callable[[float], Vec]) -> Vec3:
    """The body rate at an instant, rad/s, from ``mean_rate(r)``: the mean rate over +/- r
    about it, for r up to :data:`LEVER_RATE_HALF_WIDTH_S`.

    One mean over +/- h keeps sinc(w h) of a rate at w: 93 % at 2 Hz over 0.1 s, and a 3 m
    mast rocking +/-2 deg at 2 Hz moves at 1.3 m/s at its top, so the rest (8 cm/s) went
    into the observer's velocities: roll/pitch 0.17 deg RMS where the EKF had 0.065. The
    combination of three (:data:`_CENTRED_RATE_TERMS`) keeps 99.9 % at 2 Hz, 99.8 at 3
    (over exact windows: the observer interpolates its history; the EKF's, whole samples
    within +/- r of an epoch between two, a little off centre, 99-99.6 %), for
    :data:`LEVER_RATE_NOISE_GAIN` times the noise.
    """
    x = y = z = 0.0
    for frac, weight in _CENTRED_RATE_TERMS:
        wx, wy, wz = mean_rate(frac * LEVER_RATE_HALF_WIDTH_S)
        x += weight * wx
        y += weight * wy
        z += weight * wz
    return (x, y, z)


def centred_rate_velocity_sigma_mps(arw_rad_per_sqrt_s: float, lever_arm_m: float) -> float:
    """1-sigma of the velocity w x l, m/s, that :func:`centred_rate`'s white gyro noise puts
    on a lever arm ``lever_arm_m`` long, for a gyro of ``arw_rad_per_sqrt_s`` (its noise
    and vibration as a density: one mean over +/- h has ARW / sqrt(2 h))."""
    sigma_w = arw_rad_per_sqrt_s / math.sqrt(2.0 * LEVER_RATE_HALF_WIDTH_S)
    return LEVER_RATE_NOISE_GAIN * sigma_w * lever_arm_m


def _mat9(c_bn: Mat9 | npt.ArrayLike) -> Mat9:
    return c_bn if isinstance(c_bn, tuple) else to_mat9(c_bn)


def _rotate(c: Mat9, x: float, y: float, z: float) -> Vec3:
    return (
        c[0] * x + c[1] * y + c[2] * z,
        c[3] * x + c[4] * y + c[5] * z,
        c[6] * x + c[7] * y + c[8] * z,
    )


def lever_arm_position_ned(c_bn: Mat9 | npt.ArrayLike, lever_arm_b: Vec) -> Vec3:
    """C_b^n l: NED offset of a body point from the reference point, m."""
    lx, ly, lz = lever_arm_b
    return _rotate(_mat9(c_bn), lx, ly, lz)


def lever_arm_velocity_ned(c_bn: Mat9 | npt.ArrayLike, w_b_rps: Vec, lever_arm_b: Vec) -> Vec3:
    """C_b^n (w_b x l): velocity of a body point relative to the reference, m/s."""
    wx, wy, wz = w_b_rps
    lx, ly, lz = lever_arm_b
    return _rotate(_mat9(c_bn), wy * lz - wz * ly, wz * lx - wx * lz, wx * ly - wy * lx)


def reference_from_antenna(
    p_ant_ned_m: Vec, c_bn: Mat9 | npt.ArrayLike, lever_arm_ant_b: Vec
) -> Vec3:
    """Reference-point position p_ant - C_b^n l_ant, NED m."""
    dn, de, dd = lever_arm_position_ned(c_bn, lever_arm_ant_b)
    pn, pe, pd = p_ant_ned_m
    return (pn - dn, pe - de, pd - dd)


def velocity_at(
    v_src_ned_mps: Vec,
    c_bn: Mat9 | npt.ArrayLike,
    w_b_rps: Vec,
    lever_arm_src_b: Vec,
    lever_arm_dst_b: Vec,
) -> Vec3:
    """Velocity of body point ``dst`` from the measured velocity of body point ``src``.

    v_dst = v_src + C_b^n (w_b x (l_dst - l_src)). Used to move the antenna velocity to the
    reference point (heading, output) and to the IMU (tilt observer).
    """
    dx, dy, dz = lever_arm_dst_b
    sx, sy, sz = lever_arm_src_b
    vn, ve, vd = lever_arm_velocity_ned(c_bn, w_b_rps, (dx - sx, dy - sy, dz - sz))
    un, ue, ud = v_src_ned_mps
    return (un + vn, ue + ve, ud + vd)


def heading_from_antenna_course(
    v_ant_ne_mps: Vec,
    c_bn: Mat9 | npt.ArrayLike,
    w_b_rps: Vec,
    lever_arm_ant_b: Vec,
    forward: bool = True,
) -> float:
    """Heading, rad in [0, 2 pi), of a vehicle driving forward (or, not ``forward``,
    reversing) along its body x axis (the reference point without sideslip) whose antenna
    moves at ``v_ant_ne_mps`` (N, E) while the body turns at ``w_b_rps``. Only the tilt of
    ``c_bn`` is used: its yaw may be anything (the heading's first alignment).

    The antenna's course is not the heading: a 3 m mast rocking 3 deg/s moves the antenna
    0.16 m/s sideways, 6 deg of course at 1.5 m/s. With ``c_bn`` turned to yaw 0 the antenna
    moves at k x_b + u, u = C (w x l), x_b without a lateral part: its course there is
    asin(u_y / |v_ant|) (pi - that reversing, k < 0), and the heading the antenna's course
    less that.
    """
    c = _mat9(c_bn)
    _, u_lateral = _lateral_lever_velocity(c, w_b_rps, lever_arm_ant_b)
    vn, ve = v_ant_ne_mps[0], v_ant_ne_mps[1]
    ratio = max(-1.0, min(1.0, u_lateral / max(math.hypot(vn, ve), 1e-9)))
    course_b = math.asin(ratio) if forward else math.pi - math.asin(ratio)
    return (math.atan2(ve, vn) - course_b) % (2.0 * math.pi)


def antenna_velocity_along_body_x(
    speed_mps: float, c_bn: Mat9, w_b_rps: Vec, lever_arm_ant_b: Vec, forward: bool
) -> tuple[float, float]:
    """Horizontal antenna velocity (N, E of ``c_bn``'s own azimuth, m/s) of a vehicle driving
    along its body x axis (forward or reversing) whose antenna moves at ``speed_mps``: the
    same geometry as :func:`heading_from_antenna_course`, the other way round. The antenna's
    lateral velocity is the lever arm's, u_y; the rest of its speed is along x. Needs only
    the tilt of ``c_bn`` to be right: the result is in whatever azimuth its yaw has."""
    yaw, u_lateral = _lateral_lever_velocity(c_bn, w_b_rps, lever_arm_ant_b)
    along = math.sqrt(max(0.0, speed_mps * speed_mps - u_lateral * u_lateral))
    if not forward:
        along = -along
    cy, sy = math.cos(yaw), math.sin(yaw)
    return (along * cy - u_lateral * sy, along * sy + u_lateral * cy)


def along_body_x(v_n_mps: float, v_e_mps: float, c_bn: Mat9) -> float:
    """A horizontal velocity, or a velocity change since a rest (N, E in ``c_bn``'s own
    azimuth, m/s: the inertial one's yaw may be anything), along body x, m/s: positive when
    a wheeled vehicle drives forward (or leaves the rest forward), negative when it reverses
    (the course alone cannot tell: a reversing start aligned the heading 180 deg off, and a
    receiver's course held from before a stop points the other way)."""
    return v_n_mps * c_bn[0] + v_e_mps * c_bn[3]


def _lateral_lever_velocity(c: Mat9, w_b_rps: Vec, lever_arm_b: Vec) -> tuple[float, float]:
    """The azimuth of body x in ``c``'s frame, rad, and the lever arm's horizontal velocity
    C (w x l) across it, m/s."""
    un, ue, _ = lever_arm_velocity_ned(c, w_b_rps, lever_arm_b)
    yaw = math.atan2(c[3], c[0])
    return yaw, math.cos(yaw) * ue - math.sin(yaw) * un
