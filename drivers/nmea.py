"""NMEA 0183 decoder: raw receiver bytes or log lines in, one `GnssFix` per receiver epoch out.

Pure (no I/O, no clock), so the live serial reader and log replay run the same code. It never
raises on input: whatever is wrong is dropped, counted in `NmeaCounters` and reported by a
rate-limited warning that says what, where and what was expected.

Framing. A sentence starts at ``$`` or ``!`` and ends at CR or LF. Bytes outside sentences
(binary protocols such as RTCM3/UBX/GREIS on the same port, comments, noise) are skipped and
counted. ``$`` and ``!`` are reserved characters in NMEA 0183, and a sentence holds printable
ASCII only, so either of them or any other byte inside a sentence means the sentence was cut
(counted as truncated, not as a checksum error); a sentence longer than ``max_sentence_len``
without a line end is dropped as over-long.

Checksums. A sentence with a ``*hh`` that does not match is dropped and counted. A sentence
without any checksum (old receivers, e.g. the HP 58534A) is counted in ``no_checksum`` and, by
default, accepted: it must still end with a line end and carry the type's full field count, so
a sentence cut by binary data or a buffer overflow is still rejected (a sentence with a valid
checksum may omit trailing fields, as some receivers do: they read as empty).
``require_checksum=True`` drops them instead.

Epochs. Sentences with the same UTC time of day belong to one epoch; VTG and HDT, which carry
no time, and sentences with an empty time field belong to the epoch being assembled (or to the
next one if none is open). An epoch is emitted as soon as it holds every fix sentence type
(GGA, RMC, VTG, GST, ZDA, HDT) that the last epoch at the same place in the second closed by
a time change held (at a place not seen yet, the last epoch closed so): for a 10 Hz receiver
that is the arrival of its last fix sentence, with no wait for the next epoch, and one
sending GGA at 10 Hz and RMC at 1 Hz has the whole second's epoch wait for its RMC (with one
set for all epochs, learnt from the GGA-only ones, every RMC after the first second came
after its epoch had gone: no velocity at all). Until that set is learned, and
whenever an epoch lacks a type, the epoch is emitted when the next one starts, or by
`NmeaDecoder.flush` at end of stream. A sentence arriving for an epoch already emitted is
counted as unassigned and its type is added to the set, so the next epoch at that place
waits for it.
"""

from __future__ import annotations

import calendar
import logging
import math
import operator
import re
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field, fields
from datetime import date
from functools import lru_cache, reduce
from os import PathLike
from typing import Any

import pynmea2

from drivers.errors import ErrorPolicy
from drivers.log_limit import BadInput
from drivers.logs.nmea_log import NmeaLogReader, read_nmea_log
from drivers.samples import FixQuality, GnssFix
from drivers.units import SECONDS_PER_DAY

log = logging.getLogger(__name__)

MINUTE_M = 1852.0  # one minute of arc of latitude (the nautical mile), m
KNOT_MPS = MINUTE_M / 3600.0
TWO_PI = 2.0 * math.pi
#: Unknown sentence types counted one by one; any further one is counted under OTHER_TYPES.
MAX_COUNTED_TYPES = 64
#: Places in the second whose epochs' sentence types are learnt (20 at 20 Hz); more (epoch
#: times that are no whole fraction of a second, wandering) start the learning again.
MAX_PHASES = 100
OTHER_TYPES = "other"

_START = re.compile(rb"[$!]")
_STOP = re.compile(rb"[^\x20-\x7e]|[$!]")  # first byte that cannot continue a sentence
_CR_LF = (0x0D, 0x0A)
_ONE_SENTENCE = re.compile(r"[$!][\x20\x22\x23\x25-\x7e]*")  # (str) what _START, _STOP frame
_HEX = tuple(f"{i:02X}" for i in range(256))  # checksum byte -> its '*hh' digits
# an address character as pynmea2's sentence regex takes it (\w: framing keeps sentences ASCII);
# a first one: not 'p', which makes it read a proprietary sentence ('P\w{3}', ignoring case)
_WORD = frozenset("ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789_")
_TALKER = _WORD - {"p", "P"}  # ('P...' is proprietary to us too: its kind is the address)
_NUMBER = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)")
_TOD = re.compile(r"(\d\d)(\d\d)(\d\d(?:\.\d*)?)")
_SECONDS = re.compile(r"\d\d(?:\.\d*)?")  # _TOD's third group
# ASCII digits of hours, minutes, degrees -> their value, where int() costs ten times more
_HOURS = {f"{h:02d}": h * 3600.0 for h in range(24)}
_MINUTES = {f"{m:02d}": m * 60.0 for m in range(60)}
_DEGREES = {f"{d:0{n}d}": d for n in (1, 2, 3) for d in range(10**n)}
_DDMMYY = re.compile(r"(\d\d)(\d\d)(\d\d)")
_DEG_MIN = re.compile(r"(\d{1,3})(\d\d(?:\.\d*)?)")

Value = float | str | None


# --- field converters: strings as sent -> SI values, ValueError on anything malformed --------
#
# They are pure, so each remembers its last results: a receiver repeats most fields (an epoch's
# time in four sentences, HDOP, satellites, separation, date, empty fields). A malformed field
# is not remembered: it raises again, with the same message.

_CACHED = 256  # results remembered per converter


@lru_cache(maxsize=_CACHED)
def _number(s: str) -> float | None:
    if not s:
        return None
    if not _NUMBER.fullmatch(s):
        raise ValueError(f"{s!r} is not a decimal number")
    return float(s)


@lru_cache(maxsize=_CACHED)
def _count(s: str) -> float | None:
    if not s:
        return None
    if not s.isdigit():
        raise ValueError(f"{s!r} is not a non-negative integer")
    return float(int(s))


@lru_cache(maxsize=_CACHED)
def _tod(s: str) -> float | None:
    """hhmmss[.ss] -> seconds of the UTC day."""
    if not s:
        return None
    hours, minutes = _HOURS.get(s[:2]), _MINUTES.get(s[2:4])
    if hours is not None and minutes is not None and _SECONDS.fullmatch(s, 4):
        sec = float(s[4:])
        if sec < 61.0:  # (the usual time: what the lines below give, the same float)
            return hours + minutes + sec
    m = _TOD.fullmatch(s)
    if m is None:
        raise ValueError(f"time {s!r} is not hhmmss.ss")
    hh, mm, ss = m.groups()
    h, mi, sec = int(hh), int(mm), float(ss)
    if h > 23 or mi > 59 or sec >= 61.0:
        raise ValueError(f"time {s!r} is not hhmmss.ss")
    return h * 3600.0 + mi * 60.0 + sec


def _posix_date(year: int, month: int, day: int) -> float:
    return float(calendar.timegm(date(year, month, day).timetuple()))


@lru_cache(maxsize=_CACHED)
def _ddmmyy(s: str) -> float | None:
    """ddmmyy -> POSIX time of that UTC midnight (yy >= 80 is 19yy, as in old receivers)."""
    if not s:
        return None
    m = _DDMMYY.fullmatch(s)
    if not m:
        raise ValueError(f"date {s!r} is not ddmmyy")
    yy = int(m[3])
    return _posix_date(yy + (1900 if yy >= 80 else 2000), int(m[2]), int(m[1]))


@lru_cache(maxsize=_CACHED)
def _zda_date(day: str, month: str, year: str) -> float | None:
    if not (day or month or year):
        return None
    if not (day.isdigit() and month.isdigit() and year.isdigit() and len(year) == 4):
        raise ValueError(f"ZDA date {day!r},{month!r},{year!r} is not dd,mm,yyyy")
    return _posix_date(int(year), int(month), int(day))


def _angle(limit_deg: float, negative: str, positive: str) -> Callable[[str, str], float | None]:
    """ddmm.mm / dddmm.mm plus hemisphere -> signed degrees."""

    def convert(value: str, hemisphere: str) -> float | None:
        if not value and not hemisphere:
            return None
        m = _DEG_MIN.fullmatch(value)
        if m is None or (minutes := float(m[2])) >= 60.0 or hemisphere not in (negative, positive):
            raise ValueError(f"{value!r},{hemisphere!r} is not ddmm.mm,{positive}|{negative}")
        whole = _DEGREES.get(m[1])  # (int() for digits other than ASCII)
        deg = (int(m[1]) if whole is None else whole) + minutes / 60.0
        if deg > limit_deg:
            raise ValueError(f"{value!r} is beyond {limit_deg:g} deg")
        return -deg if hemisphere == negative else deg

    return lru_cache(maxsize=_CACHED)(convert)


@lru_cache(maxsize=_CACHED)
def _quality(s: str) -> float | None:
    q = _count(s)
    if q is not None and q not in FixQuality._value2member_map_:
        raise ValueError(f"fix quality {s!r} is not 0-8")
    return q


@lru_cache(maxsize=_CACHED)
def _letter(s: str) -> str | None:
    if not s:
        return None
    if len(s) != 1 or not s.isalpha():
        raise ValueError(f"{s!r} is not a one-letter indicator")
    return s


@lru_cache(maxsize=_CACHED)
def _rad(s: str) -> float | None:
    deg = _number(s)
    return None if deg is None else math.radians(deg) % TWO_PI


_LAT = _angle(90.0, "S", "N")  # shared by GGA and RMC: RMC finds GGA's position remembered
_LON = _angle(180.0, "W", "E")


def _position_step(lat: str, lon: str) -> float | None:
    """The least step of a position printed as ddmm.mmm, dddmm.mmm, m: one unit of the last
    decimal of the coarser minutes, as a minute of latitude (east's is no larger). Receivers
    print 4-8 decimals: 18.5 cm to 0.02 mm."""
    if not lat or not lon:
        return None
    decimals = min(len(s) - s.index(".") - 1 if "." in s else 0 for s in (lat, lon))
    return MINUTE_M * 10.0**-decimals


# --- layouts: our field <- pynmea2 field names, converter ---------------------------------------

Converter = Callable[..., Value]
Layout = tuple[int, tuple[tuple[str, tuple[str, ...], Converter], ...]]  # min fields, fields

_LAYOUTS: dict[str, Layout] = {
    "GGA": (14, (
        ("tod_s", ("timestamp",), _tod),
        ("lat_deg", ("lat", "lat_dir"), _LAT),
        ("lon_deg", ("lon", "lon_dir"), _LON),
        ("position_step_m", ("lat", "lon"), _position_step),
        ("quality", ("gps_qual",), _quality),
        ("num_sats", ("num_sats",), _count),
        ("hdop", ("horizontal_dil",), _number),
        ("alt_msl_m", ("altitude",), _number),
        ("geoid_sep_m", ("geo_sep",), _number),
        ("age_s", ("age_gps_data",), _number),
        ("reference_station_id", ("ref_station_id",), _count),
    )),
    "RMC": (11, (
        ("tod_s", ("timestamp",), _tod),
        ("status", ("status",), _letter),
        ("lat_deg", ("lat", "lat_dir"), _LAT),
        ("lon_deg", ("lon", "lon_dir"), _LON),
        ("position_step_m", ("lat", "lon"), _position_step),
        ("sog_kn", ("spd_over_grnd",), _number),
        ("cog_rad", ("true_course",), _rad),
        ("date_s", ("datestamp",), _ddmmyy),
        ("mode", ("mode_indicator",), _letter),
    )),
    "VTG": (8, (
        ("cog_rad", ("true_track",), _rad),
        ("sog_kn", ("spd_over_grnd_kts",), _number),
        ("sog_kmh", ("spd_over_grnd_kmph",), _number),
        ("mode", ("faa_mode",), _letter),
    )),
    "GST": (8, (
        ("tod_s", ("timestamp",), _tod),
        ("sigma_n_m", ("std_dev_latitude",), _number),
        ("sigma_e_m", ("std_dev_longitude",), _number),
        ("sigma_d_m", ("std_dev_altitude",), _number),
    )),
    "ZDA": (4, (
        ("tod_s", ("timestamp",), _tod),
        ("date_s", ("day", "month", "year"), _zda_date),
    )),
    "HDT": (2, (
        ("heading_rad", ("heading",), _rad),
    )),
}  # fmt: skip

# RMC/VTG mode indicator -> fix quality, used when the epoch has no GGA
_MODE_QUALITY = {
    "A": FixQuality.GNSS,
    "D": FixQuality.DGNSS,
    "P": FixQuality.GNSS,
    "R": FixQuality.RTK_FIXED,
    "F": FixQuality.RTK_FLOAT,
    "E": FixQuality.DEAD_RECKONING,
    "M": FixQuality.MANUAL,
    "S": FixQuality.SIMULATION,
    "N": FixQuality.NONE,
}
_FIX_QUALITY = {float(q): q for q in FixQuality}  # GGA quality as decoded -> FixQuality
#: GnssFix's fields in order: `NmeaDecoder._assemble` passes them by position (by name costs
#: a third more); should GnssFix change them, the import stops here instead of mixing them up
_FIX_FIELDS = (
    "t", "t_utc", "quality", "lat_deg", "lon_deg", "alt_m", "num_sats", "hdop", "age_s",
    "sog_mps", "cog_rad", "heading_rad", "sigma_n_m", "sigma_e_m", "sigma_d_m", "mode",
    "geoid_sep_m", "reference_station_id", "talker", "position_step_m",
)  # fmt: skip
if tuple(f.name for f in fields(GnssFix))[: len(_FIX_FIELDS)] != _FIX_FIELDS:
    raise ImportError(f"GnssFix fields are not {_FIX_FIELDS}...: update NmeaDecoder._assemble")
_NO_FIX, _GNSS = FixQuality.NONE, FixQuality.GNSS  # (an enum member lookup costs 0.15 us)


#: the values of a sentence type an epoch lacks: every field None (read only)
_NONE = {kind: {name: None for name, _, _ in layout} for kind, (_, layout) in _LAYOUTS.items()}
_NONE["GGA"]["talker"] = None  # (not a field: `NmeaDecoder._sentence` adds GGA's)
_NO_GGA, _NO_RMC, _NO_VTG, _NO_GST, _NO_ZDA, _NO_HDT = (
    _NONE[kind] for kind in ("GGA", "RMC", "VTG", "GST", "ZDA", "HDT")
)


def _decode_fields(
    msg: pynmea2.NMEASentence, layout: Layout, *, complete: bool
) -> dict[str, Value]:
    """Apply one layout to a pynmea2 sentence: the generic field decoder (careful path).

    Missing trailing fields read as empty unless ``complete`` (no checksum guards the length).
    """
    min_fields, fields = layout
    data: list[str] = msg.data
    if complete and len(data) < min_fields:
        raise ValueError(f"{len(data)} fields, expected at least {min_fields}")
    index = type(msg).name_to_idx
    for _, names, _ in fields:
        for n in names:
            if n not in index:  # '$pXGGA,...': pynmea2 reads a proprietary sentence 'pXGG'
                raise ValueError(f"pynmea2 reads a {type(msg).__name__}, without {n!r}")
    return {
        name: convert(*(data[index[n]].strip() if index[n] < len(data) else "" for n in names))
        for name, names, convert in fields
    }


# --- fast path: a layout resolved once against its pynmea2 class ------------------------------


@dataclass(frozen=True)
class _Compiled:
    """A layout as the positions of its fields in the pynmea2 sentence class of its type (the
    ``name_to_idx`` that `_decode_fields` looks up field by field), applied by a function made
    for it."""

    kind: str
    min_fields: int
    width: int  # fields up to the last one used
    decode: Callable[[list[str]], dict[str, Value]]  # [address, >= width fields] -> values
    min_width: int  # with this many fields the checks of `_decode_data` pass as they are


def _compile(kind: str, layout: Layout) -> _Compiled:
    cls = pynmea2.TalkerSentence.sentence_types[kind]
    min_fields, fields = layout
    namespace: dict[str, Any] = {}
    items, width = [], 0
    for k, (name, names, convert) in enumerate(fields):
        positions = [cls.name_to_idx[n] for n in names]
        width = max(width, 1 + max(positions))
        namespace[f"c{k}"] = convert
        items.append(f"{name!r}: c{k}({', '.join(f'd[{i + 1}]' for i in positions)})")
    # a dict display, as _decode_fields' comprehension: fields converted in layout order, so
    # the first malformed one is reported; three times faster than a loop over the layout
    exec(f"def decode(d):\n    return {{{', '.join(items)}}}\n", namespace)  # (no input)
    return _Compiled(kind, min_fields, width, namespace["decode"], max(width, min_fields))


_COMPILED = {kind: _compile(kind, layout) for kind, layout in _LAYOUTS.items()}
#: a sentence's first 7 characters -> the layout of a fix sentence that ``pynmea2.parse``
#: reads as ``talker + kind + ','`` ('$GNGGA,'), or None for any other sentence
_FAST_PREFIXES: dict[str, _Compiled | None] = {}
_MAX_FAST_PREFIXES = 1024  # (junk could bring millions: the ones after these are not kept)


def _fast_layout(prefix: str) -> _Compiled | None:
    """The layout of a sentence starting with ``prefix`` (7 characters) if it is '$', an
    address that pynmea2's sentence regex reads as ``(\\w{2})(\\w{3}),`` with the class of
    a fix sentence type, and ','; else None. Remembered in `_FAST_PREFIXES`."""
    layout = _COMPILED.get(prefix[3:6])
    if not (
        layout is not None
        and prefix[0] == "$"
        and prefix[1] in _TALKER
        and prefix[2] in _WORD
        and prefix[6:] == ","
    ):
        layout = None
    if len(_FAST_PREFIXES) < _MAX_FAST_PREFIXES:
        _FAST_PREFIXES[prefix] = layout
    return layout


def _decode_data(
    data: list[str], layout: _Compiled, *, complete: bool, strip: bool
) -> dict[str, Value]:
    """`_decode_fields` on the fields (after the address) of a sentence of ``layout.kind``
    (``strip``: a field may hold a space)."""
    n = len(data)
    if complete and n < layout.min_fields:
        raise ValueError(f"{n} fields, expected at least {layout.min_fields}")
    if n < layout.width:
        data += [""] * (layout.width - n)  # missing trailing fields read as empty
    if strip:
        data = [x.strip() for x in data]
    return layout.decode(["", *data])  # (in the address's place)


def nmea_checksum(body: str) -> int:
    """XOR of the characters between the start character and ``*``."""
    raw = body.encode("ascii")
    n = len(raw)
    if n > 128:
        return reduce(operator.xor, raw, 0)
    # XOR is bitwise: read the bytes as one integer and fold it in halves down to one byte
    # (its low half XOR its high half; the bits above the half are left, unused); a third of
    # the time of a byte-by-byte reduce on an 80-character sentence
    x = int.from_bytes(raw, "little")
    if n > 64:
        x ^= x >> 512
    if n > 32:
        x ^= x >> 256
    x ^= x >> 128
    x ^= x >> 64
    x ^= x >> 32
    x ^= x >> 16
    x ^= x >> 8
    return x & 0xFF


# --- decoder ------------------------------------------------------------------------------------


@dataclass
class NmeaCounters:
    """What the decoder saw; read by the service's STATUS and by tests."""

    sentences_ok: int = 0  # fix sentences decoded and used
    by_type: dict[str, int] = field(default_factory=dict)  # checksum-valid sentences by type
    checksum_errors: int = 0  # '*hh' present but wrong or malformed: dropped
    no_checksum: int = 0  # sentences without '*hh' (accepted unless require_checksum)
    parse_errors: int = 0  # fix sentences with a malformed field or too few fields: dropped
    unsupported: int = 0  # valid sentences of other types (GSV, GSA, PUBX, ...): ignored
    truncated: int = 0  # sentences cut by a byte that cannot be in a sentence, or by EOF
    overlong: int = 0  # sentences longer than max_sentence_len without a line end
    skipped_bytes: int = 0  # bytes outside any sentence (CR/LF between sentences excluded)
    unassigned: int = 0  # sentences for an epoch already emitted, or in an epoch without
    # GGA/RMC or without any time
    fixes: int = 0  # GnssFix emitted


def _phase(tod_ms: int | None) -> int | None:
    """An epoch time's place in the second, ms (None for an untimed epoch): a receiver may
    send RMC and VTG at 1 Hz and GGA at 10, and its epochs are then of two kinds."""
    return None if tod_ms is None else tod_ms % 1000


class _Epoch:
    __slots__ = ("parts", "t_host", "tod_ms")

    def __init__(self, tod_ms: int | None, t_host: float | None) -> None:
        self.tod_ms = tod_ms  # UTC time of day, ms; None until a timed sentence arrives
        self.t_host = t_host  # host receive time of the latest sentence
        self.parts: dict[str, dict[str, Value]] = {}


class NmeaDecoder:
    """Incremental NMEA 0183 decoder; see the module docstring for framing and epoch rules.

    ``source`` names the port or file in warnings. Feed it with `feed` (raw bytes, any split)
    or `feed_line` (one log line); each returns the fixes completed by that input;
    `feed_lines` yields those of many log lines.

    Fast path (issue 14): a log line that is exactly one sentence (the usual case) is not
    framed byte by byte, and a fix sentence with an address pynmea2 reads as talker + type
    ('$GNGGA,') is not given to ``pynmea2.parse`` (its regex, second checksum and class
    lookup): its fields are split once, as pynmea2 splits them, and read at the positions its
    pynmea2 class gives them. Any other input takes the careful path. Fixes, counters and
    warnings are the same either way; ``fast_path = False`` sends all input the careful way
    (the tests compare the two).
    """

    def __init__(
        self,
        source: str = "<stream>",
        *,
        require_checksum: bool = False,
        max_sentence_len: int = 256,
        warn_interval_s: float = 10.0,
        on_error: ErrorPolicy = ErrorPolicy.LOG,
        on_sentence: Callable[[float | None, str], None] | None = None,
    ) -> None:
        self.source = source
        self.on_sentence = on_sentence  # sees every framed sentence first (input recording)
        self.require_checksum = require_checksum
        self.max_sentence_len = max_sentence_len
        self.counters = NmeaCounters()
        self.fast_path = True  # False: all input the careful way (see the class docstring)
        self._offset = 0  # bytes fed so far
        self._record: int | None = None  # log record being decoded (feed_line)
        self._candidate: bytearray | None = None  # sentence being framed
        self._candidate_at: tuple[int | None, int] = (None, 0)  # its (record, offset)
        self._epoch: _Epoch | None = None
        self._emitted_tod_ms: int | None = None
        # fix sentence types of a full epoch, by its time's place in the second (_phase), and
        # the last learnt, for a place not seen yet
        self._expected: dict[int | None, frozenset[str]] = {}
        self._expected_last: frozenset[str] | None = None
        self._date_s: float | None = None  # POSIX time of the last known UTC midnight
        self._last_tod_s: float | None = None
        self._fixes: list[GnssFix] = []
        self._now = 0.0  # input time for warning rate limits
        self._bad = BadInput(log, on_error, warn_interval_s)

    # --- input ---------------------------------------------------------------------------------

    def feed(self, data: bytes, t_host: float | None = None) -> list[GnssFix]:
        """Decode a chunk of receiver bytes received at host time ``t_host`` (s, UTC)."""
        if t_host is not None:
            self._now = t_host
        pos, n = 0, len(data)
        while pos < n:
            if self._candidate is None:
                m = _START.search(data, pos)
                end = m.start() if m else n
                self._skip(data, pos, end)
                if m is None:
                    break
                self._candidate = bytearray(data[end : end + 1])
                self._candidate_at = (self._record, self._offset + end)
                pos = end + 1
                continue
            m = _STOP.search(data, pos)
            end = m.start() if m else n
            self._candidate += data[pos:end]
            pos = end
            if len(self._candidate) > self.max_sentence_len:
                self.counters.overlong += 1
                shown = self._show(self._candidate)
                self._candidate = None
                self._bad.bad(
                    self._now,
                    "overlong",
                    self._where_at(*self._candidate_at),
                    f"sentence longer than {self.max_sentence_len} bytes without a line end "
                    f"dropped: {shown}",
                    "CR/LF",
                )
            elif m is not None:
                if data[end] in _CR_LF:
                    text, self._candidate = self._candidate.decode("ascii"), None
                    pos = end + 1
                    self._sentence(text, t_host, *self._candidate_at)  # (InputError if RAISE)
                else:
                    self._truncated(f"cut by byte 0x{data[end]:02X}")
        self._offset += n
        return self._take()

    def feed_line(
        self, line: str, t_host: float | None = None, record: int | None = None
    ) -> list[GnssFix]:
        """Decode one log line (a sentence, no prefix); ``record`` numbers it in warnings."""
        if (
            self._candidate is None
            and len(line) <= self.max_sentence_len
            and _ONE_SENTENCE.fullmatch(line)
            and self.fast_path
        ):  # exactly one sentence: what `feed` would frame from line + LF
            if t_host is not None:
                self._now = t_host
            self._sentence(line, t_host, record, self._offset)  # (InputError if RAISE)
            self._offset += len(line) + 1
            fixes = self._fixes
            if fixes:
                self._fixes = []
                return fixes
            return []
        self._record = record
        try:
            return self.feed(line.encode("ascii", "replace") + b"\n", t_host)
        finally:
            self._record = None

    def feed_lines(
        self, lines: Iterable[tuple[float | None, str]], first_record: int = 1
    ) -> Iterator[GnssFix]:
        """`feed_line` on each (host time, line), numbered from ``first_record``: the fixes as
        they complete. (Replay's loop: feed_line's fast path inline saves a call a line.)"""
        one_sentence = _ONE_SENTENCE.fullmatch
        for record, (t_host, line) in enumerate(lines, first_record):
            if (
                self._candidate is None
                and len(line) <= self.max_sentence_len
                and one_sentence(line)
                and self.fast_path
            ):  # as in feed_line
                if t_host is not None:
                    self._now = t_host
                self._sentence(line, t_host, record, self._offset)  # (InputError if RAISE)
                self._offset += len(line) + 1
                if self._fixes:
                    yield from self._take()
            else:
                yield from self.feed_line(line, t_host, record)

    def flush(self) -> list[GnssFix]:
        """End of stream (or port lost): drop a partial sentence, emit the pending epoch."""
        if self._candidate is not None:
            self._truncated("cut by the end of the stream")
        if self._epoch is not None:
            self._close_epoch(learn=False)
        return self._take()

    # --- framing -------------------------------------------------------------------------------

    def _skip(self, data: bytes, start: int, end: int) -> None:
        junk = end - start - data.count(b"\r", start, end) - data.count(b"\n", start, end)
        if junk:
            self.counters.skipped_bytes += junk
            self._bad.bad(
                self._now,
                "junk",
                self._where(self._offset + start),
                f"skipped {junk} non-NMEA bytes",
                "'$' or '!' to start a sentence",
            )

    def _truncated(self, why: str) -> None:
        assert self._candidate is not None
        self.counters.truncated += 1
        shown = self._show(self._candidate)
        self._candidate = None
        self._bad.bad(
            self._now,
            "truncated",
            self._where_at(*self._candidate_at),
            f"truncated sentence {shown} dropped, {why}",
            "'*hh' and CR/LF",
        )

    def _where(self, offset: int) -> str:
        return self._where_at(self._record, offset)

    def _where_at(self, record: int | None, offset: int) -> str:
        """Where a warning points: the log record, else the stream offset (built on demand)."""
        if record is not None:
            return f"{self.source} record {record}"
        return f"{self.source} byte {offset}"

    @staticmethod
    def _show(text: str | bytearray, limit: int = 90) -> str:
        """A sentence for a warning: quoted, cut to ``limit`` characters."""
        if isinstance(text, bytearray):
            text = text.decode("ascii")  # framing keeps printable ASCII only
        return repr(text if len(text) <= limit else text[:limit] + "...")

    # --- sentences -----------------------------------------------------------------------------

    def _sentence(self, text: str, t_host: float | None, record: int | None, offset: int) -> None:
        """Check, parse and file one framed sentence (start character to checksum; printable
        ASCII, as framing guarantees) that started at ``offset`` of ``record``."""
        if self.on_sentence is not None:
            self.on_sentence(t_host, text)
        head, star, checksum = text.partition("*")  # head: the start character and the body
        if star:
            expected = _HEX[nmea_checksum(head) ^ ord(head[0])]
            if checksum != expected and (len(checksum) != 2 or checksum.upper() != expected):
                self.counters.checksum_errors += 1
                self._bad.bad(
                    self._now,
                    "checksum",
                    self._where_at(record, offset),
                    f"bad checksum in {self._show(text)}: got *{checksum}, sentence dropped",
                    f"*{expected}",
                )
                return
        else:
            self.counters.no_checksum += 1
            if self.require_checksum:
                self._bad.bad(
                    self._now,
                    "no_checksum",
                    self._where_at(record, offset),
                    f"sentence without checksum dropped: {self._show(text)}",
                    "'*hh' before the line end",
                )
                return
            self._bad.note(
                self._now,
                "no_checksum",
                f"{self._where_at(record, offset)}: sentence without checksum accepted: "
                f"{self._show(text)} (expected '*hh' before the line end)",
            )
        try:
            layout = _FAST_PREFIXES[text[:7]]
        except KeyError:
            layout = _fast_layout(text[:7])
        if layout is not None and self.fast_path:  # '$ttKND,': what pynmea2.parse would split
            kind = layout.kind
            by_type = self.counters.by_type
            by_type[kind] = by_type.get(kind, 0) + 1  # (a fix type: never under OTHER_TYPES)
            data = head.split(",")  # ('$ttKND', the fields)
            try:
                if len(data) > layout.min_width and " " not in head:
                    values = layout.decode(data)  # (the usual sentence: what _decode_data does)
                else:
                    values = _decode_data(data[1:], layout, complete=not star, strip=" " in head)
            except (ValueError, OverflowError) as exc:
                self._parse_error(text, exc, record, offset)
                return
        else:  # careful
            body = head[1:]
            comma = body.find(",")
            address = body if comma < 0 else body[:comma]
            kind = address[2:] if len(address) == 5 and address[0] != "P" else address
            by_type = self.counters.by_type
            count = by_type.get(kind)
            if count is not None:
                by_type[kind] = count + 1
            elif kind not in _LAYOUTS and len(by_type) >= MAX_COUNTED_TYPES:
                # junk with random addresses: one key each was 91 MB per 1e6
                by_type[OTHER_TYPES] = by_type.get(OTHER_TYPES, 0) + 1
            else:
                by_type[kind] = 1
            if kind not in _LAYOUTS:
                self.counters.unsupported += 1
                return
            try:
                msg = pynmea2.parse(head)  # (start character and body, as before issue 14)
                values = _decode_fields(msg, _LAYOUTS[kind], complete=not star)
            except (ValueError, OverflowError) as exc:  # ParseError is a ValueError; huge dates
                self._parse_error(text, exc, record, offset)
                return
        self.counters.sentences_ok += 1
        if kind == "GGA":  # its talker names the satellite systems of the fix
            values["talker"] = text[1:3]  # (the address's first two characters, either path)
        self._file(kind, values, t_host)

    def _parse_error(self, text: str, exc: Exception, record: int | None, offset: int) -> None:
        self.counters.parse_errors += 1
        self._bad.bad(
            self._now,
            "parse",
            self._where_at(record, offset),
            f"cannot decode {self._show(text)}: {exc}, sentence dropped",
            "fields as NMEA 0183 defines them",
        )

    # --- epochs --------------------------------------------------------------------------------

    def _file(self, kind: str, values: dict[str, Value], t_host: float | None) -> None:
        """Put a decoded sentence into its epoch; emit epochs that are complete or closed."""
        tod = values.get("tod_s")
        epoch = self._epoch
        if isinstance(tod, float):
            if t_host is None:
                self._now = tod
            tod_ms = round(tod * 1000.0)
            if epoch is not None and epoch.tod_ms != tod_ms:
                if epoch.tod_ms is None:
                    epoch.tod_ms = tod_ms  # untimed sentences that came first join this epoch
                else:
                    self._close_epoch(learn=True)
                    epoch = None
            if epoch is None:
                if tod_ms == self._emitted_tod_ms:
                    self._late(kind)
                    return
                epoch = _Epoch(tod_ms, t_host)
        elif epoch is not None and kind in epoch.parts:
            self._close_epoch(learn=True)  # a repeated untimed type starts the next epoch
            epoch = None
        if epoch is None:
            epoch = _Epoch(None, t_host)
        self._epoch = epoch
        parts = epoch.parts
        if kind == "GGA" and "GGA" in parts and parts["GGA"]["talker"] != values["talker"]:
            values["talker"] = None  # one GGA per system (Telit): no one talker names the fix's
        parts[kind] = values
        if t_host is not None:
            epoch.t_host = t_host
        expected = self._expected.get(_phase(epoch.tod_ms), self._expected_last)
        if expected is not None and len(parts) >= len(expected) and expected <= parts.keys():
            self._close_epoch(learn=False)

    def _late(self, kind: str) -> None:
        self.counters.unassigned += 1
        phase = _phase(self._emitted_tod_ms)
        expected = self._expected.get(phase, self._expected_last)
        if expected is not None:
            self._expected[phase] = expected | {kind}

    def _close_epoch(self, *, learn: bool) -> None:
        """Emit the open epoch; ``learn``: it was closed by a new epoch, so it is complete."""
        epoch = self._epoch
        assert epoch is not None
        self._epoch = None
        fix = self._assemble(epoch)
        if fix is None:
            self.counters.unassigned += len(epoch.parts)
            return
        if learn:
            if len(self._expected) >= MAX_PHASES:  # epoch times that wander within the second
                self._expected.clear()
            self._expected_last = frozenset(epoch.parts)
            self._expected[_phase(epoch.tod_ms)] = self._expected_last
        self._emitted_tod_ms = epoch.tod_ms
        self.counters.fixes += 1
        self._fixes.append(fix)

    def _assemble(self, epoch: _Epoch) -> GnssFix | None:
        """Combine an epoch's sentences into one GnssFix (None without GGA/RMC or any time)."""
        # A sentence's values hold every field of its layout, as its converters return them:
        # float or None for the numbers, str or None for the letters (status, mode); a type
        # the epoch lacks reads as all None.
        parts: dict[str, dict[str, Any]] = epoch.parts
        gga, rmc = parts.get("GGA"), parts.get("RMC")
        if gga is None and rmc is None:
            return None
        g = _NO_GGA if gga is None else gga
        r = _NO_RMC if rmc is None else rmc
        vtg, gst = parts.get("VTG", _NO_VTG), parts.get("GST", _NO_GST)
        tod = None if epoch.tod_ms is None else epoch.tod_ms / 1000.0
        t_utc = self._utc(tod, r["date_s"] or parts.get("ZDA", _NO_ZDA)["date_s"])
        t = epoch.t_host if epoch.t_host is not None else t_utc if t_utc is not None else tod
        if t is None:
            return None
        rmc_valid = rmc is not None and r["status"] != "V"
        mode = r["mode"] or vtg["mode"]
        q = g["quality"]
        if q is not None:
            quality = _FIX_QUALITY[q]  # (a value of FixQuality: _quality checked it)
        elif rmc_valid:
            quality = _MODE_QUALITY.get(mode or "A", _GNSS)
        else:
            quality = _NO_FIX
        source = g if g["lat_deg"] is not None else r
        lat, lon = source["lat_deg"], source["lon_deg"]
        alt_msl, sep = g["alt_msl_m"], g["geoid_sep_m"]
        if rmc_valid and r["sog_kn"] is not None:
            velocity, sog_kmh = r, None  # (RMC has no km/h)
        else:
            velocity, sog_kmh = vtg, vtg["sog_kmh"]
        sog_kn = velocity["sog_kn"]
        if sog_kn is not None:
            sog = sog_kn * KNOT_MPS
        else:
            sog = None if sog_kmh is None else sog_kmh * (1.0 / 3.6)
        valid = quality is not _NO_FIX
        num_sats, station = g["num_sats"], g["reference_station_id"]
        return GnssFix(  # by position, in the order of _FIX_FIELDS
            t,
            t_utc,
            quality,
            lat if valid and lon is not None else None,  # lat_deg
            lon if valid and lat is not None else None,  # lon_deg
            # alt_m: without a geoid separation the MSL altitude, a height of unknown datum
            # but right in its changes (geoid_sep_m None says so; the output sends no altitude)
            alt_msl + (sep or 0.0) if valid and alt_msl is not None else None,
            None if num_sats is None else int(num_sats),
            g["hdop"],
            g["age_s"],
            sog if valid else None,  # sog_mps
            velocity["cog_rad"] if valid else None,
            parts.get("HDT", _NO_HDT)["heading_rad"],
            gst["sigma_n_m"],
            gst["sigma_e_m"],
            gst["sigma_d_m"],
            mode,
            sep if valid else None,  # geoid_sep_m (receivers send 0.0 without a fix)
            None if station is None else int(station),
            g["talker"],
            source["position_step_m"] if valid else None,
        )

    def _utc(self, tod: float | None, date_s: float | None) -> float | None:
        """Epoch UTC: date from RMC/ZDA, else the last known date, rolled when the time wraps."""
        if date_s is not None:
            self._date_s = date_s
        elif (
            self._date_s is not None
            and tod is not None
            and self._last_tod_s is not None
            and tod < self._last_tod_s - SECONDS_PER_DAY / 2
        ):
            self._date_s += SECONDS_PER_DAY
        if tod is None:
            return None
        self._last_tod_s = tod
        return None if self._date_s is None else self._date_s + tod

    def _take(self) -> list[GnssFix]:
        fixes, self._fixes = self._fixes, []
        return fixes

    # --- warnings ------------------------------------------------------------------------------


def read_fixes_from_log(
    source: str | PathLike[str] | NmeaLogReader, decoder: NmeaDecoder | None = None
) -> Iterator[GnssFix]:
    """Fixes of an NMEA log (SPEC 3 lines, host-stamped or not), with the live decoding code."""
    reader = source if isinstance(source, NmeaLogReader) else read_nmea_log(source)
    decoder = decoder or NmeaDecoder(reader.name)
    yield from decoder.feed_lines(reader)
    yield from decoder.flush()
