"""candump -L read and write, fast path against the careful one, in one process (issue 14).

    .venv/bin/python benchmarks/candump_speed.py [--lines 100000] [--repeat 5]

Writes a log shaped like the IMU bridge's (two 8-byte frames a sample, 3 ids) and times, in CPU
time, the best of ``--repeat`` runs of each, after a ``gc.collect()``, with the cyclic collector
off and on. Off is the code's own cost; on adds the collections that the messages kept in a
list set off, full ones included, whose cost grows with everything else the process holds
(replay_speed.py's "candump parse" carries whichever of those fall in its single run):

- parse, careful: every line through ``_parse_careful`` with its "name:number" (the reader as
  it was) — parse, reader: ``list(read_candump(path))``;
- write, careful: ``format_candump_line`` per frame (the writer as it was) — write, writer:
  ``CandumpWriter.write_all``, frames in pairs sharing a timestamp object, as the core's.

Both directions are checked to give the same result before the figures are printed.
"""

from __future__ import annotations

import argparse
import gc
import random
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import can

from drivers.logs import candump

IDS = (0x0CFF1080, 0x0CFF1180, 0x18FF1280)


def best(fn: Callable[[], Any], repeat: int, collector: bool) -> float:
    """Least CPU seconds of ``repeat`` calls, the cyclic garbage collector on or off."""
    times = []
    for _ in range(repeat):
        gc.collect()
        if not collector:
            gc.disable()
        try:
            t0 = time.process_time()
            fn()
            times.append(time.process_time() - t0)
        finally:
            gc.enable()
    return min(times)


def careful_read(path: Path) -> list[can.Message]:
    out = []
    name = str(path)
    with path.open(encoding="ascii", errors="replace") as stream:
        for number, line in enumerate(stream, start=1):
            msg = candump._parse_careful(line, f"{name}:{number}")
            if msg is not None:
                out.append(msg)
    return out


def careful_write(path: Path, frames: list[can.Message]) -> None:
    with path.open("w", encoding="ascii", newline="\n") as file:
        for msg in frames:
            file.write(candump.format_candump_line(msg, "can0") + "\n")


def writer_write(path: Path, frames: list[can.Message]) -> None:
    with candump.CandumpWriter(path, "can0") as writer:
        writer.write_all(frames)


def fields(msg: can.Message) -> tuple[Any, ...]:
    return tuple(getattr(msg, s) for s in can.Message.__slots__ if s != "__weakref__")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--lines", type=int, default=100_000)
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()
    rng = random.Random(0)
    frames = []
    for k in range(args.lines // 2):
        t = 1_700_000_000.0 + k / 204.8 + rng.random() * 1e-4
        for can_id in (IDS[0], IDS[1 + k % 2]):
            data = bytes(rng.randrange(256) for _ in range(8))
            frames.append(can.Message(timestamp=t, arbitration_id=can_id, data=data))
    with tempfile.TemporaryDirectory() as tmp:
        log = Path(tmp) / "imu.log"
        careful_write(log, frames)
        writer_write(Path(tmp) / "w.log", frames)
        assert (Path(tmp) / "w.log").read_bytes() == log.read_bytes()
        assert [fields(m) for m in careful_read(log)] == [
            fields(m) for m in candump.read_candump(log)
        ]
        rows = [
            ("parse, careful", lambda: careful_read(log)),
            ("parse, reader", lambda: list(candump.read_candump(log))),
            ("write, careful", lambda: careful_write(Path(tmp) / "c.log", frames)),
            ("write, writer", lambda: writer_write(Path(tmp) / "w.log", frames)),
        ]
        n = len(frames)
        print(f"{n} lines; CPU us per 2 lines (an IMU sample's), best of {args.repeat}")
        print(f"  {'':16s} {'gc off':>7s} {'gc on':>7s}")
        for label, fn in rows:
            off, on = (best(fn, args.repeat, gc_on) / n * 2e6 for gc_on in (False, True))
            print(f"  {label:16s} {off:7.2f} {on:7.2f}")


if __name__ == "__main__":
    main()
