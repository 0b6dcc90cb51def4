"""The receiver's velocity noise as its fixes show it (gateway/estimation/gnss_error.py,
``VelocityNoise``): what both engines weigh RTK fixed velocities with where it is beyond
`gnss_vel_sigma_mps`. Fed as the observer feeds it: half the square of each component of a
velocity difference over one epoch (two fixes' white errors)."""

from __future__ import annotations

import numpy as np
import pytest

from gateway.estimation.gnss_error import VELOCITY_NOISE_TAU_S, VelocityNoise

EPOCH_S = 0.1


def _fed(sigma_mps: float, seconds: float, seed: int = 1) -> VelocityNoise:
    noise = VelocityNoise(0.02)
    v = np.random.default_rng(seed).normal(0.0, sigma_mps, (round(seconds / EPOCH_S), 2))
    for dv_n, dv_e in np.diff(v, axis=0):
        noise.add(0.5 * dv_n * dv_n, 0.5 * dv_e * dv_e, EPOCH_S)
    return noise


@pytest.mark.parametrize("sigma_mps", [0.05, 0.10])
def test_a_noisier_receiver_is_measured(sigma_mps: float) -> None:
    """Within 10 % (the model's share taken out: 1.5 % at 5 cm/s) after 30 s of epochs."""
    assert _fed(sigma_mps, 30.0).sigma_mps() == pytest.approx(sigma_mps, rel=0.1)


def test_a_receiver_as_configured_keeps_the_config() -> None:
    """2 cm/s and a tenth more (what lever arms and the IMU add) read as the config's."""
    for seed in range(5):
        assert _fed(0.02, 60.0, seed).sigma_mps() == 0.02
        assert _fed(0.022, 60.0, seed).sigma_mps() == 0.02


def test_outliers_and_outages_count_as_one_clipped_epoch() -> None:
    """A glitch's 3 m/s and an epoch after a 60 s outage move the measurement by one
    epoch's share of 4 sigma each."""
    noise = _fed(0.02, 30.0)
    noise.add(4.5, 4.5, EPOCH_S)  # a 3 m/s difference
    noise.add(4.5, 4.5, 60.0)
    assert noise.sigma_mps() == 0.02
    many = _fed(0.02, 30.0)
    for _ in range(round(VELOCITY_NOISE_TAU_S / EPOCH_S)):
        many.add(4.5, 4.5, EPOCH_S)  # for 10 s: no outlier, the receiver
    assert many.sigma_mps() > 0.05
