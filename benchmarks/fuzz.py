"""Fuzz the gateway's edges at length: tests/test_fuzz.py's properties with many examples.

    .venv/bin/python benchmarks/fuzz.py --examples 50000

Each of the properties (NMEA bytes, IMU frames, candump and NMEA log lines, config tables)
runs ``--examples`` hypothesis examples; the normal test run uses 300. Prints pytest's
report; exit status is pytest's.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--examples", type=int, default=50_000, help="per property")
    args = parser.parse_args()
    os.environ["NAVGW_FUZZ_EXAMPLES"] = str(args.examples)
    sys.path.insert(0, str(REPO))  # the tests import each other as the package "tests"
    start = time.process_time()
    status = pytest.main(
        ["-q", "-p", "no:cacheprovider", "--timeout=0", str(REPO / "tests" / "test_fuzz.py")]
    )
    print(f"{args.examples} examples per property, {time.process_time() - start:.0f} s of CPU")
    return int(status)


if __name__ == "__main__":
    sys.exit(main())
