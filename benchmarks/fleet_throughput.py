"""`navgw fleet` throughput: recording-hours re-processed per wall hour against the workers.

    .venv/bin/python benchmarks/fleet_throughput.py [--recordings 8] [--workers 1 2] [--engine ekf]

Generates ``--recordings`` runs of the ``short`` scenario (~125 s each, seeds 1..N) into a
temporary directory, then runs the whole fleet job (:func:`gateway.fleet.cluster.run_fleet`:
a LocalCluster of N single-threaded worker processes, one task per recording) once per worker
count. Wall time includes the cluster's start (worker processes importing navgw) and every
task's replay and read-back of its output log, as ``navgw fleet`` spends it.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from gateway.config.gateway_config import Engine
from gateway.fleet.cluster import run_fleet
from gateway.fleet.recordings import find_recordings
from gateway.fleet.task import FleetJob
from sim_bus.scenarios import SCENARIOS, generate


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--recordings", type=int, default=8)
    parser.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--engine", choices=[e.value for e in Engine], default="observer")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="navgw-fleet-bench-") as tmp:
        for seed in range(1, args.recordings + 1):
            generate(SCENARIOS["short"], Path(tmp) / f"run-{seed:03d}", seed=seed)
        recordings = find_recordings([Path(tmp)])
        job = FleetJob((Engine(args.engine),))
        print(f"{len(recordings)} recordings of scenario short, engine {args.engine}")
        print("workers  recording-h  wall s  task s (sum)  recording-h per wall h")
        for workers in args.workers:
            wall = time.perf_counter()
            result = run_fleet(recordings, job, workers=workers)
            wall = time.perf_counter() - wall  # with the cluster's start and stop
            hours = sum(row.duration_s or 0.0 for row in result.rows) / 3600.0
            task_s = sum(row.wall_s or 0.0 for row in result.rows)
            assert not any(row.error for row in result.rows), result.rows
            speed = hours * 3600 / wall
            print(f"{workers:7d}  {hours:11.3f}  {wall:6.1f}  {task_s:12.1f}  {speed:22.0f}")


if __name__ == "__main__":
    main()
