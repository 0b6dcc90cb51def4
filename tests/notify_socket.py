"""A unix datagram socket standing in for systemd's $NOTIFY_SOCKET in tests."""

from __future__ import annotations

import socket
import time
from pathlib import Path


class NotifySocket:
    """Binds ``path``; :meth:`wait_for` collects sd_notify datagrams until one matches."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
        self.sock.bind(str(path))
        self.received: list[tuple[float, str]] = []  # (monotonic time, assignment)

    def wait_for(self, prefix: str, timeout: float) -> str | None:
        """The first new assignment starting with ``prefix`` within ``timeout`` s, else None."""
        deadline = time.monotonic() + timeout
        while (left := deadline - time.monotonic()) > 0:
            self.sock.settimeout(left)
            try:
                data = self.sock.recv(4096)
            except TimeoutError:
                return None
            lines = data.decode().splitlines()
            now = time.monotonic()
            self.received += [(now, line) for line in lines]
            for line in lines:
                if line.startswith(prefix):
                    return line
        return None

    def times(self, assignment: str) -> list[float]:
        """When ``assignment`` (e.g. WATCHDOG=1) arrived."""
        return [t for t, line in self.received if line == assignment]

    def close(self) -> None:
        self.sock.close()
