"""GnssTrack: a jump in the receiver's own track tells a glitch from an engine that is off."""

from __future__ import annotations

from gateway.estimation.gnss_track import GnssTrack


def drive(track: GnssTrack, t0: float, n: int, north0: float = 0.0) -> float:
    """n epochs at 10 Hz driving east at 3 m/s from ``north0``; returns the next time."""
    for k in range(n):
        t = t0 + 0.1 * k
        track.add(t, (north0, 3.0 * t), (0.0, 3.0), 0.02)
    return t0 + 0.1 * n


def test_a_continuous_track_never_jumps_and_a_step_does() -> None:
    track = GnssTrack()
    t = drive(track, 0.0, 50)
    assert track.jumped_at_s is None
    drive(track, t, 10, north0=5.0)  # 5 m north from one epoch to the next
    assert track.jumped_at_s == t and track.jumped_since(t) and not track.jumped_since(t + 0.05)


def test_a_rejected_continuous_track_resets_after_reset_rejections() -> None:
    """Continuous track, engine off: reset after 20 rejections, not after 10 s."""
    track = GnssTrack()
    t = drive(track, 0.0, 50)
    for k in range(20):
        assert not track.reset_due(t + 0.1 * k, 20, 10.0)
        track.rejected(t + 0.1 * k)
    assert track.reset_due(t + 2.0, 20, 10.0)
    track.accepted()
    assert not track.reset_due(t + 2.1, 20, 10.0) and track.rejecting_since_s is None


def test_rejections_that_began_with_a_jump_hold_for_position_reset_s() -> None:
    track = GnssTrack()
    t = drive(track, 0.0, 50)
    for k in range(100):  # a 5 m glitch, rejected epoch after epoch
        tk = t + 0.1 * k
        track.add(tk, (5.0, 3.0 * tk), (0.0, 3.0), 0.02)
        assert not track.reset_due(tk, 20, 10.0)
        track.rejected(tk)
    assert track.reset_due(t + 10.0, 20, 10.0)  # it stayed: the GNSS moved for good
