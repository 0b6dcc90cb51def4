"""Play an IMU log onto a CAN bus and an NMEA log onto a pty from one shared time origin.

The demo and the live tests feed the service through the sim_bus players: frames on a
python-can bus, sentences on a real pseudo-terminal. Each player on its own anchors its clock
at its own first item, so two of them started separately drift apart by their start-up
delays (times the speed). Here both logs are paced by one function against one origin: log
time ``t`` is played at wall time ``origin_wall + (t - t0) / speed`` (absolute deadlines, no
accumulated sleep error), and the players only move the data (``play(speed=None)``,
``NmeaPlayer(speed=inf)``). The service under test maps arrival times back with
``TimeBase(t0, origin_wall, speed)`` (:meth:`SyncedPlayback.timebase`).

Each frame is stamped with its scheduled wall time before it is sent: on a ``virtual`` bus
opened with ``preserve_timestamps=True`` that is the arrival time the receiver sees, as with a
hardware timestamp, so a stall of the player thread (times the speed) does not reach the IMU
decoder's timing (``udp_multicast`` stamps frames on reception instead). GNSS receive times
are the reader's own, as live. The players are threads of the service's own process, and
CPython hands the GIL to a waiting thread only every 5 ms by default (50 ms of log time at
10x); while playing, the switch interval is :data:`SWITCH_INTERVAL_S`.
"""

from __future__ import annotations

import itertools
import math
import sys
import threading
import time
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path
from typing import TypeVar

import can

from drivers.logs.candump import read_candump
from drivers.logs.closing import Closing
from drivers.logs.nmea_log import read_nmea_log
from gateway.service.timebase import TimeBase
from sim_bus.can_player import play
from sim_bus.nmea_player import NmeaPlayer

T = TypeVar("T")

SWITCH_INTERVAL_S = 0.0005  # GIL hand-over while playing (CPython's default is 0.005)


def paced(
    items: Iterable[T],
    t_of: Callable[[T], float | None],
    timebase: TimeBase,
    stop: threading.Event,
) -> Iterator[T]:
    """Yield each item at the wall time ``timebase.wall_at(t_of(item))``; None: at once."""
    for item in items:
        t = t_of(item)
        if t is not None:
            delay = timebase.wall_at(t) - time.time()
            if delay > 0 and stop.wait(delay):
                return
        if stop.is_set():
            return
        yield item


class SyncedPlayback(Closing):
    """Both logs of one run, ``speed`` x real time, the first ``duration_s`` of them.

    ``open()`` creates the pty (:attr:`device`, the serial port to configure);
    ``start(origin_wall)`` schedules log time t0 (the first CAN frame) at ``origin_wall``.
    """

    def __init__(
        self,
        can_log: str | Path,
        nmea_log: str | Path,
        bus: can.BusABC,
        speed: float = 1.0,
        duration_s: float | None = None,
    ) -> None:
        self.can_log, self.nmea_log = Path(can_log), Path(nmea_log)
        self.bus = bus
        self.speed = speed
        first = next(iter(read_candump(self.can_log)), None)
        if first is None:
            raise ValueError(f"{self.can_log}: no CAN frames")
        self.t0 = float(first.timestamp)
        self.t_end = self.t0 + duration_s if duration_s is not None else math.inf
        self.frames_sent = 0
        self._timebase: TimeBase | None = None
        self._stop = threading.Event()
        self._player: NmeaPlayer | None = None
        self._can_thread: threading.Thread | None = None
        self._error: BaseException | None = None
        self._switch_interval: float | None = None  # CPython's, restored by close()

    @property
    def device(self) -> str:
        """The pty the NMEA log is played on (after :meth:`open`)."""
        return self._player.device if self._player is not None else ""

    @property
    def timebase(self) -> TimeBase:
        """The map from wall time to log time that this playback follows (after start)."""
        if self._timebase is None:
            raise RuntimeError("playback not started")
        return self._timebase

    def open(self) -> str:
        """Create the pty; lines wait for a reader and for :meth:`start`. Returns the device."""
        self._player = NmeaPlayer(self._nmea_lines(), speed=math.inf)
        return self._player.start()

    def start(self, origin_wall: float) -> TimeBase:
        """Play log time t0 at wall time ``origin_wall`` (both logs); returns the time map."""
        self._timebase = TimeBase(self.t0, origin_wall, self.speed)
        self._switch_interval = sys.getswitchinterval()
        sys.setswitchinterval(min(self._switch_interval, SWITCH_INTERVAL_S))
        self._can_thread = threading.Thread(target=self._play_can, name="can-player", daemon=True)
        self._can_thread.start()
        return self._timebase

    def wait(self, timeout: float | None = None) -> bool:
        """Wait until both logs are played; True if done. Re-raises a player's error."""
        deadline = math.inf if timeout is None else time.monotonic() + timeout
        if self._can_thread is not None:
            self._can_thread.join(None if timeout is None else max(0.0, timeout))
        done = self._can_thread is not None and not self._can_thread.is_alive()
        if self._error is not None:
            raise self._error
        left = None if timeout is None else max(0.0, deadline - time.monotonic())
        return done and self._player is not None and self._player.wait(left)

    def close(self) -> None:
        """Stop both players and close the pty; safe to call twice."""
        self._stop.set()
        if self._can_thread is not None:
            self._can_thread.join()
            self._can_thread = None
        if self._player is not None:
            self._player.stop()
        if self._switch_interval is not None:
            sys.setswitchinterval(self._switch_interval)
            self._switch_interval = None

    def __enter__(self) -> SyncedPlayback:
        self.open()
        return self

    def _play_can(self) -> None:
        frames = itertools.takewhile(lambda m: m.timestamp < self.t_end, read_candump(self.can_log))
        try:
            self.frames_sent = play(
                map(self._stamp, paced(frames, lambda m: m.timestamp, self.timebase, self._stop)),
                self.bus,
                speed=None,
            )
        except BaseException as exc:  # handed to wait(); a thread has nobody else to tell
            self._error = exc

    def _stamp(self, msg: can.Message) -> can.Message:
        """The frame with its scheduled wall time as timestamp."""
        msg.timestamp = self.timebase.wall_at(msg.timestamp)
        return msg

    def _nmea_lines(self) -> Iterator[tuple[float | None, str]]:
        while self._timebase is None:  # the player asks for lines once a reader is attached
            if self._stop.wait(0.01):
                return
        lines = itertools.takewhile(
            lambda line: line[0] is None or line[0] < self.t_end, read_nmea_log(self.nmea_log)
        )
        yield from paced(lines, lambda line: line[0], self._timebase, self._stop)
