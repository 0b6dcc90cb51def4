"""GNSS epochs on the host clock: UTC when the host follows it, else receive time - latency."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from drivers.samples import FixQuality, GnssFix
from gateway.estimation.epoch_clock import (
    DELAY_WINDOW_S,
    RECEIVE_EPOCH_SIGMA_S,
    EpochClock,
    EpochTime,
)

T_UTC0 = 1_700_000_000.0
WINDOW_EPOCHS = round(DELAY_WINDOW_S / 0.1)  # 10 Hz epochs over the delay window


def fixes(host_minus_utc_s: float, latency_s: float, jitter_s: float, n: int = 50) -> list[GnssFix]:
    """10 Hz epochs received ``latency_s`` plus up to ``jitter_s`` of serial jitter after them,
    on a host clock ``host_minus_utc_s`` ahead of UTC."""
    jitter = np.random.default_rng(3).uniform(0.0, jitter_s, n)
    return [
        GnssFix(
            t=T_UTC0 + 0.1 * k + host_minus_utc_s + latency_s + float(jitter[k]),
            t_utc=T_UTC0 + 0.1 * k,
            quality=FixQuality.RTK_FIXED,
        )
        for k in range(n)
    ]


def epochs(clock: EpochClock, stream: list[GnssFix]) -> np.ndarray:
    return np.array([clock.epoch_time(f) for f in stream])


def utc_times(stream: list[GnssFix]) -> list[float]:
    """The sentence (UTC) times of ``stream``, all of which carry one."""
    times = []
    for f in stream:
        assert f.t_utc is not None
        times.append(f.t_utc)
    return times


def test_auto_on_a_utc_host_uses_the_sentence_time_whatever_latency_is_configured() -> None:
    clock = EpochClock(EpochTime.AUTO, receiver_latency_s=0.3)
    stream = fixes(host_minus_utc_s=0.002, latency_s=0.068, jitter_s=0.01)
    assert np.array_equal(epochs(clock, stream), utc_times(stream))
    assert clock.host_follows_utc is True


def test_auto_on_a_free_running_host_uses_the_latency_without_the_serial_jitter() -> None:
    clock = EpochClock(EpochTime.AUTO, receiver_latency_s=0.068)
    stream = fixes(host_minus_utc_s=-3600.0, latency_s=0.068, jitter_s=0.01)
    t_e = epochs(clock, stream)
    assert clock.host_follows_utc is False
    # true epochs on this host clock: UTC - 3600 s; the error is the smallest jitter so far,
    # never a later epoch's own jitter (receive time - latency would carry up to 10 ms)
    true_epoch = np.array([f.t_utc for f in stream if f.t_utc is not None]) - 3600.0
    error = t_e - true_epoch
    naive_error = np.array([f.t for f in stream]) - 0.068 - true_epoch
    assert np.all(error >= 0.0) and np.all(np.diff(error) <= 1e-9)
    assert error[-1] < 1e-3 and np.max(naive_error) > 5e-3


def test_the_smallest_delay_is_taken_over_a_sliding_window() -> None:
    clock = EpochClock(EpochTime.RECEIVE, receiver_latency_s=0.0)
    first = fixes(host_minus_utc_s=5.0, latency_s=0.0, jitter_s=0.0, n=1)[0]
    early = GnssFix(t=first.t - 0.1, t_utc=T_UTC0 - 0.1, quality=first.quality)  # the epoch before
    clock.epoch_time(early)
    later = [
        GnssFix(t=f.t + 0.02, t_utc=f.t_utc, quality=f.quality)  # the host clock stepped 20 ms
        for f in fixes(host_minus_utc_s=5.0, latency_s=0.0, jitter_s=0.0, n=WINDOW_EPOCHS + 2)
    ]
    t_e = epochs(clock, later)
    assert t_e[0] == pytest.approx(later[0].t - 0.02)  # the old minimum still counts
    assert t_e[-1] == pytest.approx(later[-1].t)  # until it leaves the window


@pytest.mark.parametrize("mode", list(EpochTime))
def test_a_fix_without_a_date_is_placed_at_receive_time_minus_latency(mode: EpochTime) -> None:
    clock = EpochClock(mode, receiver_latency_s=0.05)
    undated = GnssFix(t=T_UTC0 + 0.07, t_utc=None, quality=FixQuality.RTK_FIXED)
    assert clock.epoch_time(undated) == pytest.approx(T_UTC0 + 0.02)


def test_explicit_modes_do_not_guess() -> None:
    stream = fixes(host_minus_utc_s=0.0, latency_s=0.068, jitter_s=0.0)
    utc = EpochClock(EpochTime.UTC, 0.0)
    assert np.array_equal(epochs(utc, stream), utc_times(stream))
    receive = EpochClock(EpochTime.RECEIVE, 0.05)
    assert epochs(receive, stream) == pytest.approx([f.t - 0.05 for f in stream], abs=1e-9)
    assert receive.host_follows_utc is False
    assert EpochClock(EpochTime.AUTO, 0.0).host_follows_utc is None  # nothing seen yet


@pytest.mark.parametrize("host_minus_utc_s", [-0.1, 0.7, 3.0])
def test_delays_out_of_a_synced_receivers_reach_mean_a_free_host(host_minus_utc_s: float) -> None:
    clock = EpochClock(EpochTime.AUTO, receiver_latency_s=0.04)
    epochs(clock, fixes(host_minus_utc_s, latency_s=0.04, jitter_s=0.0, n=5))
    assert clock.host_follows_utc is False


def test_a_receivers_utc_ahead_for_a_while_is_placed_by_its_arrival_on_a_utc_host() -> None:
    """Five seconds of the receiver's UTC 1 s ahead (a firmware or leap-second glitch) on a
    host that follows UTC: those epochs arrived before their stamp, impossible there, so the
    stamp is wrong, not the data. They are placed by arrival less the least delay, and the
    epochs after them at their UTC again. Before, their delay (-0.93 s) became the least:
    ``receive`` with it for the window's 10 s after them, every epoch placed 1 s early."""
    clock = EpochClock(EpochTime.AUTO, receiver_latency_s=0.05)
    stream = fixes(host_minus_utc_s=0.0, latency_s=0.068, jitter_s=0.01, n=200)
    glitched = [
        dataclasses.replace(f, t_utc=f.t_utc + 1.0) if 50 <= k < 100 and f.t_utc else f
        for k, f in enumerate(stream)
    ]
    t_e = epochs(clock, glitched)
    true = np.array(utc_times(stream))
    assert np.max(np.abs(t_e[50:100] - true[50:100])) < 0.01  # the serial jitter's spread
    assert np.array_equal(t_e[:50], true[:50]) and np.array_equal(t_e[100:], true[100:])
    assert clock.host_follows_utc is True


@pytest.mark.parametrize("frozen", [False, True])
def test_a_receivers_utc_behind_or_standing_still_is_placed_by_its_arrival_on_a_utc_host(
    frozen: bool,
) -> None:
    """Five seconds of the receiver's UTC 1 s behind, or stuck at one value: not after the
    epoch before, impossible for a new epoch, so the stamp is wrong, not the data. Placed by
    arrival (both engines had fused 1 s old velocities in a turn: 1.3 m off); the epochs
    after at their UTC again. Epochs that arrive late with their UTC advancing (a busy
    host, here 0.6 s late) keep it."""
    clock = EpochClock(EpochTime.AUTO, receiver_latency_s=0.05)
    stream = fixes(host_minus_utc_s=0.0, latency_s=0.068, jitter_s=0.01, n=250)
    stuck = stream[50].t_utc
    assert stuck is not None
    glitched = [
        dataclasses.replace(f, t_utc=stuck if frozen else f.t_utc - 1.0)
        if 50 <= k < 100 and f.t_utc
        else dataclasses.replace(f, t=f.t + 0.6)
        if 150 <= k < 160
        else f
        for k, f in enumerate(stream)
    ]
    t_e = epochs(clock, glitched)
    true = np.array(utc_times(stream))
    assert np.max(np.abs(t_e[50:100] - true[50:100])) < 0.01  # the serial jitter's spread
    assert np.array_equal(t_e[:50], true[:50]) and np.array_equal(t_e[100:], true[100:])


def test_the_clock_states_how_well_it_knows_an_epoch_time() -> None:
    """On a host that follows UTC an epoch's time is the receiver's UTC, exact; on a free
    one, and before the sentences give a date, it is an arrival less a configured latency,
    uncertain by :data:`RECEIVE_EPOCH_SIGMA_S`, which the EKF weighs its fixes by."""
    synced, free, undated = (EpochClock(EpochTime.AUTO, 0.05) for _ in range(3))
    epochs(synced, fixes(0.0, 0.068, 0.003))
    epochs(free, fixes(30.0, 0.068, 0.003))
    undated.epoch_time(dataclasses.replace(fixes(0.0, 0.068, 0.003)[0], t_utc=None))
    assert synced.host_follows_utc and synced.epoch_sigma_s == 0.0
    assert free.host_follows_utc is False and free.epoch_sigma_s == RECEIVE_EPOCH_SIGMA_S
    assert undated.host_follows_utc is None and undated.epoch_sigma_s == RECEIVE_EPOCH_SIGMA_S


def behind(stream: list[GnssFix], lag_s: list[float], read_every_s: float) -> list[GnssFix]:
    """``stream`` read ``lag_s[k]`` late, by a reader that reads every ``read_every_s`` while
    it is behind (0 s: at once)."""
    late = []
    for f, lag in zip(stream, lag_s, strict=True):
        arrival = f.t + lag
        if lag > 0.0 and read_every_s > 0.0:
            arrival = T_UTC0 + math.ceil((arrival - T_UTC0) / read_every_s) * read_every_s
        late.append(dataclasses.replace(f, t=arrival))
    return late


def test_a_reader_stalled_for_seconds_leaves_the_epochs_at_their_utc() -> None:
    """A busy host's reader stalled for 20 s, then 10 s, then 7 s, each backlog read in one
    burst (a recording of the in-process test at 8x real time on a loaded machine: 2.5 s of
    wall time at most). Over a 10 s window the backlog's delays turned ``auto`` to
    ``receive``, every epoch placed 10-20 s late: the observer aligned on them, 25 m off,
    COASTING without DEGRADED. A reader held up only adds to the delays: the epochs stay at
    their UTC, in order, none dropped."""
    clock = EpochClock(EpochTime.AUTO, receiver_latency_s=0.05)
    stream = fixes(host_minus_utc_s=0.0, latency_s=0.05, jitter_s=0.005, n=800)
    stalls = [(300, 500), (510, 610), (660, 730)]  # epochs [a, b) read at b's time
    lag_s = [0.0] * len(stream)
    for a, b in stalls:
        for k in range(a, b):
            lag_s[k] = stream[b].t - stream[k].t
    placed = epochs(clock, behind(stream, lag_s, read_every_s=0.0))
    assert clock.unordered == 0 and clock.host_follows_utc
    assert np.array_equal(placed, utc_times(stream))


def test_epochs_are_placed_in_time_order_or_not_at_all() -> None:
    """A host 3 s behind its serial port for longer than the delay window, then catching up
    over 15 s, reading every 0.5 s: ``auto`` turns to ``receive`` on the backlog's delays
    (a clock 3 s ahead looks the same) and places epochs on them, and back on UTC the next
    epochs before them. Those are not placed; once caught up the epochs are at their UTC
    again."""
    clock = EpochClock(EpochTime.AUTO, receiver_latency_s=0.05)
    held = WINDOW_EPOCHS + 100
    n = 100 + held + 150 + 100
    stream = fixes(host_minus_utc_s=0.0, latency_s=0.07, jitter_s=0.0, n=n)
    lag_s = [
        0.03 * k if k < 100
        else 3.0 if k < 100 + held
        else max(0.0, 3.0 - 0.02 * (k - 100 - held))
        for k in range(n)
    ]  # fmt: skip
    placed = [clock.epoch_time(f) for f in behind(stream, lag_s, read_every_s=0.5)]
    times = [t for t in placed if t is not None]
    assert np.all(np.diff(times) > 0.0)
    assert clock.unordered == len(placed) - len(times) > 0
    assert clock.host_follows_utc and placed[-100:] == utc_times(stream)[-100:]
