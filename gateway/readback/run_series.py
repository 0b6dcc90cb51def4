"""A whole output log as time series: every message of one navigation source, by DBC name.

``read_run(log)`` decodes a candump ``-L`` log with
:class:`~gateway.readback.frame_decoder.OutputFrameDecoder` and keeps the messages of the
source that sent NAVGW_STATUS first (a navgw), or else of the first source of any SPEC 4 PGN
(another navigation device). ``numbers`` and ``labels`` give a signal as a float array (NaN
where not available) or as value names, with ``times`` of its message.
"""

from __future__ import annotations

from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import numpy.typing as npt

from drivers.errors import InputError
from drivers.logs.candump import read_candump
from gateway.isobus.output_scheduler import DEFAULT_RATES_HZ
from gateway.readback.frame_decoder import DecodeStats, OutputFrameDecoder, Value

Array = npt.NDArray[np.float64]
NAV_PGNS = frozenset(int(p) for p in DEFAULT_RATES_HZ)


@dataclass
class MessageSeries:
    """The messages of one DBC name: their times and each signal's values, in order."""

    pgn: int
    t: list[float] = field(default_factory=list)
    signals: dict[str, list[Value]] = field(default_factory=lambda: defaultdict(list))


@dataclass
class RunSeries:
    """One source's messages of a log; times are the log's (host clock, s)."""

    path: Path
    source: int
    t0: float  # first frame of the log
    t_end: float  # last frame of the log
    messages: dict[str, MessageSeries]
    stats: DecodeStats

    def times(self, name: str) -> Array:
        """Times of the ``name`` messages (empty if none)."""
        series = self.messages.get(name)
        return np.asarray(series.t if series else [], dtype=float)

    def numbers(self, name: str, signal: str) -> Array:
        """``signal`` of the ``name`` messages as floats; NaN where not a number."""
        series = self.messages.get(name)
        values = series.signals.get(signal, []) if series else []
        return np.array(
            [float(v) if isinstance(v, int | float) else np.nan for v in values], dtype=float
        )

    def labels(self, name: str, signal: str) -> list[str]:
        """``signal`` of the ``name`` messages as text (value names; ``n/a`` for None)."""
        series = self.messages.get(name)
        values = series.signals.get(signal, []) if series else []
        return ["n/a" if v is None else str(v) for v in values]


def read_run(path: str | Path) -> RunSeries:
    """Decode the log at ``path``; InputError when no source in it sends SPEC 4 PGNs."""
    path = Path(path)
    decoder = OutputFrameDecoder()
    by_source: dict[int, dict[str, MessageSeries]] = {}
    first_status: int | None = None
    t0 = t_end = None
    for msg in read_candump(path):
        t0 = msg.timestamp if t0 is None else t0
        t_end = msg.timestamp
        decoded = decoder.decode(msg)
        if decoded is None:
            continue
        source, pgn = decoded.frame_id.source, decoded.frame_id.pgn
        if source not in by_source and pgn not in NAV_PGNS:
            continue
        if first_status is None and decoded.name == "NAVGW_STATUS":
            first_status = source
        series = by_source.setdefault(source, {}).setdefault(decoded.name, MessageSeries(pgn))
        series.t.append(decoded.t)
        for signal, value in decoded.signals.items():
            series.signals[signal].append(value)
    if not by_source or t0 is None or t_end is None:
        raise InputError(
            f"no navigation output ({decoder.stats.frames} frames, none of SPEC 4's PGNs)",
            str(path),
            "a candump -L log of navgw's output (navgw replay --out, the demo's "
            "navgw-output.log, candump -L of the ISOBUS)",
        )
    source = first_status if first_status is not None else next(iter(by_source))
    return RunSeries(path, source, t0, t_end, by_source[source], decoder.stats)
