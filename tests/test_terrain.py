"""Lever-arm algebra, hand-checked (ALGORITHMS.md 4)."""

import math

import numpy as np
from numpy.testing import assert_allclose

from gateway.estimation.attitude import dcm_from_rpy
from gateway.estimation.lever_arm import (
    lever_arm_position_ned,
    lever_arm_velocity_ned,
    reference_from_antenna,
    velocity_at,
)
from tests.kinematics import Motion, Segment, state_at


def test_three_metre_mast_five_degree_roll_is_26_cm_across_track() -> None:
    # heading north, right side down 5 deg: the top of a 3 m mast leans 26.1 cm to the right
    c_bn = dcm_from_rpy(math.radians(5.0), 0.0, 0.0)
    off = lever_arm_position_ned(c_bn, [0.0, 0.0, -3.0])
    assert_allclose(off, [0.0, 0.2615, -2.9886], atol=1e-4)
    assert_allclose(off[1], 3.0 * math.sin(math.radians(5.0)), atol=1e-12)
    p_ref = reference_from_antenna([10.0, 20.0, -3.0], c_bn, [0.0, 0.0, -3.0])
    assert_allclose(p_ref, [10.0, 20.0 - 0.2615, -3.0 + 2.9886], atol=1e-4)


def test_full_3d_rotation_not_lateral_shortcut() -> None:
    c_bn = dcm_from_rpy(math.radians(5.0), math.radians(3.0), math.radians(90.0))
    off = lever_arm_position_ned(c_bn, [1.0, 0.5, -3.0])
    assert_allclose(off, c_bn @ [1.0, 0.5, -3.0])
    assert_allclose(np.linalg.norm(off), math.sqrt(1.0 + 0.25 + 9.0))


def test_lever_arm_velocity_of_a_turning_vehicle() -> None:
    # 0.5 rad/s right turn, antenna 2 m ahead: it moves 1 m/s to the right (east when north)
    v = lever_arm_velocity_ned(np.eye(3), [0.0, 0.0, 0.5], [2.0, 0.0, 0.0])
    assert_allclose(v, [0.0, 1.0, 0.0])
    # a roll rate swings a 3 m mast sideways: w_x 0.1 rad/s -> 0.3 m/s to the right
    v = lever_arm_velocity_ned(np.eye(3), [0.1, 0.0, 0.0], [0.0, 0.0, -3.0])
    assert_allclose(v, [0.0, 0.3, 0.0])


def test_velocity_at_matches_the_exact_motion() -> None:
    m = Motion([Segment(10.0, yaw_rate_rps=0.4)], v0_mps=3.0, roll_rad=0.05, pitch_rad=-0.03)
    st = state_at(m, [2.7])
    l_ant, l_imu = np.array([0.8, -0.2, -3.0]), np.array([0.3, 0.1, -1.0])
    v_ant = st.v_ned_mps[0] + st.c_bn[0] @ np.cross(st.w_b_rps[0], l_ant)
    v_ref = velocity_at(v_ant, st.c_bn[0], st.w_b_rps[0], l_ant, np.zeros(3))
    assert_allclose(v_ref, st.v_ned_mps[0], atol=1e-12)
    v_imu = velocity_at(v_ant, st.c_bn[0], st.w_b_rps[0], l_ant, l_imu)
    assert_allclose(
        v_imu, st.v_ned_mps[0] + st.c_bn[0] @ np.cross(st.w_b_rps[0], l_imu), atol=1e-12
    )
