"""HdtScreen: a dual-antenna heading's jumps against the gyro's turn."""

from __future__ import annotations

import math

import numpy as np

from gateway.estimation.observer.hdt_screen import HdtScreen
from gateway.estimation.observer.observer_config import ObserverConfig

DEG = math.pi / 180.0
BIAS_SIGMA_RPS = 0.006 * DEG  # the z-gyro bias's 1-sigma once learnt
SIGMA_PSI_RAD = 0.3 * DEG  # the heading channel's 1-sigma on course over ground


def headland(t: float) -> float:
    """Heading (rad): straight north, a 180 deg turn at 0.3 rad/s from 20 s, straight south."""
    return min(max(t - 20.0, 0.0) * 0.3, math.pi)


def feed(screen: HdtScreen, hdt_off_rad: float, times: np.ndarray, seed: int) -> list[bool]:
    """HDT with 0.15 deg of noise (and ``hdt_off_rad`` more) against a heading the gyro
    and course over ground hold to 0.1 deg; no corrections applied (hc = 0)."""
    rng = np.random.default_rng(seed)
    used = []
    for t in times:
        psi = headland(float(t))
        psi_hat = psi + 0.1 * DEG * rng.standard_normal()
        hdt = psi + hdt_off_rad + 0.15 * DEG * rng.standard_normal()
        used.append(screen.screen(float(t), psi_hat, hdt, 0.0, BIAS_SIGMA_RPS, SIGMA_PSI_RAD))
    return used


def test_a_working_hdt_through_a_headland_is_always_used() -> None:
    screen = HdtScreen(ObserverConfig())
    assert all(feed(screen, 0.0, np.arange(0.0, 60.0, 0.1), seed=1))
    assert screen.rejected == 0


def test_an_hdt_5_deg_off_is_not_used_through_a_headland_until_it_comes_back() -> None:
    """The step is a jump against the gyro; a minute later, after a 180 deg turn, the gyro
    alone (1.8 deg of scale factor, 1.8 deg of its bias's 5 sigma) would let it pass: the
    heading held meanwhile does not."""
    screen = HdtScreen(ObserverConfig())
    assert all(feed(screen, 0.0, np.arange(0.0, 10.0, 0.1), seed=2))
    assert not any(feed(screen, 5.0 * DEG, np.arange(10.0, 80.0, 0.1), seed=3))
    assert screen.rejected == 700 and "dual-antenna" in screen.text(80.0)
    back = feed(screen, 0.0, np.arange(80.0, 90.0, 0.1), seed=4)
    assert back[0] and all(back)


def test_after_a_restart_the_next_hdt_is_the_new_reference() -> None:
    """The gyro's integral broken (an IMU gap bridged, the heading set directly): the next
    HDT, however far from the last, is taken; it is judged against from then on."""
    screen = HdtScreen(ObserverConfig())
    feed(screen, 0.0, np.arange(0.0, 5.0, 0.1), seed=5)
    assert not feed(screen, 5.0 * DEG, np.array([5.0]), seed=6)[0]
    screen.restart(5.05)
    assert all(feed(screen, 5.0 * DEG, np.arange(5.1, 10.0, 0.1), seed=7))
    assert not feed(screen, 0.0, np.array([10.0]), seed=8)[0]


def test_epochs_before_a_restart_are_not_judged() -> None:
    """Epochs arrive late (latency, 20 Hz): the one after the heading was set directly still
    has the platform heading from before it in the history; judged, it became the reference
    and every HDT after it was rejected."""
    screen = HdtScreen(ObserverConfig())
    screen.restart(1.12)  # set at IMU time 1.12, the epochs of 1.05 and 1.10 still to come
    assert feed(screen, 20.0 * DEG, np.array([1.05, 1.10]), seed=9) == [True, True]
    assert all(feed(screen, 0.0, np.arange(1.15, 10.0, 0.05), seed=10))
