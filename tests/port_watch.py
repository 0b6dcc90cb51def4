"""How long data sat unread in a serial port: ``python -m tests.port_watch DEVICE``.

Run as a process of its own (not a thread of the test, which would wait for the test's GIL),
it opens the port (a pty's slave) a second time without reading it and polls the bytes its
line discipline holds for readers (``TIOCINQ``) every :data:`POLL_S`, until its stdin closes;
then it prints the spans (s) in which the port held unread data longer than
:data:`REPORT_S`, as JSON, longest first. Data the kernel has not yet handed to the port
(its flip buffer, on a saturated host seconds late at times) is not the reader's to read,
and not counted.
"""

from __future__ import annotations

import fcntl
import json
import os
import select
import struct
import sys
import termios
import time

POLL_S = 0.005
REPORT_S = 0.05


def unread_spans(device: str) -> list[float]:
    """The spans of unread data in ``device`` until stdin closes, longest first."""
    fd = os.open(device, os.O_RDONLY | os.O_NONBLOCK | os.O_NOCTTY)
    spans: list[float] = []
    since: float | None = None
    try:
        while not select.select([sys.stdin], [], [], POLL_S)[0]:
            (queued,) = struct.unpack("i", fcntl.ioctl(fd, termios.TIOCINQ, b"\0" * 4))
            now = time.monotonic()
            if queued and since is None:
                since = now
            elif not queued and since is not None:
                if now - since > REPORT_S:
                    spans.append(now - since)
                since = None
    finally:
        os.close(fd)
    return sorted(spans, reverse=True)


if __name__ == "__main__":
    print(json.dumps(unread_spans(sys.argv[1])), flush=True)
