"""EKF maths: measurement Jacobians against finite differences, correct(), propagation."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import pytest
from numpy.testing import assert_allclose

from gateway.estimation.attitude import dcm_from_rpy, exp_so3
from gateway.estimation.ekf.error_state import (
    ATT,
    BG,
    CHASSIS,
    EPOCH,
    FIX,
    N_STATES,
    POS,
    VEL,
    Measurement,
    Strapdown,
    attitude_error,
    correct,
    fuse_heading,
    fuse_nonholonomic,
    fuse_position,
    fuse_velocity,
    nis_gate,
    predict,
    transition_matrix,
)

C_BN = dcm_from_rpy(0.05, -0.03, 2.0)
P_NED = np.array([10.0, -4.0, 0.5])
V_NED = np.array([2.0, -1.0, 0.1])
W_B = np.array([0.02, -0.01, 0.3])
L_B = np.array([0.3, 0.1, -3.0])


def _perturbed(dx: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """True state for error dx: p + dp, v + dv, exp([phi]x) C, rate w - dbg."""
    return P_NED + dx[POS], V_NED + dx[VEL], exp_so3(dx[ATT]) @ C_BN, W_B - dx[BG]


def _numeric_h(
    predict_fn: Callable[[np.ndarray, np.ndarray, np.ndarray, np.ndarray], np.ndarray], n_out: int
) -> np.ndarray:
    """d(prediction)/d(dx) by central differences, shape (n_out, 18)."""
    h = np.zeros((n_out, N_STATES))
    eps = 1e-6
    for j in range(N_STATES):
        dx = np.zeros(N_STATES)
        dx[j] = eps
        h[:, j] = (predict_fn(*_perturbed(dx)) - predict_fn(*_perturbed(-dx))) / (2 * eps)
    return h


def test_position_jacobian_matches_finite_differences() -> None:
    b = np.array([0.1, -0.2, 0.05])  # the receiver's position error (FIX states)
    v_ant = np.array([3.0, -1.0, 0.2])  # the antenna's velocity (the EPOCH column)

    def z_of(b: np.ndarray) -> np.ndarray:
        return fuse_position(P_NED, C_BN, L_B, np.zeros(3), np.ones(3), b, v_ant).z

    m = fuse_position(P_NED, C_BN, L_B, np.zeros(3), np.ones(3), b, v_ant)
    num = _numeric_h(lambda p, v, c, w: p + c @ L_B, 3)
    eps = 1e-6
    for j in range(3):  # d(prediction)/d(db) = -dz/d(db), by central differences
        db = np.zeros(3)
        db[j] = eps
        num[:, FIX.start + j] = -(z_of(b + db) - z_of(b - db)) / (2 * eps)
    # an epoch placed dtau late is the antenna where it was dtau earlier: p - v_ant dtau
    num[:, EPOCH] = -v_ant
    assert_allclose(m.h, num, atol=1e-8)
    assert_allclose(m.z, -(P_NED + C_BN @ L_B + b))


def test_velocity_jacobian_matches_finite_differences() -> None:
    m = fuse_velocity(V_NED, C_BN, W_B, L_B, np.zeros(2), 0.02)
    num = _numeric_h(lambda p, v, c, w: (v + c @ np.cross(w, L_B))[:2], 2)
    assert_allclose(m.h, num, atol=1e-8)
    # a velocity placed dtau late is the antenna's dtau earlier: v_ant - a_ant dtau
    a_ant = np.array([0.7, -0.3, 0.1])
    timed = fuse_velocity(V_NED, C_BN, W_B, L_B, np.zeros(2), 0.02, a_ant)
    num[:, EPOCH] = -a_ant[:2]
    assert_allclose(timed.h, num, atol=1e-8)
    assert_allclose(timed.z, m.z)


def test_nonholonomic_jacobian_matches_finite_differences() -> None:
    m = fuse_nonholonomic(V_NED, C_BN, W_B, -L_B, 0.05)
    num = _numeric_h(lambda p, v, c, w: -(c.T @ v + np.cross(w, -L_B))[1:], 2)
    eps = 1e-6  # the chassis's pitch against its track: v_z = v_x c
    z_plus = fuse_nonholonomic(V_NED, C_BN, W_B, -L_B, 0.05, eps).z
    z_minus = fuse_nonholonomic(V_NED, C_BN, W_B, -L_B, 0.05, -eps).z
    num[:, CHASSIS] = (z_plus - z_minus) / (2 * eps)
    assert abs(num[1, CHASSIS]) > 0.5  # the body x velocity, m/s
    assert_allclose(-m.h, num, atol=1e-8)  # z = 0 - prediction


def test_heading_jacobian_matches_finite_differences() -> None:
    m = fuse_heading(C_BN, 2.0, 0.01)
    num = _numeric_h(lambda p, v, c, w: np.array([math.atan2(c[1, 0], c[0, 0])]), 1)
    assert_allclose(m.h, num, atol=1e-8)


def test_correct_matches_a_hand_worked_scalar_update() -> None:
    # prior var 4, measurement var 1 on state 0, innovation 5: K = 0.8, dx = 4, var 0.8
    p = np.eye(N_STATES) * 4.0
    dx = np.zeros(N_STATES)
    h = np.zeros((1, N_STATES))
    h[0, 0] = 1.0
    res = correct(p, dx, Measurement("x", np.array([5.0]), h, np.array([[1.0]])), 5.0)
    assert res.accepted and math.isclose(res.nis, 5.0)
    assert math.isclose(dx[0], 4.0) and math.isclose(p[0, 0], 0.8)
    # a 6-sigma innovation is gated and leaves dx and P alone
    res = correct(
        p, dx, Measurement("x", np.array([4.0 + 6.0 * math.sqrt(1.8)]), h, np.array([[1.0]])), 5.0
    )
    assert not res.accepted and math.isclose(dx[0], 4.0) and math.isclose(p[0, 0], 0.8)


def test_gate_is_the_5_sigma_tail() -> None:
    assert math.isclose(nis_gate(5.0, 1), 25.0, rel_tol=1e-9)
    assert 25.0 < nis_gate(5.0, 2) < nis_gate(5.0, 3) < 40.0


@pytest.mark.parametrize(("samples", "atol"), [(10, 1e-4), (21, 1e-3)])
def test_interval_transition_equals_per_sample_product(samples: int, atol: float) -> None:
    """Phi from the IMU sums over 10 samples (50 ms) and over a 10 Hz receiver's epoch
    interval (21 samples, 0.1 s: the covariance step) vs the product of per-sample Phis."""
    dt = 4.0 / 819.2
    rng = np.random.default_rng(0)
    imu = [
        (
            np.array([0.0, 0.0, 0.5]) + 0.01 * rng.standard_normal(3),
            np.array([1.0, 1.5, -9.8]) + 0.2 * rng.standard_normal(3),
        )
        for _ in range(samples)
    ]
    per_sample, interval = Strapdown(C_BN), Strapdown(C_BN)
    phi_steps = np.eye(N_STATES)
    for w, f in imu:
        per_sample.propagate(w, f, dt)
        phi_steps = transition_matrix(*per_sample.take_interval()) @ phi_steps
        interval.propagate(w, f, dt)
    phi_interval = transition_matrix(*interval.take_interval())
    # differences are O(w T) of the couplings: 0.5 rad/s * 50 ms rotates C_bn by 1.4 deg.
    # Measured 5.3e-5 at 50 ms (1 % of the term), 4.0e-4 at 0.1 s (0.8 % of Fv G / 2, 0.05)
    assert_allclose(phi_interval, phi_steps, atol=atol)


def test_strapdown_at_rest_stays_put_and_level() -> None:
    c0 = dcm_from_rpy(0.02, -0.01, 1.0)
    ins = Strapdown(c0)
    f_b = c0.T @ np.array([0.0, 0.0, -9.80665])
    for _ in range(2048):  # 10 s
        ins.propagate(np.zeros(3), f_b, 4.0 / 819.2)
    assert_allclose(ins.v_ned_mps, 0.0, atol=1e-9)
    assert_allclose(ins.p_ned_m, 0.0, atol=1e-8)
    assert_allclose(ins.c_bn, c0, atol=1e-12)


def test_predict_keeps_p_symmetric_positive_definite() -> None:
    p = np.diag(np.full(N_STATES, 1e-4))
    phi = transition_matrix(0.05, np.array([0.1, 0.0, -0.49]), 0.05 * C_BN)
    q_c = np.full(N_STATES, 1e-6)
    for _ in range(1000):
        predict(p, phi, q_c, 0.05)
    assert np.array_equal(p, p.T) and np.linalg.eigvalsh(p)[0] > 0.0


def test_attitude_error_inverts_the_reset() -> None:
    phi = np.array([0.01, -0.02, 0.03])
    assert_allclose(attitude_error(exp_so3(phi) @ C_BN, C_BN), phi, atol=1e-12)


@pytest.mark.parametrize("dof", [1, 2, 3, 4, 5, 6])
@pytest.mark.parametrize("gate_sigma", [2.0, 3.0, 5.0])
def test_nis_gate_matches_scipy(dof: int, gate_sigma: float) -> None:
    """The EKF's chi-square gate without scipy on the ECU: scipy's value to 1e-12."""
    from scipy.stats import chi2, norm

    expected = float(chi2.isf(2.0 * norm.sf(gate_sigma), dof))
    assert nis_gate(gate_sigma, dof) == pytest.approx(expected, rel=1e-12)
