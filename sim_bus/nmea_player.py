"""Play an NMEA log onto a pseudo-terminal, so that a program reads it as a serial receiver.

The player owns the pty master; the slave (``/dev/pts/N``, optionally behind a stable symlink)
is the "serial port" that the reader opens with pyserial at any baud rate. Each line is written
with CRLF at its recorded host time offset divided by ``speed`` (``math.inf``: as fast as the
reader takes them; lines without a host time follow the previous line at once).

Nobody on the port: the player sees it (poll on a pty master reports POLLHUP while no slave
descriptor is open) and either drops the lines due meanwhile, like a receiver talking to an
unplugged cable (``Detached.DROP``, the default), or pauses the log clock until a reader is back
(``Detached.PAUSE``: no line lost, timing shifted). It never writes into the closed port:
pyserial flushes its input when it opens a port, so such bytes would be lost anyway, and a
partial line would be the first thing the next reader sees. A line interrupted by the reader
closing is dropped (DROP) or sent again whole (PAUSE). The clock starts when the first reader
opens the port (``wait_for_reader``), so a test can start the player and then open the port
without a race. Bytes the reader writes to the port are read and discarded. Linux semantics.
"""

from __future__ import annotations

import argparse
import contextlib
import enum
import math
import os
import select
import sys
import threading
import time
import tty
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

from drivers.logs.closing import Closing
from drivers.logs.nmea_log import read_nmea_log

POLL_S = 0.02  # how often a waiting player looks at the stop request and the port


class Detached(enum.Enum):
    """What the player does with lines due while no reader has the port open."""

    DROP = "drop"
    PAUSE = "pause"


@dataclass
class PlayerStats:
    """Lines written whole to a reader and lines dropped with nobody listening."""

    sent: int = 0
    dropped: int = 0


class NmeaPlayer(Closing):
    """Background thread that plays (host time, sentence) lines onto a fresh pty.

    Use as a context manager or with :meth:`start` / :meth:`stop`; :attr:`device` is the path
    to open. The pty stays open after the last line until :meth:`stop`, so the reader can
    drain it.
    """

    def __init__(
        self,
        lines: Iterable[tuple[float | None, str]],
        speed: float = 1.0,
        link: str | os.PathLike[str] | None = None,
        detached: Detached = Detached.DROP,
        wait_for_reader: bool = True,
    ) -> None:
        if not speed > 0.0:
            raise ValueError(f"speed={speed}: expected > 0 (math.inf for as fast as possible)")
        self.speed = speed
        self.link = Path(link) if link is not None else None
        self.detached = detached
        self.wait_for_reader = wait_for_reader
        self.stats = PlayerStats()
        self._lines = lines
        self._master = -1
        self._device = ""
        self._stop = threading.Event()
        self._done = threading.Event()
        self._thread: threading.Thread | None = None
        self._error: BaseException | None = None
        self._poll = select.poll()

    @property
    def device(self) -> str:
        """Path of the pty slave, the serial port to open (valid after :meth:`start`)."""
        return self._device

    def start(self) -> str:
        """Create the pty (raw mode), the optional symlink, and start playing; returns the path."""
        master, slave = os.openpty()
        tty.setraw(slave)
        self._device = os.ttyname(slave)
        os.close(slave)  # only readers hold the slave: POLLHUP then means "nobody listening"
        os.set_blocking(master, False)
        self._master = master
        self._poll.register(master, select.POLLIN | select.POLLOUT)
        if self.link is not None:
            if self.link.is_symlink():
                self.link.unlink()
            self.link.symlink_to(self._device)
        self._thread = threading.Thread(target=self._run, name="nmea-player", daemon=True)
        self._thread.start()
        return self._device

    def wait(self, timeout: float | None = None) -> bool:
        """Wait until every line is played; True if done. Re-raises an error of the thread."""
        done = self._done.wait(timeout)
        if self._error is not None:
            raise self._error
        return done

    def wait_for_hangup(self, timeout_s: float) -> bool:
        """Wait until no reader has the port open (the last one closed it: it has what it
        wanted of the lines), at most ``timeout_s``; True if it did (:meth:`_events`, as
        :meth:`_wait_for_reader` waits for the opposite)."""
        end = time.monotonic() + timeout_s
        while not self._events() & select.POLLHUP:
            if time.monotonic() >= end:
                return False
            time.sleep(POLL_S)
        return True

    def stop(self) -> None:
        """Stop playing, close the pty and remove the symlink; safe to call twice."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join()
            self._thread = None
        if self._master >= 0:
            self._poll.unregister(self._master)
            os.close(self._master)
            self._master = -1
        if (
            self.link is not None
            and self.link.is_symlink()
            and os.readlink(self.link) == self._device
        ):
            self.link.unlink()

    close = stop  # Closing: ``with player:`` stops it at the end

    def __enter__(self) -> NmeaPlayer:
        self.start()
        return self

    def _run(self) -> None:
        try:
            self._play()
        except BaseException as e:  # handed to wait(); a thread has nobody else to tell
            self._error = e
        finally:
            self._done.set()

    def _play(self) -> None:
        if self.wait_for_reader and not self._wait_for_reader():
            return
        t_log0: float | None = None
        t_wall0 = 0.0
        for host_t, sentence in self._lines:
            if host_t is not None and math.isfinite(self.speed):
                if t_log0 is None:
                    t_log0, t_wall0 = host_t, time.monotonic()
                due = t_wall0 + (host_t - t_log0) / self.speed
                if self._stop.wait(max(0.0, due - time.monotonic())):
                    return
            data = (sentence + "\r\n").encode("ascii", errors="replace")
            while True:
                if self._write(data):
                    self.stats.sent += 1
                    break
                if self._stop.is_set():
                    return
                if self.detached is Detached.DROP:
                    self.stats.dropped += 1
                    break
                paused_at = time.monotonic()
                if not self._wait_for_reader():
                    return
                t_wall0 += time.monotonic() - paused_at

    def _wait_for_reader(self) -> bool:
        """Block until a reader has the port open; False if stopped meanwhile."""
        while not self._stop.is_set():
            if not self._events() & select.POLLHUP:
                return True
            self._stop.wait(POLL_S)
        return False

    def _events(self, timeout_s: float = 0.0) -> int:
        """Poll flags of the master; discards whatever the reader wrote to the port."""
        events = 0
        for _, ev in self._poll.poll(timeout_s * 1000.0):
            events |= ev
        if events & select.POLLIN and not events & select.POLLHUP:
            with contextlib.suppress(OSError):  # nothing after all, or the reader just left
                os.read(self._master, 4096)
        return events

    def _write(self, data: bytes) -> bool:
        """Write one whole line while a reader is attached; False if it left or stop."""
        while data:
            if self._stop.is_set():
                return False
            events = self._events(POLL_S)
            if events & select.POLLHUP:
                return False
            if events & select.POLLOUT:
                try:
                    data = data[os.write(self._master, data) :]
                except BlockingIOError:
                    continue
        return True


def play_nmea_lines(
    lines: Iterable[tuple[float | None, str]],
    speed: float = 1.0,
    link: str | os.PathLike[str] | None = None,
    detached: Detached = Detached.DROP,
    on_ready: Callable[[str], None] | None = None,
    linger_s: float = 1.0,
) -> PlayerStats:
    """Play lines onto a new pty and return when done (``on_ready`` gets the device path).

    The pty stays open after the last line until the reader closes it, at most ``linger_s``,
    so that the reader gets it all. (A fixed 0.3 s was too short for a reader thread on a
    loaded CI machine: the pty closed before it had read a line.)
    """
    with NmeaPlayer(lines, speed, link, detached) as player:
        if on_ready is not None:
            on_ready(player.device)
        player.wait()
        player.wait_for_hangup(linger_s)
    return player.stats


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m sim_bus.nmea_player LOG [--speed N] [--link PATH]``: prints the device path."""
    parser = argparse.ArgumentParser(
        prog="python -m sim_bus.nmea_player",
        description="Play an NMEA log (SPEC 3) onto a pseudo-terminal serial port.",
    )
    parser.add_argument("log", type=Path, help="NMEA log, optionally with host-time prefixes")
    parser.add_argument(
        "--speed", type=float, default=1.0, help="times real time; inf: as fast as possible"
    )
    parser.add_argument("--link", type=Path, help="also make this symlink to the device")
    parser.add_argument(
        "--pause",
        action="store_true",
        help="pause while no reader has the port open (default: drop those lines)",
    )
    args = parser.parse_args(argv)
    if not args.log.is_file():
        parser.error(f"{args.log}: no such file")
    if not args.speed > 0.0:
        parser.error(f"--speed {args.speed}: expected > 0 (inf for as fast as possible)")

    def ready(device: str) -> None:
        print(device, flush=True)

    try:
        stats = play_nmea_lines(
            read_nmea_log(args.log),
            args.speed,
            args.link,
            Detached.PAUSE if args.pause else Detached.DROP,
            ready,
        )
    except KeyboardInterrupt:
        return 130
    print(f"{stats.sent} lines sent, {stats.dropped} dropped with no reader", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
