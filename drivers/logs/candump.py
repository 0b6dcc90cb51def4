"""candump ``-L`` log files (SPEC 3): one formatter, one tolerant parser.

A line is ``(1700000000.123456) can0 0CFF1080#0C00F4FF3A0001F2``. We write lines *without* the
trailing `` R``/`` T`` direction flag that python-can's ``CanutilsLogWriter`` appends: candump
itself does not write it and some tools (canboat's candump2analyzer) misread the frame when it
is there. On input the flag is accepted. The reader yields the same ``can.Message`` objects as
python-can's ``CanutilsLogReader`` for well-formed input, but skips a malformed line (counting
it and logging it, at a limited rate, with file, line number, text and what was expected)
instead of ending the whole read. Replay and the IMU driver's log source both use this parser.

Speed (issue 14): both directions have a fast path for the common shape, a data frame of at most
8 bytes with a 3- or 8-digit id, e.g. the line above. :func:`frame_fields` accepts only lines
the careful parser :func:`_parse_careful` accepts, and gives the fields of the identical
message (:func:`message_of` makes it); it returns ``None`` for anything else (remote, error and
CAN FD frames, numeric channels, every malformed line), which the careful parser then reads,
rejects or explains. The reader goes further: it reads the text in blocks and the lines of a
block's most common layout (all alike but for their digits, as a bridge's log is) at once with
numpy, to the same fields (:func:`_alike_lines`), leaving every other line to the two parsers;
replay takes those fields (:meth:`CandumpReader.records`) and makes no message of the IMU's
frames. The file location of a line ("name:number") is only built for a line the fast paths
leave. Likewise the writer formats the common frame inline, with the expressions of
:func:`format_candump_line`, and leaves the rest to it. tests/test_canlog.py and
tests/test_candump_blocks.py check all of them against the careful paths on generated lines.
"""

from __future__ import annotations

import logging
import math
import re
from collections.abc import Iterable, Iterator
from contextlib import nullcontext
from dataclasses import dataclass
from itertools import chain, islice, repeat
from pathlib import Path
from typing import TextIO

import can
import numpy as np
import numpy.typing as npt

from drivers.errors import InputError
from drivers.logs.closing import Closing

log = logging.getLogger(__name__)

#: candump's error-frame id flags (linux/can/error.h), as python-can reads and writes them.
CAN_ERR_FLAG = 0x20000000
CAN_ERR_BUSERROR = 0x00000080
_CANFD_BRS = 0x01
_CANFD_ESI = 0x02
_CANFD_LENGTHS = frozenset((*range(9), 12, 16, 20, 24, 32, 48, 64))

LINE_FORMAT = "'(<seconds>) <channel> <hex id>#<hex data>' with an optional trailing R or T"

#: Malformed lines logged individually per file before the reader goes quiet (then a summary).
MAX_LOGGED_BAD_LINES = 5

# The fast paths' constants.
_DIRECTION = {"R": True, "r": True, "T": False, "t": False}
_INF = math.inf
_NO_STAMP = object()
_new_object = object.__new__
_Message = can.Message
_fromhex = bytes.fromhex

#: A common line's data frame as :func:`frame_fields` reads it: (timestamp, arbitration id,
#: data, whether the id is extended, channel, whether received (no T flag)).
FrameFields = tuple[float, int, bytes, bool, str, bool]

# The block path's constants (:func:`_alike_lines`).
_BLOCK_CHARS = 1 << 20
_LAYOUT = re.compile(
    r"\(([0-9]{1,17})\.([0-9]{1,17})\) ([A-Za-z0-9_.\-]+) [0-9A-Fa-f]{8}#((?:[0-9A-Fa-f]{2}){1,8})"
)
_MAX_DIGITS = 18  # of a timestamp whose digits, read as one integer, fit an int64
_EXACT_INT = 2**53  # up to here every integer is a float64
_NEWLINE = ord("\n")
_ZERO, _NINE = ord("0"), ord("9")


def _hex_values() -> npt.NDArray[np.uint8]:
    """The value of each byte as a hex digit, as ``int(c, 16)`` reads it; 16 for any other."""
    table = np.full(256, 16, dtype=np.uint8)
    for c in "0123456789ABCDEFabcdef":
        table[ord(c)] = int(c, 16)
    return table


_HEX = _hex_values()


def format_candump_line(msg: can.Message, channel: str | int | None = None) -> str:
    """One candump ``-L`` line (no newline, no R/T flag) for ``msg``.

    ``channel`` is used when the message has none; a numeric channel ``n`` is written ``can<n>``
    as python-can does.
    """
    ch = msg.channel if msg.channel is not None else channel if channel is not None else "can0"
    if isinstance(ch, int) or (isinstance(ch, str) and ch.isdigit()):
        ch = f"can{ch}"
    if msg.is_error_frame:
        return f"({msg.timestamp:f}) {ch} {CAN_ERR_FLAG | CAN_ERR_BUSERROR:08X}#"
    can_id = f"{msg.arbitration_id:08X}" if msg.is_extended_id else f"{msg.arbitration_id:03X}"
    if msg.is_remote_frame:
        return f"({msg.timestamp:f}) {ch} {can_id}#R"
    fd = ""
    if msg.is_fd:
        flags = (_CANFD_BRS if msg.bitrate_switch else 0) | (
            _CANFD_ESI if msg.error_state_indicator else 0
        )
        fd = f"#{flags:X}"
    return f"({msg.timestamp:f}) {ch} {can_id}#{fd}{msg.data.hex().upper()}"


def _channel_text(channel: object) -> str | None:
    """What :func:`format_candump_line` writes for a message without a channel, given the
    writer's ``channel``; ``None`` (no fast path) unless that is a plain string or int."""
    ch = channel if channel is not None else "can0"
    if type(ch) is int:
        return f"can{ch}"
    if type(ch) is str:
        return f"can{ch}" if ch.isdigit() else ch
    return None


class CandumpWriter(Closing):
    """Writes messages as candump ``-L`` lines (without R/T); a context manager."""

    def __init__(self, path: str | Path, channel: str = "can0") -> None:
        self.path = Path(path)
        self.channel = channel
        self._default = _channel_text(channel)
        self._stamp: tuple[object, str] = (_NO_STAMP, "")  # last timestamp written fast, text
        self._file: TextIO = self.path.open("w", encoding="ascii", newline="\n")

    def write(self, msg: can.Message) -> None:
        """Append one frame."""
        self.write_all((msg,))

    def write_all(self, messages: Iterable[can.Message]) -> int:
        """Append every frame of ``messages``; returns how many.

        The common frame (data, not FD, extended id, channel a name or none) is written here
        with the expressions :func:`format_candump_line` uses, so the text is the same. The
        frames of one solution share one timestamp object, whose text is made once.
        """
        n = 0
        write = self._file.write
        channel = self.channel
        default = self._default
        last_ts, stamp = self._stamp
        for msg in messages:
            ch = msg.channel
            if ch is None:
                ch = default
            elif type(ch) is not str or ch.isdigit():
                ch = None
            if (
                ch is not None
                and msg.is_extended_id
                and not (msg.is_error_frame or msg.is_remote_frame or msg.is_fd)
            ):
                ts = msg.timestamp
                if ts is not last_ts:  # the same object has the same text
                    stamp = f"{ts:f}"
                    last_ts = ts
                    self._stamp = (ts, stamp)
                write(f"({stamp}) {ch} {msg.arbitration_id:08X}#{msg.data.hex().upper()}\n")
            else:
                write(format_candump_line(msg, channel) + "\n")
            n += 1
        return n

    def close(self) -> None:
        """Flush and close; safe to call twice."""
        if not self._file.closed:
            self._file.close()


def write_candump(path: str | Path, messages: Iterable[can.Message], channel: str = "can0") -> int:
    """Write ``messages`` to a new candump ``-L`` file; returns the number of frames."""
    with CandumpWriter(path, channel) as writer:
        return writer.write_all(messages)


def excerpt(text: str, limit: int = 60) -> str:
    """A bad line as a warning shows it: escaped, and cut to ``limit`` characters."""
    if len(text) <= limit:
        return repr(text)
    return f"{text[:limit]!r}... ({len(text)} characters)"


def parse_candump_line(line: str, where: str = "<line>") -> can.Message | None:
    """Parse one candump ``-L`` line; ``None`` for a blank line.

    Raises :class:`InputError` (naming ``where``, the text and the expected form) when the line
    is not a well-formed frame.
    """
    msg = _parse_fast(line)
    return msg if msg is not None else _parse_careful(line, where)


def _parse_fast(line: str) -> can.Message | None:
    """The common well-formed line as :func:`_parse_careful` reads it, else ``None``."""
    fields = frame_fields(line)
    return None if fields is None else message_of(fields)


def frame_fields(line: str) -> FrameFields | None:
    """The fields of a common well-formed line, as :func:`_parse_careful` reads them, else
    ``None``.

    Accepts three fields (or four, the last R, r, T or t), the same the careful parser splits:
    a finite timestamp >= 0 in parentheses, a channel that is not a number, and a data frame of
    at most 8 bytes with a 3-digit id up to 0x7FF or an 8-digit id up to 29 bits. Each field
    goes through the same conversion as there (float, int base 16, bytearray.fromhex), so the
    values are the same; any ValueError leaves the line to the careful parser.
    """
    fields = line.split()
    n = len(fields)
    if n == 3:
        stamp, channel, frame = fields
        is_rx = True
    elif n == 4:
        stamp, channel, frame, flag = fields
        direction = _DIRECTION.get(flag)
        if direction is None:
            return None
        is_rx = direction
    else:
        return None
    if stamp[0] != "(" or stamp[-1] != ")" or channel.isdigit():
        return None
    id_text, sep, data = frame.partition("#")
    if not sep:
        return None
    try:
        timestamp = float(stamp[1:-1])
        can_id = int(id_text, 16)
        payload = _fromhex(data)  # '#' (CAN FD) or R (remote) is no hex digit: ValueError
    except ValueError:
        return None
    id_len = len(id_text)
    if (
        not ((id_len == 8 and 0 <= can_id <= 0x1FFFFFFF) or (id_len == 3 and can_id <= 0x7FF))
        or len(payload) > 8
        or not 0.0 <= timestamp < _INF
    ):
        return None
    return timestamp, can_id, payload, id_len == 8, channel, is_rx


def message_of(record: FrameFields | can.Message) -> can.Message:
    """The message of a :meth:`CandumpReader.records` record: for :data:`FrameFields`, the
    one :func:`_parse_careful` makes of their line."""
    if not isinstance(record, tuple):
        return record
    timestamp, can_id, payload, is_extended, channel, is_rx = record
    msg = _new_object(_Message)  # the fields can.Message(...) sets, without its keywords
    msg.timestamp = timestamp
    msg.arbitration_id = can_id
    msg.is_extended_id = is_extended
    msg.is_remote_frame = False
    msg.is_error_frame = False
    msg.channel = channel
    msg.is_fd = False
    msg.is_rx = is_rx
    msg.bitrate_switch = False
    msg.error_state_indicator = False
    msg.data = bytearray(payload)
    msg.dlc = len(payload)
    return msg


@dataclass(frozen=True)
class _Layout:
    """Where the fields lie in lines of the shape ``(W.F) CHANNEL IIIIIIII#DD..`` that differ
    only in their digits: W and F decimal digits, an extended id, ``size`` data bytes."""

    whole: int  # digits before the point
    frac: int  # digits after it
    channel: str
    size: int

    @classmethod
    def of(cls, line: str) -> _Layout | None:
        """The layout of ``line``, if it has one: only ASCII digits in the timestamp (at most
        :data:`_MAX_DIGITS`), a channel name of letters, digits and ``_.-``, not a number."""
        match = _LAYOUT.fullmatch(line)
        if match is None:
            return None
        whole, frac, channel, data = match.groups()
        if len(whole) + len(frac) > _MAX_DIGITS or channel.isdigit():
            return None
        return cls(len(whole), len(frac), channel, len(data) // 2)

    @property
    def id_at(self) -> int:
        """Column of the id's first digit."""
        return self.whole + self.frac + len(self.channel) + 5

    def constants(self) -> tuple[list[int], bytes]:
        """The columns every line of the layout has the same character in, and those."""
        text = f"(.) {self.channel} #"
        at = self.whole + 1
        cols = [0, at, at + self.frac + 1]
        cols += range(cols[-1] + 1, self.id_at)
        cols.append(self.id_at + 8)
        return cols, text.encode("ascii")


def _blocks(stream: TextIO) -> Iterator[str]:
    """The text of ``stream`` in blocks of whole lines (about :data:`_BLOCK_CHARS`), each
    without its last newline (a block of n lines holds n - 1 newlines). The lines are those
    iterating the stream gives: it splits at its newlines, translated as configured."""
    carry = ""
    while chunk := stream.read(_BLOCK_CHARS):
        text = carry + chunk
        end = text.rfind("\n")
        if end < 0:
            carry = text
            continue
        carry = text[end + 1 :]
        yield text[:end]
    if carry:
        yield carry


def _alike_lines(block: str) -> tuple[int, list[tuple[int, str]], Iterator[FrameFields]]:
    """The lines of ``block``: how many, those (index, text) not of its most common layout,
    and the fields of those that are, in their order, as :func:`frame_fields` reads them.

    The lines of that layout are read at once with numpy, the columns of the digits and of
    the constant characters of every line checked together; a line with any other character
    (a non-ASCII one is '?' here) or with a larger value is left, like any other line, to
    the caller. Values are those of ``frame_fields``: the id and data from their hex digits;
    the timestamp, ``float`` of decimal digits W.F, is the integer N of the digits WF over
    10^len(F), both exact in float64 (N <= 2^53), so the division's correctly rounded result
    is the correctly rounded value of the decimal, which ``float`` gives.
    """
    raw = np.frombuffer((block + "\n").encode("ascii", "replace"), np.uint8)
    ends = np.flatnonzero(raw == _NEWLINE)
    count = len(ends)
    starts = np.concatenate(([0], ends[:-1] + 1))
    lengths = ends - starts
    common = int(np.argmax(np.bincount(lengths)))
    first = int(np.argmax(lengths == common))
    layout = _Layout.of(block[starts[first] : starts[first] + common])
    if layout is None:
        return count, _lines_at(block, starts, lengths, np.arange(count)), iter(())
    if (lengths == common).all():
        rows = raw.reshape(count, common + 1)[:, :common]
        chosen = np.arange(count)
    else:
        chosen = np.flatnonzero(lengths == common)
        rows = raw[starts[chosen, None] + np.arange(common)]
    ok, fields = _read_rows(rows, layout)
    left = np.ones(count, dtype=bool)
    left[chosen[ok]] = False
    return count, _lines_at(block, starts, lengths, np.flatnonzero(left)), fields


def _lines_at(
    block: str,
    starts: npt.NDArray[np.int64],
    lengths: npt.NDArray[np.int64],
    indices: npt.NDArray[np.int64],
) -> list[tuple[int, str]]:
    """(index, text) of the lines of ``block`` at ``indices``."""
    return [
        (i, block[start : start + n])
        for i, start, n in zip(
            indices.tolist(), starts[indices].tolist(), lengths[indices].tolist(), strict=True
        )
    ]


def _read_rows(
    rows: npt.NDArray[np.uint8], layout: _Layout
) -> tuple[npt.NDArray[np.bool_], Iterator[FrameFields]]:
    """Which ``rows`` (lines of ``layout``'s length, a column a character) are of
    ``layout``, and the fields of those (:func:`_alike_lines`)."""
    cols, chars = layout.constants()
    ok = (rows[:, cols] == np.frombuffer(chars, np.uint8)).all(axis=1)
    point = layout.whole + 1
    digits = np.concatenate(
        (rows[:, 1:point], rows[:, point + 1 : point + 1 + layout.frac]), axis=1
    ).astype(np.int64)
    ok &= ((digits >= _ZERO) & (digits <= _NINE)).all(axis=1)
    n = (digits - _ZERO) @ (10 ** np.arange(digits.shape[1] - 1, -1, -1, dtype=np.int64))
    ok &= n <= _EXACT_INT
    nibbles = _HEX[rows[:, layout.id_at :]]
    nibbles = np.delete(nibbles, 8, axis=1)  # the '#'
    ok &= (nibbles < 16).all(axis=1)
    can_id = nibbles[:, :8].astype(np.int64) @ (16 ** np.arange(7, -1, -1, dtype=np.int64))
    ok &= can_id <= 0x1FFFFFFF
    data = nibbles[ok, 8::2] << 4 | nibbles[ok, 9::2]
    size = layout.size
    blob = data.tobytes()
    payloads = [blob[i : i + size] for i in range(0, len(blob), size)]
    stamps = n[ok].astype(np.float64) / float(10**layout.frac)  # both exact
    fields = zip(
        stamps.tolist(),
        can_id[ok].tolist(),
        payloads,
        repeat(True),
        repeat(layout.channel),
        repeat(True),
    )
    return ok, fields


def _parse_careful(line: str, where: str) -> can.Message | None:
    """:func:`parse_candump_line` for every line: each check in turn, a reason for a bad line."""
    text = line.strip()
    if not text:
        return None
    fields = text.split()
    is_rx = True
    if len(fields) == 4 and fields[3].lower() in ("r", "t"):
        is_rx = fields[3].lower() == "r"
        fields = fields[:3]
    if len(fields) != 3:
        raise InputError(f"{len(fields)} fields in {excerpt(text)}", where, LINE_FORMAT)
    stamp, channel_text, frame = fields
    try:
        if not (stamp.startswith("(") and stamp.endswith(")")):
            raise ValueError("timestamp not in parentheses")
        timestamp = float(stamp[1:-1])
        if not (math.isfinite(timestamp) and timestamp >= 0.0):
            raise ValueError(f"timestamp {stamp} is not finite seconds >= 0")
        id_text, sep, data = frame.partition("#")
        if not sep or len(id_text) not in (3, 8):
            raise ValueError("id must be 3 (standard) or 8 (extended) hex digits before '#'")
        can_id = int(id_text, 16)
        is_extended = len(id_text) == 8
        if not is_extended and can_id > 0x7FF:
            raise ValueError("standard id above 0x7FF")
        if is_extended and can_id & CAN_ERR_FLAG and can_id & CAN_ERR_BUSERROR:
            return can.Message(timestamp=timestamp, is_error_frame=True)
        if can_id > 0x1FFFFFFF:
            raise ValueError("id above 29 bits")
        is_fd = brs = esi = False
        if data.startswith("#"):
            if len(data) < 2:
                raise ValueError("CAN FD flags digit missing after '##'")
            is_fd = True
            fd_flags = int(data[1], 16)
            brs, esi = bool(fd_flags & _CANFD_BRS), bool(fd_flags & _CANFD_ESI)
            data = data[2:]
        if data[:1] in ("R", "r"):
            dlc = int(data[1:]) if len(data) > 1 else 0
            if not 0 <= dlc <= 8:
                raise ValueError("remote frame DLC above 8")
            payload = None
            is_remote = True
        else:
            if len(data) % 2:
                raise ValueError("odd number of hex digits in the data")
            payload = bytearray.fromhex(data)
            if len(payload) not in _CANFD_LENGTHS or (not is_fd and len(payload) > 8):
                raise ValueError(f"{len(payload)} data bytes")
            dlc = len(payload)
            is_remote = False
    except ValueError as exc:
        raise InputError(f"{exc} in {excerpt(text)}", where, LINE_FORMAT) from None
    return can.Message(
        timestamp=timestamp,
        arbitration_id=can_id,
        is_extended_id=is_extended,
        is_remote_frame=is_remote,
        is_fd=is_fd,
        is_rx=is_rx,
        bitrate_switch=brs,
        error_state_indicator=esi,
        dlc=dlc,
        data=payload,
        channel=int(channel_text) if channel_text.isdigit() else channel_text,
    )


@dataclass
class CandumpReader:
    """Iterator over the frames of a candump ``-L`` log, skipping malformed lines.

    ``source`` is a path or an open text stream. After (or during) the iteration,
    ``bad_lines`` is the number of lines skipped and ``frames`` the number yielded.
    """

    source: str | Path | TextIO
    bad_lines: int = 0
    frames: int = 0

    @property
    def name(self) -> str:
        """File name used in messages."""
        if isinstance(self.source, str | Path):
            return str(self.source)
        return str(getattr(self.source, "name", "<stream>"))

    def __iter__(self) -> Iterator[can.Message]:
        return map(message_of, self.records())

    def records(self) -> Iterator[FrameFields | can.Message]:
        """Each frame: the :data:`FrameFields` of a common line (:func:`frame_fields`), or the
        message the careful parser makes of any other; a malformed line is counted, logged
        and skipped. Replay takes these, and makes no message of most frames.

        The text is read in blocks: the lines of a block's most common layout at once
        (:func:`_alike_lines`), the others one by one, all in their order. ``frames`` counts
        a run of alike lines as the run starts.
        """
        return chain.from_iterable(self._runs())

    def _runs(self) -> Iterator[Iterable[FrameFields | can.Message]]:
        """:meth:`records` in runs, in order: alike lines of a block together, any other
        line alone (a 1-tuple of its record; nothing for a blank or malformed line)."""
        source = self.source
        with (
            Path(source).open(encoding="ascii", errors="replace")
            if isinstance(source, str | Path)
            else nullcontext(source)  # a stream is the caller's to close
        ) as stream:
            number = 1  # of the block's first line
            for block in _blocks(stream):
                count, others, alike = _alike_lines(block)
                done = 0  # lines of the block yielded or skipped
                for index, line in others:
                    if index > done:
                        self.frames += index - done
                        yield islice(alike, index - done)
                    record = self._read_line(line, number + index)
                    if record is not None:
                        self.frames += 1
                        yield (record,)
                    done = index + 1
                self.frames += count - done
                yield alike
                number += count
            if self.bad_lines > MAX_LOGGED_BAD_LINES:
                log.warning(
                    "%s: %d malformed lines skipped in all (%d not shown)",
                    self.name,
                    self.bad_lines,
                    self.bad_lines - MAX_LOGGED_BAD_LINES,
                )

    def _read_line(self, line: str, number: int) -> FrameFields | can.Message | None:
        """One line as :meth:`records` gives it; None for a blank or (counted, logged at a
        limited rate) malformed line."""
        fields = frame_fields(line)
        if fields is not None:
            return fields
        try:
            return _parse_careful(line, f"{self.name}:{number}")
        except InputError as exc:
            self.bad_lines += 1
            if self.bad_lines <= MAX_LOGGED_BAD_LINES:
                log.warning("skipped malformed candump line: %s", exc)
            return None


def read_candump(source: str | Path | TextIO) -> CandumpReader:
    """The frames of a candump ``-L`` log (path or text stream), malformed lines skipped."""
    return CandumpReader(source)


def time_span(path: str | Path, tail_bytes: int = 4096) -> tuple[float, float] | None:
    """Host times of the first and the last frame of a candump ``-L`` log, read from its two
    ends only (a progress bar's total, whether two rotated files follow on); None when no
    well-formed line is found there."""
    path = Path(path)
    with path.open("rb") as f:
        head = f.read(tail_bytes)
        f.seek(max(0, path.stat().st_size - tail_bytes))
        tail = f.read()
    stamps = [
        [msg.timestamp for msg in _frames(chunk.decode("ascii", "replace").splitlines())]
        for chunk in (head, tail)
    ]
    return (stamps[0][0], stamps[1][-1]) if stamps[0] and stamps[1] else None


def _frames(lines: Iterable[str]) -> Iterator[can.Message]:
    """The well-formed frames among ``lines`` (a cut line at a chunk's end is skipped)."""
    for line in lines:
        try:
            msg = parse_candump_line(line)
        except InputError:
            continue
        if msg is not None:
            yield msg
