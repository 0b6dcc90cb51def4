"""python-can's ``udp_multicast`` bus in tests: the group, and a port of the test's own."""

from __future__ import annotations

import json
import random
import time

import can
import pytest

GROUP = "239.74.163.2"  # python-can's udp_multicast default group; the port is the test's own


@pytest.fixture
def multicast_port(monkeypatch: pytest.MonkeyPatch) -> int:
    """A udp_multicast port of the test's own (through CAN_CONFIG, as python-can reads it);
    skips where the group does not loop back within the process."""
    port = random.randrange(44000, 44999)
    monkeypatch.setenv("CAN_CONFIG", json.dumps({"port": port}))
    try:
        with (
            can.Bus(interface="udp_multicast", channel=GROUP) as a,
            can.Bus(interface="udp_multicast", channel=GROUP) as b,
        ):
            a.send(can.Message(arbitration_id=0x0CFF1080, data=bytes(8)))
            looped = b.recv(1.0) is not None
    except (can.CanError, OSError) as exc:
        pytest.skip(f"udp_multicast not available here: {exc}")
    if not looped:
        pytest.skip("udp_multicast does not loop back here (route the group to lo)")
    return port


def until_stamped_on_arrival(tx: can.BusABC, rx: can.BusABC, timeout_s: float = 5.0) -> None:
    """Wait until ``rx`` gets ``tx``'s frames stamped on arrival. Linux turns receive time
    stamps on for the first socket that asks, in deferred work: until then a frame carries
    the time it was read (the first frames after opening came 0.11 s "late" in one run of
    five, held in the socket 0.11 s)."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        tx.send(can.Message(arbitration_id=0x7FF, is_extended_id=False))
        time.sleep(0.05)
        msg = rx.recv(1.0)
        if msg is not None and time.time() - msg.timestamp > 0.04:
            return
    raise AssertionError(f"udp_multicast frames not stamped on arrival within {timeout_s} s")
