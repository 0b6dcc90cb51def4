"""candump ``-L`` log files (SPEC 3): one formatter, one tolerant parser.

A line is ``(1700000000.123456) can0 0CFF1080#0C00F4FF3A0001F2``. We write lines *without* the
trailing `` R``/`` T`` direction flag that python-can's ``CanutilsLogWriter`` appends: candump
itself does not write it and some tools (canboat's candump2analyzer) misread the frame when it
is there. On input the flag is accepted. The reader yields the same ``can.Message`` objects as
python-can's ``CanutilsLogReader`` for well-formed input, but skips a malformed line (counting
it and logging it, at a limited rate, with file, line number, text and what was expected)
instead of ending the whole read. Replay and the IMU driver's log source both use this parser.

Speed (issue 14): both directions have a fast path for the common shape, a data frame of at most
8 bytes with a 3- or 8-digit id, e.g. the line above. :func:`_parse_fast` accepts only lines the
careful parser :func:`_parse_careful` accepts, and gives the identical message; it returns
``None`` for anything else (remote, error and CAN FD frames, numeric channels, every malformed
line), which the careful parser then reads, rejects or explains. The file location of a line
("name:number") is only built for a line the fast path leaves. Likewise the writer formats the
common frame inline, with the expressions of :func:`format_candump_line`, and leaves the rest
to it. tests/test_canlog.py checks both against the careful paths on generated lines and frames.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Iterable, Iterator
from contextlib import nullcontext
from dataclasses import dataclass
from pathlib import Path
from typing import TextIO

import can

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
_fromhex = bytearray.fromhex


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
    """The common well-formed line as :func:`_parse_careful` reads it, else ``None``.

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
    msg = _new_object(_Message)  # the fields can.Message(...) sets, without its keywords
    msg.timestamp = timestamp
    msg.arbitration_id = can_id
    msg.is_extended_id = id_len == 8
    msg.is_remote_frame = False
    msg.is_error_frame = False
    msg.channel = channel
    msg.is_fd = False
    msg.is_rx = is_rx
    msg.bitrate_switch = False
    msg.error_state_indicator = False
    msg.data = payload
    msg.dlc = len(payload)
    return msg


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
        source = self.source
        with (
            Path(source).open(encoding="ascii", errors="replace")
            if isinstance(source, str | Path)
            else nullcontext(source)  # a stream is the caller's to close
        ) as stream:
            name = self.name
            fast = _parse_fast
            for number, line in enumerate(stream, start=1):
                msg = fast(line)
                if msg is None:  # not the common shape: the careful parser, with the place
                    try:
                        msg = _parse_careful(line, f"{name}:{number}")
                    except InputError as exc:
                        self.bad_lines += 1
                        if self.bad_lines <= MAX_LOGGED_BAD_LINES:
                            log.warning("skipped malformed candump line: %s", exc)
                        continue
                    if msg is None:
                        continue
                self.frames += 1
                yield msg
            if self.bad_lines > MAX_LOGGED_BAD_LINES:
                log.warning(
                    "%s: %d malformed lines skipped in all (%d not shown)",
                    name,
                    self.bad_lines,
                    self.bad_lines - MAX_LOGGED_BAD_LINES,
                )


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
