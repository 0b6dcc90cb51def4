"""The EKF's fast path computes the same bits as the plain numpy forms it replaces (issue 14).

The INS history applies corrections when a row is read (:mod:`gateway.estimation.ekf.ins_history`);
here it is checked against a history that shifts every row at once, and the in-place
symmetrisation of P against ``0.5 * (P + P^T)`` of the full expressions.
"""

from __future__ import annotations

import math

import numpy as np

from gateway.estimation.attitude import exp_so3
from gateway.estimation.ekf.error_state import N_STATES, Measurement, correct, predict
from gateway.estimation.ekf.ins_history import ROW_C, ROW_P, ROW_T, ROW_V, ROW_W, InsHistory

Array = np.ndarray


class EagerHistory:
    """The reference: every row kept as numpy and shifted at once."""

    def __init__(self, n: int) -> None:
        self.rows = np.zeros((0, 19))
        self.n = n

    def append(self, row: tuple[float, ...]) -> None:
        self.rows = np.vstack((self.rows, row))[-self.n :]

    def shift(self, dp: Array, dv: Array, rot: Array, t_e: float = math.inf) -> None:
        rows = self.rows
        rows[:, ROW_P] += dp + np.maximum(rows[:, ROW_T] - t_e, 0.0)[:, None] * dv
        rows[:, ROW_V] += dv
        rows[:, ROW_C] = (rot @ rows[:, ROW_C].reshape(-1, 3, 3)).reshape(-1, 9)

    def at(self, t_s: float) -> Array | None:
        rows = self.rows
        if not rows[0, ROW_T] <= t_s <= rows[-1, ROW_T]:
            return None
        i = int(np.searchsorted(rows[:, ROW_T], t_s))
        if i == 0:
            return rows[0].copy()
        a, b = rows[i - 1], rows[i]
        u = (t_s - a[ROW_T]) / (b[ROW_T] - a[ROW_T])
        return a + u * (b - a)

    def mean_rate(self, t_s: float, half_width_s: float) -> Array:
        rows = self.rows
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
            lazy.shift(dp, dv, rot, t_e)
            eager.shift(dp, dv, rot, t_e)
        for t_s in (t - float(rng.uniform(0.0, 0.2)), float(eager.rows[0, ROW_T]), t, t + 1.0):
            want, got = eager.at(t_s), lazy.at(t_s)
            if want is None or got is None:
                assert want is None and got is None
            else:
                assert np.array_equal(want, got)
            assert np.array_equal(lazy.mean_rate(t_s, 0.02), eager.mean_rate(t_s, 0.02))
        assert lazy.oldest_s() == eager.rows[0, ROW_T]
        assert lazy.full == (len(eager.rows) == n)


def _spd(rng: np.random.Generator) -> Array:
    a = rng.normal(size=(N_STATES, N_STATES))
    return a @ a.T + np.eye(N_STATES)


def test_covariance_updates_equal_the_full_expressions() -> None:
    rng = np.random.default_rng(4)
    for _ in range(20):
        p = _spd(rng)
        phi = np.eye(N_STATES) + 0.01 * rng.normal(size=(N_STATES, N_STATES))
        q_c, t_s = rng.uniform(0.0, 1.0, N_STATES), 0.05
        want = phi @ p @ phi.T + 0.5 * t_s * ((phi * q_c) @ phi.T + np.diag(q_c))
        predict(p, phi, q_c, t_s)
        assert np.array_equal(p, 0.5 * (want + want.T))

        h, r = rng.normal(size=(2, N_STATES)), np.diag(rng.uniform(1.0, 2.0, 2))
        m = Measurement("x", 0.1 * rng.normal(size=2), h, r)
        k = p @ h.T @ np.linalg.inv(h @ (p @ h.T) + r)
        ikh = np.eye(N_STATES) - k @ h
        want = ikh @ p @ ikh.T + k @ r @ k.T
        assert correct(p, np.zeros(N_STATES), m, 1e3).accepted
        assert np.array_equal(p, 0.5 * (want + want.T))
