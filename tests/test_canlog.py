"""candump -L log I/O: write/read round trip, agreement with python-can, tolerant reading."""

from __future__ import annotations

import io
import logging
import math
from collections.abc import Callable
from decimal import Decimal
from pathlib import Path

import can
import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from drivers.errors import InputError
from drivers.logs import candump as canlog
from drivers.logs.candump import (
    CandumpReader,
    CandumpWriter,
    format_candump_line,
    read_candump,
    write_candump,
)

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


# --- The fast paths (issue 14) against the careful ones -------------------------------------
#
# The reader and parse_candump_line try canlog._parse_fast first and leave every line it does
# not take to canlog._parse_careful (the parser as it was). The properties: on any line, the
# combination gives what the careful parser alone gives (the same message, slot for slot and
# type for type, or the same error with the same text), and the reader's frames, counts and
# warnings are those of a plain careful loop. The writer's inline fast path writes the same
# bytes as format_candump_line for any frames, over several write_all/write calls.

SLOTS = tuple(s for s in can.Message.__slots__ if s != "__weakref__")
HEXDIGITS = "0123456789ABCDEFabcdef"


def slots(m: can.Message | None) -> tuple | None:
    """Every field of a message, its type and its repr (so 0.0 and -0.0, int and bool differ)."""
    if m is None:
        return None
    return tuple((s, type(getattr(m, s)).__name__, repr(getattr(m, s))) for s in SLOTS)


def outcome(parse: Callable[[], can.Message | None]) -> tuple:
    """What a parse gives: the message's slots, or the exception's type and text."""
    try:
        return ("ok", slots(parse()))
    except Exception as exc:  # the careful parser's own ValueError (channel '²') included
        return ("raised", type(exc).__name__, str(exc))


def hex_text(draw: st.DrawFn, n: int) -> str:
    return "".join(draw(st.lists(st.sampled_from(HEXDIGITS), min_size=n, max_size=n)))


ODD_STAMPS = [
    "-0.0", "+1.5", "-1.000000", "1e9", "1.5E-3", "1_0.5", "1_.5", "inf", "nan", "-inf",
    "Infinity", "١٧٠٠.٥", "0.000000", ".5", "5.", ".", "", "1e400", "9" * 400 + ".0", "0x10",
    "²", "(1.0)", "1.0)", "1,5",
]  # fmt: skip
ODD_IDS = [
    "7FF", "800", "000", "FFF", "1FFFFFFF", "20000000", "20000080", "200000A0", "FFFFFFFF",
    "00000000", "80000000", "0x1", "-12", "+7F", "1_2", "-0000001", "-1FFFFFF", "-7FFFFFF",
    "0x1FFFFF", "1_FFFFFF", "١٢٣", "0CFF108", "0CFF10800", "",
]  # fmt: skip
ODD_DATA = [
    "R", "r", "R0", "R8", "R9", "R-1", "R+1", "R_1", "RX", "R١", "#", "#1", "#G00", "#0" + "00" * 9,
    "#3" + "00" * 12, "#1" + "00" * 64, "#1" + "00" * 65, "0", "001", "0" * 18, "ZZ", "0x",
    "1_2", "١٢", "#R",
]  # fmt: skip
CHANNELS = ["can0"] * 8 + ["vcan1", "0", "12", "²", "can_x", "any", "٣", "c#n", "(1.0)", "ç"]
FLAGS = ["R", "T", "r", "t", "X", "RR", "İ", "R T", "#", "1"]
SPACES = [" "] * 8 + ["  ", "\t", "\x0b", "\x1c", "\u2003", "\u00a0"]


@st.composite
def stamps(draw: st.DrawFn) -> str:
    kind = draw(st.integers(0, 9))
    if kind <= 4:  # what candump and python-can write
        return f"{draw(st.floats(0.0, 4e9, allow_nan=False)):f}"
    if kind <= 6:  # any number of digits either side of the point, or none, or two points
        whole = draw(st.text("0123456789", max_size=20))
        frac = draw(st.text("0123456789", max_size=12))
        return whole + draw(st.sampled_from([".", ".", "", ".."])) + frac
    if kind == 7:
        return repr(draw(st.floats()))
    if kind == 8:  # signs, exponents, underscores, other digits, words float() takes
        return draw(st.sampled_from(ODD_STAMPS))
    return draw(st.text(max_size=12))


@st.composite
def frames(draw: st.DrawFn) -> str:
    kind = draw(st.integers(0, 9))
    if kind <= 3:
        id_text = hex_text(draw, 8)
    elif kind <= 5:
        id_text = hex_text(draw, 3)
    elif kind <= 7:  # the edges: largest ids, error frames, signs and prefixes int() takes
        id_text = draw(st.sampled_from(ODD_IDS))
    elif kind == 8:
        id_text = hex_text(draw, draw(st.integers(0, 10)))
    else:
        id_text = draw(st.text(max_size=9))
    kind = draw(st.integers(0, 9))
    if kind <= 5:  # classic data, whole bytes
        data = hex_text(draw, 2 * draw(st.integers(0, 8)))
    elif kind == 6:
        data = hex_text(draw, draw(st.integers(0, 20)))
    elif kind == 7:  # CAN FD ('##', a flags digit, data), remote frames, odd data
        data = draw(st.sampled_from(ODD_DATA))
    elif kind == 8:
        data = (
            "#"
            + draw(st.sampled_from(["0", "1", "3", "F"]))
            + hex_text(draw, 2 * draw(st.sampled_from([0, 1, 8, 9, 12, 64])))
        )
    else:
        data = draw(st.text(HEXDIGITS + "#Rr xZ", max_size=20))
    return id_text + draw(st.sampled_from(["#"] * 8 + ["", "##"])) + data


@st.composite
def lines(draw: st.DrawFn) -> str:
    """A candump line: well formed, or with one or more fields odd, or cut, or text inserted."""
    fields = [f"({draw(stamps())})", draw(st.sampled_from(CHANNELS)), draw(frames())]
    if draw(st.booleans()):
        fields.append(draw(st.sampled_from(FLAGS)))
    if draw(st.integers(0, 9)) == 0:
        del fields[draw(st.integers(0, len(fields) - 1))]
    text = fields[0]
    for field in fields[1:]:
        text += draw(st.sampled_from(SPACES)) + field
    if draw(st.integers(0, 3)) == 0:  # a mutation anywhere
        at = draw(st.integers(0, len(text)))
        cut = draw(st.integers(0, 3))
        text = text[:at] + draw(st.text(max_size=3)) + text[at + cut :]
    lead = draw(st.sampled_from(["", "", "", " ", "\t"]))
    end = draw(st.sampled_from(["\n", "\n", "\n", "", "\r\n", " \n", "\t"]))
    return lead + text + end


#: Lines at the fast path's edges, tried on every run.
EDGE_LINES = [
    "(1.0) can0 -0000001#01\n",  # the careful parser reads an error frame
    "(1.0) can0 -1FFFFFF#\n",
    "(1.0) can0 -12#01\n",  # a negative standard id, read as such
    "(1.0) can0 0x1#01\n",
    "(1.0) can0 20000080#\n",
    "(1.0) can0 123#01 t\n",
    "(1.0) can0 123#01 T\n",
    "(1.0) can0 123#01 r\n",
    "(1.0) can0 1FFFFFFF#0102030405060708 R\n",
    "(1.0) can0 7FF#01\n",
    "(1.0) can0 800#01\n",
    "(1.0) 12 123#01\n",
    "(-0.0) can0 123#01\n",
    "(١٧٠٠.٥) can0 123#01\n",
    "(1_0.5) can0 123#01\n",
    "(1.0) can0 123\n",
    "(1.0) can0 123#0\n",
    "(1.0) can0 123#0102030405060708090A\n",
    "(1700000000.123456)\tcan0\x1c0CFF1080#0102\u2003\n",
]


CAREFUL = settings(max_examples=1500, deadline=None, suppress_health_check=[HealthCheck.too_slow])


def edge_lines(f: Callable[[str], None]) -> Callable[[str], None]:
    for line in EDGE_LINES:
        f = example(line)(f)
    return f


@CAREFUL
@given(lines())
@edge_lines
def test_fast_parse_gives_what_the_careful_parser_gives(line: str) -> None:
    careful = outcome(lambda: canlog._parse_careful(line, "f.log:7"))
    assert outcome(lambda: canlog.parse_candump_line(line, "f.log:7")) == careful
    fast = canlog._parse_fast(line)
    if fast is not None:  # it only takes lines the careful parser reads, as that reads them
        assert careful == ("ok", slots(fast))


@CAREFUL
@given(st.text(max_size=80))
def test_fast_parse_of_any_text_is_the_careful_parse(line: str) -> None:
    careful = outcome(lambda: canlog._parse_careful(line, "f.log:7"))
    assert outcome(lambda: canlog.parse_candump_line(line, "f.log:7")) == careful


def test_fast_parse_takes_the_common_lines_and_leaves_the_rest() -> None:
    fast = canlog._parse_fast
    taken = [
        "(1700000000.123456) can0 0CFF1080#0102030405060708\n",
        "(1700000000.123456) can0 0CFF1080#0102030405060708",
        "(1.000000) vcan1 123#01 R\n",
        "(0.5) can0 1FFFFFFF# T\r\n",
        "(1700000000.000699) can0 0CFF1080#f6bf0180008000f2\n",
        "(-0.0) can0 123#01\n",  # -0.0 seconds, as float() reads it
    ]
    for line in taken:
        msg = fast(line)
        assert msg is not None and slots(msg) == slots(canlog._parse_careful(line, "x")), line
    left = [
        "",
        "\n",
        "(1.0) can0 123#R\n",  # remote
        "(1.0) can0 20000080#\n",  # error frame
        "(1.0) can0 123##1010203\n",  # CAN FD
        "(1.0) 0 123#01\n",  # numeric channel: can.Message.channel is the int 0
        "(1.0) can0 123#0102 X\n",
        "(nan) can0 0CFF1080#0102030405060708\n",
        "(1.0) can0 0CFF1080#00112233445566778899\n",
        "garbage\n",
        "(1.0) can0 000\n",  # no '#'
    ]
    assert [line for line in left if fast(line) is not None] == []


class ListHandler(logging.Handler):
    """Keeps the records (caplog is function-scoped, so not for a hypothesis test)."""

    def __init__(self) -> None:
        super().__init__(logging.WARNING)
        self.records: list[logging.LogRecord] = []

    def emit(self, record: logging.LogRecord) -> None:
        self.records.append(record)


def careful_read(text: str, name: str) -> tuple[list[tuple | None], int, list[str]]:
    """The reader as it was: the careful parser on every line, the same counting and log."""
    msgs: list[tuple | None] = []
    bad = 0
    warnings = []
    for number, line in enumerate(io.StringIO(text), start=1):
        try:
            msg = canlog._parse_careful(line, f"{name}:{number}")
        except InputError as exc:
            bad += 1
            if bad <= canlog.MAX_LOGGED_BAD_LINES:
                warnings.append(f"skipped malformed candump line: {exc}")
            continue
        if msg is not None:
            msgs.append(slots(msg))
    if bad > canlog.MAX_LOGGED_BAD_LINES:
        n = canlog.MAX_LOGGED_BAD_LINES
        warnings.append(f"{name}: {bad} malformed lines skipped in all ({bad - n} not shown)")
    return msgs, bad, warnings


def reader_result(text: str) -> tuple[list[tuple | None], int, int, list[str]]:
    """The reader's messages (as slots), frames, bad lines and warnings on ``text``."""
    stream = io.StringIO(text)
    stream.name = "gen.log"
    reader = CandumpReader(stream)
    logger = logging.getLogger(canlog.__name__)
    handler = ListHandler()
    logger.addHandler(handler)
    try:
        got = [slots(m) for m in reader]
    finally:
        logger.removeHandler(handler)
    return got, reader.frames, reader.bad_lines, [r.getMessage() for r in handler.records]


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(lines(), max_size=20))
def test_reader_gives_the_frames_counts_and_warnings_of_the_careful_loop(
    line_list: list[str],
) -> None:
    text = "".join(line if line.endswith("\n") else line + "\n" for line in line_list)
    text = text.replace("²", "2")  # its ValueError would end both reads: tested line by line
    msgs, bad, warnings = careful_read(text, "gen.log")
    assert reader_result(text) == (msgs, len(msgs), bad, warnings)


def test_reader_on_a_file_counts_lines_like_the_careful_loop(tmp_path: Path) -> None:
    good = "(1700000000.000699) can0 0CFF1080#F6BF0180008000F2"
    lines_ = [good, "", "(1.0) can0 123#R", "x y z", good + " T", "(1.0) can0 123##0", good]
    path = tmp_path / "mixed.log"
    path.write_text("\n".join(lines_) + "\n")
    reader = CandumpReader(path)
    got = [slots(m) for m in reader]
    msgs, bad, _ = careful_read(path.read_text(), str(path))
    assert got == msgs and len(msgs) == 5 and reader.frames == 5 and reader.bad_lines == bad == 1


TIMESTAMPS = st.one_of(
    st.sampled_from([0.0, -0.0, 1700000000.123456, 1700000000.1234565, 1.0, 5e-324, 1e300]),
    st.floats(),
    st.floats(0.0, 4e9),
    st.integers(0, 2**40),
)


@st.composite
def messages(draw: st.DrawFn, stamps: list[float]) -> can.Message:
    """A frame as the core or a bus hands it to the writer: mostly plain extended data frames."""
    kind = draw(st.integers(0, 9))
    fd = kind == 7
    msg = can.Message(
        timestamp=draw(st.sampled_from(stamps)),
        arbitration_id=draw(st.integers(0, 0x1FFFFFFF) if kind != 8 else st.integers(0, 0x7FF)),
        is_extended_id=kind != 8,
        is_remote_frame=kind == 6,
        is_error_frame=kind == 5,
        is_fd=fd,
        bitrate_switch=fd and draw(st.booleans()),
        error_state_indicator=fd and draw(st.booleans()),
        data=draw(st.binary(max_size=64 if fd else 8)),
        channel=draw(st.sampled_from([None, None, None, "can0", "vcan1", "2", 3, "٣", "ç"])),
    )
    if kind == 9:  # an int or numpy timestamp, a bool id: left to format_candump_line
        if math.isfinite(msg.timestamp):
            msg.timestamp = draw(st.sampled_from([int, np.float64]))(msg.timestamp)
        msg.arbitration_id = draw(st.sampled_from([msg.arbitration_id, True]))
    return msg


def raised(fn: Callable[[], object]) -> tuple[str, str] | None:
    try:
        fn()
    except Exception as exc:
        return type(exc).__name__, str(exc)
    return None


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    st.data(),
    st.one_of(st.lists(TIMESTAMPS, min_size=1, max_size=4), st.just([0.0, -0.0])),
    st.sampled_from(["can0", "vcan9", "7"]),
)
def test_writer_writes_the_bytes_of_format_candump_line(
    tmp_path_factory: pytest.TempPathFactory, data: st.DataObject, stamps: list[float], channel: str
) -> None:
    """Any frames, in several calls (the timestamp text is reused across them) and write();
    a channel ASCII cannot encode fails the same way, after the same lines."""
    msgs = data.draw(st.lists(messages(stamps), max_size=40))
    cuts = sorted(data.draw(st.lists(st.integers(0, len(msgs)), max_size=4)))
    folder = tmp_path_factory.mktemp("w")

    def ours() -> None:
        with CandumpWriter(folder / "ours.log", channel) as writer:
            start = 0
            for cut in [*cuts, len(msgs)]:
                if cut - start == 1:
                    writer.write(msgs[start])
                else:
                    assert writer.write_all(iter(msgs[start:cut])) == cut - start
                start = cut

    def reference() -> None:  # the writer as it was
        with (folder / "ref.log").open("w", encoding="ascii", newline="\n") as file:
            for msg in msgs:
                file.write(format_candump_line(msg, channel) + "\n")

    assert raised(ours) == raised(reference)
    assert (folder / "ours.log").read_bytes() == (folder / "ref.log").read_bytes()


def test_writer_reuses_a_timestamp_text_only_for_the_same_object(tmp_path: Path) -> None:
    t = 1700000000.5
    stamps_: list[object] = [t, t, t + 0.0, t + 1e-7, 0.0, -0.0, 0.0, -0.0, math.nan, math.nan]
    stamps_ += [5.0, Decimal(5), 5, np.float64(5.0), t]  # equal to 5.0, written differently
    msgs = [can.Message(arbitration_id=0x0CFF1080, data=b"\x01") for _ in stamps_]
    for msg, ts in zip(msgs, stamps_, strict=True):
        msg.timestamp = ts  # type: ignore[assignment]
    path = tmp_path / "stamps.log"
    write_candump(path, msgs)
    assert path.read_text() == "".join(format_candump_line(m) + "\n" for m in msgs)
    written = [line.split()[0] for line in path.read_text().splitlines()]
    assert written[4:8] == ["(0.000000)", "(-0.000000)", "(0.000000)", "(-0.000000)"]
    assert written[10:13] == ["(5.000000)", "(5)", "(5.000000)"]
    # a message without a time fails as it did, after the lines before it
    msgs[1].timestamp = None  # type: ignore[assignment]
    with pytest.raises(TypeError):
        format_candump_line(msgs[1])
    with pytest.raises(TypeError):
        write_candump(path, msgs[:2])
    assert path.read_text() == format_candump_line(msgs[0]) + "\n"
