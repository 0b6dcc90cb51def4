"""The Dask shell of a fleet job: one task per recording, on a local or an existing cluster.

Without a scheduler address a ``dask.distributed`` LocalCluster is started with one
single-threaded worker process per core (replay is CPU-bound Python: threads would share one
GIL); with one, the job runs on that cluster (``dask scheduler`` / ``dask worker``), whose
workers must see the recordings' paths and have navgw installed. A task that fails anyway (a
worker lost, navgw missing on a worker) becomes error rows like an unreadable recording.
"""

from __future__ import annotations

import os
import sys
import time
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from importlib.util import find_spec

from distributed import Client, Future, LocalCluster, as_completed
from tqdm import tqdm

from gateway.fleet.recordings import Recording
from gateway.fleet.rows import FleetRow, error_row
from gateway.fleet.task import FleetJob, replay_recording

#: Seconds to wait for a scheduler given by address.
CONNECT_TIMEOUT_S = 30.0


@dataclass(frozen=True)
class FleetResult:
    """The rows of a job (recording order, engines in job order) and how it ran."""

    rows: list[FleetRow]
    wall_s: float
    workers: int
    dashboard: str | None


def run_fleet(
    recordings: Sequence[Recording],
    job: FleetJob,
    scheduler: str | None = None,
    workers: int | None = None,
) -> FleetResult:
    """Replay every recording as one task; the progress line and dashboard link on stderr."""
    with _client(scheduler, workers) as client:
        dashboard = client.dashboard_link if find_spec("bokeh") else None
        n_workers = len(client.scheduler_info()["workers"])
        print(
            f"navgw fleet: {len(recordings)} recordings on {n_workers} workers"
            + (f", dashboard {dashboard}" if dashboard else " (no dashboard: pip install bokeh)"),
            file=sys.stderr,
        )
        wall = time.perf_counter()
        futures = client.map(replay_recording, recordings, job=job, pure=False)
        index = {future.key: i for i, future in enumerate(futures)}
        results: list[list[FleetRow] | None] = [None] * len(futures)
        failed = 0
        with tqdm(total=len(futures), unit="rec", desc="fleet", disable=None) as bar:
            for future in as_completed(futures):
                i = index[future.key]
                results[i] = _rows(future, recordings[i], job)
                failed += any(row.error for row in results[i] or [])
                bar.set_postfix(errors=failed, refresh=False)
                bar.update()
        wall = time.perf_counter() - wall
    rows = [row for result in results for row in result or []]
    return FleetResult(rows, wall, n_workers, dashboard)


def _rows(future: Future, recording: Recording, job: FleetJob) -> list[FleetRow]:
    """The task's rows; error rows when the task itself failed."""
    if future.status == "finished":
        rows: list[FleetRow] = future.result()
        return rows
    err = future.exception()
    why = f"task failed on the cluster: {type(err).__name__}: {err}"
    return [error_row(recording.name, e.value, len(recording.can_logs), why) for e in job.engines]


@contextmanager
def _client(scheduler: str | None, workers: int | None) -> Iterator[Client]:
    if scheduler is not None:
        with Client(scheduler, timeout=CONNECT_TIMEOUT_S) as client:
            yield client
        return
    n = workers or os.cpu_count() or 1
    with (
        LocalCluster(n_workers=n, threads_per_worker=1, processes=True) as cluster,
        Client(cluster) as client,
    ):
        yield client
