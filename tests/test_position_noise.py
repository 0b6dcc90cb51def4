"""The white part of the receiver's position noise as its fixes show it
(gateway/estimation/gnss_error.py, ``PositionNoise``, fed by ``GnssTrack`` with each short
step's miss of its velocities' trapezoid and by the EKF with its innovations' changes), and
the split of a fix's sigma that both engines take from it (``split_fix_variance``)."""

from __future__ import annotations

import numpy as np
import pytest

from gateway.estimation.gnss_error import PositionNoise, split_fix_variance
from gateway.estimation.gnss_track import GnssTrack

SIGMA_NE_M = (0.02, 0.02)  # GGA's default RTK fixed sigma per axis
RTK_FIXED = 4
RTK_FLOAT = 5


def _driven(
    track: GnssTrack, white_m: float, seconds: float, rate_hz: float = 10.0, seed: int = 1,
    wander_m: float = 0.0, quality: int = RTK_FIXED, t0_s: float = 0.0, sigma_h_m: float = 0.028,
) -> GnssTrack:  # fmt: skip
    """``track`` fed a straight drive east at 3 m/s: positions with ``white_m`` white noise
    and a wander of ``wander_m`` (Gauss-Markov, 30 s), velocities with 2 cm/s; the fixes'
    stated horizontal sigma ``sigma_h_m``."""
    rng = np.random.default_rng(seed)
    n, dt = round(seconds * rate_hz), 1.0 / rate_hz
    a = np.exp(-dt / 30.0)
    wander = np.zeros(2)
    for k in range(n):
        t = t0_s + k * dt
        wander = a * wander + wander_m * np.sqrt(1.0 - a * a) * rng.standard_normal(2)
        p = np.array([0.0, 3.0 * t]) + wander + white_m * rng.standard_normal(2)
        v = np.array([0.0, 3.0]) + 0.02 * rng.standard_normal(2)
        track.add(
            t, (float(p[0]), float(p[1])), (float(v[0]), float(v[1])), sigma_h_m, None, 0.0, quality
        )
    return track


@pytest.mark.parametrize("white_m", [0.02, 0.05])
def test_white_positions_are_measured(white_m: float) -> None:
    """Within 10 % after 30 s of 10 Hz epochs (the velocities' noise adds 0.1 cm)."""
    share = _driven(GnssTrack(), white_m, 30.0).noise.white_share(RTK_FIXED, SIGMA_NE_M)
    assert share * SIGMA_NE_M[0] == pytest.approx(white_m, rel=0.1)


def test_an_rtk_solution_that_wanders_keeps_the_configured_share() -> None:
    """1 cm of wander and 2 mm of white: the steps show millimetres, under the 0.3 share
    (a simulated `short` run's 1 cm wander: 0.12 in both engines)."""
    for seed in range(3):
        track = _driven(GnssTrack(), 0.002, 60.0, wander_m=0.01, seed=seed)
        assert track.noise.white_share(RTK_FIXED, SIGMA_NE_M) < 0.2


def test_slow_receivers_steps_are_not_measured() -> None:
    """At 1 Hz a step's miss is mostly the velocities' noise and the turn: not measured."""
    track = _driven(GnssTrack(), 0.05, 60.0, rate_hz=1.0)
    assert track.noise.white_share(RTK_FIXED, SIGMA_NE_M) == 0.0


def test_each_solution_has_its_own_and_a_jump_is_no_noise() -> None:
    """Float's 15 cm steps say nothing of fixed's; a 0.5 m jump (not taken as a step) and
    a step from the last fixed epoch to the first float one leave both as they were."""
    track = _driven(GnssTrack(), 0.005, 20.0)
    fixed = track.noise.white_share(RTK_FIXED, SIGMA_NE_M)
    track.add(20.0, (0.5, 60.0), (0.0, 3.0), 0.028, None, 0.0, RTK_FIXED)
    assert track.jumped_at_s == 20.0
    _driven(track, 0.15, 20.0, quality=RTK_FLOAT, t0_s=20.1, sigma_h_m=0.28)
    assert track.noise.white_share(RTK_FIXED, SIGMA_NE_M) == fixed
    assert track.noise.white_share(RTK_FLOAT, (0.2, 0.2)) == pytest.approx(0.75, rel=0.15)


def test_the_split_takes_the_seen_white_and_keeps_the_configured_wander() -> None:
    assert split_fix_variance(0.02, 0.3, 0.1) == pytest.approx((0.09 * 4e-4, 0.91 * 4e-4))
    assert split_fix_variance(0.02, 0.3, 1.2) == pytest.approx((1.44 * 4e-4, 0.91 * 4e-4))


def test_samples_that_average_below_zero_are_no_white_noise() -> None:
    """The EKF's samples are half an innovation change's square less the filter's share of
    it: an RTK receiver that barely moves from epoch to epoch averages below zero, which is
    no white noise (its square root took the engine down on `float-spells` seed 841)."""
    noise = PositionNoise()
    for k in range(50):
        noise.add(RTK_FIXED, (-1e-5 + 1e-6 * (k % 3), -2e-5), 0.1, 1e-4)
    assert noise.white_share(RTK_FIXED, SIGMA_NE_M) == 0.0
    noise.add(RTK_FIXED, (1.0, 1.0), 5.0, 1e-4)  # 5 s of 10: clipped at 4 sigma of 1 cm
    assert noise.white_share(RTK_FIXED, SIGMA_NE_M) == pytest.approx(
        np.sqrt(0.5 * 16e-4) / 0.02, rel=0.02
    )
