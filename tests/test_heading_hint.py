"""The heading a restarted engine inherits (gateway/estimation/heading_hint.py)."""

from __future__ import annotations

import math

from gateway.estimation.heading_hint import MAX_BOUND_RAD, MAX_YAW_RATE_RPS, HeadingHint


def test_the_heading_is_carried_over_the_gap_with_its_rate_and_bounded_by_the_gap() -> None:
    hint = HeadingHint.over_gap(1.0, 0.2, 1.3)
    assert hint is not None
    assert math.isclose(hint.yaw_rad, 1.26)
    assert math.isclose(hint.bound_rad, MAX_YAW_RATE_RPS * 1.3)


def test_no_hint_over_a_gap_the_vehicle_may_have_turned_too_far_in_or_a_clock_step_back() -> None:
    longest = MAX_BOUND_RAD / MAX_YAW_RATE_RPS  # about 2.1 s
    assert HeadingHint.over_gap(1.0, 0.0, 0.99 * longest) is not None
    assert HeadingHint.over_gap(1.0, 0.0, 1.01 * longest) is None
    assert HeadingHint.over_gap(1.0, 0.0, -2.0) is None


def test_forward_is_a_course_within_90_deg_of_the_heading_carried_on_by_the_platform() -> None:
    hint = HeadingHint(yaw_rad=0.5, bound_rad=0.6)  # the platform levelled at yaw 0
    hint.turn(0.1, 2.0)  # 0.2 rad of turn before it levelled: true heading 0.7 at yaw 0
    platform_yaw = -0.3  # it has turned since: true heading 0.4 now
    assert hint.forward(0.4 + math.radians(80.0), platform_yaw)
    assert not hint.forward(0.4 + math.radians(100.0), platform_yaw)
    assert not hint.forward(0.4 + math.pi, platform_yaw)  # reversing: the course behind
    assert hint.forward(0.4 - math.radians(80.0) + 2.0 * math.pi, platform_yaw)  # wraps
