"""Where the monitor's frames come from: a python-can bus, or a candump ``-L`` log played back.

Both are polled (``poll(limit)`` returns what has arrived, never blocks) from the app's timer,
so the UI and the state model stay on one thread. ``now()`` is the time on the frames' clock:
the host clock for a bus (python-can stamps frames on reception), the log's own clock for a
log, advancing ``speed`` times real time from its first frame. A log's clock stops at its last
frame once the log is played (:attr:`LogSource.ended`): the monitor keeps showing the end of
the run, rates included, rather than a stopped bus.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Protocol

import can

from drivers.logs.candump import read_candump


class FrameSource(Protocol):
    """What the monitor reads."""

    description: str

    def poll(self, limit: int) -> list[can.Message]:
        """The frames arrived since the last call, at most ``limit``; never blocks."""
        ...

    def now(self) -> float:
        """The current time on the frames' clock."""
        ...

    @property
    def ended(self) -> bool:
        """No frame will come any more."""
        ...

    def close(self) -> None:
        """Release the bus or file; safe to call twice."""
        ...


class LogSource:
    """A candump ``-L`` log played ``speed`` times faster than real time (malformed lines are
    skipped and counted by the reader)."""

    def __init__(
        self, path: str | Path, speed: float = 1.0, clock: Callable[[], float] = time.monotonic
    ) -> None:
        self.path = Path(path)
        self.speed = speed
        self.description = f"log {self.path} at {speed:g}x"
        self._reader = read_candump(self.path)
        self._frames: Iterator[can.Message] = iter(self._reader)
        self._next = next(self._frames, None)  # raises OSError for a file that cannot be read
        self._t0 = self._next.timestamp if self._next is not None else 0.0
        self._last_t = self._t0
        self._clock = clock
        self._wall0 = clock()

    @property
    def bad_lines(self) -> int:
        """Lines of the log that were not a frame."""
        return self._reader.bad_lines

    @property
    def ended(self) -> bool:
        return self._next is None

    def _log_clock(self) -> float:
        return self._t0 + (self._clock() - self._wall0) * self.speed

    def now(self) -> float:
        """The log's clock; the last frame's time while frames are due but not yet polled
        (the state is behind, not the bus silent), and once the log ended."""
        clock = self._log_clock()
        if self._next is None or self._next.timestamp <= clock:
            return self._last_t
        return clock

    def poll(self, limit: int) -> list[can.Message]:
        clock = self._log_clock()
        out: list[can.Message] = []
        while self._next is not None and self._next.timestamp <= clock and len(out) < limit:
            out.append(self._next)
            self._last_t = self._next.timestamp
            self._next = next(self._frames, None)
        return out

    def close(self) -> None:
        self._next = None
        self._frames = iter(())  # the reader's generator goes, and closes the file


class BusSource:
    """Any python-can bus, read without blocking."""

    def __init__(self, interface: str, channel: str) -> None:
        self.description = f"{interface} {channel}"
        self._bus = can.Bus(interface=interface, channel=channel)
        self._closed = False

    @property
    def ended(self) -> bool:
        return self._closed

    def now(self) -> float:
        return time.time()

    def poll(self, limit: int) -> list[can.Message]:
        out: list[can.Message] = []
        while not self._closed and len(out) < limit:
            msg = self._bus.recv(timeout=0)
            if msg is None:
                break
            out.append(msg)
        return out

    def close(self) -> None:
        if not self._closed:
            self._closed = True
            self._bus.shutdown()
