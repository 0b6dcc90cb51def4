"""systemd's sd_notify protocol over ``$NOTIFY_SOCKET``: READY, STATUS, WATCHDOG, STOPPING.

A datagram of ``KEY=value`` lines to a unix socket (``@name`` is an abstract address). Written
with the standard library (the protocol is a few lines; the ``sdnotify`` package adds nothing
we need). Outside systemd (no ``$NOTIFY_SOCKET``) every call does nothing. A failed send is
logged once and never raised: the service must not die because its supervisor went away.
"""

from __future__ import annotations

import logging
import os
import socket
from collections.abc import Mapping

log = logging.getLogger(__name__)


class SdNotifier:
    """Sends notifications to the socket ``$NOTIFY_SOCKET`` names (``environ`` for tests)."""

    def __init__(self, environ: Mapping[str, str] | None = None) -> None:
        env = os.environ if environ is None else environ
        address = env.get("NOTIFY_SOCKET", "")
        self._address = "\0" + address[1:] if address.startswith("@") else address
        self._watchdog_usec = _watchdog_usec(env)
        self._sock: socket.socket | None = None
        self._failed = False
        if self._address:
            self._sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM | socket.SOCK_CLOEXEC)
            self._sock.setblocking(False)

    @property
    def enabled(self) -> bool:
        """True when running under a supervisor that listens."""
        return self._sock is not None

    @property
    def watchdog_interval_s(self) -> float | None:
        """How often to send WATCHDOG=1: half of ``$WATCHDOG_USEC``; None if not asked for."""
        if self._sock is None or self._watchdog_usec is None:
            return None
        return self._watchdog_usec / 2e6

    def notify(self, *assignments: str) -> None:
        """Send ``KEY=value`` lines in one datagram."""
        if self._sock is None:
            return
        try:
            self._sock.sendto("\n".join(assignments).encode(), self._address)
        except OSError as exc:
            if not self._failed:
                log.warning("sd_notify to %r failed: %s (further failures not logged)",
                            self._address.replace("\0", "@"), exc)  # fmt: skip
                self._failed = True

    def ready(self, status: str | None = None) -> None:
        """Start-up done (Type=notify units become active)."""
        self.notify("READY=1", *([f"STATUS={status}"] if status else []))

    def status(self, text: str) -> None:
        """One-line status shown by ``systemctl status``."""
        self.notify(f"STATUS={text.splitlines()[0] if text else ''}")

    def watchdog(self) -> None:
        """Still healthy (WatchdogSec=)."""
        self.notify("WATCHDOG=1")

    def stopping(self) -> None:
        """Shutting down."""
        self.notify("STOPPING=1")

    def close(self) -> None:
        """Close the socket; safe to call twice."""
        if self._sock is not None:
            self._sock.close()
            self._sock = None


def _watchdog_usec(env: Mapping[str, str]) -> int | None:
    """``$WATCHDOG_USEC`` if it is meant for this process (``$WATCHDOG_PID`` unset or ours)."""
    pid = env.get("WATCHDOG_PID")
    if pid and pid != str(os.getpid()):
        return None
    try:
        usec = int(env.get("WATCHDOG_USEC", ""))
    except ValueError:
        return None
    return usec if usec > 0 else None
