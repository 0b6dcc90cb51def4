"""The decoder on real receiver streams from gpsd's regression logs (tests/data/nmea, BSD-2).

The logs are raw receiver output without host stamps, some with binary protocols, so they
are fed to the decoder as bytes, in chunks of a serial port's size.
"""

from __future__ import annotations

import calendar
import logging
import math
import re
from collections import Counter
from functools import reduce
from operator import xor
from pathlib import Path

import pytest

from drivers.nmea import KNOT_MPS, NmeaCounters, NmeaDecoder, read_fixes_from_log
from drivers.samples import FixQuality, GnssFix

DATA = Path(__file__).parent / "data" / "nmea"
LOGS = sorted(DATA.glob("*.log"))
# a complete sentence: start character, printable ASCII without another start, then CR or LF
SENTENCE = re.compile(rb"[$!]([\x20\x22\x23\x25-\x7e]*)(?=[\r\n])")


def decode(name: str, chunk: int = 64) -> tuple[list[GnssFix], NmeaDecoder]:
    data = (DATA / name).read_bytes()
    decoder = NmeaDecoder(name)
    fixes = [f for i in range(0, len(data), chunk) for f in decoder.feed(data[i : i + chunk])]
    return fixes + decoder.flush(), decoder


def bad_checksums(data: bytes) -> int:
    """Independent count: complete sentences whose '*hh' is not the XOR of the body."""
    count = 0
    for m in SENTENCE.finditer(data):
        body, star, checksum = m[1].partition(b"*")
        count += bool(star) and checksum.upper() != b"%02X" % reduce(xor, body, 0)
    return count


def test_all_logs_are_here() -> None:
    assert len(LOGS) == 34 and (DATA / "COPYING.gpsd").exists()


@pytest.mark.parametrize("path", LOGS, ids=[p.name for p in LOGS])
def test_log_read_to_the_end_with_checksum_errors_counted(path: Path) -> None:
    fixes, decoder = decode(path.name)
    c = decoder.counters
    assert c.checksum_errors == bad_checksums(path.read_bytes())
    assert c.fixes == len(fixes) and c.overlong == 0
    assert all(f.quality is FixQuality.NONE or f.lat_deg is not None for f in fixes if f.t_utc)


@pytest.mark.parametrize(("name", "expected"), [("gpsdf.log", 46), ("com-1289.log", 1)])
def test_hand_counted_checksum_errors(name: str, expected: int) -> None:
    assert decode(name)[1].counters.checksum_errors == expected


def test_trimble_rtk_fixed_position() -> None:
    fixes, decoder = decode("nmea-rtk.log")
    assert Counter(f.quality for f in fixes) == {FixQuality.DGNSS: 104, FixQuality.RTK_FIXED: 18}
    # $GNGGA,133859.80,4134.50180205,N,09345.03586649,W,4,19,0.7,280.827,M,-31.442,M,5.8,0002*6D
    # $GNRMC,133859.80,A,4134.50180205,N,09345.03586649,W,0.008,0.000,180320,11.5982,E,D*36
    fix = next(f for f in fixes if f.quality is FixQuality.RTK_FIXED)
    assert fix == GnssFix(
        t=calendar.timegm((2020, 3, 18, 13, 38, 59)) + 0.8,
        t_utc=calendar.timegm((2020, 3, 18, 13, 38, 59)) + 0.8,
        quality=FixQuality.RTK_FIXED,
        lat_deg=41 + 34.50180205 / 60,
        lon_deg=-(93 + 45.03586649 / 60),
        alt_m=280.827 - 31.442,
        num_sats=19,
        hdop=0.7,
        age_s=5.8,
        sog_mps=0.008 * KNOT_MPS,
        cog_rad=0.0,
        mode="D",
        geoid_sep_m=-31.442,
        reference_station_id=2,
        talker="GN",
        position_step_m=1852.0 * 10.0**-8,  # 8 decimals of a minute: 0.02 mm
    )
    assert decoder.counters.by_type == {"GGA": 122, "RMC": 122}


@pytest.mark.parametrize(
    ("name", "expected"),
    [  # (talker, quality, geoid separation, reference station): fixes, counted by hand (grep)
        ("nmea-rtk.log", {("GN", 2, -31.442, 133): 32, ("GP", 2, -31.442, 133): 72,
                          ("GN", 4, -31.442, 2): 18}),
        ("ublox-f9p-hpnmea.log", {("GN", 2, -21.35, 278): 9}),
        ("skytraq-dgps.log", {("GP", 2, -20.3, 0): 96}),
        # GGA at 10 Hz, RMC at 1 Hz: each whole second's RMC joins its GGA's epoch (it came
        # after that epoch had gone, a fix of its own at the same time, before the sentence
        # set was learnt per place in the second); the first RMC's GGA is before the log
        ("rst39.log", {("GP", 2, None, 138): 40, (None, 2, None, None): 1}),
        # a GLONASS-only epoch among GN ones; no fix: no separation (the receiver's 14.6 stays)
        ("ch-4711.log", {("GN", 1, 14.6, None): 6, ("GL", 1, 14.6, None): 1,
                         ("GP", 0, None, None): 7}),
        # 0000 as station without corrections, no separation sent
        ("telit-he910.log", {("GP", 1, None, 0): 186, ("GP", 1, None, None): 1}),
    ],
)  # fmt: skip
def test_geoid_separation_reference_station_and_talker(
    name: str, expected: dict[tuple[str | None, int, float | None, int | None], int]
) -> None:
    fixes, _ = decode(name)
    got = Counter((f.talker, int(f.quality), f.geoid_sep_m, f.reference_station_id) for f in fixes)
    assert got == expected


def test_one_gga_per_system_names_no_talker() -> None:
    """Telit PLS83-W sends $GPGGA (5 satellites) and $GAGGA (1) for one GPS+GLONASS+Galileo+
    BeiDou solution ($GNGNS: 14, mode AAAAN): neither talker names the fix's systems."""
    fixes, _ = decode("telit-pls83-w.log")
    with_gga = [f for f in fixes if f.geoid_sep_m is not None]
    assert len(with_gga) == 10 and {f.talker for f in fixes} == {None}
    assert {(f.quality, f.geoid_sep_m) for f in with_gga} == {(FixQuality.GNSS, 50.0)}


def test_zed_f9p_epoch_with_gst_and_zda() -> None:
    fixes, decoder = decode("ublox-zed-f9p-nmea.log")
    # $GNRMC,003956.00,A,4552.65403,S,17030.00668,E,0.025,,120419,,,A,V*07
    # $GNGGA,003956.00,4552.65403,S,17030.00668,E,1,12,0.64,14.2,M,1.8,M,,*56
    # $GNGST,003956.00,235111,,,,2.3,3.5,4.0*46
    first = fixes[0]
    assert (first.lat_deg, first.lon_deg) == (-(45 + 52.65403 / 60), 170 + 30.00668 / 60)
    assert (first.alt_m, first.num_sats, first.hdop, first.cog_rad) == (14.2 + 1.8, 12, 0.64, None)
    assert (first.sigma_n_m, first.sigma_e_m, first.sigma_d_m) == (2.3, 3.5, 4.0)
    assert first.t_utc == calendar.timegm((2019, 4, 12, 0, 39, 56))
    assert (len(fixes), decoder.counters.unassigned) == (29, 0)
    assert decoder.counters.unsupported == 870  # GSA, GSV, GLL, GBS


def test_dual_antenna_heading() -> None:
    fixes, _ = decode("rst39.log")
    # $GPHDT,25.50,T*37 is the first HDT
    assert next(f.heading_rad for f in fixes if f.heading_rad is not None) == math.radians(25.5)


@pytest.mark.parametrize(
    "name",
    ["greis-binary.log", "oncore-binary.log", "skytraq-bin.log", "rtcm3.log", "rtcm3.2.log"]
    + ["ublox-zed-f9t-rtcm3.log", "bu303-nofix.log"],
)
def test_binary_logs_only_skip_junk(name: str) -> None:
    fixes, decoder = decode(name)
    c = decoder.counters
    assert (fixes, c.sentences_ok, c.parse_errors) == ([], 0, 0)
    assert c.skipped_bytes > 0.9 * (DATA / name).stat().st_size


def test_nmea_between_ubx_frames_is_found() -> None:
    fixes, decoder = decode("ublox-zed-f9t-ubx_nmea_l5.log")
    data = (DATA / "ublox-zed-f9t-ubx_nmea_l5.log").read_bytes()
    assert len(fixes) == data.count(b"$GNGGA") == 9
    assert decoder.counters.by_type["GGA"] == 9 and decoder.counters.skipped_bytes > 15000


@pytest.mark.parametrize(("name", "expected"), [("skytraq.log", 17), ("ublox-lea-5q.log", 10)])
def test_no_fix_logs_give_quality_none(name: str, expected: int) -> None:
    fixes, _ = decode(name)
    assert [f.quality for f in fixes] == [FixQuality.NONE] * expected
    assert all(f.lat_deg is None and f.alt_m is None and f.sog_mps is None for f in fixes)


def test_untimed_no_fix_sentences_with_host_time() -> None:
    """Telit HE910 before its first fix sends GGA/RMC without time: fixes need host time."""
    lines = (DATA / "telit-he910.log").read_bytes().splitlines(keepends=True)
    decoder = NmeaDecoder("telit-he910.log")
    fixes = [f for i, line in enumerate(lines) for f in decoder.feed(line, 1000.0 + i)]
    no_fix = sum(line.startswith(b"$GPGGA,,") for line in lines)
    assert Counter(f.quality for f in fixes) == {FixQuality.NONE: no_fix, FixQuality.GNSS: 187}
    assert no_fix == 37


@pytest.mark.parametrize("name", ["nmea-rtk.log", "ublox-zed-f9p-nmea.log", "gpsdf.log"])
def test_log_reader_path_gives_the_same_fixes(name: str) -> None:
    assert list(read_fixes_from_log(DATA / name)) == decode(name)[0]


@pytest.mark.parametrize("path", LOGS, ids=[p.name for p in LOGS])
def test_fast_path_gives_what_the_careful_path_gives(
    path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """Issue 14: bytes in serial-port chunks and log lines (records), decoded the fast way and
    the careful way (framing every line, pynmea2.parse every sentence): the same fixes,
    counters and warnings."""
    data = path.read_bytes()
    chunks = [data[i : i + 64] for i in range(0, len(data), 64)]
    lines = [x.decode("ascii", "replace").strip() for x in data.splitlines()]
    results: list[tuple[list[GnssFix], NmeaCounters, list[GnssFix], NmeaCounters, list[str]]] = []
    for fast in (True, False):
        caplog.clear()
        by_bytes, by_lines = NmeaDecoder(path.name), NmeaDecoder(path.name)
        by_bytes.fast_path = by_lines.fast_path = fast
        with caplog.at_level(logging.WARNING, logger="drivers.nmea"):
            fixes = [f for i, x in enumerate(chunks) for f in by_bytes.feed(x, i * 0.01)]
            fixes += by_bytes.flush()
            line_fixes = [
                f for i, x in enumerate(lines) for f in by_lines.feed_line(x, 100 + i * 0.01, i + 1)
            ]
            line_fixes += by_lines.flush()
        results.append((fixes, by_bytes.counters, line_fixes, by_lines.counters, caplog.messages))
    assert results[0] == results[1]
