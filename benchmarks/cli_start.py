"""Start-up cost of the `navgw` command line: what an engineer waits for, what an ECU pays.

Runs each command line ``--repeat`` times in a fresh interpreter and reports the median
wall time and CPU time (user + system of the child, from resource usage). Target (issue
13): `navgw --help` under 0.3 s. Run:

    .venv/bin/python benchmarks/cli_start.py [--repeat 10]
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import subprocess
import sys
import time
from pathlib import Path

NAVGW = Path(sys.executable).with_name("navgw")
COMMANDS = (["--help"], ["run", "--help"], ["replay", "--help"], ["config", "--example"])


def measure(argv: list[str]) -> tuple[float, float]:
    """(wall s, CPU s) of one run of ``navgw argv``."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    subprocess.run([str(NAVGW), *argv], check=True, stdout=subprocess.DEVNULL)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=10)
    args = parser.parse_args()
    print(f"navgw start-up, median of {args.repeat} runs; {os.cpu_count()} cores")
    for argv in COMMANDS:
        runs = [measure(argv) for _ in range(args.repeat)]
        wall = statistics.median(w for w, _ in runs)
        cpu = statistics.median(c for _, c in runs)
        print(f"  navgw {' '.join(argv):20s} wall {wall * 1e3:6.0f} ms   CPU {cpu * 1e3:6.0f} ms")
    print("command: .venv/bin/python benchmarks/cli_start.py")


if __name__ == "__main__":
    main()
