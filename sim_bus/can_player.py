"""Put a CAN log onto a python-can bus, in real time, N times faster, or as fast as possible.

Relative timing is kept against absolute deadlines (``start + (t_log - t_log0) / speed``), so
sleep errors do not accumulate. From a test::

    with can.Bus(interface="virtual", channel="x") as bus:
        play(read_candump("IMU.log"), bus, speed=None)

From a shell (python-can ``virtual`` is in-process only; use ``udp_multicast`` to reach
another process)::

    python -m sim_bus.can_player IMU.log --interface udp_multicast --channel 239.74.163.2 --speed 10
"""

from __future__ import annotations

import argparse
import logging
import sys
import threading
import time
from collections.abc import Iterable, Sequence

import can

from drivers.logs.candump import read_candump

log = logging.getLogger(__name__)


def play(
    messages: Iterable[can.Message],
    bus: can.BusABC,
    speed: float | None = 1.0,
    stop: threading.Event | None = None,
) -> int:
    """Send ``messages`` on ``bus`` keeping their relative timing; returns the number sent.

    ``speed`` is the time-scale factor (1 = real time, 10 = ten times faster); ``None`` sends
    as fast as the bus takes them. ``stop``, when set, ends the playback early.
    """
    if speed is not None and speed <= 0:
        raise ValueError(f"speed must be positive or None (as fast as possible), got {speed}")
    sent = 0
    t_log0: float | None = None
    start = time.perf_counter()
    for msg in messages:
        if stop is not None and stop.is_set():
            break
        if speed is not None:
            if t_log0 is None:
                t_log0 = msg.timestamp
            delay = start + (msg.timestamp - t_log0) / speed - time.perf_counter()
            if delay > 0:
                time.sleep(delay)
        bus.send(msg)
        sent += 1
    return sent


def main(argv: Sequence[str] | None = None) -> int:
    """Command line: ``python -m sim_bus.can_player LOG --interface I --channel C --speed S``."""
    parser = argparse.ArgumentParser(
        prog="python -m sim_bus.can_player", description="Play a candump -L log onto a CAN bus."
    )
    parser.add_argument("log", help="candump -L log file")
    parser.add_argument("--interface", default="virtual", help="python-can interface name")
    parser.add_argument("--channel", default="vcan0", help="python-can channel")
    parser.add_argument(
        "--speed",
        type=float,
        default=1.0,
        help="time-scale factor (1 real time, 10 ten times faster, 0 as fast as possible)",
    )
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(levelname)s %(name)s: %(message)s")
    try:
        with can.Bus(interface=args.interface, channel=args.channel) as bus:
            n = play(read_candump(args.log), bus, args.speed or None)
    except (OSError, can.CanError) as exc:
        print(f"can_player: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        return 130
    log.info("sent %d frames from %s", n, args.log)
    return 0


if __name__ == "__main__":
    sys.exit(main())
