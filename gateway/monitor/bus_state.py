"""What a bus says, frame by frame: the monitor's model, pure (no I/O, no clock of its own).

``BusState.feed(msg)`` takes every frame the bus or log gives, in order; the questions that
depend on time (rates, silence) take the caller's ``now`` on the frames' clock. Each source
address is a :class:`NavSource`: its last message of each kind, the arrival times of each PGN
(rates), and short histories for sparklines. Of those that send a PGN of SPEC 4, one is
:attr:`BusState.selected` (the first to send NAVGW_STATUS, i.e. a navgw; another with
:meth:`BusState.select_next`), so a bus with two gateways, or a GNSS receiver besides navgw,
is shown one source at a time. Claims go to a :class:`~gateway.monitor.claims.ClaimTable`;
frames of other nodes are counted by source; unknown and malformed frames are counted by the
decoder and never raise.
"""

from __future__ import annotations

import math
from collections import Counter, deque
from collections.abc import Mapping
from dataclasses import dataclass, field

import can

from drivers.units import RAD_TO_DEG
from gateway.isobus.j1939 import Pgn
from gateway.isobus.output_scheduler import DEFAULT_RATES_HZ
from gateway.monitor.claims import ClaimTable
from gateway.readback.frame_decoder import Decoded, OutputFrameDecoder, Value

STALL_S = 1.0  # no frame for this long (NAVGW_STATUS alone comes at 10 Hz): the bus stopped
RATE_WINDOW_S = 5.0  # rates are counted over this much of the recent past
RATE_TOLERANCE = 0.1  # a measured rate within 10 % of the configured one is on time
SPARK_POINTS = 120
#: History kept per sparkline: (DBC message, signal, scale to display units, seconds between
#: points). Attitude over the last 30 s, biases over the last 2 min.
SPARKS: dict[str, tuple[str, str, float, float]] = {
    "roll": ("ATTITUDE", "ROLL", RAD_TO_DEG, 0.25),
    "pitch": ("ATTITUDE", "PITCH", RAD_TO_DEG, 0.25),
    "gyro x": ("NAVGW_GYRO_BIAS", "GYRO_BIAS_X", 1.0, 1.0),
    "gyro y": ("NAVGW_GYRO_BIAS", "GYRO_BIAS_Y", 1.0, 1.0),
    "gyro z": ("NAVGW_GYRO_BIAS", "GYRO_BIAS_Z", 1.0, 1.0),
    "accel x": ("NAVGW_ACCEL_BIAS", "ACCEL_BIAS_X", 1.0, 1.0),
    "accel y": ("NAVGW_ACCEL_BIAS", "ACCEL_BIAS_Y", 1.0, 1.0),
}
NAV_PGNS = frozenset(int(p) for p in DEFAULT_RATES_HZ)
SPEC_RATES_HZ: Mapping[int, float] = {int(p): hz for p, hz in DEFAULT_RATES_HZ.items()}


@dataclass
class Series:
    """A decimated history: the first point of each ``interval_s`` slot of time, the last
    :data:`SPARK_POINTS` of them (slots, not spacing: a 1 Hz frame a hair early still counts)."""

    interval_s: float
    values: deque[float] = field(default_factory=lambda: deque(maxlen=SPARK_POINTS))
    slot: float = float("-inf")

    def add(self, t: float, value: float) -> None:
        """Keep ``value`` if it is the first of its slot (or time went back: a new run)."""
        slot = math.floor(t / self.interval_s)
        if slot != self.slot:
            self.values.append(value)
            self.slot = slot


@dataclass(frozen=True, slots=True)
class Rate:
    """One PGN of a source: its measured rate (None at its first message), SPEC 4's, and how
    many were received in all."""

    pgn: int
    name: str
    measured_hz: float | None
    configured_hz: float | None
    received: int

    @property
    def verdict(self) -> str:
        """``ok``, ``low``, ``high``, ``missing``, ``off`` (configured 0 Hz: ``high`` if it
        comes all the same) or ``""`` (no configured rate)."""
        if self.configured_hz is None:
            return ""
        if self.configured_hz == 0.0:
            return "high" if self.measured_hz else "off"
        if not self.measured_hz:
            return "missing"
        ratio = self.measured_hz / self.configured_hz
        if ratio < 1 - RATE_TOLERANCE:
            return "low"
        return "high" if ratio > 1 + RATE_TOLERANCE else "ok"


@dataclass
class NavSource:
    """One source address of SPEC 4 PGNs: what it said last, and when."""

    address: int
    #: PGN -> rate the unit is configured for (SPEC 4 defaults unless told), Hz
    configured_hz: Mapping[int, float] = field(default_factory=lambda: SPEC_RATES_HZ)
    latest: dict[str, Decoded] = field(default_factory=dict)  # DBC message name -> message
    arrivals: dict[int, deque[float]] = field(default_factory=dict)  # PGN -> recent times
    first_t: dict[int, float] = field(default_factory=dict)  # PGN -> first arrival
    received: Counter[int] = field(default_factory=Counter)  # PGN -> messages in all
    names: dict[int, str] = field(default_factory=dict)  # PGN -> DBC message name
    sparks: dict[str, Series] = field(
        default_factory=lambda: {k: Series(v[3]) for k, v in SPARKS.items()}
    )
    most_imu_lost: int = 0
    last_t: float = float("-inf")

    def value(self, message: str, signal: str) -> Value:
        """The last value of ``signal`` in ``message``; None if not seen or not available."""
        decoded = self.latest.get(message)
        return decoded.signals.get(signal) if decoded is not None else None

    def number(self, message: str, signal: str) -> float | None:
        """:meth:`value` when it is a number."""
        v = self.value(message, signal)
        return float(v) if isinstance(v, int | float) else None

    @property
    def is_navgw(self) -> bool:
        """It sends NAVGW_STATUS."""
        return "NAVGW_STATUS" in self.latest

    @property
    def navigates(self) -> bool:
        """It sends some PGN of SPEC 4 (a navgw, or another navigation device)."""
        return not NAV_PGNS.isdisjoint(self.received)

    def add(self, decoded: Decoded) -> None:
        """Take one of its messages."""
        pgn, t = decoded.frame_id.pgn, decoded.t
        self.latest[decoded.name] = decoded
        self.names.setdefault(pgn, decoded.name)
        self.first_t.setdefault(pgn, t)
        self.received[pgn] += 1
        times = self.arrivals.setdefault(pgn, deque())
        times.append(t)
        while times and times[0] <= t - RATE_WINDOW_S:
            times.popleft()
        self.last_t = max(self.last_t, t)
        for key, (message, signal, scale, _) in SPARKS.items():
            value = decoded.signals.get(signal) if decoded.name == message else None
            if isinstance(value, int | float):
                self.sparks[key].add(t, value * scale)
        lost = decoded.signals.get("IMU_SAMPLES_LOST") if decoded.name == "NAVGW_STATUS" else None
        if isinstance(lost, int):
            self.most_imu_lost = max(self.most_imu_lost, lost)

    def rates(self, now: float) -> list[Rate]:
        """Every PGN it sent and every SPEC 4 PGN, SPEC 4's first, at ``now``."""
        pgns = [int(p) for p in DEFAULT_RATES_HZ]
        pgns += sorted(set(self.arrivals) - set(pgns))
        return [self._rate(pgn, now) for pgn in pgns]

    def _rate(self, pgn: int, now: float) -> Rate:
        configured = self.configured_hz.get(pgn, 0.0) if pgn in NAV_PGNS else None
        name = self.names.get(pgn) or Pgn(pgn).name
        first = self.first_t.get(pgn)
        span = min(RATE_WINDOW_S, now - first) if first is not None else 0.0
        received = self.received[pgn]
        if span <= 0:
            return Rate(pgn, name, None, configured, received)
        count = sum(now - span < t <= now for t in self.arrivals[pgn])
        return Rate(pgn, name, count / span, configured, received)


@dataclass
class BusState:
    """Feed it every frame; read what the bus says. ``stall_s``: silence that counts as
    stopped."""

    stall_s: float = STALL_S
    #: PGN -> configured output rate, Hz (a unit's [output] section; SPEC 4's by default)
    configured_hz: Mapping[int, float] = field(default_factory=lambda: SPEC_RATES_HZ)
    decoder: OutputFrameDecoder = field(default_factory=OutputFrameDecoder)
    sources: dict[int, NavSource] = field(default_factory=dict)  # every sender, in order heard
    frames_by_source: Counter[int] = field(default_factory=Counter)
    selected: int | None = None
    first_t: float | None = None
    last_t: float | None = None
    claims: ClaimTable = field(init=False)

    def __post_init__(self) -> None:
        self.claims = ClaimTable(self.decoder.frames_db)

    def feed(self, msg: can.Message) -> None:
        """Take one frame (any frame: unknown and malformed ones are counted)."""
        t = float(msg.timestamp)
        self.first_t = t if self.first_t is None else self.first_t
        self.last_t = t if self.last_t is None else max(self.last_t, t)
        if msg.is_extended_id:
            self.frames_by_source[msg.arbitration_id & 0xFF] += 1
        decoded = self.decoder.decode(msg)
        if decoded is None:
            return
        if decoded.name == "ADDRESS_CLAIM":
            self.claims.on_claim(decoded)
        address = decoded.frame_id.source
        source = self.sources.get(address)
        if source is None:
            source = self.sources[address] = NavSource(address, self.configured_hz)
        source.add(decoded)
        if source.navigates and (
            self.selected is None or (source.is_navgw and not self._current_is_navgw())
        ):
            self.selected = address

    @property
    def nav_sources(self) -> dict[int, NavSource]:
        """The senders of SPEC 4 PGNs, in the order first heard: what can be shown."""
        return {a: s for a, s in self.sources.items() if s.navigates}

    def _current_is_navgw(self) -> bool:
        """The selected source sends NAVGW_STATUS."""
        return self.selected is not None and self.sources[self.selected].is_navgw

    @property
    def current(self) -> NavSource | None:
        """The source shown."""
        return self.sources.get(self.selected) if self.selected is not None else None

    def select_next(self) -> None:
        """Show the next source, in the order they were first heard."""
        order = list(self.nav_sources)
        if order:
            at = order.index(self.selected) if self.selected in order else -1
            self.selected = order[(at + 1) % len(order)]

    def banner(self, now: float) -> str:
        """A warning when frames stopped (the whole bus, or the source shown); else ``""``."""
        if self.last_t is None:
            return "no frames received yet"
        silent = now - self.last_t
        if silent > self.stall_s:
            return f"NO FRAMES for {silent:.1f} s"
        current = self.current
        if current is not None and now - current.last_t > self.stall_s:
            return (
                f"source 0x{current.address:02X} silent for {now - current.last_t:.1f} s "
                "(other nodes still sending)"
            )
        return ""
