"""candump -L log I/O: write/read round trip, agreement with python-can, tolerant reading."""

from __future__ import annotations

import io
import logging
from pathlib import Path

import can
import pytest

from drivers.logs import candump as canlog
from drivers.logs.candump import CandumpReader, format_candump_line, read_candump, write_candump

FIELDS = (
    "timestamp",
    "arbitration_id",
    "is_extended_id",
    "is_remote_frame",
    "is_error_frame",
    "is_fd",
    "is_rx",
    "bitrate_switch",
    "error_state_indicator",
    "dlc",
    "channel",
)


def key(m: can.Message) -> tuple:
    return (*(getattr(m, f) for f in FIELDS), bytes(m.data))


def sample_messages() -> list[can.Message]:
    t = 1700000000.123456
    return [
        can.Message(timestamp=t, arbitration_id=0x0CFF1080, data=bytes.fromhex("0C00F4FF3A0001F2")),
        can.Message(
            timestamp=t + 0.000301, arbitration_id=0x123, is_extended_id=False, data=b"\x01"
        ),
        can.Message(timestamp=t + 0.001, arbitration_id=0x18FF1280, data=b""),
        can.Message(
            timestamp=t + 0.002, arbitration_id=0x7FF, is_extended_id=False, is_remote_frame=True
        ),
        can.Message(
            timestamp=t + 0.003,
            arbitration_id=0x1ABCDEF0,
            is_fd=True,
            bitrate_switch=True,
            data=bytes(range(12)),
        ),
        can.Message(timestamp=t + 0.004, is_error_frame=True),
    ]


def test_format_has_no_direction_flag() -> None:
    m = sample_messages()[0]
    assert format_candump_line(m, "can0") == "(1700000000.123456) can0 0CFF1080#0C00F4FF3A0001F2"
    m.channel = 1
    assert format_candump_line(m).split()[1] == "can1"


def test_write_then_read_is_identical_and_equals_python_can(tmp_path: Path) -> None:
    path = tmp_path / "x.log"
    msgs = sample_messages()
    assert write_candump(path, msgs, channel="can0") == len(msgs)
    assert not any(line.endswith((" R", " T")) for line in path.read_text().splitlines())
    ours = list(read_candump(path))
    theirs = list(can.CanutilsLogReader(path))
    assert [key(m) for m in ours] == [key(m) for m in theirs]
    for a, b in zip(ours, msgs, strict=True):
        assert a.equals(b, timestamp_delta=1e-6, check_channel=False)


def test_reads_python_can_writer_output_like_python_can(tmp_path: Path) -> None:
    path = tmp_path / "pc.log"
    with can.CanutilsLogWriter(path, channel="vcan0") as writer:
        for i, m in enumerate(sample_messages()):
            m.is_rx = i % 2 == 0
            writer.on_message_received(m)
    assert "R" in path.read_text().splitlines()[0].split()[-1]
    assert [key(m) for m in read_candump(path)] == [key(m) for m in can.CanutilsLogReader(path)]


def test_bad_lines_are_counted_skipped_and_reported(caplog: pytest.LogCaptureFixture) -> None:
    good = "(1.000000) can0 0CFF1080#0102030405060708"
    bad = [
        "garbage",
        "(x) can0 123#00",
        "1.0 can0 123#00",
        "(1.0) can0 123#0",
        "(1.0) can0 12345#00",
        "(1.0) can0 0CFF1080#00112233445566778899",
        "(1.0) can0 800#00",
        "(1.0) can0 123#ZZ",
        "(nan) can0 0CFF1080#0102030405060708",  # ended all output before, exit 0
        "(-inf) can0 0CFF1080#0102030405060708",  # a traceback before
        "(-1700000000.000001) can0 0CFF1080#0102030405060708",  # 4.9e11 samples 'lost'
    ]
    text = "\n".join([good, *bad, "", good]) + "\n"
    reader = CandumpReader(io.StringIO(text))
    with caplog.at_level(logging.WARNING, logger=canlog.__name__):
        msgs = list(reader)
    assert len(msgs) == 2 and reader.bad_lines == len(bad) and reader.frames == 2
    records = [r.getMessage() for r in caplog.records]
    assert len(records) == canlog.MAX_LOGGED_BAD_LINES + 1
    assert "<stream>:2:" in records[0] and "'garbage'" in records[0] and "expected" in records[0]
    assert f"{len(bad)} malformed lines skipped" in records[-1]
    with pytest.raises(ValueError):
        list(can.CanutilsLogReader(io.StringIO(text)))  # what we do not copy


def test_reader_names_the_file(tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    path = tmp_path / "bad.log"
    path.write_text("(1.0) can0 123#00 X\n")
    with caplog.at_level(logging.WARNING, logger=canlog.__name__):
        assert list(read_candump(path)) == []
    assert f"{path}:1:" in caplog.records[0].getMessage()
