"""Input recording: SPEC 3 pairs, rotated by size, oldest deleted, and they replay."""

from __future__ import annotations

import itertools
import subprocess
import sys
from pathlib import Path
from typing import TypedDict, Unpack

import pytest

from drivers.logs.candump import read_candump
from drivers.logs.nmea_log import read_nmea_log
from drivers.nmea import NmeaDecoder
from gateway.config.gateway_config import RecordingSection
from gateway.offline.log_replay import replay
from gateway.service.input_recording import CAN_SUFFIX, NMEA_SUFFIX, InputRecorder
from sim_bus.scenarios import SCENARIOS, generate

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("rec")
    generate(SCENARIOS["short"], out, seed=1)
    return out


class Limits(TypedDict, total=False):
    """The [recording] fields a test may set (RecordingSection)."""

    max_file_mb: float
    keep_files: int


def record(
    run_dir: Path, directory: Path, seconds: float, **section: Unpack[Limits]
) -> InputRecorder:
    """Record the first ``seconds`` of a simulated run as the service would."""
    recorder = InputRecorder(RecordingSection(enabled=True, directory=str(directory), **section))
    recorder.open()
    decoder = NmeaDecoder("pty", on_sentence=recorder.sentence)
    t_end = next(iter(read_candump(run_dir / "imu.log"))).timestamp + seconds
    for msg in itertools.takewhile(
        lambda m: m.timestamp < t_end, read_candump(run_dir / "imu.log")
    ):
        recorder.can(msg)
    for t, sentence in read_nmea_log(run_dir / "gnss.nmea"):
        if t is not None and t < t_end:
            decoder.feed(sentence.encode() + b"\r\n", t)
    recorder.close()
    return recorder


def test_rotation_by_size_keeps_the_newest_pairs(run_dir: Path, tmp_path: Path) -> None:
    recorder = record(run_dir, tmp_path, 60.0, max_file_mb=0.1, keep_files=3)
    stems = recorder.pairs()
    assert len(stems) == 3
    numbers = [int(s.split("-")[1]) for s in stems]
    assert numbers == list(range(numbers[0], numbers[0] + 3)) and numbers[0] >= 8  # rotated often
    for stem in stems:
        for suffix in (CAN_SUFFIX, NMEA_SUFFIX):
            assert (tmp_path / (stem + suffix)).is_file()
        # checked every CHECK_EVERY writes, on disk: within a check interval of the limit
        assert (tmp_path / (stem + CAN_SUFFIX)).stat().st_size < 100_000 + 30_000
    assert len(list(tmp_path.iterdir())) == 6
    recorder.close()  # twice is fine


def test_a_recorded_pair_replays_like_the_original(run_dir: Path, tmp_path: Path) -> None:
    (stem,) = record(run_dir, tmp_path / "rec", 20.0).pairs()
    can_log, nmea_log = (tmp_path / "rec" / (stem + s) for s in (CAN_SUFFIX, NMEA_SUFFIX))
    assert not any(line.endswith((" R\n", " T\n")) for line in can_log.open())
    result = subprocess.run(
        [sys.executable, "-m", "gateway.cli.main", "replay", "--can", str(can_log), "--nmea",
         str(nmea_log), "--out", str(tmp_path / "out.log")],
        cwd=REPO, capture_output=True, text=True, check=False,
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    summary = replay(can_log, nmea_log, tmp_path / "again.log")
    assert summary.stats.imu_samples == pytest.approx(20 * 204.8, abs=2)
    assert summary.stats.gnss_fixes == pytest.approx(200, abs=2)
    assert summary.bad_can_lines == summary.bad_nmea_lines == summary.gnss.checksum_errors == 0
    assert (tmp_path / "out.log").read_bytes() == (tmp_path / "again.log").read_bytes()
