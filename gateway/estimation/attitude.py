"""Attitude algebra: skew matrices, the SO(3) exponential, ZYX Euler angles, orthonormalisation.

Conventions (ALGORITHMS.md): body FRD, navigation NED, ``c_bn`` maps body vectors to NED,
Euler angles are ZYX (yaw about down, then pitch, then roll), yaw clockwise from true north.
These numpy helpers serve alignment, tests and once-per-epoch work; the per-sample hot path of
the observer uses the unrolled float forms :func:`exp_so3_2nd`, :func:`exp_so3_9` and
:func:`dcm_mul`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import numpy.typing as npt

Array = npt.NDArray[np.float64]

#: A 3x3 matrix as 9 floats, row major: (c00, c01, c02, c10, ..., c22). Hot-path form.
Mat9 = tuple[float, float, float, float, float, float, float, float, float]
#: The identity as a :data:`Mat9`.
IDENTITY9: Mat9 = (1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0)


def skew(v: npt.ArrayLike) -> Array:
    """[v]x, shape (3, 3), such that skew(a) @ b == cross(a, b)."""
    x, y, z = np.asarray(v, dtype=float).tolist()
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def cross3(a: npt.ArrayLike, b: npt.ArrayLike) -> Array:
    """a x b of two 3-vectors: np.cross's own formula and operation order (the same bits),
    without its axis handling, which costs 15 us a call."""
    a0, a1, a2 = np.asarray(a, dtype=float).ravel().tolist()
    b0, b1, b2 = np.asarray(b, dtype=float).ravel().tolist()
    return np.array((a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0))


def exp_so3(phi: npt.ArrayLike) -> Array:
    """Rotation matrix exp([phi]x), shape (3, 3), by Rodrigues' formula (exact):
    :func:`exp_so3_9` as an array."""
    x, y, z = np.asarray(phi, dtype=float).ravel().tolist()
    return np.array(exp_so3_9(x, y, z)).reshape(3, 3)


def exp_so3_9(x: float, y: float, z: float) -> Mat9:
    """exp([phi]x) of phi = (x, y, z) rad as 9 row-major floats, by Rodrigues' formula
    I + a K + b K^2 (a = sin(t) / t, b = (1 - cos(t)) / t^2, t = |phi|; the series to second
    order below 1e-8 rad), in plain floats: the per-epoch rotations need no numpy."""
    xx, yy, zz, xy, xz, yz = x * x, y * y, z * z, x * y, x * z, y * z
    angle = math.sqrt(xx + yy + zz)
    if angle < 1e-8:
        a, b = 1.0, 0.5
    else:
        a, b = math.sin(angle) / angle, (1.0 - math.cos(angle)) / (angle * angle)
    # K^2 = phi phi^T - |phi|^2 I
    return (
        1.0 - b * (yy + zz), b * xy - a * z, b * xz + a * y,
        b * xy + a * z, 1.0 - b * (xx + zz), b * yz - a * x,
        b * xz - a * y, b * yz + a * x, 1.0 - b * (xx + yy),
    )  # fmt: skip


def dcm_from_rpy_array(rpy_rad: npt.ArrayLike) -> Array:
    """C_b^n = Rz(yaw) Ry(pitch) Rx(roll), shape (n, 3, 3), from roll, pitch, yaw (n, 3)."""
    r = np.asarray(rpy_rad, dtype=float).reshape(-1, 3)
    cr, cp, cy = np.cos(r).T
    sr, sp, sy = np.sin(r).T
    return np.stack(
        (
            np.stack((cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr), axis=-1),
            np.stack((sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr), axis=-1),
            np.stack((-sp, cp * sr, cp * cr), axis=-1),
        ),
        axis=1,
    )


def dcm_from_rpy_deg(rpy_deg: npt.ArrayLike) -> Array:
    """C = Rz(yaw) Ry(pitch) Rx(roll), shape (3, 3), from roll, pitch, yaw in degrees (the
    IMU mounting of SPEC 5: v_b = C v_imu)."""
    return dcm_from_rpy_array(np.deg2rad(np.asarray(rpy_deg, dtype=float)))[0]


def dcm_from_rpy(roll_rad: float, pitch_rad: float, yaw_rad: float) -> Array:
    """C_b^n = Rz(yaw) Ry(pitch) Rx(roll), shape (3, 3)."""
    return dcm_from_rpy_array((roll_rad, pitch_rad, yaw_rad))[0]


def rpy_from_dcm(c_bn: npt.ArrayLike) -> tuple[float, float, float]:
    """Roll, pitch (rad) and yaw in [0, 2 pi) of C_b^n, shape (3, 3)."""
    c = np.asarray(c_bn, dtype=float)
    roll = math.atan2(c[2, 1], c[2, 2])
    pitch = -math.asin(max(-1.0, min(1.0, c[2, 0])))
    yaw = math.atan2(c[1, 0], c[0, 0]) % (2.0 * math.pi)
    return roll, pitch, yaw


def rpy_from_mat9(c9: Mat9) -> tuple[float, float, float]:
    """:func:`rpy_from_dcm` of 9 row-major floats (the engines' hot-path form), no numpy."""
    roll = math.atan2(c9[7], c9[8])
    pitch = -math.asin(max(-1.0, min(1.0, c9[6])))
    yaw = math.atan2(c9[3], c9[0]) % (2.0 * math.pi)
    return roll, pitch, yaw


def heading_rate_from_mat9(c9: Mat9, w_b: Sequence[float]) -> float:
    """Rate of change of the heading (yaw of :func:`rpy_from_mat9`), rad/s, of a body turning
    at ``w_b`` (rad/s, body): (sin(roll) w_y + cos(roll) w_z) / cos(pitch). Not the rate about
    the vertical, (C w_b)[2]: that one misses roll rate x sin(pitch), 1 deg/s when roll
    changes 6 deg/s on a 9 deg slope, and the heading sent beside it would not follow it."""
    c20, c21, c22 = c9[6], c9[7], c9[8]
    return (c21 * w_b[1] + c22 * w_b[2]) / (1.0 - c20 * c20)


def roll_pitch_from_specific_force(f_b: npt.ArrayLike) -> tuple[float, float]:
    """Roll and pitch (rad) of a platform whose accelerometers read ``f_b`` (3,) at rest.

    At rest f_b = C_n^b [0, 0, -g] = [g sin(pitch), -g sin(roll) cos(pitch),
    -g cos(roll) cos(pitch)].
    """
    fx, fy, fz = np.asarray(f_b, dtype=float)
    return math.atan2(-fy, -fz), math.atan2(fx, math.hypot(fy, fz))


def orthonormalise(c: npt.ArrayLike) -> Array:
    """Nearest rotation matrix to ``c`` (3, 3) in the Frobenius norm (polar part, by SVD)."""
    u, _, vt = np.linalg.svd(np.asarray(c, dtype=float))
    return u @ vt


def to_mat9(c: npt.ArrayLike) -> Mat9:
    """(3, 3) array -> 9 row-major floats."""
    a = np.asarray(c, dtype=float).reshape(9).tolist()
    return (a[0], a[1], a[2], a[3], a[4], a[5], a[6], a[7], a[8])


def from_mat9(m: Mat9) -> Array:
    """9 row-major floats -> (3, 3) array."""
    return np.array(m, dtype=float).reshape(3, 3)


def exp_so3_2nd(x: float, y: float, z: float) -> Mat9:
    """exp([phi]x) to second order, I + [phi]x + [phi]x^2 / 2, for small phi = (x, y, z).

    Error O(|phi|^3 / 6): 3e-9 rad per step at 0.5 rad/s and 200 Hz; the caller
    re-orthonormalises periodically to remove the slow loss of orthogonality.
    """
    xx, yy, zz = 0.5 * x * x, 0.5 * y * y, 0.5 * z * z
    xy, xz, yz = 0.5 * x * y, 0.5 * x * z, 0.5 * y * z
    return (
        1.0 - yy - zz, xy - z, xz + y,
        xy + z, 1.0 - xx - zz, yz - x,
        xz - y, yz + x, 1.0 - xx - yy,
    )  # fmt: skip


def dcm_mul(a: Sequence[float], b: Sequence[float]) -> Mat9:
    """Matrix product a @ b of two row-major 3x3 matrices of 9 floats (unrolled, no numpy)."""
    a00, a01, a02, a10, a11, a12, a20, a21, a22 = a
    b00, b01, b02, b10, b11, b12, b20, b21, b22 = b
    return (
        a00 * b00 + a01 * b10 + a02 * b20,
        a00 * b01 + a01 * b11 + a02 * b21,
        a00 * b02 + a01 * b12 + a02 * b22,
        a10 * b00 + a11 * b10 + a12 * b20,
        a10 * b01 + a11 * b11 + a12 * b21,
        a10 * b02 + a11 * b12 + a12 * b22,
        a20 * b00 + a21 * b10 + a22 * b20,
        a20 * b01 + a21 * b11 + a22 * b21,
        a20 * b02 + a21 * b12 + a22 * b22,
    )
