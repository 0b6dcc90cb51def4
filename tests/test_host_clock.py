"""A step of the host clock (NTP, chrony, timesyncd) is taken out of the core's time.

Both logs of a recording, and live the CAN stamps and the GNSS receive times, share the host
clock (SPEC 3). Before the IMU decoder found its steps (:mod:`drivers.host_clock`), a step of
+0.3 s at 100 s of `short` slid the IMU's anchor over 10 s while the epochs kept the receive
delays of the minute before: the observer sent 186 tilt frames beyond 0.1 deg + 3 sigma and
809 positions beyond NAVIGATING's 0.2 m, the EKF 331 and 811; +3 s (re-anchored), 470
implausible frames from the observer and 119 from the EKF; -1 s, 69 tilt and 69 positions
beyond from the EKF.
"""

from __future__ import annotations

import re
from dataclasses import replace
from pathlib import Path

import can
import numpy as np
import pytest

from drivers.host_clock import HostClock
from drivers.imu_can import ImuDecoder
from drivers.samples import FixQuality, GnssFix, ImuSample
from gateway.cli.cmd_replay import summary_text
from gateway.config.gateway_config import Engine, load_config
from gateway.estimation.epoch_clock import EpochClock, EpochTime
from gateway.estimation.solution import Mode
from gateway.offline.log_replay import replay
from sim_bus.scenarios import SCENARIOS, generate
from sim_bus.truth import Truth
from tests.n2k_check import (
    decode_log,
    heading_beyond_navigating,
    implausible_frames,
    position_beyond_mode,
    status_modes,
    tilt_beyond_stated,
)
from tests.test_imu_timing import WRAP_S, stream

STEP_AT = 600  # the first sample on the new clock: 2.9 s in, the anchor long settled
STAMP_LINE = re.compile(r"\((\d+\.\d+)\)(.*)")


def stepped(step_s: float, at: int = STEP_AT, jitter_s: float = 3e-4) -> list[can.Message]:
    """The bridge's frames of 6 s, stamped by a host whose clock steps by ``step_s`` from
    sample ``at`` on, each frame up to ``jitter_s`` late (as SocketCAN stamps them)."""
    _, indexed = stream(6.0)
    rng = np.random.default_rng(7)
    return [
        can.Message(
            timestamp=m.timestamp + (step_s if k >= at else 0.0) + rng.uniform(0.0, jitter_s),
            arbitration_id=m.arbitration_id,
            data=m.data,
            is_extended_id=True,
        )
        for k, m in indexed
    ]


def decoded(msgs: list[can.Message]) -> tuple[ImuDecoder, list[ImuSample]]:
    dec = ImuDecoder()
    samples = [i for m in msgs for i in dec.feed(m) if isinstance(i, ImuSample)]
    dec.finish()
    return dec, samples


@pytest.mark.parametrize("step_s", [0.06, 0.3, 0.7, 1.3, 3.0, 1000.3, -0.06, -0.3, -1.3, -1000.3])
def test_a_host_clock_step_is_taken_out_of_the_sample_times(step_s: float) -> None:
    """Forward (time skipped) or back (time repeated), from 60 ms to 17 min: the samples go
    on, on the IMU's clock, and the step is kept from the first sample on the new clock
    (its host time is the step ahead); nothing is counted lost or re-anchored."""
    out, _ = stream(6.0)
    dec, samples = decoded(stepped(step_s))
    c = dec.counters
    assert (c.samples, c.lost, c.reanchors, c.duplicates, c.out_of_order, c.clock_steps) == (
        len(out),
        0,
        0,
        0,
        0,
        1,
    )
    t = np.array([s.t for s in samples])
    assert np.abs(t - out.t).max() < 1e-3  # the jitter's least, kept by the anchor
    (step,) = dec.host_clock.steps
    assert step.delta_s == pytest.approx(step_s, abs=1e-3)
    host = np.array([dec.host_clock.host(x) for x in t])
    on_new = np.arange(len(t)) >= STEP_AT
    assert np.abs(host[~on_new] - out.t[~on_new]).max() < 1e-3
    assert np.abs(host[on_new] - out.t[on_new] - step_s).max() < 2e-3


def test_a_step_too_small_to_tell_from_latency_slides_in() -> None:
    # 40 ms, under clock_step_min_s: the anchor rises to it over anchor_tau_s, as for drift
    out, _ = stream(6.0)
    dec, samples = decoded(stepped(0.04))
    assert (dec.counters.clock_steps, dec.counters.reanchors) == (0, 0)
    err = np.array([s.t for s in samples]) - out.t
    assert np.abs(err[:STEP_AT]).max() < 1e-3
    assert 0.0 < err[-1] < 0.04


def test_a_step_of_whole_seq_wraps_is_taken_for_an_outage() -> None:
    """4 wraps (5 s at 204.8 Hz): the SEQ cannot tell it from 1,024 samples lost, and an
    outage taken for a step would send a position 5 s old. The times jump with the host
    clock's (the fusion core tells the epoch clock, test below)."""
    out, _ = stream(6.0)
    dec, samples = decoded(stepped(4 * WRAP_S))
    assert (dec.counters.clock_steps, dec.counters.reanchors, dec.counters.lost) == (0, 1, 0)
    err = np.array([s.t for s in samples]) - out.t
    assert np.abs(err[:STEP_AT]).max() < 1e-3
    assert np.abs(err[-100:] - 4 * WRAP_S).max() < 1e-3


def test_a_clock_set_hours_forward_is_taken_into_the_core_s_time() -> None:
    """A day ahead (an ECU's clock set at boot): the IMU's anchor restarts on the new clock,
    so that the core's time, and what the learned state is saved with, are the host's."""
    out, _ = stream(6.0)
    dec, samples = decoded(stepped(86400.3))
    assert (dec.counters.clock_steps, dec.counters.reanchors) == (0, 1)
    err = np.array([s.t for s in samples]) - out.t
    assert np.abs(err[-100:] - 86400.3).max() < 1e-3


def test_a_step_before_the_anchor_has_settled_restarts_it() -> None:
    # -0.3 s at the 10th sample, before a steady window: the start's anchor may be late
    dec, _ = decoded(stepped(-0.3, at=10))
    assert (dec.counters.clock_steps, dec.counters.reanchors) == (0, 1)


def test_other_streams_take_a_step_from_their_first_time_on_the_new_clock() -> None:
    clock = HostClock()
    ahead = clock.stream()
    assert ahead.core(100.0) == 100.0
    clock.step(100.5, 2.0)  # forward: the old clock read 100.5 at the step
    assert ahead.core(100.6) == 100.6  # before it (the old clock never read 101.5)
    assert ahead.core(102.6) == pytest.approx(100.6)  # after it
    assert ahead.core(102.6) == pytest.approx(100.6)  # the same time, the same answer
    assert clock.host(100.4) == 100.4 and clock.host(100.6) == pytest.approx(102.6)

    clock.step(110.0, -1.0)  # back, at core 110.0: the host clock read 112.0, then 111.0
    back = clock.stream()
    assert back.core(100.2) == 100.2  # before both
    assert back.core(111.8) == pytest.approx(109.8)  # after the first, before the second
    assert back.core(111.2) == pytest.approx(110.2)  # went back: after the second
    assert back.core(111.9) == pytest.approx(110.9)
    assert clock.host(109.9) == pytest.approx(111.9) and clock.host(110.2) == pytest.approx(111.2)

    late = clock.stream()  # a stream whose first time is past both
    assert late.core(113.0) == pytest.approx(112.0)


def test_a_fix_after_a_step_back_is_told_by_its_receive_delay() -> None:
    """A 1 Hz receiver: its first fix on the new clock, 0.7 s back, comes later than its
    last on the old one. Its receive delay tells: 0.7 s less than the last one's on the old
    clock, as much as the last one's on the new. A fix read before the step in the same
    span has the last one's delay on the old clock."""
    clock = HostClock()
    after, before = clock.stream(), clock.stream()
    for fixes_of in (after, before):
        assert fixes_of.core(100.0, 99.93) == 100.0
    clock.step(100.9, -0.7)  # at core (and old host) time 100.9
    assert after.core(100.9, 101.53) == pytest.approx(101.6)  # core 101.6, on the new clock
    assert before.core(100.6, 100.53) == 100.6  # on the old one, before the step
    assert before.core(100.5, 101.13) == pytest.approx(101.2)  # then on the new: went back


def fixes(delays: list[float], t0: float = 1000.0) -> list[GnssFix]:
    """10 Hz fixes received ``delays`` after their UTC epoch."""
    return [
        GnssFix(t=t0 + 0.1 * i + d, t_utc=t0 + 0.1 * i, quality=FixQuality.RTK_FIXED)
        for i, d in enumerate(delays)
    ]


@pytest.mark.parametrize(
    ("jump_s", "step"),
    [(5.0, True), (5.0, False), (-5.0, True)],
    ids=["clock-step", "outage", "clock-step-back"],
)
def test_a_jump_the_imu_took_moves_the_receive_delays_if_they_jumped_too(
    jump_s: float, *, step: bool
) -> None:
    """The IMU decoder takes a step of whole SEQ wraps for an outage, and a step before its
    anchor has settled restarts the anchor: the core's time jumps with the host's. A step
    moves the receive delays too, and the delays kept and the last epoch placed move with
    them: else the host would be taken to follow UTC for a minute and each epoch placed 5 s
    off the IMU's samples, or, after a step back, every epoch dropped as out of order for
    5 s. After a real outage they stay."""
    clock = EpochClock(EpochTime.AUTO, receiver_latency_s=0.05)
    before = fixes([0.08] * 50)
    assert all(clock.epoch_time(f) == f.t_utc for f in before)
    clock.host_jumped(jump_s)
    moved = jump_s if step else 0.0
    after = fixes([0.08 + moved] * 10, t0=1006.0)
    placed = [clock.epoch_time(f) for f in after]
    assert clock.host_follows_utc is not step  # the host is 5 s off UTC after the step
    expected = [1006.0 + 0.1 * i + (moved + 0.08 - 0.05 if step else 0.0) for i in range(10)]
    assert placed == pytest.approx(expected)
    assert clock.unordered == 0


def stepped_fixes(delay_s: float, host_offset_s: float, t0: float, n: int = 10) -> list[GnssFix]:
    """10 Hz fixes ``delay_s`` after their UTC epoch on core time, with the host clock
    ``host_offset_s`` ahead of the core's (the steps taken out)."""
    return [replace(f, host_offset_s=host_offset_s) for f in fixes([delay_s] * n, t0=t0)]


@pytest.mark.parametrize(
    ("core_delay_s", "step_s", "on_host"),
    [
        (-3.63, 3.7, True),  # the host ran 3.7 s behind UTC, then NTP set it
        (3.77, -3.7, True),  # ahead, set back
        (0.07, 0.3, False),  # the host followed UTC, and stepped off it: the core still does
        (0.07, -0.3, False),
    ],
)
def test_the_clock_that_follows_utc_after_a_step_places_the_epochs(
    core_delay_s: float, step_s: float, *, on_host: bool
) -> None:
    """After a step taken out of the core's time, either clock may follow UTC: the host's
    if NTP set it (its delays now a receiver's), the core's if it followed UTC before the
    step and the host's was stepped off it. A clock ahead only adds to its delays: of two
    that look synchronised, the lesser delay's. The epoch goes at its UTC on that clock."""
    clock = EpochClock(EpochTime.AUTO, receiver_latency_s=0.05)
    before = stepped_fixes(core_delay_s, 0.0, t0=1000.0, n=50)
    placed = [clock.epoch_time(f) for f in before]
    assert clock.host_follows_utc is (core_delay_s == 0.07)
    after = stepped_fixes(core_delay_s, step_s, t0=1006.0)
    placed = [clock.epoch_time(f) for f in after]
    assert clock.host_follows_utc
    shift = step_s if on_host else 0.0
    assert placed == pytest.approx([f.t_utc - shift for f in after])  # type: ignore[operator]


@pytest.fixture(scope="module")
def drive(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """`short` seed 5: its logs, truth and config."""
    run = generate(SCENARIOS["short"], tmp_path_factory.mktemp("clock-step"), seed=5)
    return run.imu_log.parent


def with_clock_step(
    src: Path, dst: Path, at_s: float, step_s: float, before_s: float = 0.0
) -> Path:
    """``src`` with its host stamps ``before_s`` off until ``at_s`` after its first, then
    ``step_s`` more."""
    lines = src.read_text().splitlines()
    t0 = float(STAMP_LINE.match(lines[0]).group(1))  # type: ignore[union-attr]
    out = []
    for line in lines:
        m = STAMP_LINE.match(line)
        assert m is not None
        t = float(m.group(1))
        out.append(f"({t + before_s + (step_s if t - t0 >= at_s else 0.0):.6f}){m.group(2)}")
    dst.write_text("\n".join(out) + "\n")
    return dst


def stamps(log: Path) -> np.ndarray:
    return np.array([float(STAMP_LINE.match(x).group(1)) for x in log.read_text().splitlines()])  # type: ignore[union-attr]


def on_first_clock(log: Path, dst: Path, t_step: float, step_s: float) -> Path:
    """The output ``log`` with its stamps taken back to the recording's first clock, in file
    order: from its first stamp on the new clock (past the step's half, or gone back)."""
    out, after, latest = [], False, -np.inf
    for line in log.read_text().splitlines():
        m = STAMP_LINE.match(line)
        assert m is not None
        t = float(m.group(1))
        if not after and (
            t >= t_step + abs(step_s) / 2 or (step_s < 0 and t < latest - abs(step_s) / 2)
        ):
            after = True
        latest = max(latest, t)
        out.append(f"({t - (step_s if after else 0.0):.6f}){m.group(2)}")
    dst.write_text("\n".join(out) + "\n")
    return dst


@pytest.mark.parametrize(
    ("step_s", "before_s"),
    [(0.3, 0.0), (-1.0, 0.0), (5.0, 0.0), (3.7, -3.7)],
    ids=["+0.3s", "-1s", "+5s-whole-wraps", "set-to-utc+3.7s"],
)
@pytest.mark.parametrize("engine", [Engine.OBSERVER, Engine.EKF], ids=["observer", "ekf"])
def test_no_frame_lies_across_a_host_clock_step(
    drive: Path, engine: Engine, step_s: float, before_s: float, tmp_path: Path
) -> None:
    """The host clock steps 100 s into `short` (both logs; on the fifth pass) and replay
    stamps its frames on the host clock, as the logs are: on the new clock from the step on.
    Taken back to the first clock, no frame is beyond its stated accuracy or implausible
    (the independent ``nmea2000`` decoder). A step of whole SEQ wraps restarts the engine
    (taken for an outage); any other goes through. A host clock 3.7 s behind UTC that NTP
    sets right (`set-to-utc`) has its epochs at their UTC from then on: the observer, which
    cannot learn a free clock's epoch error, says NAVIGATING again (it stayed DEGRADED
    while the core's time, the old clock's, was taken to be the only one)."""
    at_s = 100.0
    imu = with_clock_step(drive / "imu.log", tmp_path / "imu.log", at_s, step_s, before_s)
    gnss = with_clock_step(drive / "gnss.nmea", tmp_path / "gnss.nmea", at_s, step_s, before_s)
    config = load_config(drive / "navgw.toml").with_engine(engine)
    summary = replay(imu, gnss, tmp_path / "out.log", config)
    whole_wraps = step_s == 5.0
    assert summary.imu.clock_steps == (0 if whole_wraps else 1)
    told = "1 host clock step(s) taken out" in summary_text(summary)
    assert told is not whole_wraps
    assert summary.stats.engine_restarts == (1 if whole_wraps else 0)
    sent = stamps(tmp_path / "out.log")
    gaps = np.diff(sent[sent > sent[0] + 1.0])  # after the address claim's 250 ms
    jumps = np.flatnonzero(np.abs(gaps) > 0.2)
    assert len(jumps) == 1 and gaps[jumps[0]] == pytest.approx(step_s, abs=0.25)
    assert sent[-1] == pytest.approx(stamps(imu)[-1], abs=0.1)  # on the host clock
    t_step = stamps(drive / "imu.log")[0] + before_s + at_s
    first = on_first_clock(tmp_path / "out.log", tmp_path / "first.log", t_step, step_s)
    truth = Truth.load(drive / "truth.npz")
    truth = replace(truth, t=truth.t + before_s)
    if before_s:
        after = [mode for t, mode in status_modes(first) if t > t_step + 5.0]
        assert after and all(mode == Mode.NAVIGATING for mode in after), set(after)
    checked, beyond = tilt_beyond_stated(first, truth)
    # (a free clock: the observer DEGRADED on the move before the step, its tilt not stated)
    assert checked > (2500 if before_s else 4500) and not beyond, "\n".join(beyond[:10])
    _, off = heading_beyond_navigating(first, truth)
    assert not off, "\n".join(off[:10])
    _, far = position_beyond_mode(first, truth)
    assert not far, "\n".join(far[:10])
    wrong = implausible_frames(decode_log(first), truth, status=status_modes(first))
    assert not wrong, "\n".join(wrong[:10])
