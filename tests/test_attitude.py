"""Attitude helpers against hand-worked answers and each other."""

import math

import numpy as np
from numpy.testing import assert_allclose

from drivers.units import wrap_pi
from gateway.estimation.attitude import (
    dcm_from_rpy,
    dcm_mul,
    exp_so3,
    exp_so3_2nd,
    from_mat9,
    heading_rate_from_mat9,
    orthonormalise,
    roll_pitch_from_specific_force,
    rpy_from_dcm,
    skew,
    to_mat9,
)


def test_skew_is_the_cross_product() -> None:
    a, b = np.array([1.0, -2.0, 0.5]), np.array([0.3, 4.0, -1.0])
    assert_allclose(skew(a) @ b, np.cross(a, b))


def test_exp_so3_quarter_turn_about_down_maps_north_to_east() -> None:
    c = exp_so3([0.0, 0.0, math.pi / 2])
    assert_allclose(c @ [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], atol=1e-15)
    assert_allclose(c, dcm_from_rpy(0.0, 0.0, math.pi / 2), atol=1e-15)


def test_rpy_round_trip_and_yaw_range() -> None:
    for rpy in [(0.1, -0.2, 3.0), (-0.05, 0.3, 5.5), (0.0, 0.0, 0.0)]:
        r, p, y = rpy_from_dcm(dcm_from_rpy(*rpy))
        assert_allclose((r, p, y), (rpy[0], rpy[1], rpy[2] % (2 * math.pi)), atol=1e-12)
    assert 0.0 <= rpy_from_dcm(dcm_from_rpy(0.0, 0.0, -0.1))[2] < 2 * math.pi


def test_roll_pitch_from_specific_force_at_rest() -> None:
    g = 9.80665
    c_bn = dcm_from_rpy(0.07, -0.04, 1.2)
    f_b = c_bn.T @ [0.0, 0.0, -g]
    assert_allclose(roll_pitch_from_specific_force(f_b), (0.07, -0.04), atol=1e-12)


def test_second_order_exp_matches_rodrigues_at_farm_rates() -> None:
    phi = np.array([0.3, -0.2, 0.6]) * 4.0 / 819.2  # rad/s times one ADIS sample period
    err = from_mat9(exp_so3_2nd(*phi)) - exp_so3(phi)
    assert np.abs(err).max() < np.linalg.norm(phi) ** 3 / 6 * 1.01


def test_dcm_mul_and_mat9_round_trip() -> None:
    a, b = dcm_from_rpy(0.1, 0.2, 0.3), dcm_from_rpy(-0.3, 0.1, 2.0)
    assert_allclose(from_mat9(dcm_mul(to_mat9(a), to_mat9(b))), a @ b, atol=1e-15)


def test_orthonormalise_restores_a_rotation() -> None:
    c = dcm_from_rpy(0.1, 0.2, 0.3) + 1e-4 * np.arange(9.0).reshape(3, 3)
    r = orthonormalise(c)
    assert_allclose(r @ r.T, np.eye(3), atol=1e-14)
    assert abs(np.linalg.det(r) - 1.0) < 1e-14
    assert np.abs(r - c).max() < 1e-3


def test_wrap_pi() -> None:
    assert_allclose(
        [wrap_pi(3 * math.pi / 2), wrap_pi(-3 * math.pi / 2), wrap_pi(0.1)],
        [-math.pi / 2, math.pi / 2, 0.1],
    )


def test_the_heading_rate_is_the_derivative_of_the_heading() -> None:
    """Rolling 6 deg/s while turning 24 deg/s on a 9 deg slope: the heading changes at
    (sin(roll) w_y + cos(roll) w_z) / cos(pitch), 1 deg/s more than the rate about the
    vertical, (C w_b)[2], which the rate of turn sent before."""
    c_bn = dcm_from_rpy(math.radians(-7.0), math.radians(9.0), 1.0)
    w_b = np.array([math.radians(6.0), 0.05, math.radians(24.0)])
    dt = 1e-5
    yaw_next = rpy_from_dcm(c_bn @ exp_so3(w_b * dt))[2]
    yaw_prev = rpy_from_dcm(c_bn @ exp_so3(-w_b * dt))[2]
    rate = heading_rate_from_mat9(to_mat9(c_bn), w_b.tolist())
    assert abs(rate - wrap_pi(yaw_next - yaw_prev) / (2 * dt)) < 1e-8
    assert math.degrees(rate - (c_bn @ w_b)[2]) > 0.9  # about the vertical: 1 deg/s short
