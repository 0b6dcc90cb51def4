"""The candump reader's block path (issue 14) against the careful per-line parser.

The reader takes the lines of each block's most common layout at once with numpy and leaves
every other line to :func:`candump.frame_fields` and the careful parser. The properties: the
records are those each line alone gives (the same values, bit for bit, and types), the frames,
counts and warnings those of the careful loop, whatever the lines, the block size, the line
endings; and the IMU decoder fed those records gives what it gives fed the messages.
"""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from drivers.imu_can import ImuDecoder, read_log, sample_period_s
from drivers.logs import candump as canlog
from drivers.logs.candump import CandumpReader, format_candump_line, read_candump
from sim_bus.adis16334 import Adis16334Config, simulate
from sim_bus.imu_frames import frames
from tests.test_canlog import HEXDIGITS, careful_read, hex_text, lines, reader_result, slots

#: Characters a mutation puts into a line of the common layout: each kind a check must catch.
ODD_CHARS = "0 9aF?.#()-_+\t\r\x00\u00e9\u0661\u00b2\ufffd"


@st.composite
def layout_lines(draw: st.DrawFn) -> list[str]:
    """Lines of one layout ``(W.F) CH IIIIIIII#DD..``, digits drawn, some mutated or odd."""
    whole = draw(st.integers(1, 19))
    frac = draw(st.integers(1, 19))
    channel = draw(st.sampled_from(["can0", "vcan1", "c-a_n.2", "12", "can0 "]))
    size = draw(st.integers(1, 9))
    out = []
    for _ in range(draw(st.integers(1, 40))):
        kind = draw(st.integers(0, 9))
        if kind == 9:
            out.append(draw(lines()).rstrip("\n"))
            continue
        digits = draw(st.text("0123456789", min_size=whole + frac, max_size=whole + frac))
        if kind == 8:  # the largest values: at and beyond 2^53 and 29 bits
            digits = str(2**53 + draw(st.integers(-2, 2))).zfill(whole + frac)[-(whole + frac) :]
        can_id = hex_text(draw, 8) if kind != 7 else draw(st.sampled_from(["1FFFFFFF", "20000000"]))
        line = f"({digits[:whole]}.{digits[whole:]}) {channel} {can_id}#{hex_text(draw, 2 * size)}"
        if kind == 6:  # one character replaced
            at = draw(st.integers(0, len(line) - 1))
            line = line[:at] + draw(st.sampled_from(ODD_CHARS)) + line[at + 1 :]
        out.append(line)
    return out


BLOCKS = settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])


@BLOCKS
@given(layout_lines(), st.sampled_from([1, 7, 64, 300, 1 << 20]), st.sampled_from(["\n", ""]))
def test_blocks_read_what_the_careful_loop_reads(
    line_list: list[str], block_chars: int, end: str
) -> None:
    text = "\n".join(line_list) + end
    text = text.replace("²", "2")  # its ValueError would end both reads: tested line by line
    saved = canlog._BLOCK_CHARS
    canlog._BLOCK_CHARS = block_chars
    try:
        got, n_frames, bad, warnings = reader_result(text)
    finally:
        canlog._BLOCK_CHARS = saved
    msgs, careful_bad, careful_warnings = careful_read(text, "gen.log")
    assert got == msgs
    assert (n_frames, bad) == (len(msgs), careful_bad)
    assert warnings == careful_warnings


@BLOCKS
@given(layout_lines())
def test_block_records_are_the_fields_of_each_line(line_list: list[str]) -> None:
    """Bit for bit and type for type: the block path's records are frame_fields' of the line."""
    text = "\n".join(line_list).replace("²", "2")
    records = list(CandumpReader(io.StringIO(text)).records())
    alone = [r for r in map(canlog.frame_fields, text.split("\n")) if r is not None]
    fields = [r for r in records if isinstance(r, tuple)]
    assert [(repr(r), [type(v) for v in r]) for r in fields] == [
        (repr(r), [type(v) for v in r]) for r in alone
    ]
    assert [r[0].hex() for r in fields] == [r[0].hex() for r in alone]


@settings(max_examples=2000, deadline=None)
@given(st.integers(2, 18), st.data())
def test_block_timestamps_are_float_of_the_text(digits: int, data: st.DataObject) -> None:
    """N / 10^F is the correctly rounded decimal, as float() reads it, up to N = 2^53."""
    whole = data.draw(st.integers(1, digits - 1))
    text = data.draw(st.text("0123456789", min_size=digits, max_size=digits))
    if data.draw(st.booleans()):  # around 2^53
        text = str(2**53 + data.draw(st.integers(-(10**6), 10**6))).zfill(digits)[-digits:]
    stamp = f"{text[:whole]}.{text[whole:]}"
    _, others, alike = canlog._alike_lines(f"({stamp}) can0 0CFF1080#00")
    if int(text) <= 2**53:
        ((t, *_),) = list(alike)
        assert not others and t.hex() == float(stamp).hex()
    else:
        assert not list(alike) and len(others) == 1


def test_line_endings_of_a_file_are_those_of_line_iteration(tmp_path: Path) -> None:
    good = "(1700000000.000699) can0 0CFF1080#F6BF0180008000F2"
    body = [good] * 30 + ["(1.0) can0 123#R", good + "\r", "x", good, "", good]
    for newline in ("\n", "\r\n", "\r"):
        path = tmp_path / "endings.log"
        path.write_bytes(newline.join(body).encode("ascii") + b"\r\n\xff" + good.encode())
        got = [slots(m) for m in read_candump(path)]
        with path.open(encoding="ascii", errors="replace") as f:
            msgs, _, _ = careful_read(f.read(), str(path))
        assert got == msgs, newline


def imu_log_text(seconds: float, seed: int) -> str:
    """A bridge log as candump lines, with frames dropped, repeated, moved and corrupted."""
    dt = sample_period_s(2)
    n = int(seconds / dt)
    t = 1.7e9 + np.arange(n) * dt
    out = simulate(t, np.zeros((n, 3)), np.tile([0.0, 0.0, -9.80665], (n, 1)), Adis16334Config())
    text = [format_candump_line(m) for m in frames(out)]
    rng = np.random.default_rng(seed)
    for k in rng.choice(len(text), len(text) // 20, replace=False).tolist():
        line = text[k]
        match k % 5:
            case 0:
                text[k] = ""
            case 1:
                text[k] = line + "\n" + line
            case 2:
                text[k] = line[:-2]  # a byte short
            case 3:
                text[k] = line.replace("can0", "can0 ", 1) + " R"  # read one by one
            case _:
                at = int(rng.integers(len(line)))
                text[k] = line[:at] + "F" + line[at + 1 :]  # a wrong digit: SEQ, reserved ...
    return "\n".join(text) + "\n"


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_decoder_fed_records_gives_what_it_gives_fed_messages(seed: int) -> None:
    text = imu_log_text(3.0, seed)
    by_message = ImuDecoder()
    expected = [repr(i) for m in read_candump(io.StringIO(text)) for i in by_message.feed(m)]
    by_message.finish()
    by_record = ImuDecoder()
    got = [repr(i) for i in read_log(io.StringIO(text), by_record)]
    assert got == expected and len(got) > 500
    assert by_record.counters == by_message.counters
    assert by_record.counters.malformed and by_record.counters.unpaired


def test_hex_table_is_int_base_16() -> None:
    for byte in range(256):
        c = chr(byte)
        expected = int(c, 16) if c in HEXDIGITS else 16
        assert canlog._HEX[byte] == expected
