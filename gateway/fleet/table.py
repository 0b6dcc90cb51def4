"""The fleet table: rows to Parquet (pyarrow) with a fixed schema, and a short text summary.

The schema comes from :class:`~gateway.fleet.rows.FleetRow`'s fields, so a table of error rows
only still has typed columns; ``pandas.read_parquet`` opens it as it is.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from pathlib import Path

import pyarrow as pa
import pyarrow.parquet as pq

from gateway.fleet.rows import FleetRow

_ARROW = {"str": pa.string(), "int": pa.int64(), "float": pa.float64()}


def schema() -> pa.Schema:
    """One column per FleetRow field, typed from its annotation (``float | None``: float64)."""
    return pa.schema(
        [
            pa.field(f.name, _ARROW[str(f.type).split(" | ")[0]])
            for f in dataclasses.fields(FleetRow)
        ]
    )


def write_parquet(rows: Sequence[FleetRow], path: Path) -> None:
    """Write ``rows`` as one Parquet file at ``path``."""
    table = pa.Table.from_pylist([dataclasses.asdict(row) for row in rows], schema=schema())
    pq.write_table(table, path)


def read_rows(path: Path) -> list[FleetRow]:
    """The rows of a table written by :func:`write_parquet`."""
    return [FleetRow(**row) for row in pq.read_table(path).to_pylist()]


def summary_text(rows: Sequence[FleetRow], wall_s: float, workers: int) -> str:
    """What a person reads first: totals, speed, per-engine medians, and the errors."""
    good = [row for row in rows if row.error is None]
    recordings = {row.recording for row in rows}
    hours = sum(row.duration_s or 0.0 for row in good) / 3600.0
    lines = [
        f"{len(recordings)} recordings, {len(rows)} rows ({len(rows) - len(good)} with errors): "
        f"{hours:.2f} recording-hours in {wall_s:.1f} s on {workers} workers "
        f"({hours * 3600.0 / wall_s if wall_s > 0 else math.inf:.0f}x real time)"
    ]
    for engine in sorted({row.engine for row in good}):
        mine = [row for row in good if row.engine == engine]
        navigating = sum(r.navigating_s or 0.0 for r in mine) / max(
            sum(r.duration_s or 0.0 for r in mine), 1e-9
        )
        lines.append(
            f"  {engine}: navigating {100 * navigating:.0f} % of the time, IMU samples lost "
            f"{sum(r.imu_lost or 0 for r in mine)}, gyro z converged in "
            f"{sum(r.gyro_z_converged_s is not None for r in mine)}/{len(mine)} "
            f"(median {_median([r.gyro_z_converged_s for r in mine])} s)"
        )
    lines += [f"  error: {row.recording} ({row.engine}): {row.error}" for row in rows if row.error]
    return "\n".join(lines)


def _median(values: Sequence[float | None]) -> str:
    known = sorted(v for v in values if v is not None)
    return f"{known[len(known) // 2]:.0f}" if known else "-"
