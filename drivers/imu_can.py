"""IMU driver: ADIS16334 register frames from the SPI-to-CAN bridge (SPEC 1) to ImuSample/ImuAux.

Layers, each usable alone:

- :class:`ImuDecoder`, pure (no I/O): fed frames in arrival order (``can.Message`` objects, or
  a candump line's fields, which replay reads without making a message), it decodes
  IMU_GYRO / IMU_ACCEL / IMU_AUX through the DBC (the two per-sample frames with unpackers
  compiled from it, :meth:`dbc.fast_decode.LittleEndianDecoder.compile`: a few us a sample in
  all), pairs gyro and accel by SEQ, converts to SI in the body frame, rebuilds sample times
  from SEQ and DEC, and counts everything that went wrong (:class:`ImuCounters`), warning at
  a limited rate.
- :func:`read_bus`: asyncio source over any python-can bus (receive filters set to our ids).
- :func:`read_log`: the same decoder over a candump ``-L`` log (``drivers.logs.candump``).

Sample time: the IMU's own clock is the truth for the period (``dt = 2^DEC / 819.2`` s, exact),
and frame arrival only bounds it: a frame cannot arrive before its sample was taken, but it may
arrive late, and after a host stall (a busy ECU, or an interface such as udp_multicast that
stamps frames when the process reads them) the whole backlog arrives late in one burst. Sample
n is stamped ``offset + n dt - bridge_latency_s``. What is decided when, and why:

- Per sample, SEQ is trusted first: the step is the SEQ difference k in 1..255 whatever the
  arrival gap, so a stall whose frames all arrive counts nothing lost, and a gap of k - 1 is
  counted at once. Only a step of 128..255 is ambiguous with an earlier sample arriving late
  (out of order, or duplicated): it is taken as that if it fills a SEQ gap already counted, or if
  the sample ahead would have been taken more than a quarter wrap after its frame arrived
  (causality). An unchanged SEQ is a duplicate, unless half a wrap of silence passed and a whole
  wrap ahead is causal (then 255 samples were lost).
- The anchor ``offset`` follows the *earliest* arrivals (minimum latency). It drops at once to an
  earlier-than-predicted arrival (counted as a re-anchor if by more than half a period, or after
  an arrival gap over ``reanchor_gap_s``). It rises only from the least lateness of windows of
  ``wrap_check_s / 2`` of arrival time, by the window's share of ``anchor_tau_s`` (clock drift),
  and only when two consecutive windows are steady: their arrivals span as long as their
  samples (tolerance ``wrap_check_s / 32``: no burst, no backlog read faster than real time) and
  their least lateness agrees. Late frames, a stall's burst, never move the anchor nor the
  sample times.
- An outage longer than a SEQ wrap (256 samples) is under-counted by 256 m by its SEQ step, so
  from then on every arrival is late by about 256 m dt, steadily. A stall is the opposite: its
  burst catches up, or is read faster than real time. So when a SEQ gap comes with lateness
  over half a wrap, the windows restart there, and if two steady windows (``wrap_check_s`` of
  arrivals) agree on a lateness over half a wrap, 256 m samples (m from that lateness) are added
  to the index and to ``lost``, the anchor restarts on the earliest of those arrivals, and a
  warning is logged. The samples of those ``wrap_check_s`` (at most wrap_check_s / dt + 1 of
  them, more if the host stalls meanwhile) were already emitted 256 m dt early, each marked
  ``timing_unknown`` (from the late SEQ gap until it is decided, either way); the times jump
  forward there, still increasing.
- The host clock steps (:mod:`drivers.host_clock`): the arrivals jump by the step, the SEQ
  goes on. Once the anchor is settled (a steady window on time since it last restarted), two
  steady windows late by over ``clock_step_min_s`` with no SEQ gap, or one arrival of the
  next sample early by as much, are a step of the host clock: it is added to
  :attr:`ImuDecoder.host_clock` (from the first sample on the new clock), arrivals are taken
  less it from then on, and the anchor and the sample times go on through it. Lateness over
  an hour is the clock being set (:data:`CLOCK_SET_S`); lateness of a whole number of SEQ
  wraps (within 2 ms and 200 ppm of up to a minute) is taken for an outage of exactly 256 m
  samples (its SEQ cannot tell, and a step taken for an outage costs a restart, an outage
  taken for a step a position as old as it). Either way the anchor restarts there, no loss
  counted, and the sample times jump (the fusion core tells a step from the GNSS). Before the
  anchor has settled, steady lateness over half a wrap with no SEQ gap restarts it too. A
  backlog read steadily less than 1/16 faster than real time looks like a step forward and is
  taken for one.
- A change of DEC restarts the anchor from that sample's arrival.

Pairing: a half (IMU_GYRO or IMU_ACCEL) waits ``pair_timeout_s`` of arrival time for its
partner, but at least 2 more frames (a stall may fall between the two frames of a sample) and at
most 256 frames (a burst squeezes arrival times; a stale half must not meet the same SEQ one
wrap later). A sample's arrival is its earlier half's; halves stamped more than
``pair_timeout_s`` apart with the earlier the farther from the stream's next arrival have a
stamp no stall can make (a corrupted log line): the later is taken, and counted
(``bad_stamps``).
"""

from __future__ import annotations

import dataclasses
import logging
import math
import types
from collections.abc import AsyncIterator, Callable, Iterator
from dataclasses import dataclass, field
from enum import Enum, IntFlag
from functools import cache
from pathlib import Path
from typing import Any, TextIO

import can
import numpy as np
from can.typechecking import CanFilter

import dbc
from dbc.fast_decode import AllOf, AnyOf, LittleEndianDecoder, Lookup, Output, Raw
from drivers.axis_checks import ACCEL_JUMP_MPS2, GYRO_JUMP_RPS, STUCK_SAMPLES, AxisChecks
from drivers.errors import ErrorPolicy
from drivers.frame_reader import FrameReader
from drivers.host_clock import HostClock
from drivers.log_limit import BadInput
from drivers.logs.candump import CandumpReader, FrameFields, read_candump
from drivers.samples import Float3, ImuAux, ImuCounters, ImuSample
from drivers.units import DEG_TO_RAD, GRAVITY_MPS2

log = logging.getLogger(__name__)

#: Internal sample clock of the ADIS16334; output rate is this / 2^DEC.
ADIS_CLOCK_HZ = 819.2
#: 1 g as the accelerometer's mg LSB uses it (SPEC 1).
#: The bits of a 29-bit id that a frame is matched on: PGN and source address, not priority.
PGN_SA_MASK = 0x03FFFFFF
#: Arrivals later than this with no SEQ gap are the host clock being set (at boot, from a
#: clock months off), not a step to take out: the IMU's anchor restarts on the new clock, so
#: that the core's time, and the time the learned state is saved with, are the host's.
CLOCK_SET_S = 3600.0
#: No mounting rotation: IMU axes are the body axes.
IDENTITY = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))
_SI_PER_UNIT = {"deg/s": DEG_TO_RAD, "g": GRAVITY_MPS2, "degC": 1.0, "V": 1.0}


def sample_period_s(dec: int) -> float:
    """Output sample period for decimation exponent ``dec``: 2^DEC / 819.2 Hz."""
    return float(2**dec) / ADIS_CLOCK_HZ


class DiagStat(IntFlag):
    """DIAG_STAT register bits (SPEC 1)."""

    SUPPLY_LOW = 1 << 0
    SUPPLY_HIGH = 1 << 1
    SPI_ERROR = 1 << 3
    OVERRANGE = 1 << 4
    SELFTEST_FAIL = 1 << 5
    ST_XGYRO = 1 << 10
    ST_YGYRO = 1 << 11
    ST_ZGYRO = 1 << 12
    ST_XACCL = 1 << 13
    ST_YACCL = 1 << 14
    ST_ZACCL = 1 << 15


class ImuFrame(Enum):
    """The bridge's three frames, valued by their DBC message names."""

    GYRO = "IMU_GYRO"
    ACCEL = "IMU_ACCEL"
    AUX = "IMU_AUX"


@dataclass(frozen=True)
class ImuCanIds:
    """29-bit ids of the bridge's frames; matched on PGN and source address, not priority."""

    gyro: int
    accel: int
    aux: int

    @classmethod
    def for_source_address(cls, source_address: int = 0x80) -> ImuCanIds:
        """The DBC's ids (priority and PGN) with ``source_address`` as the last byte."""
        db = dbc.load(dbc.IMU_DBC)
        sa = source_address & 0xFF
        ids = {f: (db.get_message_by_name(f.value).frame_id & ~0xFF) | sa for f in ImuFrame}
        return cls(gyro=ids[ImuFrame.GYRO], accel=ids[ImuFrame.ACCEL], aux=ids[ImuFrame.AUX])

    def by_frame(self) -> dict[ImuFrame, int]:
        """Id of each frame."""
        return {ImuFrame.GYRO: self.gyro, ImuFrame.ACCEL: self.accel, ImuFrame.AUX: self.aux}

    def can_filters(self) -> list[CanFilter]:
        """python-can receive filters passing only these frames (any priority)."""
        return [
            {"can_id": i & PGN_SA_MASK, "can_mask": PGN_SA_MASK, "extended": True}
            for i in self.by_frame().values()
        ]


@dataclass(frozen=True)
class ImuCanConfig:
    """Driver settings. Times in seconds of the frames' (host) clock."""

    ids: ImuCanIds = field(default_factory=ImuCanIds.for_source_address)
    c_b_imu: tuple[tuple[float, ...], ...] = IDENTITY  # mounting: v_b = C v_imu
    bridge_latency_s: float = 0.0005  # nominal sample instant -> frame arrival
    anchor_tau_s: float = 10.0  # how slowly the time anchor may rise (clock drift)
    reanchor_gap_s: float = 0.5  # an earlier arrival after such a gap counts as a re-anchor
    wrap_check_s: float = 0.25  # arrivals late by over half a SEQ wrap this long: missed wraps
    pair_timeout_s: float = 0.05  # a half (gyro or accel) waits this long for its partner
    clock_step_min_s: float = 0.05  # arrivals late or early by more, steadily: a clock step
    warn_interval_s: float = 10.0  # at most one warning per kind per this much frame time
    stuck_samples: int = STUCK_SAMPLES  # an axis unchanged this many samples: stuck (0: off)
    on_error: ErrorPolicy = ErrorPolicy.LOG  # malformed frames: raise, log (and skip), ignore


class WarningKind(Enum):
    """Kinds of rate-limited warnings, one limit each."""

    LOST = "lost samples"
    DUPLICATE = "duplicate sample"
    OUT_OF_ORDER = "out-of-order sample"
    MALFORMED = "malformed frame"
    UNPAIRED = "unpaired frame"
    ALARM = "IMU alarm"
    SATURATED = "saturated axis"
    NO_NEW_DATA = "stale data"
    STUCK = "stuck output"
    SPIKE = "spike"
    REANCHOR = "time re-anchored"
    CLOCK_STEP = "host clock step"
    SEQ = "SEQ discontinuity"
    BAD_STAMP = "frame stamped before its partner"


_GYRO, _ACCEL = ImuFrame.GYRO, ImuFrame.ACCEL  # read per frame: no Enum attribute lookups
_TRIADS = {_GYRO: "GYRO", _ACCEL: "ACCL"}
#: Frames a half waits for its partner, at least and at most (module docstring, Pairing).
_PAIR_MIN_FRAMES = 2
_PAIR_MAX_FRAMES = 256
#: Key of a waiting half in ImuDecoder._pending: its SEQ, plus this for an accel half.
_ACCEL_KEY = 256


@dataclass(frozen=True)
class _Triad:
    """Signal names of the three axis words of IMU_GYRO or IMU_ACCEL, from the DBC."""

    out: tuple[str, ...]
    ea: tuple[str, ...]
    nd: tuple[str, ...]
    low: float  # at or below: saturated (within half an LSB of the register minimum)
    high: float
    si_per_unit: float

    @classmethod
    def from_dbc(cls, definition: Any) -> _Triad:
        name = next(v for f, v in _TRIADS.items() if f.value == definition.name)
        out = tuple(f"{a}{name}_OUT" for a in "XYZ")
        sig = definition.get_signal_by_name(out[0])
        return cls(
            out=out,
            ea=tuple(f"{a}{name}_EA" for a in "XYZ"),
            nd=tuple(f"{a}{name}_ND" for a in "XYZ"),
            low=sig.minimum + sig.scale / 2,
            high=sig.maximum - sig.scale / 2,
            si_per_unit=_SI_PER_UNIT[sig.unit],
        )


#: The fields of a decoded IMU_GYRO or IMU_ACCEL frame, by index (DEC only in IMU_GYRO): the
#: axis words in SI and IMU axes, each its DBC value times si_per_unit (the product a float64
#: array times that float gives); some EA bit set; every ND bit set; some axis at or beyond
#: the triad's low or high (saturated); SEQ; the RESERVED bits; DEC.
_X, _Y, _Z, _ALARM, _NEW_DATA, _SATURATED, _SEQ, _RESERVED, _DEC = range(9)

#: A decoded IMU_GYRO or IMU_ACCEL frame: (arrival time, counters.frames when it arrived (a burst
#: squeezes arrival times), its fields). Tuples all through: a frozen dataclass cost 1 us.
_Half = tuple[float, int, tuple[Any, ...]]
_Unpacker = Callable[[bytes | bytearray], tuple[Any, ...]]


@cache
def _half_unpacker(frame: ImuFrame) -> tuple[_Unpacker, int]:
    """The unpacker of IMU_GYRO or IMU_ACCEL into its fields (``_X`` ...), compiled from the DBC
    once per process, and the value of its RESERVED bits (all ones, SPEC 1)."""
    definition = dbc.load(dbc.IMU_DBC).get_message_by_name(frame.value)
    decoder = LittleEndianDecoder(definition)
    tri = _Triad.from_dbc(definition)
    tables = {name: decoder.physical_table(name) for name in tri.out}
    si: dict[tuple[float | int, ...], tuple[float, ...]] = {}  # axes of one layout share tables
    saturated: dict[tuple[float | int, ...], tuple[bool, ...]] = {}
    for values in tables.values():
        if values not in si:
            si[values] = tuple(v * tri.si_per_unit for v in values)
            saturated[values] = tuple(v <= tri.low or v >= tri.high for v in values)
            # What makes skipping the identity mounting exact (ImuDecoder.__init__).
            if not all(math.isfinite(v) and (v or math.copysign(1.0, v) > 0) for v in si[values]):
                raise ValueError(f"{frame.value}: an axis value non-finite or -0.0")
    outputs: dict[int, Output] = {
        _X: Lookup(tri.out[0], si[tables[tri.out[0]]]),
        _Y: Lookup(tri.out[1], si[tables[tri.out[1]]]),
        _Z: Lookup(tri.out[2], si[tables[tri.out[2]]]),
        _ALARM: AnyOf(tuple(Raw(name) for name in tri.ea)),
        _NEW_DATA: AllOf(tuple(Raw(name) for name in tri.nd)),
        _SATURATED: AnyOf(tuple(Lookup(name, saturated[tables[name]]) for name in tri.out)),
        _SEQ: Raw("SEQ"),
        _RESERVED: Raw("RESERVED"),
        **({_DEC: Raw("DEC")} if frame is _GYRO else {}),
    }
    assert list(outputs) == list(range(len(outputs)))
    reserved = definition.get_signal_by_name("RESERVED")
    return decoder.compile(list(outputs.values())), (1 << reserved.length) - 1


_SampleMaker = Callable[[float, float, Float3, Float3, int, bool, bool, bool, bool], ImuSample]


def _sample_maker() -> _SampleMaker:
    """``ImuSample(t, dt, w_ib_b, f_ib_b, seq, alarm, saturated, stuck, timing_unknown)`` at
    half the cost: a frozen dataclass's ``__init__`` sets each field through
    ``object.__setattr__`` (~0.9 us a sample, as much as decoding both frames); this sets the
    same slots directly, so the sample is the same. If ImuSample ever needs more than its
    slots set (other fields, a ``__post_init__``, no slots), the class itself is called."""
    names = ("t", "dt", "w_ib_b", "f_ib_b", "seq", "alarm", "saturated", "stuck", "timing_unknown")
    fields = dataclasses.fields(ImuSample)
    slots = [vars(ImuSample).get(n) for n in names]
    if (
        sorted(f.name for f in fields) != sorted(names)
        or not all(f.init for f in fields)
        or hasattr(ImuSample, "__post_init__")
        or not all(isinstance(slot, types.MemberDescriptorType) for slot in slots)
    ):

        def construct(*values: Any) -> ImuSample:
            return ImuSample(**dict(zip(names, values, strict=True)))

        return construct
    new, cls = object.__new__, ImuSample
    set_t, set_dt, set_w, set_f, set_seq, set_alarm, set_saturated, set_stuck, set_unknown = (
        slot.__set__ for slot in slots if isinstance(slot, types.MemberDescriptorType)
    )

    def make(
        t: float,
        dt: float,
        w: Float3,
        f: Float3,
        seq: int,
        alarm: bool,
        saturated: bool,
        stuck: bool,
        timing_unknown: bool,
    ) -> ImuSample:
        sample = new(cls)
        set_t(sample, t)
        set_dt(sample, dt)
        set_w(sample, w)
        set_f(sample, f)
        set_seq(sample, seq)
        set_alarm(sample, alarm)
        set_saturated(sample, saturated)
        set_stuck(sample, stuck)
        set_unknown(sample, timing_unknown)
        return sample

    return make


_new_sample = _sample_maker()


class ImuDecoder:
    """Pure decoder: ``feed(msg)`` returns the ImuSample/ImuAux that the frame completes."""

    def __init__(self, config: ImuCanConfig | None = None) -> None:
        self.config = config or ImuCanConfig()
        self.counters = ImuCounters()
        self.c_b_imu = np.array(self.config.c_b_imu, dtype=float)
        # v_b = C v_imu, through numpy as ever. With C the identity it is skipped: each entry
        # of the product is 1.0 v_i plus terms 0.0 v_j, which are +/-0.0, and in any order or
        # with fused multiply-adds, v_i plus +/-0.0 is v_i, bit for bit, since v_i is finite
        # and, when zero, +0.0 (the unpacker's tables are checked for that).
        self._mounted = not np.array_equal(self.c_b_imu, np.eye(3))
        self._latency = self.config.bridge_latency_s
        self._checks = AxisChecks(self.config.stuck_samples)
        db = dbc.load(dbc.IMU_DBC)
        aux = db.get_message_by_name(ImuFrame.AUX.value)
        self._aux_decoder = LittleEndianDecoder(aux)
        # masked id -> (frame, length, the configured id, unpacker (None: IMU_AUX), RESERVED
        # value, what its SEQ is offset by in self._pending)
        self._frames: dict[int, tuple[ImuFrame, int, int, _Unpacker | None, int, int]] = {}
        for f, i in self.config.ids.by_frame().items():
            unpack, reserved = _half_unpacker(f) if f in _TRIADS else (None, 0)
            length = db.get_message_by_name(f.value).length
            key = _ACCEL_KEY if f is _ACCEL else 0
            self._frames[i & PGN_SA_MASK] = (f, length, i, unpack, reserved, key)
        #: The bridge's frames by ``arbitration_id & key_mask``: any other is not the IMU's.
        self.frame_keys = frozenset(self._frames)
        self.key_mask = PGN_SA_MASK
        diag = [s for s in aux.signals if s.name.startswith("DIAG_")]
        base = min(s.start for s in diag)
        self._diag_bits = {s.name: s.start - base for s in diag}
        # Halves waiting for their partner by SEQ (+ _ACCEL_KEY for accel), and a lower bound
        # of the frame count from which one may be stale: the oldest's frame_no + 3 at most.
        self._pending: dict[int, _Half] = {}
        self._stale_from = 0
        self._bad = BadInput(log, self.config.on_error, self.config.warn_interval_s)
        self._dec: int | None = None
        self._dt = 0.0
        self._half_wrap = 0.0  # 128 dt
        self._seq_tolerance_s = 0.0  # how early a sample may arrive against its sample clock
        self._seq_taken = 0  # the SEQ the sample being decoded is counted as
        self._shift_pending: int | None = None  # SEQ offset of a discontinuity, if one just came
        self._n_last = 0  # absolute index of the last emitted sample
        self._n_first = 0
        self._seq_last = 0
        self._a_last = 0.0  # arrival of the last emitted sample
        self._offset = 0.0  # t_arrival_min(n) = offset + n dt
        self._missing: set[int] = set()
        self._skipped_frames = 0  # IMU frames received but not fed since the last sample
        # Lateness windows (module docstring), in q = arrival - n dt, which needs no offset.
        self._win_s = self.config.wrap_check_s / 2
        self._steady_tol = self.config.wrap_check_s / 32
        self._win_start = 0.0  # arrival that opened the current window
        self._win_n0 = 0  # index of the sample that opened it
        self._win_q = math.inf  # min q of the current window
        self._prev_q = math.inf  # min q of the previous window (inf: none, or not steady)
        self._gap_late = False  # a SEQ gap since the arrivals were last within half a wrap
        self._gap_n = 0  # last index before the first such gap
        self._settled = False  # a steady window on time since the anchor last restarted
        self._sample_frame = 0  # counters.frames when the last sample was emitted
        self._step_min = self.config.clock_step_min_s
        self._late_from: int | None = None  # first index of the arrivals late by a clock step
        #: The host clock's steps found; arrival times are taken less its correction.
        self.host_clock = HostClock()
        self._correction = 0.0  # host_clock.correction_s, read per frame
        self._stepped = 0.0  # a step just found: the arrival being decoded is taken less it

    def feed(self, msg: can.Message) -> list[ImuSample | ImuAux]:
        """Decode one frame; returns what it completes (nothing or one item)."""
        if msg.is_error_frame:
            self.counters.ignored += 1
            return []
        item = self.feed_frame(
            float(msg.timestamp),
            msg.arbitration_id,
            msg.data,
            msg.is_extended_id,
            msg.is_remote_frame,
        )
        return [] if item is None else [item]

    def skipped(self, frames: int) -> None:
        """``frames`` IMU frames were received but not fed (a reader behind its input shed
        them as stale). The next SEQ step is then taken as the one nearest to that many
        samples (two frames each), whole SEQ wraps included: a shed backlog of more than a
        wrap was otherwise an outage of unknown length, its samples under-counted and timed
        a wrap early until the arrivals showed it, and the samples on the edge of that
        decision read as out of order (the live service at 8x under two CPU hogs: 8 dropped)."""
        self._skipped_frames += frames

    def feed_record(self, record: FrameFields | can.Message) -> ImuSample | ImuAux | None:
        """Decode one frame, a message or a candump line's fields
        (:meth:`drivers.logs.candump.CandumpReader.records`); returns what it completes."""
        if isinstance(record, tuple):
            t, can_id, data, is_extended, _, _ = record
            return self.feed_frame(t, can_id, data, is_extended)
        items = self.feed(record)
        return items[0] if items else None

    def feed_frame(
        self,
        t: float,
        arbitration_id: int,
        data: bytes | bytearray,
        is_extended_id: bool = True,
        is_remote_frame: bool = False,
    ) -> ImuSample | ImuAux | None:
        """:meth:`feed_record` of a frame that is no error frame, given by its fields (arrival
        time ``t`` in seconds): replay makes no :class:`can.Message` and no list per frame."""
        entry = self._frames.get(arbitration_id & PGN_SA_MASK)
        if entry is None:
            self.counters.ignored += 1
            return None
        t -= self._correction
        frame, length, frame_id, unpack, expected_reserved, key = entry
        frames = self.counters.frames = self.counters.frames + 1
        pending = self._pending
        if pending and frames >= self._stale_from:
            self._evict_stale_halves(t)
        if not is_extended_id or is_remote_frame or len(data) != length:
            what = (
                f"{frame.value} frame id 0x{arbitration_id:X} "
                f"(extended {is_extended_id}, remote {is_remote_frame}, "
                f"{len(data)} bytes)"
            )
            self._malformed(t, what, f"an extended data frame of {length} bytes")
            return None
        if unpack is None:
            return self._aux(t, self._aux_decoder.decode(bytes(data)))
        fields = unpack(data)
        if fields[_RESERVED] != expected_reserved:
            self._malformed(
                t,
                f"{frame.value} id 0x{frame_id:X} reserved bits 0x{fields[_RESERVED]:X}",
                f"0x{expected_reserved:X} (reserved bits sent as 1)",
            )
            return None
        seq = fields[_SEQ]
        key += seq
        partner = pending.pop(key ^ _ACCEL_KEY, None)
        if partner is None:
            if key in pending:
                del pending[key]
                self._unpaired(t, frame, seq, "a second one of the same SEQ")
            if not pending:  # the oldest now; a later half leaves the bound valid
                self._stale_from = frames + _PAIR_MIN_FRAMES + 1
            pending[key] = (t, frames, fields)
            return None
        t_partner, _, partner_fields = partner
        if key & _ACCEL_KEY:
            return self._sample(seq, t_partner, partner_fields, t, fields)
        return self._sample(seq, t, fields, t_partner, partner_fields)

    def finish(self) -> None:
        """End of input: any half still waiting for its partner is unpaired."""
        self._evict_stale_halves(math.inf, final=True)

    @property
    def step_pending(self) -> bool:
        """The arrivals have been late by over ``clock_step_min_s`` for less time than a step
        forward of the host clock takes to be found (three windows): one may be found yet."""
        late_from = self._late_from
        return late_from is not None and (self._n_last - late_from) * self._dt < 3 * self._win_s

    @property
    def pending_step_s(self) -> float:
        """How late the last sample arrived while :attr:`step_pending` (else 0), s: the
        host clock may be that much ahead of the sample times not yet on its new reading."""
        if not self.step_pending:
            return 0.0
        return self._a_last - self._n_last * self._dt - self._offset

    @property
    def dt(self) -> float:
        """Current nominal sample period (0 before the first sample)."""
        return self._dt

    def _sample(
        self, seq: int, t_gyro: float, g: tuple[Any, ...], t_accel: float, f: tuple[Any, ...]
    ) -> ImuSample | None:
        """The sample of IMU_GYRO fields ``g`` and IMU_ACCEL fields ``f`` of SEQ ``seq``,
        arrived at ``t_gyro`` and ``t_accel``; None if it came late (a duplicate, or out of
        order)."""
        dec = g[_DEC]
        a = t_accel if t_accel < t_gyro else t_gyro  # min(t_gyro, t_accel), which is slower
        if abs(t_gyro - t_accel) > self.config.pair_timeout_s and self._dec is not None:
            a = self._earlier_stamp_checked(seq, a, t_gyro + t_accel - a)
        c = self.counters
        if dec != self._dec:
            start = self._dec is None
            self._dec, self._dt = dec, sample_period_s(dec)
            self._half_wrap = 128 * self._dt
            # the anchor follows the earliest arrivals, so a real sample is never much earlier
            # than its clock says: two periods and 2 ms of jitter
            self._seq_tolerance_s = 2.0 * self._dt + 0.002
            n = 0 if start else self._n_last + 1
            self._n_first = n
            self._seq_taken, self._shift_pending = seq, None  # the SEQ counted on from
            self._missing.clear()
            self._skipped_frames = 0
            self._anchor(a, n, a - n * self._dt, seq, None if start else f"DEC changed to {dec}")
        elif self._skipped_frames:
            n = self._track(seq, a, self._after_skip(seq, a))
        else:
            if (seq - self._seq_last) & 0xFF == 1:  # the next sample: nothing to unwrap
                self._seq_taken, self._shift_pending = seq, None
                n = self._track(seq, a, self._n_last + 1)
            else:
                step = self._unwrap(seq, a)
                if step is None:
                    return None
                n = self._track(seq, a, step)
        if self._stepped:
            a -= self._stepped
            self._stepped = 0.0
        self._n_last, self._seq_last, self._a_last = n, self._seq_taken, a
        if len(self._missing) > 512:
            self._missing = {i for i in self._missing if i > n - 256}
        alarm = g[_ALARM] or f[_ALARM]
        saturated = g[_SATURATED] or f[_SATURATED]
        c.samples += 1
        self._sample_frame = c.frames
        if alarm:
            c.alarms += 1
            self._warn(
                WarningKind.ALARM,
                a,
                f"EA bit set in SEQ {seq}: a DIAG_STAT flag is set "
                "(see IMU_AUX); expected EA clear",
            )
        if saturated:
            c.saturated += 1
            self._warn(
                WarningKind.SATURATED,
                a,
                f"IMU axis at the end of its register range "
                f"in SEQ {seq}; expected |value| below the 14-bit limit",
            )
        if not (g[_NEW_DATA] and f[_NEW_DATA]):
            c.no_new_data += 1
            self._warn(
                WarningKind.NO_NEW_DATA,
                a,
                f"ND bit clear in SEQ {seq}: register read "
                "before new data; expected ND set on every sample",
            )
        w_imu: Float3 = (g[_X], g[_Y], g[_Z])
        f_imu: Float3 = (f[_X], f[_Y], f[_Z])
        checks = self._checks
        stuck = checks.check(w_imu, f_imu)
        w_ib_b, f_ib_b = checks.w, checks.f
        if w_ib_b is not w_imu or f_ib_b is not f_imu:
            self._on_jump(seq, a, w_imu, f_imu)
        if stuck:
            self._on_stuck(seq, a)
        if self._mounted:
            w_ib_b, f_ib_b = self._mount(w_ib_b), self._mount(f_ib_b)
        dt = self._dt
        t = self._offset + n * dt - self._latency
        return _new_sample(t, dt, w_ib_b, f_ib_b, seq, alarm, saturated, stuck, self._gap_late)

    def _earlier_stamp_checked(self, seq: int, earlier: float, later: float) -> float:
        """The arrival of sample ``seq`` whose two frames are stamped more than
        ``pair_timeout_s`` apart, ``earlier`` and ``later``. A stall between them delays the
        second: the earlier is the arrival, unless it is the farther from the stream's next
        (the last arrival + dt). A stall cannot advance a frame, so that stamp is not its
        arrival (a corrupted log line: one digit of a candump time took the host clock for
        stepped back 48 years, and every GNSS epoch after it missed the IMU's time line):
        the later is taken, counted and warned."""
        expected = self._a_last + self._dt
        if abs(later - expected) >= abs(earlier - expected):
            return earlier
        self.counters.bad_stamps += 1
        self._warn(
            WarningKind.BAD_STAMP,
            later,
            f"IMU frame of SEQ {seq} stamped {later - earlier:.3f} s before its partner and "
            f"{expected - earlier:.3f} s before the stream's next: its partner's time taken; "
            f"expected the two frames of a sample within {self.config.pair_timeout_s} s",
        )
        return later

    def _on_stuck(self, seq: int, a: float) -> None:
        checks = self._checks
        self.counters.stuck += 1
        self._warn(
            WarningKind.STUCK,
            a,
            f"IMU {', '.join(checks.stuck_axes())} output unchanged for "
            f"{max(checks.runs) + 1} samples up to SEQ {seq}: the sensor or its bridge "
            "is not updating; expected its noise to change every axis from sample to sample",
        )

    def _on_jump(self, seq: int, a: float, w_imu: Float3, f_imu: Float3) -> None:
        """A triad of sample ``seq`` taken for a transfer error (drivers.axis_checks)."""
        checks = self._checks
        self.counters.spikes += 1
        if w_imu is not checks.w:
            jump = max(abs(x - y) for x, y in zip(w_imu, checks.w, strict=True))
            what = f"gyro jumped {jump / DEG_TO_RAD:.1f} deg/s"
            bound = f"{GYRO_JUMP_RPS / DEG_TO_RAD:.0f} deg/s"
        else:
            jump = max(abs(x - y) for x, y in zip(f_imu, checks.f, strict=True))
            what = f"accelerometer jumped {jump / GRAVITY_MPS2:.2f} g"
            bound = f"{ACCEL_JUMP_MPS2 / GRAVITY_MPS2:.1f} g"
        self._warn(
            WarningKind.SPIKE,
            a,
            f"IMU {what} in one sample at SEQ {seq}: taken for a transfer error, the previous "
            f"sample's values used for it (a lasting change is taken from the next sample); "
            f"expected a change of at most {bound} a sample",
        )

    def _mount(self, v_imu: Float3) -> Float3:
        """C v_imu: the IMU's axes turned into the body's, by numpy's product as ever."""
        x, y, z = (self.c_b_imu @ np.array(v_imu)).tolist()
        return (x, y, z)

    def _unwrap(self, seq: int, a: float) -> int | None:
        """The index of sample ``seq`` arriving at ``a`` (None if late); counts SEQ gaps lost.
        (:meth:`_sample` takes the common case, the SEQ after the last, itself.)"""
        n_last = self._n_last
        k = (seq - self._seq_last) & 0xFF
        self._seq_taken = seq
        if 2 <= k < 128 and a - (n_last + k) * self._dt - self._offset < -self._seq_tolerance_s:
            return self._seq_discontinuity(seq, a)
        self._shift_pending = None
        if k == 0 or k >= 128:
            # Behind by SEQ (a duplicate, or out of order) unless the step ahead is causal: not
            # sampled more than a quarter wrap after it arrived; for an unchanged SEQ only after
            # half a wrap of silence, and for a step of 128..255 only if it fills no SEQ gap
            # or arrived on time for the step ahead (then it is a loss: an overloaded reader
            # drops runs of 128-255 samples with their stamps intact, and with losses that
            # frequent, some earlier gap is always there to be "filled").
            ahead = n_last + (k or 256)
            back = ahead - 256
            late_ahead = a - ahead * self._dt - self._offset
            if (
                k != 0
                and late_ahead < -0.5 * self._half_wrap
                and back not in self._missing
                and a - (n_last + 1) * self._dt - self._offset >= -self._seq_tolerance_s
            ):
                return self._seq_discontinuity(seq, a, behind=True)
            if (
                late_ahead < -0.5 * self._half_wrap
                or (k == 0 and a - self._a_last <= self._half_wrap)
                or (k != 0 and back in self._missing and late_ahead > 0.5 * self._half_wrap)
            ):
                self._late(a, back, seq)
                return None
            k = k or 256
        return self._lost_before(seq, a, n_last + k)

    def _after_skip(self, seq: int, a: float) -> int:
        """The index of sample ``seq`` arriving at ``a`` after frames the reader shed
        (:meth:`skipped`): its SEQ step plus the whole wraps that bring it nearest to half
        the frames shed; the samples between counted lost."""
        k = (seq - self._seq_last) & 0xFF or 256
        wraps = max(0, round((self._skipped_frames / 2 + 1 - k) / 256))
        self._skipped_frames = 0
        self._seq_taken, self._shift_pending = seq, None
        return self._lost_before(seq, a, self._n_last + k + 256 * wraps)

    def _lost_before(self, seq: int, a: float, n: int) -> int:
        """Sample ``seq`` is index ``n``: the samples since the last counted lost; returns n."""
        n_last = self._n_last
        if n - n_last > 1:
            self.counters.lost += n - n_last - 1
            self._missing.update(range(max(n - 256, n_last + 1), n))
            self._warn(
                WarningKind.LOST,
                a,
                f"{n - n_last - 1} IMU samples lost before SEQ {seq} "
                f"(id 0x{self.config.ids.gyro:X}); expected SEQ {(self._seq_last + 1) % 256}",
            )
        return n

    def _seq_discontinuity(self, seq: int, a: float, behind: bool = False) -> int:
        """A SEQ that the sample cannot carry: a step ahead it cannot have made (it arrived
        before a sample that far ahead would have been taken) or, ``behind``, a SEQ already
        passed that fills no gap, and either way on time for the next sample. So it is the
        next one and its SEQ is wrong: a lone outlier (the SEQ after it is the expected one)
        or the bridge restarted its counter (the next SEQ follows this one: counted from then
        on; a SEQ behind is counted from at once, so a duplicate of an old sample costs one
        sample's data, not the samples after it). Taken as a step, an outlier of +37 cost 36
        phantom losses and 36 good samples dropped as out of order, and a restart 129 back
        129 samples dropped as duplicates."""
        expected = (self._seq_last + 1) & 0xFF
        shift = (seq - expected) & 0xFF
        if behind or shift == self._shift_pending:
            self.counters.seq_restarts += 1
            self._shift_pending = None
            self._warn(
                WarningKind.SEQ,
                a,
                f"IMU SEQ restarted: SEQ {seq} on time where {expected} was due; counting "
                "from it (expected a continuous SEQ)",
            )
        else:
            self.counters.seq_errors += 1
            self._shift_pending = shift
            self._seq_taken = expected
            self._warn(
                WarningKind.SEQ,
                a,
                f"IMU SEQ {seq} where {expected} was due, on time for it: taken as SEQ "
                f"{expected} (a corrupted counter, or the bridge restarted)",
            )
        return self._n_last + 1

    def _track(self, seq: int, a: float, n: int) -> int:
        """Update the anchor with sample ``n`` arriving at ``a``; returns n plus missed wraps."""
        q = a - n * self._dt  # the offset this arrival alone implies
        r = q - self._offset  # its lateness against the sample clock
        step_min = self._step_min
        if r > step_min:
            if self._late_from is None:
                self._late_from = n
        else:
            self._late_from = None
        if r < 0:
            gap = a - self._a_last
            if r < -0.5 * self._dt:
                if r < -step_min and self._settled and n - self._n_last == 1:
                    self._clock_step(seq, a, n, n, r)
                    return n
                self._anchor(a, n, q, seq, f"IMU frames {-r * 1e3:.2f} ms earlier than predicted")
                return n
            if gap > self.config.reanchor_gap_s:
                self._anchor(a, n, q, seq, f"{gap:.3f} s gap in IMU frames")
                return n
            self._offset = q
        if r <= self._half_wrap:
            self._gap_late = False
        elif n - self._n_last > 1 and not self._gap_late:
            # perhaps an outage over a SEQ wrap: judge the arrivals from here on
            self._gap_late, self._gap_n = True, self._n_last
            self._win_start, self._win_n0, self._win_q, self._prev_q = a, n, q, math.inf
            return n
        if a - self._win_start < self._win_s:
            if q < self._win_q:
                self._win_q = q
            return n
        return self._close_window(seq, a, n, q)

    def _close_window(self, seq: int, a: float, n: int, q: float) -> int:
        """Window of arrivals done (``a`` opens the next): rise the anchor, or add missed wraps."""
        offset, tol = self._offset, self._steady_tol
        now, before = self._win_q - offset, self._prev_q - offset
        span = a - self._win_start
        # Steady: its arrivals span as long as its samples (no burst, no backlog read faster
        # than real time) and its earliest lateness agrees with the previous steady window's.
        rate_error = self._a_last - self._win_start - (self._n_last - self._win_n0) * self._dt
        normal_rate = abs(rate_error) <= tol
        self._prev_q = self._win_q if normal_rate else math.inf
        self._win_q, self._win_start, self._win_n0 = q, a, n
        if normal_rate and abs(now) <= tol:
            self._settled = True
        if not (normal_rate and abs(now - before) <= tol):
            return n
        late = min(now, before)
        if (
            self._step_min < late < CLOCK_SET_S
            and self._settled
            and not self._gap_late
            and self._late_from is not None
            and not self._whole_wraps(late)
        ):
            self._clock_step(seq, a, n, self._late_from, late)
            return n
        if late <= self._half_wrap:
            if late > 0:
                self._offset = offset + late * min(1.0, span / self.config.anchor_tau_s)
            return n
        wait = f"{late:.3f} s later than predicted for {self.config.wrap_check_s} s"
        if not self._gap_late:
            self._anchor(a, n, offset + late, seq, f"IMU frames {wait} with no SEQ gap")
            return n
        shift = 256 * round(late / (2 * self._half_wrap))
        self.counters.lost += shift
        self._missing = {i + shift if i > self._gap_n else i for i in self._missing}
        why = (
            f"IMU frames {wait} after a SEQ gap: the gap spanned {shift // 256} more SEQ "
            f"wrap(s), {shift} more samples lost"
        )
        self._warn(WarningKind.LOST, a, f"{why} before SEQ {seq}")
        n += shift
        self._anchor(a, n, offset + late - shift * self._dt, seq, why)
        return n

    def _whole_wraps(self, late: float) -> bool:
        """``late`` is a whole number of SEQ wraps, within 2 ms (the arrivals' least jitter)
        and 200 ppm of up to a minute of it (the IMU's clock against the host's over an
        outage the bridge's SEQ counted through)."""
        wraps = round(late / (2 * self._half_wrap))
        tolerance = 0.002 + 2e-4 * min(late, 60.0)
        return wraps > 0 and abs(late - wraps * 2 * self._half_wrap) <= tolerance

    def _clock_step(self, seq: int, a: float, n: int, n_from: int, delta: float) -> None:
        """The host clock stepped by ``delta`` from sample ``n_from`` on (sample ``n`` arrived
        at ``a`` on the new clock): added to :attr:`host_clock`; the anchor goes on. Late
        arrivals had opened a window: it opens again at ``a`` on the new clock."""
        found = self.host_clock.step(self._offset + n_from * self._dt - self._latency, delta)
        self._correction = self.host_clock.correction_s
        self._stepped = delta
        a -= delta
        if delta > 0:
            self._win_start, self._win_n0, self._win_q = a, n, a - n * self._dt
            self._prev_q = math.inf
        self._late_from = None
        how = "late" if delta > 0 else "early"
        self.counters.clock_steps += 1
        self._warn(
            WarningKind.CLOCK_STEP,
            a,
            f"host clock stepped {delta:+.3f} s at t={found.host_s + delta:.3f} (IMU arrivals "
            f"to SEQ {seq} {abs(delta):.3f} s {how} with no SEQ gap): IMU, GNSS "
            "and ISOBUS times taken less it from then on, on one time line; expected a host "
            "clock that slews (NTP, chrony)",
        )

    def _anchor(self, a: float, n: int, offset: float, seq: int, reason: str | None) -> None:
        """Restart the sample clock at ``offset`` (sample ``n`` arrived at ``a``)."""
        self._offset = offset
        self._win_start, self._win_n0, self._win_q, self._prev_q = a, n, a - n * self._dt, math.inf
        self._gap_late = False
        self._settled = False
        self._late_from = None
        if reason is not None:
            self.counters.reanchors += 1
            self._warn(WarningKind.REANCHOR, a, f"IMU time re-anchored at SEQ {seq}: {reason}")

    def _late(self, a: float, n: int, seq: int) -> None:
        c = self.counters
        if n in self._missing or n < self._n_first:
            self._missing.discard(n)
            if n >= self._n_first:
                c.lost -= 1
            c.out_of_order += 1
            self._warn(
                WarningKind.OUT_OF_ORDER,
                a,
                f"IMU sample SEQ {seq} arrived after SEQ "
                f"{self._seq_last} and was dropped; expected increasing SEQ",
            )
        else:
            c.duplicates += 1
            self._warn(
                WarningKind.DUPLICATE,
                a,
                f"IMU sample SEQ {seq} received again "
                f"(last SEQ {self._seq_last}); expected each SEQ once",
            )

    def _aux(self, t: float, values: dict[str, Any]) -> ImuAux:
        """IMU_AUX arrived at ``t``. Sent among the samples (a frame before it completed
        one), it is put on their clock: a step of the host clock not yet found, or a stall,
        moves its arrival, not its time (the first frame after a step at 45 s, it had put the
        core 3 h ahead, FAULT, and back)."""
        self.counters.aux += 1
        if self._dec is not None and self.counters.frames - self._sample_frame <= _PAIR_MIN_FRAMES:
            last = self._offset + self._n_last * self._dt
            t = min(max(t, last), last + self._dt + self._step_min)
        diag = sum(int(values[n]) << bit for n, bit in self._diag_bits.items())
        if diag:
            self._warn(
                WarningKind.ALARM, t, f"IMU DIAG_STAT 0x{diag:04X} ({DiagStat(diag)!r}); expected 0"
            )
        return ImuAux(
            t=t - self.config.bridge_latency_s,
            temp_c=float(values["TEMP_OUT"]),
            supply_v=float(values["SUPPLY_OUT"]),
            diag_stat=diag,
            smpl_prd=int(values["SMPL_PRD"]),
        )

    def _evict_stale_halves(self, t: float, final: bool = False) -> None:
        if not self._pending:
            return
        limit = t - self.config.pair_timeout_s
        frames = self.counters.frames
        for key in [
            k
            for k, (t_arrival, frame_no, _) in self._pending.items()
            if final
            or (t_arrival < limit and frames - frame_no > _PAIR_MIN_FRAMES)
            or frames - frame_no > _PAIR_MAX_FRAMES
        ]:
            del self._pending[key]
            self._unpaired(
                t,
                _ACCEL if key & _ACCEL_KEY else _GYRO,
                key & 0xFF,
                f"no partner within {self.config.pair_timeout_s} s or {_PAIR_MAX_FRAMES} frames",
            )
        if self._pending:
            self._stale_from = min(h[1] for h in self._pending.values()) + _PAIR_MIN_FRAMES + 1

    def _unpaired(self, t: float, frame: ImuFrame, seq: int, why: str) -> None:
        self.counters.unpaired += 1
        other = ImuFrame.ACCEL if frame is ImuFrame.GYRO else ImuFrame.GYRO
        self._warn(
            WarningKind.UNPAIRED,
            t,
            f"{frame.value} SEQ {seq} dropped: {why}; expected "
            f"one {other.value} (id 0x{self.config.ids.by_frame()[other]:X}) per SEQ",
        )

    def _malformed(self, t: float, what: str, expected: str) -> None:
        self.counters.malformed += 1
        where = f"IMU CAN frame at t={t:.6f}"
        self._bad.bad(t, WarningKind.MALFORMED, where, f"malformed {what} dropped", expected)

    def _warn(self, kind: WarningKind, t: float, text: str) -> None:
        """Log at most one warning of ``kind`` per ``warn_interval_s`` of frame time."""
        self._bad.note(t, kind, text)


async def read_bus(
    bus: can.BusABC, decoder: ImuDecoder | None = None
) -> AsyncIterator[ImuSample | ImuAux]:
    """Yield ImuSample/ImuAux from a python-can bus until it fails (then raise BusError).

    Sets the bus's receive filters to the IMU ids, so unrelated traffic is dropped early (in the
    kernel for socketcan); reading and error handling are
    :class:`drivers.frame_reader.FrameReader`'s.
    """
    decoder = decoder or ImuDecoder()
    async with FrameReader(bus, decoder.config.ids.can_filters()) as frames:
        async for msg in frames:
            for item in decoder.feed(msg):
                yield item


def read_log(
    source: str | Path | TextIO | CandumpReader, decoder: ImuDecoder | None = None
) -> Iterator[ImuSample | ImuAux]:
    """Yield ImuSample/ImuAux from a candump ``-L`` log (malformed lines skipped and counted)."""
    decoder = decoder or ImuDecoder()
    reader = source if isinstance(source, CandumpReader) else read_candump(source)
    for record in reader.records():
        item = decoder.feed_record(record)
        if item is not None:
            yield item
    decoder.finish()
