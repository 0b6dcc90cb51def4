"""The weighted least-squares line by running sums (gateway.estimation.line_fit)."""

import numpy as np
import pytest

from gateway.estimation.line_fit import LineSums


def test_the_sums_give_numpy_s_weighted_line_and_the_slope_s_variance() -> None:
    rng = np.random.default_rng(5)
    x = np.linspace(0.0, 10.0, 40)
    sigma = rng.uniform(0.5, 2.0, x.size)
    y = 1.5 - 0.3 * x + sigma * rng.standard_normal(x.size)
    sums = LineSums()
    for xi, yi, si in zip(x, y, sigma, strict=True):
        sums.add(1.0 / si**2, float(xi), float(yi))
    a, b = sums.line()
    slope, intercept = np.polyfit(x, y, 1, w=1.0 / sigma)  # polyfit weighs residuals by w
    assert (a, b) == pytest.approx((intercept, slope), rel=1e-9)
    design = np.column_stack((np.ones_like(x), x)) / sigma[:, None]
    assert sums.w / sums.det == pytest.approx(np.linalg.inv(design.T @ design)[1, 1], rel=1e-9)


def test_no_spread_of_x_has_no_slope() -> None:
    sums = LineSums()
    sums.add(1.0, 2.0, 1.0)
    sums.add(3.0, 2.0, 5.0)
    assert sums.det == 0.0
