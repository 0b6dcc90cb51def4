"""Lever-arm algebra for terrain compensation (ALGORITHMS.md section 4).

A point P fixed on the body at ``lever_arm_b`` (body FRD, metres, relative to the vehicle
reference point R) has position p_P = p_R + C_b^n l and velocity v_P = v_R + C_b^n (w_b x l).
Full 3-D rotation, no lateral-only h*sin(roll) shortcut. Per-epoch code (numpy is fine here).
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from gateway.estimation.attitude import cross3

Array = npt.NDArray[np.float64]


def lever_arm_position_ned(c_bn: npt.ArrayLike, lever_arm_b: npt.ArrayLike) -> Array:
    """C_b^n l, shape (3,): NED offset of a body point from the reference point, m."""
    return np.asarray(c_bn, dtype=float) @ np.asarray(lever_arm_b, dtype=float)


def lever_arm_velocity_ned(
    c_bn: npt.ArrayLike, w_b_rps: npt.ArrayLike, lever_arm_b: npt.ArrayLike
) -> Array:
    """C_b^n (w_b x l), shape (3,): velocity of a body point relative to the reference, m/s."""
    return np.asarray(c_bn, dtype=float) @ cross3(
        np.asarray(w_b_rps, dtype=float), np.asarray(lever_arm_b, dtype=float)
    )


def reference_from_antenna(
    p_ant_ned_m: npt.ArrayLike, c_bn: npt.ArrayLike, lever_arm_ant_b: npt.ArrayLike
) -> Array:
    """Reference-point position p_ant - C_b^n l_ant, shape (3,), NED m."""
    return np.asarray(p_ant_ned_m, dtype=float) - lever_arm_position_ned(c_bn, lever_arm_ant_b)


def velocity_at(
    v_src_ned_mps: npt.ArrayLike,
    c_bn: npt.ArrayLike,
    w_b_rps: npt.ArrayLike,
    lever_arm_src_b: npt.ArrayLike,
    lever_arm_dst_b: npt.ArrayLike,
) -> Array:
    """Velocity of body point ``dst`` from the measured velocity of body point ``src``.

    v_dst = v_src + C_b^n (w_b x (l_dst - l_src)), shape (3,). Used to move the antenna
    velocity to the reference point (heading, output) and to the IMU (tilt observer).
    """
    dl = np.asarray(lever_arm_dst_b, dtype=float) - np.asarray(lever_arm_src_b, dtype=float)
    return np.asarray(v_src_ned_mps, dtype=float) + lever_arm_velocity_ned(c_bn, w_b_rps, dl)
