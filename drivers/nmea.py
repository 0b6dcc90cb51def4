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
(GGA, RMC, VTG, GST, ZDA, HDT) that the last epoch closed by a time change held: for a 10 Hz
receiver that is the arrival of its last fix sentence, with no wait for the next epoch. Until
that set is learned, and whenever an epoch lacks a type, the epoch is emitted when the next
one starts, or by `NmeaDecoder.flush` at end of stream. A sentence arriving for an epoch
already emitted is counted as unassigned and its type is added to the set, so the next epoch
waits for it.
"""

from __future__ import annotations

import calendar
import logging
import math
import operator
import re
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from datetime import date
from functools import reduce
from os import PathLike

import pynmea2

from drivers.errors import ErrorPolicy
from drivers.log_limit import BadInput
from drivers.logs.nmea_log import NmeaLogReader, read_nmea_log
from drivers.samples import FixQuality, GnssFix
from drivers.units import SECONDS_PER_DAY

log = logging.getLogger(__name__)

KNOT_MPS = 1852.0 / 3600.0
TWO_PI = 2.0 * math.pi
#: Unknown sentence types counted one by one; any further one is counted under OTHER_TYPES.
MAX_COUNTED_TYPES = 64
OTHER_TYPES = "other"

_START = re.compile(rb"[$!]")
_STOP = re.compile(rb"[^\x20-\x7e]|[$!]")  # first byte that cannot continue a sentence
_CR_LF = (0x0D, 0x0A)
_NUMBER = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)")
_TOD = re.compile(r"(\d\d)(\d\d)(\d\d(?:\.\d*)?)")
_DDMMYY = re.compile(r"(\d\d)(\d\d)(\d\d)")
_DEG_MIN = re.compile(r"(\d{1,3})(\d\d(?:\.\d*)?)")

Value = float | str | None


# --- field converters: strings as sent -> SI values, ValueError on anything malformed --------


def _number(s: str) -> float | None:
    if not s:
        return None
    if not _NUMBER.fullmatch(s):
        raise ValueError(f"{s!r} is not a decimal number")
    return float(s)


def _count(s: str) -> float | None:
    if not s:
        return None
    if not s.isdigit():
        raise ValueError(f"{s!r} is not a non-negative integer")
    return float(int(s))


def _tod(s: str) -> float | None:
    """hhmmss[.ss] -> seconds of the UTC day."""
    if not s:
        return None
    m = _TOD.fullmatch(s)
    if not m or int(m[1]) > 23 or int(m[2]) > 59 or float(m[3]) >= 61.0:
        raise ValueError(f"time {s!r} is not hhmmss.ss")
    return int(m[1]) * 3600.0 + int(m[2]) * 60.0 + float(m[3])


def _posix_date(year: int, month: int, day: int) -> float:
    return float(calendar.timegm(date(year, month, day).timetuple()))


def _ddmmyy(s: str) -> float | None:
    """ddmmyy -> POSIX time of that UTC midnight (yy >= 80 is 19yy, as in old receivers)."""
    if not s:
        return None
    m = _DDMMYY.fullmatch(s)
    if not m:
        raise ValueError(f"date {s!r} is not ddmmyy")
    yy = int(m[3])
    return _posix_date(yy + (1900 if yy >= 80 else 2000), int(m[2]), int(m[1]))


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
        if not m or float(m[2]) >= 60.0 or hemisphere not in (negative, positive):
            raise ValueError(f"{value!r},{hemisphere!r} is not ddmm.mm,{positive}|{negative}")
        deg = int(m[1]) + float(m[2]) / 60.0
        if deg > limit_deg:
            raise ValueError(f"{value!r} is beyond {limit_deg:g} deg")
        return -deg if hemisphere == negative else deg

    return convert


def _quality(s: str) -> float | None:
    q = _count(s)
    if q is not None and q not in FixQuality._value2member_map_:
        raise ValueError(f"fix quality {s!r} is not 0-8")
    return q


def _letter(s: str) -> str | None:
    if not s:
        return None
    if len(s) != 1 or not s.isalpha():
        raise ValueError(f"{s!r} is not a one-letter indicator")
    return s


def _rad(s: str) -> float | None:
    deg = _number(s)
    return None if deg is None else math.radians(deg) % TWO_PI


# --- layouts: our field <- pynmea2 field names, converter ---------------------------------------

Converter = Callable[..., Value]
Layout = tuple[int, tuple[tuple[str, tuple[str, ...], Converter], ...]]  # min fields, fields

_LAYOUTS: dict[str, Layout] = {
    "GGA": (14, (
        ("tod_s", ("timestamp",), _tod),
        ("lat_deg", ("lat", "lat_dir"), _angle(90.0, "S", "N")),
        ("lon_deg", ("lon", "lon_dir"), _angle(180.0, "W", "E")),
        ("quality", ("gps_qual",), _quality),
        ("num_sats", ("num_sats",), _count),
        ("hdop", ("horizontal_dil",), _number),
        ("alt_msl_m", ("altitude",), _number),
        ("geoid_sep_m", ("geo_sep",), _number),
        ("age_s", ("age_gps_data",), _number),
    )),
    "RMC": (11, (
        ("tod_s", ("timestamp",), _tod),
        ("status", ("status",), _letter),
        ("lat_deg", ("lat", "lat_dir"), _angle(90.0, "S", "N")),
        ("lon_deg", ("lon", "lon_dir"), _angle(180.0, "W", "E")),
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


def _decode_fields(
    msg: pynmea2.NMEASentence, layout: Layout, *, complete: bool
) -> dict[str, Value]:
    """Apply one layout to a pynmea2 sentence: the generic field decoder.

    Missing trailing fields read as empty unless ``complete`` (no checksum guards the length).
    """
    min_fields, fields = layout
    data: list[str] = msg.data
    if complete and len(data) < min_fields:
        raise ValueError(f"{len(data)} fields, expected at least {min_fields}")
    index = type(msg).name_to_idx
    return {
        name: convert(*(data[index[n]].strip() if index[n] < len(data) else "" for n in names))
        for name, names, convert in fields
    }


def nmea_checksum(body: str) -> int:
    """XOR of the characters between the start character and ``*``."""
    return reduce(operator.xor, body.encode("ascii"), 0)


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


@dataclass
class _Epoch:
    tod_ms: int | None  # UTC time of day, ms; None until a timed sentence arrives
    t_host: float | None  # host receive time of the latest sentence
    parts: dict[str, dict[str, Value]] = field(default_factory=dict)


class NmeaDecoder:
    """Incremental NMEA 0183 decoder; see the module docstring for framing and epoch rules.

    ``source`` names the port or file in warnings. Feed it with `feed` (raw bytes, any split)
    or `feed_line` (one log line); each returns the fixes completed by that input.
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
        self._offset = 0  # bytes fed so far
        self._record: int | None = None  # log record being decoded (feed_line)
        self._candidate: bytearray | None = None  # sentence being framed
        self._candidate_where = ""
        self._epoch: _Epoch | None = None
        self._emitted_tod_ms: int | None = None
        self._expected: frozenset[str] | None = None  # fix sentence types of a full epoch
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
                self._candidate_where = self._where(self._offset + end)
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
                    self._candidate_where,
                    f"sentence longer than {self.max_sentence_len} bytes without a line end "
                    f"dropped: {shown}",
                    "CR/LF",
                )
            elif m is not None:
                if data[end] in _CR_LF:
                    text, self._candidate = self._candidate.decode("ascii"), None
                    pos = end + 1
                    self._sentence(text, t_host)  # (raises InputError under RAISE)
                else:
                    self._truncated(f"cut by byte 0x{data[end]:02X}")
        self._offset += n
        return self._take()

    def feed_line(
        self, line: str, t_host: float | None = None, record: int | None = None
    ) -> list[GnssFix]:
        """Decode one log line (a sentence, no prefix); ``record`` numbers it in warnings."""
        self._record = record
        try:
            return self.feed(line.encode("ascii", "replace") + b"\n", t_host)
        finally:
            self._record = None

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
            self._candidate_where,
            f"truncated sentence {shown} dropped, {why}",
            "'*hh' and CR/LF",
        )

    def _where(self, offset: int) -> str:
        if self._record is not None:
            return f"{self.source} record {self._record}"
        return f"{self.source} byte {offset}"

    @staticmethod
    def _show(text: str | bytearray, limit: int = 90) -> str:
        """A sentence for a warning: quoted, cut to ``limit`` characters."""
        if isinstance(text, bytearray):
            text = text.decode("ascii")  # framing keeps printable ASCII only
        return repr(text if len(text) <= limit else text[:limit] + "...")

    # --- sentences -----------------------------------------------------------------------------

    def _sentence(self, text: str, t_host: float | None) -> None:
        """Check, parse and file one framed sentence (start character to checksum)."""
        if self.on_sentence is not None:
            self.on_sentence(t_host, text)
        where = self._candidate_where
        body, star, checksum = text[1:].partition("*")
        if star:
            expected = nmea_checksum(body)
            if len(checksum) != 2 or checksum.upper() != f"{expected:02X}":
                self.counters.checksum_errors += 1
                self._bad.bad(
                    self._now,
                    "checksum",
                    where,
                    f"bad checksum in {self._show(text)}: got *{checksum}, sentence dropped",
                    f"*{expected:02X}",
                )
                return
        else:
            self.counters.no_checksum += 1
            if self.require_checksum:
                self._bad.bad(
                    self._now,
                    "no_checksum",
                    where,
                    f"sentence without checksum dropped: {self._show(text)}",
                    "'*hh' before the line end",
                )
                return
            self._bad.note(
                self._now,
                "no_checksum",
                f"{where}: sentence without checksum accepted: {self._show(text)} "
                "(expected '*hh' before the line end)",
            )
        address = body.split(",", 1)[0]
        kind = address[2:] if len(address) == 5 and address[0] != "P" else address
        by_type = self.counters.by_type
        if kind not in by_type and kind not in _LAYOUTS and len(by_type) >= MAX_COUNTED_TYPES:
            kind_key = OTHER_TYPES  # junk with random addresses: one key each was 91 MB per 1e6
        else:
            kind_key = kind
        by_type[kind_key] = by_type.get(kind_key, 0) + 1
        layout = _LAYOUTS.get(kind)
        if layout is None:
            self.counters.unsupported += 1
            return
        try:
            values = _decode_fields(pynmea2.parse(text[0] + body), layout, complete=not star)
        except (ValueError, OverflowError) as exc:  # ParseError is a ValueError; huge dates
            self.counters.parse_errors += 1
            self._bad.bad(
                self._now,
                "parse",
                where,
                f"cannot decode {self._show(text)}: {exc}, sentence dropped",
                "fields as NMEA 0183 defines them",
            )
            return
        self.counters.sentences_ok += 1
        self._file(kind, values, t_host)

    # --- epochs --------------------------------------------------------------------------------

    def _file(self, kind: str, values: dict[str, Value], t_host: float | None) -> None:
        """Put a decoded sentence into its epoch; emit epochs that are complete or closed."""
        tod = values.get("tod_s")
        epoch = self._epoch
        if isinstance(tod, float):
            if t_host is None:
                self._now = tod
            tod_ms = round(tod * 1000.0)
            if epoch is not None and epoch.tod_ms is None:
                epoch.tod_ms = tod_ms  # untimed sentences that came first join this epoch
            elif epoch is not None and epoch.tod_ms != tod_ms:
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
        epoch.parts[kind] = values
        if t_host is not None:
            epoch.t_host = t_host
        if self._expected is not None and self._expected <= epoch.parts.keys():
            self._close_epoch(learn=False)

    def _late(self, kind: str) -> None:
        self.counters.unassigned += 1
        if self._expected is not None:
            self._expected |= {kind}

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
            self._expected = frozenset(epoch.parts)
        self._emitted_tod_ms = epoch.tod_ms
        self.counters.fixes += 1
        self._fixes.append(fix)

    def _assemble(self, epoch: _Epoch) -> GnssFix | None:
        """Combine an epoch's sentences into one GnssFix (None without GGA/RMC or any time)."""
        parts = epoch.parts
        gga, rmc = parts.get("GGA"), parts.get("RMC")
        vtg, gst = parts.get("VTG", {}), parts.get("GST", {})
        if gga is None and rmc is None:
            return None
        tod = None if epoch.tod_ms is None else epoch.tod_ms / 1000.0
        t_utc = self._utc(tod, _num(rmc, "date_s") or _num(parts.get("ZDA"), "date_s"))
        t = epoch.t_host if epoch.t_host is not None else t_utc if t_utc is not None else tod
        if t is None:
            return None
        rmc_valid = rmc is not None and rmc.get("status") != "V"
        mode = _text(rmc, "mode") or _text(vtg, "mode")
        if gga is not None and gga.get("quality") is not None:
            quality = FixQuality(int(_num(gga, "quality") or 0))
        elif rmc_valid:
            quality = _MODE_QUALITY.get(mode or "A", FixQuality.GNSS)
        else:
            quality = FixQuality.NONE
        source = gga if _num(gga, "lat_deg") is not None else rmc
        lat, lon = _num(source, "lat_deg"), _num(source, "lon_deg")
        alt_msl, sep = _num(gga, "alt_msl_m"), _num(gga, "geoid_sep_m")
        velocity = rmc if rmc_valid and _num(rmc, "sog_kn") is not None else vtg
        sog_kn, sog_kmh = _num(velocity, "sog_kn"), _num(velocity, "sog_kmh")
        sog = sog_kn * KNOT_MPS if sog_kn is not None else _scaled(sog_kmh, 1.0 / 3.6)
        valid = quality is not FixQuality.NONE
        num_sats = _num(gga, "num_sats")
        return GnssFix(
            t=t,
            t_utc=t_utc,
            quality=quality,
            lat_deg=lat if valid and lon is not None else None,
            lon_deg=lon if valid and lat is not None else None,
            alt_m=alt_msl + sep if valid and alt_msl is not None and sep is not None else None,
            num_sats=None if num_sats is None else int(num_sats),
            hdop=_num(gga, "hdop"),
            age_s=_num(gga, "age_s"),
            sog_mps=sog if valid else None,
            cog_rad=_num(velocity, "cog_rad") if valid else None,
            heading_rad=_num(parts.get("HDT"), "heading_rad"),
            sigma_n_m=_num(gst, "sigma_n_m"),
            sigma_e_m=_num(gst, "sigma_e_m"),
            sigma_d_m=_num(gst, "sigma_d_m"),
            mode=mode,
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


def _num(values: dict[str, Value] | None, name: str) -> float | None:
    v = None if values is None else values.get(name)
    return v if isinstance(v, float) else None


def _scaled(value: float | None, factor: float) -> float | None:
    return None if value is None else value * factor


def _text(values: dict[str, Value] | None, name: str) -> str | None:
    v = None if values is None else values.get(name)
    return v if isinstance(v, str) else None


def read_fixes_from_log(
    source: str | PathLike[str] | NmeaLogReader, decoder: NmeaDecoder | None = None
) -> Iterator[GnssFix]:
    """Fixes of an NMEA log (SPEC 3 lines, host-stamped or not), with the live decoding code."""
    reader = source if isinstance(source, NmeaLogReader) else read_nmea_log(source)
    decoder = decoder or NmeaDecoder(reader.name)
    for record, (t_host, sentence) in enumerate(reader, start=1):
        yield from decoder.feed_line(sentence, t_host, record)
    yield from decoder.flush()
