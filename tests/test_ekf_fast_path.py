"""The EKF's fast path computes what the plain forms it replaces compute (issue 14).

The INS history applies corrections when a row is read (:mod:`gateway.estimation.ekf.ins_history`);
here it is checked, bit for bit, against a history that shifts every row at once. The
covariance prediction and correction, the transition matrix and the small inverse are
checked against the textbook expressions, to rounding.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.testing import assert_allclose

from gateway.estimation.attitude import Mat9, exp_so3, skew, to_mat9
from gateway.estimation.ekf.error_state import (
    N_STATES,
    Measurement,
    correct,
    inverse_small,
    predict,
    transition_matrix,
)
from gateway.estimation.ekf.ins_history import ROW_T, ROW_W, InsHistory, Shift

Array = np.ndarray


class EagerHistory:
    """The reference: every row kept and shifted at once."""

    def __init__(self, n: int) -> None:
        self.rows: list[list[float]] = []
        self.n = n

    def append(self, row: tuple[float, ...]) -> None:
        self.rows = [*self.rows, list(row)][-self.n :]

    def shift(self, dp: Array, dv: Array, rot: Mat9, t_e: float = math.inf) -> None:
        correction = Shift(tuple(dp.tolist()), tuple(dv.tolist()), rot, t_e)
        for row in self.rows:
            correction.apply(row)

    def at(self, t_s: float) -> Array | None:
        rows = np.array(self.rows)
        if not rows[0, ROW_T] <= t_s <= rows[-1, ROW_T]:
            return None
        i = int(np.searchsorted(rows[:, ROW_T], t_s))
        if i == 0:
            return rows[0].copy()
        a, b = rows[i - 1], rows[i]
        u = (t_s - a[ROW_T]) / (b[ROW_T] - a[ROW_T])
        return a + u * (b - a)

    def mean_rate(self, t_s: float, half_width_s: float) -> Array:
        rows = np.array(self.rows)
        near = np.abs(rows[:, ROW_T] - t_s) <= half_width_s
        return rows[near, ROW_W].mean(axis=0) if near.any() else rows[-1, ROW_W].copy()


def _row(rng: np.random.Generator, t: float) -> tuple[float, ...]:
    c = exp_so3(rng.normal(size=3)).reshape(9)
    return (t, *rng.normal(size=6) * 100.0, *c, *rng.normal(size=3))


def test_history_read_late_equals_history_shifted_at_once() -> None:
    rng = np.random.default_rng(3)
    n = 50
    lazy, eager = InsHistory(n), EagerHistory(n)
    t = 0.0
    for k in range(400):  # several trims of the lazy lists
        t += float(rng.uniform(0.004, 0.006))
        row = _row(rng, t)
        lazy.append(row)
        eager.append(row)
        if k % 3 == 0:
            dp, dv, rot = rng.normal(size=3), rng.normal(size=3), exp_so3(rng.normal(size=3) * 1e-3)
            t_e = t - float(rng.uniform(0.0, 0.1)) if k % 2 else math.inf
            lazy.shift(dp, dv, to_mat9(rot), t_e)
            eager.shift(dp, dv, to_mat9(rot), t_e)
        for t_s in (t - float(rng.uniform(0.0, 0.2)), float(eager.rows[0][ROW_T]), t, t + 1.0):
            want, got = eager.at(t_s), lazy.at(t_s)
            if want is None or got is None:
                assert want is None and got is None
            else:
                assert np.array_equal(want, got)
            assert np.array_equal(lazy.mean_rate(t_s, 0.02), eager.mean_rate(t_s, 0.02))
        assert lazy.oldest_s() == eager.rows[0][ROW_T]
        assert lazy.full == (len(eager.rows) == n)


def _spd(rng: np.random.Generator) -> Array:
    a = rng.normal(size=(N_STATES, N_STATES))
    return a @ a.T + np.eye(N_STATES)


def test_covariance_updates_equal_the_textbook_forms() -> None:
    """predict: Phi (P + Q T/2) Phi^T + Q T/2 is the trapezoid Phi P Phi^T + (Phi Q Phi^T +
    Q) T/2; correct: P - K (P H^T)^T is the Joseph form for the optimal gain. Equal to
    rounding (relative 1e-12 of the matrix), and exactly symmetric."""
    rng = np.random.default_rng(4)
    for _ in range(20):
        p = _spd(rng)
        phi = np.eye(N_STATES) + 0.01 * rng.normal(size=(N_STATES, N_STATES))
        q_c, t_s = rng.uniform(0.0, 1.0, N_STATES), 0.05
        want = phi @ p @ phi.T + 0.5 * t_s * ((phi * q_c) @ phi.T + np.diag(q_c))
        predict(p, phi, q_c, t_s)
        assert np.array_equal(p, p.T)
        assert_allclose(p, want, rtol=0.0, atol=1e-12 * float(np.abs(want).max()))

        for m_rows in (1, 2, 3):
            h = rng.normal(size=(m_rows, N_STATES))
            r = np.diag(rng.uniform(1.0, 2.0, m_rows))
            m = Measurement("x", 0.1 * rng.normal(size=m_rows), h, r)
            k = p @ h.T @ np.linalg.inv(h @ (p @ h.T) + r)
            ikh = np.eye(N_STATES) - k @ h
            want = ikh @ p @ ikh.T + k @ r @ k.T
            dx = np.zeros(N_STATES)
            assert correct(p, dx, m, 1e3).accepted
            assert np.array_equal(p, p.T)
            assert_allclose(p, want, rtol=0.0, atol=1e-12 * float(np.abs(want).max()))
            want_dx = k @ m.z
            assert_allclose(dx, want_dx, rtol=0.0, atol=1e-12 * float(np.abs(want_dx).max()))


def test_small_inverse_equals_numpys() -> None:
    rng = np.random.default_rng(5)
    for n in (1, 2, 3):
        for _ in range(50):
            a = rng.normal(size=(n, n)) * 10.0 ** rng.uniform(-6, 2)
            s = a @ a.T + np.eye(n) * 10.0 ** rng.uniform(-8, 0)
            assert_allclose(inverse_small(s) @ s, np.eye(n), atol=1e-9)
            assert_allclose(inverse_small(s), np.linalg.inv(s), rtol=1e-9)


def test_transition_blocks_equal_the_series() -> None:
    """The written-out blocks of Phi equal I + A + A^2/2 + A^3/6 of the averaged F."""
    rng = np.random.default_rng(6)
    for _ in range(20):
        t_s, dv, c_dt = 0.05, rng.normal(size=3), 0.05 * exp_so3(rng.normal(size=3))
        a = np.zeros((N_STATES, N_STATES))
        a[0:3, 3:6] = t_s * np.eye(3)
        a[3:6, 6:9] = -skew(dv)
        a[3:6, 9:12] = -c_dt
        a[6:9, 12:15] = -c_dt
        a2 = a @ a
        want = np.eye(N_STATES) + a + a2 / 2.0 + a2 @ a / 6.0
        want[15:18, 15:18] = 0.9 * np.eye(3)
        assert_allclose(transition_matrix(t_s, dv, c_dt, 0.9), want, rtol=0.0, atol=1e-15)
