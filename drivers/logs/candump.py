"""candump ``-L`` log files (SPEC 3): one formatter, one tolerant parser.

A line is ``(1700000000.123456) can0 0CFF1080#0C00F4FF3A0001F2``. We write lines *without* the
trailing `` R``/`` T`` direction flag that python-can's ``CanutilsLogWriter`` appends: candump
itself does not write it and some tools (canboat's candump2analyzer) misread the frame when it
is there. On input the flag is accepted. The reader yields the same ``can.Message`` objects as
python-can's ``CanutilsLogReader`` for well-formed input, but skips a malformed line (counting
it and logging it, at a limited rate, with file, line number, text and what was expected)
instead of ending the whole read. Replay and the IMU driver's log source both use this parser.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Iterable, Iterator
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


class CandumpWriter(Closing):
    """Writes messages as candump ``-L`` lines (without R/T); a context manager."""

    def __init__(self, path: str | Path, channel: str = "can0") -> None:
        self.path = Path(path)
        self.channel = channel
        self._file: TextIO = self.path.open("w", encoding="ascii", newline="\n")

    def write(self, msg: can.Message) -> None:
        """Append one frame."""
        self._file.write(format_candump_line(msg, self.channel) + "\n")

    def write_all(self, messages: Iterable[can.Message]) -> int:
        """Append every frame of ``messages``; returns how many."""
        n = 0
        write = self._file.write
        channel = self.channel
        for msg in messages:
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
        if isinstance(self.source, str | Path):
            with Path(self.source).open(encoding="ascii", errors="replace") as stream:
                yield from self._read(stream)
        else:
            yield from self._read(self.source)

    def _read(self, stream: TextIO) -> Iterator[can.Message]:
        name = self.name
        for number, line in enumerate(stream, start=1):
            try:
                msg = parse_candump_line(line, f"{name}:{number}")
            except InputError as exc:
                self.bad_lines += 1
                if self.bad_lines <= MAX_LOGGED_BAD_LINES:
                    log.warning("skipped malformed candump line: %s", exc)
                continue
            if msg is not None:
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
