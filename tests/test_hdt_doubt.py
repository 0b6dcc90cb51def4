"""An HDT the courses contradicted: used again only once the courses agree with it."""

from __future__ import annotations

import math

import numpy as np

from gateway.estimation.hdt_doubt import HdtDoubt

DEG = math.pi / 180.0
SIGMA = math.hypot(0.4, 0.2) * DEG  # a course at 3 m/s and an HDT, 1-sigma


def fed(doubt: HdtDoubt, offsets_deg: np.ndarray, t0_s: float = 0.0) -> list[bool]:
    """admits() before each epoch at 10 Hz, each epoch's HDT less course then added."""
    out = []
    for k, off in enumerate(offsets_deg):
        out.append(doubt.admits())
        doubt.add_course(t0_s + 0.1 * k, off * DEG, SIGMA, 0.0, 0.1)
    return out


def test_an_hdt_is_used_until_doubted_and_again_once_the_courses_agree_for_2_s() -> None:
    rng = np.random.default_rng(3)
    doubt = HdtDoubt()
    assert doubt.admits()
    doubt.add_course(0.0, 5.0 * DEG, SIGMA, 0.0, 0.1)  # not doubted: no evidence kept
    doubt.doubt()
    agreeing = rng.normal(0.0, SIGMA / DEG, 40)
    admitted = fed(doubt, agreeing)
    assert not any(admitted[:21])  # the courses span 2 s from the 21st epoch on
    assert admitted[22] and all(admitted[22:])


def test_a_drifting_hdt_stays_doubted() -> None:
    """0.2 deg/s away from the courses: its 5 s mean never within 2 sigma of them."""
    rng = np.random.default_rng(4)
    doubt = HdtDoubt()
    doubt.doubt()
    t = np.arange(300) * 0.1
    drifting = 1.0 + 0.2 * t + rng.normal(0.0, SIGMA / DEG, len(t))
    assert not any(fed(doubt, drifting))
    doubt.doubt()  # a new doubt forgets the evidence so far
    assert not any(fed(doubt, rng.normal(0.0, SIGMA / DEG, 15), t0_s=40.0))
