"""A stuck IMU (an axis's word unchanged sample after sample) is a FAULT, never a measurement.

Before :mod:`drivers.stuck_output`, a bridge that kept re-sending its last SPI read (SEQ
counting, ND set) for 10 s of the field run sent roll and pitch up to 4 deg off while STATUS
said navigating (observer), and the EKF's reference point went 1.4 m off for two minutes
after. The runs here: `short` with the words cut into its IMU log as such a unit would send
them, through ``navgw replay``, the frames decoded by the independent ``nmea2000`` package.
"""

from __future__ import annotations

import logging
from pathlib import Path

import can
import numpy as np
import pytest

from drivers.imu_can import ImuCanConfig, ImuDecoder
from drivers.logs.candump import CandumpWriter, read_candump
from drivers.samples import ImuSample
from drivers.stuck_output import STUCK_SAMPLES
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
    noise is 1.5 LSB a sample: runs of 6-8; 24 would take some 10^12 hours)."""
    samples = decoded(parked(600.0, dec, seed=dec))
    assert len(samples) == round(600.0 * 819.2 / 2**dec)
    assert not any(s.stuck for s in samples)
    assert 1 <= longest_run(samples) <= STUCK_SAMPLES // 2


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
    msgs = [can.Message(arbitration_id=m.arbitration_id, data=bytes(m.data)) for m in base]
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
    all_six = [can.Message(arbitration_id=m.arbitration_id, data=bytes(m.data)) for m in base]
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
