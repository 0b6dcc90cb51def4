"""GNSS receiver on a serial port: asyncio reader that feeds `NmeaDecoder` and yields fixes.

The port is opened with pyserial (which sets the line: baud rate, 8N1, raw, non-blocking) and
read without threads through ``loop.add_reader`` on its file descriptor (POSIX). Each chunk is
stamped with the host clock when it is read; the decoder itself has no clock. A port that is
missing at start or disappears (USB receiver unplugged) is not fatal: the reader flushes the
decoder, reports ``connected = False`` and retries with exponential back-off until the device is
back, logging each state change once.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import os
import time
from collections.abc import AsyncIterator, Callable

import serial

from drivers.backoff import Backoff
from drivers.nmea import NmeaDecoder
from drivers.samples import GnssFix

log = logging.getLogger(__name__)


class GnssSerialReader:
    """Reads NMEA from ``port`` and yields `GnssFix` via `fixes`; `close` stops it.

    ``clock`` gives host UTC seconds (injectable for tests). Back-off starts at
    ``backoff_initial_s`` and doubles up to ``backoff_max_s``; it restarts after a connection.
    """

    def __init__(
        self,
        port: str,
        baudrate: int = 115200,
        *,
        decoder: NmeaDecoder | None = None,
        clock: Callable[[], float] = time.time,
        backoff_initial_s: float = 0.5,
        backoff_max_s: float = 10.0,
        read_size: int = 4096,
    ) -> None:
        self.port = port
        self.baudrate = baudrate
        self.decoder = decoder if decoder is not None else NmeaDecoder(port)
        self.clock = clock
        self._backoff = Backoff(backoff_initial_s, backoff_max_s)
        self.read_size = read_size
        self.connected = False  # for the service's STATUS
        self._closed = asyncio.Event()

    def close(self) -> None:
        """Stop `fixes` at its next wake-up; safe to call twice."""
        self._closed.set()

    async def fixes(self) -> AsyncIterator[GnssFix]:
        """Fixes as they complete, across disconnections, until `close`."""
        reported_down = False
        while not self._closed.is_set():
            try:
                port = serial.Serial(self.port, self.baudrate, timeout=0)
            except (serial.SerialException, OSError) as exc:
                if not reported_down:
                    log.warning(
                        "GNSS port %s not available (%s); retrying, at most every %g s",
                        self.port, exc, self._backoff.max_s,
                    )  # fmt: skip
                    reported_down = True
                await self._sleep(self._backoff.next())
                continue
            log.info("GNSS port %s connected at %d baud", self.port, self.baudrate)
            self.connected, reported_down = True, False
            self._backoff.reset()
            try:
                async for t_host, data in self._chunks(port):
                    for fix in self.decoder.feed(data, t_host):
                        yield fix
            finally:
                port.close()
                self.connected = False
            for fix in self.decoder.flush():
                yield fix
            if not self._closed.is_set():
                log.warning("GNSS port %s lost; reconnecting", self.port)
                reported_down = True

    async def _chunks(self, port: serial.Serial) -> AsyncIterator[tuple[float, bytes]]:
        """(host receive time, bytes) as the port delivers them; ends when the port fails."""
        loop = asyncio.get_running_loop()
        queue: asyncio.Queue[tuple[float, bytes] | None] = asyncio.Queue()
        fd = port.fileno()

        def on_readable() -> None:
            try:
                data = os.read(fd, self.read_size)
            except BlockingIOError:
                return
            except OSError:
                data = b""  # EIO: device gone
            if data:
                queue.put_nowait((self.clock(), data))
            else:
                loop.remove_reader(fd)
                queue.put_nowait(None)

        loop.add_reader(fd, on_readable)
        closed = asyncio.ensure_future(self._closed.wait())
        try:
            while True:
                got = asyncio.ensure_future(queue.get())
                await asyncio.wait({got, closed}, return_when=asyncio.FIRST_COMPLETED)
                if not got.done():
                    got.cancel()
                    return
                item = got.result()
                if item is None:
                    return
                yield item
        finally:
            closed.cancel()
            loop.remove_reader(fd)

    async def _sleep(self, seconds: float) -> None:
        """Back-off wait that `close` cuts short."""
        with contextlib.suppress(asyncio.TimeoutError):  # not the builtin before 3.11
            await asyncio.wait_for(self._closed.wait(), seconds)
