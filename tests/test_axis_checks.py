"""A stuck IMU (an axis's word unchanged sample after sample) is a FAULT, never a measurement;
a spike (one sample a bit flip away from its neighbours) is a transfer error, not motion.

Before :mod:`drivers.axis_checks`, a bridge that kept re-sending its last SPI read (SEQ
counting, ND set) for 10 s of the field run sent roll and pitch up to 4 deg off while STATUS
said navigating (observer), and the EKF's reference point went 1.4 m off for two minutes
after; one gyro sample 102.4 deg/s off put roll 0.5 deg out for seconds. The runs here:
`short` with the words cut into its IMU log as such a unit would send them, through ``navgw
replay``, the frames decoded by the independent ``nmea2000`` package.
"""

from __future__ import annotations

import logging
import re
from pathlib import Path

import can
import numpy as np
import pytest

from drivers.axis_checks import ACCEL_JUMP_MPS2, GYRO_JUMP_RPS, STUCK_SAMPLES
from drivers.imu_can import ImuCanConfig, ImuDecoder
from drivers.logs.candump import CandumpWriter, read_candump
from drivers.samples import ImuSample
from gateway.config.gateway_config import Engine, load_config
from gateway.estimation.solution import Mode
from gateway.offline.log_replay import replay
from sim_bus.adis16334 import Adis16334Config, simulate
from sim_bus.imu_frames import frames
from sim_bus.scenarios import SCENARIOS, generate
from sim_bus.truth import Truth
from tests.n2k_check import decode_log, position_errors_m, status_modes, tilt_beyond_stated

GYRO_PGN, ACCEL_PGN = 0xFF10, 0xFF11
G = 9.80665


def decoded(msgs: list[can.Message], config: ImuCanConfig | None = None) -> list[ImuSample]:
    decoder = ImuDecoder(config)
    return [s for m in msgs for s in decoder.feed(m) if isinstance(s, ImuSample)]


def copies(msgs: list[can.Message]) -> list[can.Message]:
    """Frames to cut into, the originals untouched."""
    return [can.Message(arbitration_id=m.arbitration_id, data=bytes(m.data)) for m in msgs]


def parked(seconds: float, dec: int, seed: int) -> list[can.Message]:
    """The simulator's ADIS16334 on a vehicle parked with its engine off: level, no rotation,
    no vibration, the datasheet noise alone (the least that moves its words)."""
    dt = 2**dec / 819.2
    n = round(seconds / dt)
    t = 1.7e9 + np.arange(n) * dt
    w = np.zeros((n, 3))
    f = np.tile([0.0, 0.0, -G], (n, 1))
    return list(frames(simulate(t, w, f, Adis16334Config(dec=dec, vibration=None, seed=seed))))


def longest_run(samples: list[ImuSample]) -> int:
    """The most samples running with some axis's value unchanged."""
    values = np.array([(*s.w_ib_b, *s.f_ib_b) for s in samples])
    same = np.diff(values, axis=0) == 0.0
    best = 0
    for axis in same.T:
        run = 0
        for eq in axis:
            run = run + 1 if eq else 0
            best = max(best, run)
    return best


@pytest.mark.parametrize("dec", [2, 4])
def test_a_working_imu_is_never_stuck_even_parked_with_the_engine_off(dec: int) -> None:
    """Ten minutes of the datasheet noise alone at 204.8 and 51.2 Hz: the longest run of an
    unchanged axis is far below the 24 that make it stuck (at 51.2 Hz the accelerometer's
    noise is 1.5 LSB a sample: runs of 6-8; 24 would take some 10^11 hours)."""
    decoder = ImuDecoder()
    msgs = parked(600.0, dec, seed=dec)
    samples = [s for m in msgs for s in decoder.feed(m) if isinstance(s, ImuSample)]
    assert len(samples) == round(600.0 * 819.2 / 2**dec)
    assert not any(s.stuck for s in samples) and decoder.counters.spikes == 0
    assert 1 <= longest_run(samples) <= STUCK_SAMPLES // 2


def largest_steps(samples: list[ImuSample]) -> tuple[float, float]:
    """The largest change of the gyro triad (rad/s) and of the accelerometer's (m/s^2) from one
    sample to the next, each the distance of its three axes."""
    w = np.diff(np.array([s.w_ib_b for s in samples]), axis=0)
    f = np.diff(np.array([s.f_ib_b for s in samples]), axis=0)
    return float(np.linalg.norm(w, axis=1).max()), float(np.linalg.norm(f, axis=1).max())


def test_the_vibration_of_a_field_run_is_far_inside_the_spike_bounds(tmp_path: Path) -> None:
    """The simulator's engine vibration and the datasheet noise, rough ground (the `field`
    run's bumps): no sample is taken for a spike, and the largest step from one sample to the
    next is under a quarter of either bound."""
    run = generate(SCENARIOS["short"], tmp_path, seed=11)
    decoder = ImuDecoder()
    samples = [
        s for m in read_candump(run.imu_log) for s in decoder.feed(m) if isinstance(s, ImuSample)
    ]
    assert decoder.counters.spikes == 0 and decoder.counters.stuck == 0
    w_step, f_step = largest_steps(samples)
    assert w_step < GYRO_JUMP_RPS / 4 and f_step < ACCEL_JUMP_MPS2 / 4


def moved(data: bytes | bytearray, axis: int, lsb: int) -> bytearray:
    """A frame's ``axis`` word (0-2) moved by ``lsb`` counts within its 14 bits, EA/ND kept,
    as a bit error on the SPI would."""
    sl = slice(2 * axis, 2 * axis + 2)
    w = int.from_bytes(data[sl], "little")
    v = (w & 0x3FFF) - ((w & 0x2000) << 1)
    v = max(-8191, min(8190, v + lsb))
    out = bytearray(data)
    out[sl] = ((w & 0xC000) | (v & 0x3FFF)).to_bytes(2, "little")
    return out


def with_word(msgs: list[can.Message], k: int, word: int, lsb: int) -> None:
    """Sample ``k``'s ``word`` (0-2 gyro x, y, z; 3-5 accel x, y, z) moved by ``lsb``."""
    m = msgs[2 * k + word // 3]
    m.data = moved(m.data, word % 3, lsb)


def test_a_one_sample_spike_is_held_a_lasting_step_is_taken(
    caplog: pytest.LogCaptureFixture,
) -> None:
    """Gyro x 102.4 deg/s (bit 11) off in sample 100, accel y 2.048 g (bit 11) off in sample
    300: each triad takes its previous sample's values for that one sample (the other triad
    as sent), counted and logged with the jump. A lasting step of 102.4 deg/s from sample 500
    costs its first sample and is taken from the next. 25.6 deg/s (bit 9) is inside the
    bound and taken as sent."""
    base = [m for m in parked(3.0, 2, seed=2) if (m.arbitration_id >> 8) & 0xFFFF != 0xFF12]
    clean = decoded(copies(base))
    msgs = copies(base)
    with_word(msgs, 100, 0, 2048)
    with_word(msgs, 300, 4, 2048)
    for k in range(500, len(clean)):
        with_word(msgs, k, 2, 2048)
    with_word(msgs, 200, 1, 512)
    with caplog.at_level(logging.WARNING, logger="drivers"):
        decoder = ImuDecoder()
        samples = [s for m in msgs for s in decoder.feed(m) if isinstance(s, ImuSample)]
    assert len(samples) == len(clean) and decoder.counters.spikes == 3
    assert samples[100].w_ib_b == clean[99].w_ib_b and samples[100].f_ib_b == clean[100].f_ib_b
    assert samples[300].f_ib_b == clean[299].f_ib_b and samples[300].w_ib_b == clean[300].w_ib_b
    assert samples[200].w_ib_b[1] == pytest.approx(clean[200].w_ib_b[1] + np.radians(25.6))
    assert samples[500].w_ib_b == clean[499].w_ib_b
    step = np.radians(102.4)
    assert all(
        samples[k].w_ib_b[2] == pytest.approx(clean[k].w_ib_b[2] + step)
        for k in range(501, len(clean))
    )
    others = [k for k in range(len(clean)) if k not in (100, 200, 300) and k < 500]
    assert all(samples[k] == clean[k] for k in others)
    lines = [r.getMessage() for r in caplog.records if "transfer error" in r.getMessage()]
    # the jump from the previous sample: 102.4 deg/s plus that sample's noise
    assert lines and re.search(r"IMU gyro jumped 10\d\.\d deg/s .* at most 40 deg/s", lines[0])


def freeze_words(msgs: list[can.Message], start: int, stop: int, words: range) -> None:
    """Samples ``start`` to ``stop`` - 1 carry sample ``start - 1``'s ``words`` (0-2 gyro x, y,
    z; 3-5 accel x, y, z), EA/ND bits and SEQ as they were sent: a bridge re-sending a read."""
    pairs = [msgs[i : i + 2] for i in range(0, len(msgs), 2)]
    pairs = [p for p in pairs if len(p) == 2]
    for w in words:
        frame, word = w // 3, w % 3
        sl = slice(2 * word, 2 * word + 2)
        held = pairs[start - 1][frame].data[sl]
        for k in range(start, stop):
            data = bytearray(pairs[k][frame].data)
            data[sl] = held
            pairs[k][frame].data = data


def test_an_axis_unchanged_for_24_samples_is_stuck_until_it_changes(
    caplog: pytest.LogCaptureFixture,
) -> None:
    """The accelerometer z word held from sample 100 to 199: the samples from the 25th equal
    one on are stuck, counted and logged naming the axis; the first changed word ends it. All
    six held: the same. ``stuck_samples = 0`` (a source without noise) never says stuck."""
    base = [m for m in parked(3.0, 2, seed=1) if (m.arbitration_id >> 8) & 0xFFFF != 0xFF12]
    msgs = copies(base)
    freeze_words(msgs, 100, 200, range(5, 6))
    with caplog.at_level(logging.WARNING, logger="drivers"):
        decoder = ImuDecoder()
        samples = [s for m in msgs for s in decoder.feed(m) if isinstance(s, ImuSample)]
    stuck = [k for k, s in enumerate(samples) if s.stuck]
    assert stuck == list(range(99 + STUCK_SAMPLES, 200))
    assert decoder.counters.stuck == len(stuck)
    [line] = [r.getMessage() for r in caplog.records if "unchanged" in r.getMessage()]
    assert "IMU accel z output unchanged for 25 samples" in line
    assert samples[150].f_ib_b[2] == samples[99].f_ib_b[2]  # the words are decoded as sent
    all_six = copies(base)
    freeze_words(all_six, 300, 330, range(6))
    assert [k for k, s in enumerate(decoded(all_six)) if s.stuck] == list(
        range(299 + STUCK_SAMPLES, 330)
    )
    assert not any(s.stuck for s in decoded(all_six, ImuCanConfig(stuck_samples=0)))


@pytest.fixture(scope="module")
def drive(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("stuck")
    generate(SCENARIOS["short"], out, seed=3)
    return out


def with_words_held(imu_log: Path, out: Path, span_s: tuple[float, float], words: range) -> Path:
    """``imu_log`` with ``words`` (0-2 gyro, 3-5 accel) of every IMU frame within ``span_s``
    (s from the log's start) as they were in the last frame before it."""
    frames_in = list(read_candump(imu_log))
    t0 = frames_in[0].timestamp
    held: dict[int, bytes] = {}
    with CandumpWriter(out, "can0") as writer:
        for m in frames_in:
            pgn = (m.arbitration_id >> 8) & 0xFFFF
            if pgn in (GYRO_PGN, ACCEL_PGN):
                first = 0 if pgn == GYRO_PGN else 3
                if span_s[0] <= m.timestamp - t0 < span_s[1] and pgn in held:
                    data = bytearray(m.data)
                    for w in words:
                        if first <= w < first + 3:
                            k = 2 * (w - first)
                            data[k : k + 2] = held[pgn][k : k + 2]
                    m.data = data
                else:
                    held[pgn] = bytes(m.data)
            writer.write(m)
    return out


@pytest.mark.parametrize(
    ("fault", "words", "length_s"),
    [("all-held-5s", range(6), 5.0), ("gyro-z-held-20s", range(2, 3), 20.0)],
)
@pytest.mark.parametrize("engine", [Engine.OBSERVER, Engine.EKF], ids=["observer", "ekf"])
def test_a_stuck_imu_in_a_turn_is_a_fault_then_the_engine_realigns(
    drive: Path, engine: Engine, fault: str, words: range, length_s: float, tmp_path: Path
) -> None:
    """Held in the run's sharpest turn: STATUS says FAULT within 0.15 s (24 samples) and to
    the end of it, no attitude goes out meanwhile, every attitude frame is within 0.1 deg + 3
    stated sigma of the truth and every position within 0.5 m, and the engine is navigating
    again 15 s after."""
    truth = Truth.load(drive / "truth.npz")
    t = truth.t - truth.t[0]
    yaw_rate = np.abs(truth.w_ib_b[:, 2])
    start = float(t[np.argmax(np.where(t < t[-1] - 40.0, yaw_rate, 0.0))]) - 0.5
    assert np.degrees(yaw_rate.max()) > 10.0
    span = (start, start + length_s)
    imu = with_words_held(drive / "imu.log", tmp_path / "imu.log", span, words)
    config = load_config(drive / "navgw.toml").with_engine(engine)
    out = tmp_path / "out.log"
    replay(imu, drive / "gnss.nmea", out, config)
    modes = [(ts - truth.t[0], Mode(m)) for ts, m in status_modes(out)]
    assert {m for ts, m in modes if span[0] + 0.15 <= ts < span[1]} == {Mode.FAULT}, fault
    assert not [m for ts, m in modes if span[0] - 5.0 <= ts < span[0] and m is Mode.FAULT]
    attitude = [m.t - truth.t[0] for m in decode_log(out) if m.id == "attitude"]
    assert not [ts for ts in attitude if span[0] + 0.15 <= ts < span[1]]
    checked, beyond = tilt_beyond_stated(out, truth)
    assert checked > 4000 and not beyond, "\n".join(beyond[:10])
    positions = position_errors_m(decode_log(out), truth, 0.0)
    sent = positions[np.isfinite(positions)]  # not available: NaN
    assert len(sent) > 2500 and sent.max() < 0.5
    assert {m for ts, m in modes if span[1] + 15.0 <= ts < span[1] + 20.0} == {Mode.NAVIGATING}


def with_spikes(imu_log: Path, out: Path, spikes: list[tuple[float, int, int]]) -> Path:
    """``imu_log`` with, for each (time s from the start, word 0-5, counts), the first sample
    at or after that time's word moved by the counts (a bit error on the SPI)."""
    frames_in = list(read_candump(imu_log))
    t0 = frames_in[0].timestamp
    todo = sorted(spikes)
    with CandumpWriter(out, "can0") as writer:
        for m in frames_in:
            pgn = (m.arbitration_id >> 8) & 0xFFFF
            if todo and pgn == (GYRO_PGN if todo[0][1] < 3 else ACCEL_PGN):
                t, word, lsb = todo[0]
                if m.timestamp - t0 >= t:
                    todo.pop(0)
                    m.data = moved(m.data, word % 3, lsb)
            writer.write(m)
    assert not todo
    return out


@pytest.mark.parametrize("engine", [Engine.OBSERVER, Engine.EKF], ids=["observer", "ekf"])
def test_bit_errors_on_the_spi_never_reach_the_bus(
    drive: Path, engine: Engine, tmp_path: Path
) -> None:
    """30 single-sample bit errors of bits 11-13 (102.4-409.6 deg/s, 2-8 g), on random axes,
    through the run (turns included): each is held for its sample, and every attitude frame
    is within 0.1 deg + 3 stated sigma of the truth, every position within 0.5 m, STATUS
    never says FAULT. Before: 41-58 frames beyond for one gyro bit 11 on the field run."""
    rng = np.random.default_rng(4)
    spikes = [
        (float(t), int(word), int(sign * (1 << bit)))
        for t, word, bit, sign in zip(
            np.sort(rng.uniform(35.0, 120.0, 30)),
            rng.integers(0, 6, 30),
            rng.integers(11, 14, 30),
            rng.choice([-1, 1], 30),
            strict=True,
        )
    ]
    imu = with_spikes(drive / "imu.log", tmp_path / "imu.log", spikes)
    config = load_config(drive / "navgw.toml").with_engine(engine)
    out = tmp_path / "out.log"
    summary = replay(imu, drive / "gnss.nmea", out, config)
    assert summary.imu.spikes == 30
    truth = Truth.load(drive / "truth.npz")
    checked, beyond = tilt_beyond_stated(out, truth)
    assert checked > 4000 and not beyond, "\n".join(beyond[:10])
    positions = position_errors_m(decode_log(out), truth, 0.0)
    sent = positions[np.isfinite(positions)]
    assert len(sent) > 2500 and sent.max() < 0.5
    assert Mode.FAULT not in {Mode(m) for _, m in status_modes(out)}
