"""The unit of work of a fleet job: one recording replayed with each engine, its rows made.

Runs on a Dask worker (or anywhere: nothing here knows Dask). The replay is
:func:`gateway.offline.log_replay.replay`, exactly as ``navgw replay`` runs it; rotated parts
are joined in order into a temporary file first, so the project's readers see one log. A
recording that cannot be read gives error rows: a fleet job never fails for one recording.
"""

from __future__ import annotations

import re
import tempfile
import traceback
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path

from drivers.errors import DriverError
from gateway.config.config_schema import ConfigError
from gateway.config.gateway_config import Engine, GatewayConfig, load_config
from gateway.fleet.agreement import attitude_agreement
from gateway.fleet.input_tally import InputTally
from gateway.fleet.recordings import Recording
from gateway.fleet.rows import FleetRow, error_row, measured_row
from gateway.offline.log_replay import replay, unreadable
from gateway.readback.run_series import RunSeries, read_run

_UNSAFE = re.compile(r"[^A-Za-z0-9._-]+")


@dataclass(frozen=True)
class FleetJob:
    """What every task of one job shares."""

    engines: tuple[Engine, ...]
    config: GatewayConfig | None = None  # --config: for every recording, over its own
    logs_dir: Path | None = None  # where the output logs are kept (None: thrown away)


def replay_recording(recording: Recording, job: FleetJob) -> list[FleetRow]:
    """One row per engine of ``job``; never raises for the recording's content."""
    try:
        return _replay_all(recording, job)
    except Exception as err:  # a bug must cost one recording's rows, not the whole job
        where = traceback.extract_tb(err.__traceback__)[-1]
        why = f"unexpected {type(err).__name__}: {err} (at {where.filename}:{where.lineno})"
        return _errors(recording, job, why)


def output_log_name(recording: Recording, engine: Engine) -> str:
    """The file name of a recording's output log with ``engine`` (``--logs DIR``)."""
    return f"{_UNSAFE.sub('_', recording.name).strip('_.')}.{engine.value}.log"


def _replay_all(recording: Recording, job: FleetJob) -> list[FleetRow]:
    try:
        config = job.config or load_config(recording.config)
    except ConfigError as err:
        return _errors(recording, job, str(err))
    with tempfile.TemporaryDirectory(prefix="navgw-fleet-") as tmp:
        try:
            can_log = _joined(recording.can_logs, Path(tmp) / "imu.log")
            nmea_log = _joined(recording.nmea_logs, Path(tmp) / "gnss.nmea")
        except OSError as err:
            return _errors(recording, job, f"{err.filename}: {err.strerror}")
        rows, runs = [], []
        for engine in job.engines:
            out = (job.logs_dir or Path(tmp)) / output_log_name(recording, engine)
            row, run = _replay_one(recording, engine, config, can_log, nmea_log, out)
            rows.append(row)
            runs.append(run)
    if len(runs) == 2 and runs[0] is not None and runs[1] is not None:
        a, b = attitude_agreement(runs[0], runs[1]), attitude_agreement(runs[1], runs[0])
        rows = [replace(rows[0], **vars(a)), replace(rows[1], **vars(b))]
    return rows


def _replay_one(
    recording: Recording,
    engine: Engine,
    config: GatewayConfig,
    can_log: Path,
    nmea_log: Path,
    out: Path,
) -> tuple[FleetRow, RunSeries | None]:
    """The row of one replay, and its output log read back (None if it failed)."""
    parts = len(recording.can_logs)
    tally = InputTally()
    try:
        summary = replay(can_log, nmea_log, out, config.with_engine(engine), tally)
        problem = unreadable(summary, _names(recording.can_logs), _names(recording.nmea_logs))
        if problem:
            return error_row(recording.name, engine.value, parts, problem), None
        run = read_run(out)
    except DriverError as err:
        return error_row(recording.name, engine.value, parts, str(err)), None
    except OSError as err:
        return error_row(
            recording.name, engine.value, parts, f"{err.filename}: {err.strerror}"
        ), None
    return measured_row(recording.name, engine.value, parts, summary, tally, run), run


def _joined(parts: Sequence[Path], into: Path) -> Path:
    """The one file of ``parts``, or ``parts`` concatenated in order into ``into`` (a part
    cut mid-line, as a full disk leaves it, ends its line first)."""
    if len(parts) == 1:
        return parts[0]
    with into.open("wb") as out:
        for part in parts:
            data = part.read_bytes()
            out.write(data if data.endswith(b"\n") or not data else data + b"\n")
    return into


def _names(parts: Sequence[Path]) -> str:
    return str(parts[0]) if len(parts) == 1 else f"{parts[0]} (+{len(parts) - 1} rotated parts)"


def _errors(recording: Recording, job: FleetJob, why: str) -> list[FleetRow]:
    parts = len(recording.can_logs)
    return [error_row(recording.name, e.value, parts, why) for e in job.engines]
