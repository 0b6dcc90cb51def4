"""NMEA log format (SPEC 3): write, read back, and survive bad lines."""

from __future__ import annotations

import io
import logging
import re
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from drivers.errors import InputError
from drivers.logs.nmea_log import (
    format_nmea_log_line,
    parse_nmea_log_line,
    read_nmea_log,
    write_nmea_log,
)

GGA = "$GNGGA,221320.10,5212.0000480,N,01029.9999604,E,4,22,0.70,32.984,M,47.000,M,1.1,0000*58"
RMC = "$GNRMC,221320.10,A,5212.0000480,N,01029.9999604,E,2.136,334.77,141123,,,R*64"


def test_format_and_parse_one_line() -> None:
    line = format_nmea_log_line(1700000000.123456, GGA)
    assert line == f"(1700000000.123456) {GGA}"
    assert parse_nmea_log_line(line + "\r\n") == (1700000000.123456, GGA)
    assert format_nmea_log_line(None, RMC + "\r\n") == RMC


def test_blank_unprefixed_and_junk_lines() -> None:
    assert parse_nmea_log_line("   \r\n") is None
    assert parse_nmea_log_line(RMC) == (None, RMC)
    assert parse_nmea_log_line("\x00\xb5bjunk") == (None, "\x00\xb5bjunk")  # the driver judges it


@pytest.mark.parametrize(
    ("line", "what"),
    [
        ("(1700000000.123456 $GNGGA", "no ')' closing the host time"),
        ("(17000x0000.1) $GNGGA", "not decimal seconds"),
        ("(-1.0) $GNGGA", "not decimal seconds"),
        ("(1700000000.1)   ", "nothing after"),
    ],
)
def test_malformed_prefixes_raise_with_what_was_expected(line: str, what: str) -> None:
    with pytest.raises(InputError, match=re.escape(what)) as info:
        parse_nmea_log_line(line, "gnss.nmea:7")
    assert str(info.value).startswith("gnss.nmea:7: ")
    assert "expected '(<seconds>) $<sentence>'" in str(info.value)


def test_written_log_reads_back_identical(tmp_path: Path) -> None:
    lines = [(1700000000.1 + 0.1 * i, GGA if i % 2 else RMC) for i in range(50)] + [(None, RMC)]
    path = tmp_path / "gnss.nmea"
    write_nmea_log(path, lines)
    back = list(read_nmea_log(path))
    assert [s for _, s in back] == [s for _, s in lines]
    assert back[-1][0] is None
    assert [t for t, _ in back[:-1]] == pytest.approx([t for t, _ in lines[:-1]], abs=5e-7)
    path2 = tmp_path / "again.nmea"
    write_nmea_log(path2, back)
    assert path2.read_bytes() == path.read_bytes()


def test_reader_skips_and_reports_bad_lines_without_aborting(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    path = tmp_path / "bad.nmea"
    path.write_bytes(
        f"(1700000000.100000) {GGA}\n".encode()
        + b"\xb5b\x01\x07\xff\xfe binary\r\n"
        + b"(17000000x0.2) $GNRMC\n"
        + b"\n"
        + f"{RMC}\r\n".encode()
    )
    with caplog.at_level(logging.WARNING, logger="drivers.logs.nmea_log"):
        reader = read_nmea_log(path)
        got = list(reader)
    assert got == [(1700000000.1, GGA), (None, "\ufffdb\x01\x07\ufffd\ufffd binary"), (None, RMC)]
    assert reader.bad_lines == 1
    assert caplog.messages == [
        f"skipped malformed NMEA log line: {path}:3: host time '17000000x0.2' is not decimal "
        "seconds; expected '(<seconds>) $<sentence>', e.g. '(1700000000.123456) $GNGGA,...*hh', "
        "or no prefix"
    ]


def test_reports_are_rate_limited_but_every_bad_line_counted(
    caplog: pytest.LogCaptureFixture,
) -> None:
    text = io.StringIO("(bad) x\n" * 25 + f"{GGA}\n")
    with caplog.at_level(logging.WARNING, logger="drivers.logs.nmea_log"):
        reader = read_nmea_log(text, max_reports=3)
        assert list(reader) == [(None, GGA)]
    assert reader.bad_lines == 25
    assert len(caplog.messages) == 3 + 1
    assert caplog.messages[0].startswith("skipped malformed NMEA log line: <stream>:1: ")
    assert caplog.messages[-1] == "<stream>: 25 malformed lines skipped in all (22 not shown)"


def test_round_trip_of_simulated_receiver_output(tmp_path: Path) -> None:
    from sim_bus.gnss_receiver import simulate_receiver
    from tests.test_gnss_receiver import straight_truth

    out = simulate_receiver(straight_truth(3.0, (1.0, 0.0)))
    path = tmp_path / "sim.nmea"
    write_nmea_log(path, out.lines)
    back = list(read_nmea_log(path))
    assert [s for _, s in back] == [line.sentence for line in out.lines]
    assert [t for t, _ in back] == pytest.approx([a.host_t for a in out.lines], abs=5e-7)


@pytest.mark.parametrize("eol", ["\r\n", "\n", "\r"])
def test_any_line_end_splits_records(tmp_path: Path, eol: str) -> None:
    """CR-only logs were read as one record: aligning for the whole run."""
    path = tmp_path / "log.nmea"
    path.write_bytes(eol.join([f"(1700000000.1) {GGA}", f"(1700000000.2) {RMC}", ""]).encode())
    assert list(read_nmea_log(path)) == [(1700000000.1, GGA), (1700000000.2, RMC)]


class _Warnings(logging.Handler):
    def __init__(self) -> None:
        super().__init__()
        self.messages: list[str] = []

    def emit(self, record: logging.LogRecord) -> None:
        self.messages.append(record.getMessage())


SPACE = st.sampled_from(["", " ", "  ", "\t", "\u00a0", "\u2003", "\x1c", "\x0b", "\x85"])
STAMP = st.one_of(
    st.from_regex(r"\d{1,10}(\.\d{0,6})?", fullmatch=True),
    st.sampled_from(["", ".5", "1.", "1.2.3", "-1", "1e5", "1_0", " 1", "\u0661\u0662.3", "inf"]),
    st.text(alphabet="0123456789.()x ", max_size=8),
)
LOG_LINE = st.one_of(
    st.builds(
        lambda a, stamp, close, b, rest, c: f"{a}({stamp}{close}{b}{rest}{c}",
        *(SPACE, STAMP, st.sampled_from([")", "", "))"]), SPACE),
        *(st.sampled_from(["", GGA, RMC, "$", "x y", "(1) $X"]), SPACE),
    ),
    st.builds(lambda a, s, b: a + s + b, SPACE, st.sampled_from(["", GGA, "junk", ")"]), SPACE),
    st.text(max_size=30),
)


@settings(max_examples=300, deadline=None)
@given(st.lists(LOG_LINE, max_size=25), st.integers(0, 4))
def test_reader_gives_what_parse_nmea_log_line_gives(lines: list[str], max_reports: int) -> None:
    """Issue 14: the reader parses well-formed lines itself (no where-string per line); for
    any line it keeps and reports what parse_nmea_log_line says of it."""
    stream = io.StringIO("".join(x + "\n" for x in lines))
    expected, bad, reports = [], 0, []
    for lineno, line in enumerate(io.StringIO(stream.getvalue()), 1):
        try:
            parsed = parse_nmea_log_line(line, f"<stream>:{lineno}")
        except InputError as exc:
            bad += 1
            reports += [f"skipped malformed NMEA log line: {exc}"] if bad <= max_reports else []
            continue
        expected += [parsed] if parsed is not None else []
    if bad > max_reports:
        reports.append(
            f"<stream>: {bad} malformed lines skipped in all ({bad - max_reports} not shown)"
        )
    assert read_all(stream, max_reports) == (expected, bad, reports)


@settings(max_examples=100, deadline=None)
@given(st.lists(LOG_LINE, max_size=25))
def test_reader_of_a_binary_stream_decodes_each_line_as_ascii(lines: list[str]) -> None:
    data = "".join(x + "\n" for x in lines).encode("utf-8", "replace")
    text = io.StringIO(
        "".join(x.decode("ascii", errors="replace") for x in io.BytesIO(data)), newline="\n"
    )
    assert read_all(io.BytesIO(data), 3) == read_all(text, 3)


def read_all(
    stream: io.StringIO | io.BytesIO, max_reports: int
) -> tuple[list[tuple[float | None, str]], int, list[str]]:
    warnings = _Warnings()
    logger = logging.getLogger("drivers.logs.nmea_log")
    logger.addHandler(warnings)
    try:
        reader = read_nmea_log(stream, max_reports)
        got = list(reader)
    finally:
        logger.removeHandler(warnings)
    return got, reader.bad_lines, warnings.messages
