"""The NMEA log format of SPEC 3: one sentence a line, optionally prefixed by the host time.

    (1700000000.123456) $GNGGA,...*hh

The prefix is the host receive time in UTC seconds with microseconds, as in candump ``-L``;
a line without it is kept with host time None (the consumer then uses the sentence's own
time). This module splits lines into (host time, sentence) and never judges the sentence:
checksums and sentence types are the NMEA driver's business. Reading is tolerant: junk bytes
are decoded as U+FFFD, a line with a malformed prefix is reported (file:line, what was
expected; the first ``max_reports`` of a file, then a summary), counted and skipped, as
:mod:`drivers.logs.candump` does for CAN logs.
"""

from __future__ import annotations

import io
import logging
import os
import re
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import IO, TextIO

from drivers.errors import InputError
from drivers.logs.candump import excerpt
from drivers.logs.closing import Closing

log = logging.getLogger(__name__)

_STAMP = re.compile(r"\d+(?:\.\d*)?")
# a well-formed prefix as parse_nmea_log_line takes it: '(', _STAMP up to the first ')', the
# whitespace that str.strip() takes (the same: Py_UNICODE_ISSPACE)
_PREFIX = re.compile(r"\((\d+(?:\.\d*)?)\)\s*")
LINE_FORMAT = "'(<seconds>) $<sentence>', e.g. '(1700000000.123456) $GNGGA,...*hh', or no prefix"

#: Malformed lines logged individually per file before the reader goes quiet (then a summary).
MAX_LOGGED_BAD_LINES = 5


def format_nmea_log_line(host_t: float | None, sentence: str) -> str:
    """One log line (without newline): the sentence, prefixed with the host time if known."""
    sentence = sentence.rstrip("\r\n")
    return sentence if host_t is None else f"({host_t:.6f}) {sentence}"


def parse_nmea_log_line(line: str, where: str = "<line>") -> tuple[float | None, str] | None:
    """(host time or None, sentence) of a log line; None for a blank line.

    Raises :class:`InputError` (naming ``where``) when the line starts with ``(`` but the
    prefix is not ``(seconds)`` followed by something. The sentence itself is not validated.
    """
    text = line.strip()
    if not text:
        return None
    if not text.startswith("("):
        return None, text
    close = text.find(")")
    if close < 0:
        raise InputError(f"no ')' closing the host time in {excerpt(text)}", where, LINE_FORMAT)
    stamp = text[1:close]
    if not _STAMP.fullmatch(stamp):
        raise InputError(
            f"host time {excerpt(stamp, 40)} is not decimal seconds", where, LINE_FORMAT
        )
    sentence = text[close + 1 :].lstrip()
    if not sentence:
        raise InputError(f"nothing after the host time in {excerpt(text)}", where, LINE_FORMAT)
    return float(stamp), sentence


class NmeaLogReader(Closing, Iterator[tuple[float | None, str]]):
    """Iterates (host time, sentence) over a log; skips blank and malformed lines.

    ``bad_lines`` counts the lines skipped for a malformed prefix. A path is opened (and closed
    at the end or by :meth:`close`); a stream given by the caller stays the caller's.
    """

    def __init__(
        self,
        source: str | os.PathLike[str] | IO[str] | IO[bytes],
        max_reports: int = MAX_LOGGED_BAD_LINES,
    ) -> None:
        self.bad_lines = 0
        self.max_reports = max_reports
        self._own: IO[str] | None = None
        stream: IO[str] | IO[bytes]
        if isinstance(source, (str, os.PathLike)):
            # universal newlines: CR-only logs too (else the whole file was one record)
            self._own = stream = open(  # noqa: SIM115 - closed at the end
                source, encoding="ascii", errors="replace", newline=None
            )
            self.name = str(source)
        else:
            stream = source
            self.name = str(getattr(source, "name", "<stream>"))
        self._lines = self._read(stream)

    def _read(self, stream: Iterable[str | bytes]) -> Iterator[tuple[float | None, str]]:
        prefix = _PREFIX.match
        lines: Iterable[str] = (
            stream  # (a text stream, as a file this reader opened: lines of str)
            if isinstance(stream, io.TextIOBase)
            else (
                x.decode("ascii", errors="replace") if isinstance(x, bytes) else x for x in stream
            )
        )
        try:
            for lineno, line in enumerate(lines, 1):
                # parse_nmea_log_line inline for a well-formed line (replay reads millions)
                text = line.strip()
                m = prefix(text)
                if m is not None:
                    sentence = text[m.end() :]
                    if sentence:
                        yield float(m[1]), sentence
                        continue
                elif text[:1] != "(":
                    if text:
                        yield None, text
                    continue
                try:  # malformed: the reason, from the careful path
                    parsed = parse_nmea_log_line(line, f"{self.name}:{lineno}")
                except InputError as exc:
                    self.bad_lines += 1
                    if self.bad_lines <= self.max_reports:
                        log.warning("skipped malformed NMEA log line: %s", exc)
                    continue
                if parsed is not None:  # (not reached: the fast path takes every good line)
                    yield parsed
        finally:
            self._summarise()
            self.close()

    def _summarise(self) -> None:
        if self.bad_lines > self.max_reports:
            log.warning(
                "%s: %d malformed lines skipped in all (%d not shown)",
                self.name,
                self.bad_lines,
                self.bad_lines - self.max_reports,
            )

    def __iter__(self) -> Iterator[tuple[float | None, str]]:
        return self._lines  # (the generator itself: a for loop calls no __next__ per line)

    def __next__(self) -> tuple[float | None, str]:
        return next(self._lines)

    def close(self) -> None:
        """Close the file if this reader opened it; safe to call twice."""
        if self._own is not None:
            self._own.close()
            self._own = None


def read_nmea_log(
    source: str | os.PathLike[str] | IO[str] | IO[bytes], max_reports: int = MAX_LOGGED_BAD_LINES
) -> NmeaLogReader:
    """(host time or None, sentence) for every usable line of a log file or stream."""
    return NmeaLogReader(source, max_reports)


class NmeaLogWriter(Closing):
    """Writes log lines to a path (created, closed by :meth:`close`) or a caller's text stream."""

    def __init__(self, target: str | os.PathLike[str] | TextIO) -> None:
        self._own: TextIO | None = None
        self._stream: TextIO
        if isinstance(target, (str, os.PathLike)):
            own = Path(target).open("w", encoding="ascii", newline="\n")  # noqa: SIM115 - close()
            self._own = self._stream = own
        else:
            self._stream = target

    def write(self, host_t: float | None, sentence: str) -> None:
        """Append one sentence with its host receive time (None: no prefix)."""
        self._stream.write(format_nmea_log_line(host_t, sentence) + "\n")

    def close(self) -> None:
        """Close the file if this writer opened it; safe to call twice."""
        if self._own is not None:
            self._own.close()
            self._own = None


def write_nmea_log(
    target: str | os.PathLike[str] | TextIO, lines: Iterable[tuple[float | None, str]]
) -> None:
    """Write (host time, sentence) pairs, e.g. :class:`sim_bus.gnss_receiver.NmeaLine`s."""
    with NmeaLogWriter(target) as writer:
        for host_t, sentence in lines:
            writer.write(host_t, sentence)
