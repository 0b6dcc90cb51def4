"""Output scheduler: which PGNs are due at a solution's time, and their frames.

Driven by the solution time only (no wall clock), so replay and live produce the same frames.
Each PGN's due instants lie on a fixed grid ``k / rate`` (absolute time): a PGN is sent with
the first solution at or after each grid point, so the phase is stable and never drifts, and
after a gap the missed slots are skipped (one frame, no burst). Frames of one instant share
one SID, which advances once per instant that sends any SID-carrying PGN.

The slot of ``t`` is ``floor(t * rate + tolerance)``; a PGN is due when that exceeds the last
slot it was sent in. ``due`` runs per IMU sample and mostly finds nothing, so it is built for
that: PGNs of one rate sent in the same slots share one state (a :class:`_Group`; 3 with the
default rates); a time before which no group can be due (:data:`_QUIET`) answers most calls
with one comparison; and a group is due when ``t * rate + tolerance >= last + 1``, the same
test as ``floor(...) > last`` for a finite value (Python compares floats with ints exactly),
so ``math.floor`` runs only for the slots sent. Same answers, same ``is_due``, as computing
every PGN's slot on every call.
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
#: A group is certainly not due at ``t < next_t * _QUIET`` (when ``next_t > 0``), float
#: rounding included. ``next_t``, ``(need - tolerance) / rate`` in floats, is within 3
#: roundings (2**-53 relative each) of the exact value, and ``need >= 1`` when it is positive;
#: so such a ``t`` is below the exact time of slot ``need`` by more than 2**-50 relative, and
#: ``t * rate + tolerance``, rounded twice, stays below ``need``.
_QUIET = 1.0 - 2.0**-48
#: Times within +/- this keep ``t * rate`` finite for every rate (<= MAX_RATE_HZ). Beyond
#: (and for NaN), ``math.floor`` raises for some PGNs: ``due`` then goes PGN by PGN in the
#: order of ``rates_hz``, so that it raises at the same PGN, with the same PGNs marked sent
#: before, as computing every PGN's slot in turn does.
_T_LIMIT = 1e300
_INF = math.inf


class _Group:
    """PGNs of one rate that were sent in the same slots so far: they share one state, so
    ``due`` checks them at once. A call of ``due`` with ``only`` that sends some of them
    splits the others off."""

    __slots__ = ("need", "next_t", "pgns", "quiet", "rate")

    def __init__(self, rate: float, pgns: tuple[Pgn, ...]) -> None:
        self.rate = rate
        self.pgns = pgns
        self.need: float = -_INF  # the next slot number (the last slot sent + 1)
        self.next_t = -_INF  # its time, ``(last + 1 - tolerance) / rate`` (as is_due ever did)
        self.quiet = -_INF  # a time before which they are certainly not due (see _QUIET)

    def split(self, pgns: tuple[Pgn, ...]) -> _Group:
        """A new group of ``pgns`` (some of these), with the same state; this group keeps
        the others (when it keeps none, it is dropped: callers replace the list)."""
        other = _Group(self.rate, pgns)
        other.need, other.next_t, other.quiet = self.need, self.next_t, self.quiet
        self.pgns = tuple(p for p in self.pgns if p not in pgns)
        return other


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
        self._framers = {pgn: self._encoder.framer(pgn) for pgn in self.rates_hz}
        self._order = {pgn: i for i, pgn in enumerate(self.rates_hz)}
        by_rate: dict[float, list[Pgn]] = {}
        for pgn, rate in self.rates_hz.items():
            by_rate.setdefault(rate, []).append(pgn)
        self._groups = [_Group(rate, tuple(pgns)) for rate, pgns in by_rate.items()]
        #: Earliest grid point not yet served: nothing is due before it (a caller per IMU
        #: sample compares with it instead of calling :meth:`is_due`).
        self.next_due_t = -_INF
        self._quiet_until = -_INF  # no PGN is due before this: the least group.quiet
        self._sid = SID_MODULO - 1  # the first instant sends SID 0

    def is_due(self, t: float) -> bool:
        """True when some PGN is due at ``t``: callers skip building a solution otherwise."""
        return t >= self.next_due_t

    def due(self, t: float, only: Collection[Pgn] | None = None) -> list[Pgn]:
        """PGNs (of ``only``, if given) whose next grid slot has come at time ``t`` (marks
        them sent)."""
        if -_T_LIMIT < t < self._quiet_until:
            return []
        if not -_T_LIMIT < t < _T_LIMIT:
            self._one_by_one()
        if only is not None:
            self._split(only)
        pgns: list[Pgn] = []
        next_due = quiet_until = _INF
        for group in self._groups:
            if not -_T_LIMIT < t < group.quiet and (only is None or group.pgns[0] in only):
                x = t * group.rate + _GRID_TOLERANCE
                if x >= group.need or not x > -_INF:  # NaN, -inf: math.floor raises, as ever
                    slot = math.floor(x)
                    group.need = slot + 1
                    group.next_t = next_t = (slot + 1 - _GRID_TOLERANCE) / group.rate
                    group.quiet = next_t * _QUIET if next_t > 0 else -_INF
                    if pgns:  # a second group is due: back to the order of rates_hz
                        pgns = sorted([*pgns, *group.pgns], key=self._order.__getitem__)
                    else:
                        pgns = list(group.pgns)
            if group.next_t < next_due:
                next_due = group.next_t
            if group.quiet < quiet_until:
                quiet_until = group.quiet
        self.next_due_t = next_due
        self._quiet_until = quiet_until
        return pgns

    def _one_by_one(self) -> None:
        """One group per PGN, in the order of rates_hz (for times that may raise)."""
        singles = [group.split((pgn,)) for group in self._groups for pgn in group.pgns]
        self._groups = sorted(singles, key=lambda group: self._order[group.pgns[0]])

    def _split(self, only: Collection[Pgn]) -> None:
        """Every group either wholly in ``only`` or wholly out of it (the parts keep the
        group's state, so this changes no answer)."""
        for group in list(self._groups):
            outside = tuple(p for p in group.pgns if p not in only)
            if outside and len(outside) < len(group.pgns):
                self._groups.append(group.split(outside))

    def frames(
        self,
        solution: Solution,
        loop: LoopStatus,
        only: Collection[Pgn] | None = None,
        now: Collection[Pgn] = (),
    ) -> Iterator[can.Message]:
        """Frames to send for ``solution`` (none before the address is claimed); ``only``
        limits them to those PGNs; ``now`` adds PGNs at this instant whether due or not (the
        status on a change of mode), their grid unchanged.

        Which PGNs are due and their SID are decided now; each frame is encoded as the caller
        takes it, in the order of :data:`DEFAULT_RATES_HZ` (attitude and rate of turn first),
        so a caller that sends as it iterates puts 127257 on the bus before the other PGNs of
        the instant are even encoded.
        """
        if not loop.address_claimed:
            return iter(())
        pgns = self.due(solution.t, only)
        if now:
            extra = [p for p in now if p in self.rates_hz and p not in pgns]
            pgns = sorted([*pgns, *extra], key=self._order.__getitem__)
        if not pgns:
            return iter(())
        if not SID_PGNS.isdisjoint(pgns):
            self._sid = (self._sid + 1) % SID_MODULO
        return self._encode(pgns, solution, loop, self._sid)

    def _encode(
        self, pgns: list[Pgn], solution: Solution, loop: LoopStatus, sid: int
    ) -> Iterator[can.Message]:
        framers = self._framers
        for pgn in pgns:
            yield from framers[pgn](solution, loop, sid)
