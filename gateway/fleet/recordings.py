"""Recordings found on disk: what one fleet task replays.

A path given to ``navgw fleet`` is a manifest (:func:`read_manifest`) or a directory searched
with its sub-directories for

- pairs of SPEC 3 logs as ``[recording]`` writes them (``navgw-000042-<UTC>.imu.log`` and
  ``.gnss.nmea``): the recorder rotates a running session into consecutive pairs, so pairs
  whose numbers follow on and whose CAN logs continue within :data:`JOIN_GAP_S` are the parts
  of one recording, replayed in order as one (a service restart starts a new one);
- a directory holding ``imu.log`` and ``gnss.nmea`` as ``navgw sim`` writes them, with its
  vehicle's ``navgw.toml`` if there.

A pair missing one of its files is still a recording: its task reports the missing file.
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

from drivers.errors import InputError
from drivers.logs.candump import time_span
from gateway.config.config_schema import load_toml
from gateway.service.input_recording import CAN_SUFFIX, NMEA_SUFFIX, recorded_stems

#: The files of a ``navgw sim`` run directory (sim_bus.scenarios writes them).
SIM_CAN_LOG, SIM_NMEA_LOG, SIM_CONFIG = "imu.log", "gnss.nmea", "navgw.toml"
#: Largest gap (s) between the last frame of a rotated pair and the first of the next for the
#: two to be one recording: the recorder rotates between two writes (one IMU period, ~5 ms).
JOIN_GAP_S = 1.0
EXPECTED = (
    "a manifest (TOML), or a directory holding [recording] pairs (navgw-NNNNNN-*.imu.log and "
    ".gnss.nmea) or navgw sim runs (imu.log and gnss.nmea)"
)


@dataclass(frozen=True)
class Recording:
    """One recording: its CAN and NMEA logs (rotated parts in order) and its own config."""

    name: str
    can_logs: tuple[Path, ...]
    nmea_logs: tuple[Path, ...]
    config: Path | None = None  # the vehicle's gateway config kept with the logs, if any


def find_recordings(paths: Sequence[Path]) -> list[Recording]:
    """Every recording under ``paths``, in the order given (directories sorted by name).

    Raises :class:`InputError` for a path that does not exist or holds no recording, or a
    manifest that is not one; ConfigError for a file that is not TOML.
    """
    found: list[Recording] = []
    for path in paths:
        if not path.exists():
            raise InputError("not found", str(path), EXPECTED)
        in_path = read_manifest(path) if path.is_file() else list(_in_directory(path))
        if not in_path:
            raise InputError("no recording in it", str(path), EXPECTED)
        found += in_path
    return found


def _in_directory(top: Path) -> Iterator[Recording]:
    for directory, subdirs, files in os.walk(top):
        subdirs.sort()
        name, here = directory, Path(directory).absolute()  # a remote worker needs all of it
        if SIM_CAN_LOG in files and SIM_NMEA_LOG in files:
            config = here / SIM_CONFIG if SIM_CONFIG in files else None
            yield Recording(name, (here / SIM_CAN_LOG,), (here / SIM_NMEA_LOG,), config)
        for session in sessions(here, recorded_stems(here)):
            yield Recording(
                str(Path(name) / session[0]),
                tuple(here / (stem + CAN_SUFFIX) for stem in session),
                tuple(here / (stem + NMEA_SUFFIX) for stem in session),
            )


def sessions(directory: Path, stems: Iterable[str]) -> list[list[str]]:
    """``stems`` (oldest first) grouped into recordings: a pair joins the one before it when
    its number is the next and its CAN log starts within :data:`JOIN_GAP_S` of that one's end
    (before or after it: a log that starts long before the last one ended is another session)."""
    groups: list[list[str]] = []
    last_end: float | None = None
    last_number = -1
    for stem in stems:
        number = int(stem.split("-")[1])
        span = _span(directory / (stem + CAN_SUFFIX))
        follows = (
            groups
            and number == last_number + 1
            and span is not None
            and last_end is not None
            and abs(span[0] - last_end) <= JOIN_GAP_S
        )
        if follows:
            groups[-1].append(stem)
        else:
            groups.append([stem])
        last_number, last_end = number, span[1] if span else None
    return groups


def _span(can_log: Path) -> tuple[float, float] | None:
    """The log's first and last frame times; None if missing or unreadable (then not joined)."""
    try:
        return time_span(can_log)
    except OSError:
        return None


_MANIFEST_KEYS = {"name", "can", "nmea", "config"}
_MANIFEST_FORM = (
    '[[recording]] tables: can = "X.imu.log" or a list of rotated parts in order, nmea = '
    'the same, optional name = "..." and config = "FILE.toml" (paths relative to the manifest)'
)


def read_manifest(path: Path) -> list[Recording]:
    """The recordings a manifest lists: a TOML file of ``[[recording]]`` tables, e.g.

    .. code-block:: toml

        [[recording]]
        name = "tractor-07 2025-03-01"
        can = ["t7/navgw-000001-20250301T060000Z.imu.log", "t7/navgw-000002-20250301T0815Z.imu.log"]
        nmea = ["t7/navgw-000001-20250301T060000Z.gnss.nmea", "t7/navgw-000002-...gnss.nmea"]
        config = "tractor-07.toml"
    """
    document = load_toml(path)  # ConfigError naming the file if unreadable or not TOML
    tables = document.get("recording")
    if set(document) != {"recording"} or not isinstance(tables, list):
        raise InputError("no [[recording]] tables only", str(path), _MANIFEST_FORM)
    return [_manifest_entry(table, path, n) for n, table in enumerate(tables, start=1)]


def _manifest_entry(table: dict[str, object], path: Path, n: int) -> Recording:
    where = f"{path}: recording {n}"
    if unknown := set(table) - _MANIFEST_KEYS:
        raise InputError(f"unknown key {sorted(unknown)[0]!r}", where, _MANIFEST_FORM)
    logs = {key: _paths(table.get(key), path.parent, f"{where}: {key}") for key in ("can", "nmea")}
    config, name = table.get("config"), table.get("name")
    if config is not None and not isinstance(config, str):
        raise InputError(f"config = {config!r}", where, _MANIFEST_FORM)
    if name is not None and not isinstance(name, str):
        raise InputError(f"name = {name!r}", where, _MANIFEST_FORM)
    return Recording(
        name or str(logs["can"][0]),
        logs["can"],
        logs["nmea"],
        (path.parent / config).absolute() if config else None,
    )


def _paths(value: object, base: Path, where: str) -> tuple[Path, ...]:
    parts = [value] if isinstance(value, str) else value
    if not isinstance(parts, list) or not parts or not all(isinstance(p, str) for p in parts):
        raise InputError(f"{value!r}", where, "a path or a non-empty list of paths")
    return tuple((base / str(p)).absolute() for p in parts)
