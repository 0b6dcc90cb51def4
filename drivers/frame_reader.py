"""One asyncio reader of CAN frames for every consumer (IMU driver, live service).

:class:`FrameReader` sets the bus's receive filters, reads it with ``can.Notifier(...,
loop=loop)`` (``loop.add_reader`` on the bus's socket, or python-can's thread for buses without
one, such as ``virtual``) into a bounded buffer, and ends its iteration with
:class:`~drivers.errors.BusError` when the bus fails. In loop mode a receive error reaches only
the event loop's exception handler, not ``Listener.on_error`` (python-can issue #1912), so one
handler per loop routes such errors to the reader whose notifier raised them, and passes
everything else on to the handler that was there before.

Overload: when the consumer falls behind and the buffer is full, the *oldest* frame is dropped
(fresh data matter more to a navigation loop than stale data) and counted in ``dropped``.
A consumer that finds itself behind its input calls :meth:`FrameReader.shed`: the frames
stamped before a time it gives are dropped at the cost of a receive each, not of handling
each (which is what it could not keep up with). On a bus read in the loop that includes those
still in the socket's receive buffer, where a reader slower than its input keeps a backlog of
a full buffer for good (some 400 frames on udp_multicast here: 1 s of the IMU's).
"""

from __future__ import annotations

import asyncio
from collections.abc import Callable, Sequence
from types import TracebackType
from typing import Any

import can
from can.typechecking import CanFilter

from drivers.errors import BusError

#: Frames buffered per bus before the oldest is dropped (about 5 s of IMU frames at 204.8 Hz).
DEFAULT_BUFFER_FRAMES = 2048

_FAILED = can.Message(arbitration_id=0x1FFFFFFF, is_extended_id=True, data=b"")


class FrameReader(can.Listener):
    """``async with FrameReader(bus, filters) as frames: async for msg in frames: ...``."""

    def __init__(
        self,
        bus: can.BusABC,
        filters: Sequence[CanFilter] | None = None,
        max_frames: int = DEFAULT_BUFFER_FRAMES,
    ) -> None:
        self.bus = bus
        self.filters = list(filters) if filters is not None else None
        self.dropped = 0  # frames dropped because the buffer was full
        self.error: BaseException | None = None
        self._buffer: asyncio.Queue[can.Message] = asyncio.Queue(max_frames)
        self._notifier: can.Notifier | None = None
        self._in_loop = False  # the notifier reads the bus in the loop (not in a thread)

    # --- can.Listener, called in the event loop's thread -----------------------------------

    def on_message_received(self, msg: can.Message) -> None:
        if self.error is None:
            self._put(msg)

    def on_error(self, exc: Exception) -> None:
        self.fail(exc)

    # --- reading --------------------------------------------------------------------------

    def fail(self, exc: BaseException) -> None:
        """End the iteration with BusError (a receive error, or a send error meaning the same)."""
        if self.error is None:
            self.error = exc
            self._put(_FAILED)

    async def __aenter__(self) -> FrameReader:
        loop = asyncio.get_running_loop()
        self.bus.set_filters(self.filters)
        _ErrorRouter.of(loop).add(self)
        try:
            self._notifier = can.Notifier(self.bus, [self], loop=loop)
            self._in_loop = _has_fileno(self.bus)
        except BaseException:
            _ErrorRouter.of(loop).remove(self)
            raise
        return self

    async def __aexit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        if self._notifier is not None:
            self._notifier.stop()
            self._notifier = None
        _ErrorRouter.of(asyncio.get_running_loop()).remove(self)

    def __aiter__(self) -> FrameReader:
        return self

    async def __anext__(self) -> can.Message:
        msg = await self._buffer.get()
        if msg is _FAILED:
            raise BusError(f"CAN bus {self.bus.channel_info} failed: {self.error}") from self.error
        return msg

    @property
    def pending(self) -> int:
        """Frames received and not yet taken (a consumer behind its input has some)."""
        return self._buffer.qsize()

    def _put(self, msg: can.Message) -> None:
        if self._buffer.full():
            self._buffer.get_nowait()
            self.dropped += 1
        self._buffer.put_nowait(msg)

    def shed(self, before: float, keep: Callable[[can.Message], bool]) -> list[can.Message]:
        """Drop the frames stamped before ``before`` (the bus's clock) but those ``keep``
        wants, from the buffer and, read in the loop, from the socket up to the first newer
        frame; the others stay in order. Returns the frames dropped, in order."""
        kept: list[can.Message] = []
        dropped: list[can.Message] = []
        while not self._buffer.empty():
            msg = self._buffer.get_nowait()
            stale = msg is not _FAILED and msg.timestamp < before and not keep(msg)
            (dropped if stale else kept).append(msg)
        behind = not kept or (kept[-1] is not _FAILED and kept[-1].timestamp < before)
        failure: BaseException | None = None
        while self._in_loop and behind and self.error is None:
            try:
                received = self.bus.recv(0)
            except (can.CanError, OSError) as exc:
                failure = exc
                break
            if received is None:
                break
            behind = received.timestamp < before
            (dropped if behind and not keep(received) else kept).append(received)
        for msg in kept:
            self._put(msg)
        if failure is not None:
            self.fail(failure)  # the iteration ends after the frames kept
        return dropped

    def owns(self, notifier: object) -> bool:
        """True if ``notifier`` is this reader's (to route a loop-mode receive error)."""
        return notifier is not None and notifier is self._notifier


def _has_fileno(bus: can.BusABC) -> bool:
    """True if can.Notifier reads ``bus`` in the event loop (it has a file descriptor)."""
    try:
        return bus.fileno() >= 0
    except NotImplementedError:
        return False


class _ErrorRouter:
    """The loop exception handler while readers are active: CAN errors to their reader."""

    _routers: dict[asyncio.AbstractEventLoop, _ErrorRouter] = {}  # noqa: RUF012 - registry

    def __init__(self, loop: asyncio.AbstractEventLoop) -> None:
        self.loop = loop
        self.readers: list[FrameReader] = []
        self.previous = loop.get_exception_handler()

    @classmethod
    def of(cls, loop: asyncio.AbstractEventLoop) -> _ErrorRouter:
        router = cls._routers.get(loop)
        if router is None:
            router = cls._routers[loop] = cls(loop)
        return router

    def add(self, reader: FrameReader) -> None:
        if not self.readers:
            self.previous = self.loop.get_exception_handler()
            self.loop.set_exception_handler(self.handle)
        self.readers.append(reader)

    def remove(self, reader: FrameReader) -> None:
        if reader in self.readers:
            self.readers.remove(reader)
        if not self.readers:
            self.loop.set_exception_handler(self.previous)
            del self._routers[self.loop]

    def handle(self, loop: asyncio.AbstractEventLoop, context: dict[str, Any]) -> None:
        exc = context.get("exception")
        if isinstance(exc, can.CanError | OSError) and self.readers:
            # The failing callback is Notifier._on_message_available bound to its notifier;
            # if that cannot be told, every reader of this loop restarts (safe, just slower).
            callback = getattr(context.get("handle"), "_callback", None)
            owner = getattr(callback, "__self__", None)
            targets = [r for r in self.readers if r.owns(owner)] or list(self.readers)
            for reader in targets:
                reader.fail(exc)
        elif self.previous is not None:
            self.previous(loop, context)
        else:
            loop.default_exception_handler(context)
