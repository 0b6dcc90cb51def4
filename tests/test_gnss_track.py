"""GnssTrack: a jump in the receiver's own track tells a glitch from an engine that is off."""

from __future__ import annotations

import numpy as np

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


def test_a_decimetre_step_of_a_fixed_track_is_a_jump() -> None:
    """A wrong RTK ambiguity moves a fixed (1 cm) track 0.3 m: a jump (with a 0.5 m floor it
    was a continuous track, and the engines took it after 2 s instead of 10)."""
    track = GnssTrack()
    t = drive(track, 0.0, 50)
    drive(track, t, 5, north0=0.3)
    assert track.jumped_at_s == t


def test_a_tight_turn_at_1_hz_is_no_jump() -> None:
    """6 m/s on a 10 m radius (0.6 rad/s), one epoch a second: the trapezoid of the two
    velocities misses the arc by 18 cm, beyond the floor and 5 sigma of a 1 cm track."""
    track = GnssTrack()
    rng = np.random.default_rng(3)
    u, w = 6.0, 0.6
    for k in range(60):
        t = float(k)
        p = (u / w * np.sin(w * t) + 0.01 * rng.standard_normal(),
             u / w * (1.0 - np.cos(w * t)) + 0.01 * rng.standard_normal())  # fmt: skip
        track.add(t, p, (u * np.cos(w * t), u * np.sin(w * t)), 0.01)
    assert track.jumped_at_s is None


def test_a_height_step_is_a_jump_and_a_crest_is_not() -> None:
    """NMEA has no vertical velocity: the height is extrapolated from the last two. Over a
    crest (3 m/s on a 10 m vertical radius, 0.9 m/s^2) at 10 Hz the trend holds to a few mm;
    GGA's altitude 5 m off for one epoch is a jump."""
    track = GnssTrack()
    for k in range(100):
        t = 0.1 * k
        down = 10.0 * (1.0 - np.cos(0.3 * (t - 5.0)))  # highest at 5 s: a crest
        track.add(t, (0.0, 3.0 * t), (0.0, 3.0), 0.014, down, 0.025)
    assert track.jumped_at_s is None
    track.add(10.0, (0.0, 30.0), (0.0, 3.0), 0.014, -5.0, 0.025)
    assert track.jumped_at_s == 10.0


def test_epochs_going_back_in_time_are_a_jump() -> None:
    """The receiver's UTC stepping back 1 s: its epochs are not a track to reset to after 2 s
    as if the engine were off (both engines did, and sent positions 3 m off, NAVIGATING)."""
    track = GnssTrack()
    t = drive(track, 0.0, 50)
    track.add(t - 0.9, (0.0, 3.0 * t), (0.0, 3.0), 0.014)
    assert track.jumped_at_s == t - 0.9


def test_a_fixed_track_drifting_2_cm_s_is_caught_within_the_window_and_noise_is_not() -> None:
    """Positions leaving their own velocity by 2 mm a step (2 cm/s at 10 Hz: multipath, a
    wrong fix as the geometry turns): no step is a jump, the window's sum is. The same
    track with the receiver's noise (1 cm positions, 2 cm/s velocity) never is."""
    rng = np.random.default_rng(5)
    clean, drifting = GnssTrack(), GnssTrack()
    flagged_at = None
    for k in range(300):
        t = 0.1 * k
        v = (0.02 * rng.standard_normal(), 3.0 + 0.02 * rng.standard_normal())
        p = (0.01 * rng.standard_normal(), 3.0 * t + 0.01 * rng.standard_normal())
        clean.add(t, p, v, 0.014, quality=4)
        assert not clean.drifting
        drifting.add(t, (p[0] + 0.02 * max(0.0, t - 10.0), p[1]), v, 0.014, quality=4)
        if drifting.drifting and flagged_at is None:
            flagged_at = t
    assert flagged_at is not None and 10.0 < flagged_at < 20.0, flagged_at


def test_an_epoch_without_a_velocity_leaves_the_drift_test_seeing() -> None:
    """A first epoch with no course (no velocity) and a solution drifting 5 cm/s from the
    start: caught a step later than with the velocity there (that step is not one). It had
    a NaN miss, which stayed in the window's sums for its 10 s: blind until 10.2 s."""
    flagged = []
    for first_v in ((0.0, 3.0), None):
        track = GnssTrack()
        track.add(0.0, (0.0, 0.0), first_v, 0.014, quality=4)
        t = 0.1
        while not track.drifting and t < 20.0:
            track.add(t, (0.05 * t, 3.0 * t), (0.0, 3.0), 0.014, quality=4)
            t += 0.1
        flagged.append(round(t, 1))
    assert flagged[0] < 10.0 and flagged[1] <= flagged[0] + 0.15, flagged  # one step less


def test_a_swaying_mast_at_1_hz_and_a_new_solution_are_no_drift() -> None:
    """1 Hz epochs of a 3 m mast rocking at 0.7 Hz, 0.3 m/s: the antenna's velocity,
    sampled once a second, misses its mean by decimetres over each step, and the trapezoid
    with it, while the positions are exact. Then RTK float ends 0.3 m off and fixed
    resumes: the step between the solutions is not counted."""
    track = GnssTrack()
    w = 2.0 * np.pi * 0.7
    for k in range(60):
        t = float(k)
        p = (0.0, 3.0 * t - 0.3 / w * np.cos(w * t))
        track.add(t, p, (0.0, 3.0 + 0.3 * np.sin(w * t)), 0.014, quality=4)
        assert not track.drifting
    track = GnssTrack()
    for k in range(100):
        t = 0.1 * k
        track.add(t, (0.3, 3.0 * t), (0.0, 3.0), 0.21, quality=5)
    for k in range(100, 200):
        t = 0.1 * k
        track.add(t, (0.0, 3.0 * t), (0.0, 3.0), 0.014, quality=4)
        assert not track.drifting


def test_a_drift_stays_caught_through_noise_and_a_headland_and_is_never_reset_to() -> None:
    """A fixed solution drifting 2.5 cm/s with the receiver's noise (1 cm positions, 2 cm/s
    velocity), seen; then a headland at 0.3 m/s for 5 s (courses at walking pace are
    filtered: no drift test) and driving on. The drift stays caught (its misses, near the
    bound, cross it back and forth with the noise), and the engine, rejecting it, does not
    reset to it however long (the window used to restart at the headland, and the engines to
    take the drifting fix at each dip and reset to it after 10 s: field seed 3 sent 49 cm
    off, NAVIGATING). When the drift stops, the reset comes within the window."""
    rng = np.random.default_rng(7)
    track = GnssTrack()
    north, t, flagged = 0.0, 0.0, []
    east = 0.0
    for k in range(600):
        t = 0.1 * k
        speed = 0.3 if 20.0 <= t < 25.0 else 3.0
        east += speed * 0.1
        north += 0.0025 if 5.0 <= t < 45.0 else 0.0  # 2.5 cm/s for 40 s, then it holds
        p = (north + 0.01 * rng.standard_normal(), east + 0.01 * rng.standard_normal())
        v = (0.02 * rng.standard_normal(), speed + 0.02 * rng.standard_normal())
        track.add(t, p, v, 0.014, quality=4)
        flagged.append(track.drifting)
        if track.rejecting_since_s is not None or track.drifting:
            if track.reset_due(t, 20, 10.0):
                break
            track.rejected(t)
    first = flagged.index(True)
    assert 0.1 * first < 15.0  # seen within the window
    assert all(flagged[first:450])  # through the headland, until the drift stops at 45 s
    assert not track.drifting and 45.0 < t <= 55.0  # reset once the drift left the window


def test_a_stop_ends_a_drift_s_window_after_drift_max_age() -> None:
    """Evidence of a drift does not outlive a long stop: after 30 s at rest the window is
    empty, so positions after it are judged on their own."""
    track = GnssTrack()
    north = 0.0
    for k in range(200):  # drifting 3 cm/s from 5 s: caught
        t = 0.1 * k
        north += 0.003 if t >= 5.0 else 0.0
        track.add(t, (north, 3.0 * t), (0.0, 3.0), 0.014, quality=4)
    assert track.drifting
    for k in range(200, 520):  # at rest for 32 s
        track.add(0.1 * k, (north, 60.0), (0.0, 0.0), 0.014, quality=4)
    assert not track.drifting and track.drift_m == 0.0
