"""Output scheduler: which PGNs are due at a solution's time, and their frames.

Driven by the solution time only (no wall clock), so replay and live produce the same frames.
Each PGN's due instants lie on a fixed grid ``k / rate`` (absolute time): a PGN is sent with
the first solution at or after each grid point, so the phase is stable and never drifts, and
after a gap the missed slots are skipped (one frame, no burst). Frames of one instant share
one SID, which advances once per instant that sends any SID-carrying PGN.
"""

from __future__ import annotations

import math
from collections.abc import Collection, Iterator, Mapping

import can

from gateway.estimation.solution import Solution
from gateway.isobus.j1939 import Pgn
from gateway.isobus.n2k_encode import LoopStatus, OutputEncoder

#: SPEC 4 default rates, Hz (0 turns a PGN off).
DEFAULT_RATES_HZ: Mapping[Pgn, float] = {
    Pgn.ATTITUDE: 50.0,
    Pgn.RATE_OF_TURN: 50.0,
    Pgn.VESSEL_HEADING: 10.0,
    Pgn.POSITION_RAPID_UPDATE: 50.0,
    Pgn.COG_SOG_RAPID_UPDATE: 10.0,
    Pgn.GNSS_POSITION_DATA: 10.0,
    Pgn.NAVGW_GYRO_BIAS: 1.0,
    Pgn.NAVGW_ACCEL_BIAS: 1.0,
    Pgn.NAVGW_STATUS: 10.0,
}

#: PGNs whose frames carry the shared SID.
SID_PGNS = frozenset(
    {
        Pgn.ATTITUDE,
        Pgn.RATE_OF_TURN,
        Pgn.VESSEL_HEADING,
        Pgn.COG_SOG_RAPID_UPDATE,
        Pgn.GNSS_POSITION_DATA,
    }
)
SID_MODULO = 253  # SID runs 0-252; 253-255 are special values
MAX_RATE_HZ = 100.0
_GRID_TOLERANCE = 1e-6  # of a period: a time a rounding error before a grid point is on it


class OutputScheduler:
    """Returns the frames due for each solution; the caller sends them."""

    def __init__(
        self,
        rates_hz: Mapping[Pgn, float] | None = None,
        encoder: OutputEncoder | None = None,
    ) -> None:
        rates = {**DEFAULT_RATES_HZ, **(rates_hz or {})}
        for pgn, rate in rates.items():
            if pgn not in DEFAULT_RATES_HZ:
                raise ValueError(f"PGN {pgn} is not an output of SPEC 4")
            if not 0.0 <= rate <= MAX_RATE_HZ:
                raise ValueError(f"rate of PGN {pgn} is {rate} Hz, expected 0-{MAX_RATE_HZ}")
        self.rates_hz = {Pgn(pgn): rate for pgn, rate in rates.items() if rate > 0}
        self._encoder = encoder or OutputEncoder()
        self._last_slot: dict[Pgn, int] = {}
        self._next_due_t = -math.inf  # earliest grid point not yet served
        self._sid = SID_MODULO - 1  # the first instant sends SID 0

    def is_due(self, t: float) -> bool:
        """True when some PGN is due at ``t``: callers skip building a solution otherwise."""
        return t >= self._next_due_t

    def due(self, t: float, only: Collection[Pgn] | None = None) -> list[Pgn]:
        """PGNs (of ``only``, if given) whose next grid slot has come at time ``t`` (marks
        them sent)."""
        pgns = []
        for pgn, rate in self.rates_hz.items():
            if only is not None and pgn not in only:
                continue
            slot = math.floor(t * rate + _GRID_TOLERANCE)
            last = self._last_slot.get(pgn)
            if last is None or slot > last:
                self._last_slot[pgn] = slot
                pgns.append(pgn)
        self._next_due_t = min(
            (
                (self._last_slot[p] + 1 - _GRID_TOLERANCE) / r
                if p in self._last_slot
                else -math.inf
                for p, r in self.rates_hz.items()
            ),
            default=math.inf,
        )
        return pgns

    def frames(
        self, solution: Solution, loop: LoopStatus, only: Collection[Pgn] | None = None
    ) -> Iterator[can.Message]:
        """Frames to send for ``solution`` (none before the address is claimed); ``only``
        limits them to those PGNs.

        Which PGNs are due and their SID are decided now; each frame is encoded as the caller
        takes it, in the order of :data:`DEFAULT_RATES_HZ` (attitude and rate of turn first),
        so a caller that sends as it iterates puts 127257 on the bus before the other PGNs of
        the instant are even encoded.
        """
        if not loop.address_claimed:
            return iter(())
        pgns = self.due(solution.t, only)
        if SID_PGNS.intersection(pgns):
            self._sid = (self._sid + 1) % SID_MODULO
        return self._encode(pgns, solution, loop, self._sid)

    def _encode(
        self, pgns: list[Pgn], solution: Solution, loop: LoopStatus, sid: int
    ) -> Iterator[can.Message]:
        for pgn in pgns:
            yield from self._encoder.frames(pgn, solution, loop, sid)
