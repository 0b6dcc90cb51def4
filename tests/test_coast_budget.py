"""The observer's open-loop error budget against a Monte Carlo of the gyro's angular random
walk: the terms added for it are the spread of that walk, not a tuning."""

from __future__ import annotations

import math

import numpy as np
import pytest

from drivers.units import GRAVITY_MPS2
from gateway.estimation.observer.coast_budget import CoastBudget

ARW = math.radians(2.0) / 60.0  # ADIS16334: 2 deg/sqrt(h), in rad/sqrt(s)
DT, T = 0.01, 20.0


def _walks(n: int = 4000) -> np.ndarray:
    """Tilt random walks theta(t) = ARW W(t), shape (n, steps)."""
    rng = np.random.default_rng(7)
    return np.cumsum(ARW * math.sqrt(DT) * rng.standard_normal((n, round(T / DT))), axis=1)


def test_the_along_track_arw_term_is_the_spread_of_the_tilt_walk_twice_integrated() -> None:
    """Forward acceleration error g theta(t), integrated twice: its spread after 20 s is the
    budget's ARW term (2.3 m, as large as a 0.01 deg/s gyro bias's g b t^3 / 6)."""
    theta = _walks()
    position = np.cumsum(np.cumsum(GRAVITY_MPS2 * theta, axis=1) * DT, axis=1) * DT
    budget = CoastBudget(0.0, 0.0, 0.0, 0.0, ARW, 0.0, 0.0)
    assert budget.sigma_h_m(T, 0.0) == pytest.approx(float(position[:, -1].std()), rel=0.05)
    assert budget.sigma_h_m(T, 0.0) == pytest.approx(2.27, abs=0.02)
