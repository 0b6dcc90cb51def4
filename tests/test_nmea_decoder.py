"""NMEA decoder: each sentence type, epoch grouping, dates, framing errors, never raising."""

from __future__ import annotations

import calendar
import logging
import math
import re
from collections.abc import Callable, Sequence
from dataclasses import asdict
from functools import partial, reduce
from operator import xor
from pathlib import Path
from typing import Any
from unittest.mock import patch

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from drivers import nmea
from drivers.errors import ErrorPolicy, InputError
from drivers.nmea import KNOT_MPS, NmeaDecoder, nmea_checksum, read_fixes_from_log
from drivers.samples import FixQuality, GnssFix

T0 = float(calendar.timegm((1994, 3, 23, 12, 35, 19)))


def s(body: str, talker: str = "GN") -> str:
    """A sentence with its checksum: s('GGA,...') -> '$GNGGA,...*hh'."""
    body = talker + body
    return f"${body}*{nmea_checksum(body):02X}"


def stream(*sentences: str, eol: str = "\r\n") -> bytes:
    return "".join(x + eol for x in sentences).encode()


def decode(
    data: bytes, t_host: float | None = None, *, require_checksum: bool = False
) -> tuple[list[GnssFix], NmeaDecoder]:
    decoder = NmeaDecoder("test", require_checksum=require_checksum)
    return decoder.feed(data, t_host) + decoder.flush(), decoder


def epoch(tod: str = "123519.00", ddmmyy: str = "230394", talker: str = "GN") -> list[str]:
    """The six fix sentences of one epoch, in u-blox order."""
    return [
        s(f"RMC,{tod},A,4807.0380,N,01131.0000,E,10.0,90.0,{ddmmyy},003.1,W,R", talker),
        s("VTG,90.0,T,93.1,M,10.0,N,18.5,K,R", talker),
        s(f"GGA,{tod},4807.0380,N,01131.0000,E,4,12,0.9,545.4,M,46.9,M,1.2,0031", talker),
        s(f"GST,{tod},0.5,0.02,0.01,30.0,0.015,0.012,0.030", talker),
        s(f"ZDA,{tod},{ddmmyy[:2]},{ddmmyy[2:4]},19{ddmmyy[4:]},00,00", talker),
        s("HDT,270.0,T", talker),
    ]


def test_full_epoch_every_field() -> None:
    fixes, decoder = decode(stream(*epoch()), t_host=1700000000.5)
    assert fixes == [
        GnssFix(
            t=1700000000.5,
            t_utc=T0,
            quality=FixQuality.RTK_FIXED,
            lat_deg=48 + 7.038 / 60,
            lon_deg=11 + 31.0 / 60,
            alt_m=545.4 + 46.9,
            num_sats=12,
            hdop=0.9,
            age_s=1.2,
            sog_mps=10.0 * KNOT_MPS,
            cog_rad=math.pi / 2,
            heading_rad=3 * math.pi / 2,
            sigma_n_m=0.015,
            sigma_e_m=0.012,
            sigma_d_m=0.030,
            mode="R",
            geoid_sep_m=46.9,
            reference_station_id=31,
            talker="GN",
            position_step_m=1852.0 * 10.0**-4,  # 4 decimals of a minute
        )
    ]
    c = decoder.counters
    assert (c.sentences_ok, c.fixes, c.unassigned) == (6, 1, 0)
    assert c.by_type == {"RMC": 1, "VTG": 1, "GGA": 1, "GST": 1, "ZDA": 1, "HDT": 1}


@pytest.mark.parametrize("talker", ["GP", "GN", "GL", "GA", "GB", "BD"])
def test_any_talker(talker: str) -> None:
    fixes, _ = decode(stream(*epoch(talker=talker)))
    assert [(f.quality, f.t, f.t_utc, f.talker) for f in fixes] == [
        (FixQuality.RTK_FIXED, T0, T0, talker)
    ]


@pytest.mark.parametrize(
    ("lat", "lon", "step_m"),
    [
        ("4807.0380", "01131.0000", 0.1852),  # 4 decimals of a minute: older receivers
        ("4807.03801", "01131.00002", 0.01852),  # 5: u-blox's default
        ("4807.0380123", "01131.0000", 0.1852),  # the coarser of the two
        ("4807.03801234", "01131.00000001", 1.852e-5),  # 8: RTK receivers
        ("4807", "01131", 1852.0),  # whole minutes
    ],
)
def test_the_position_step_and_its_rounding_in_the_sigma(lat: str, lon: str, step_m: float) -> None:
    """A position printed with 4 decimals of a minute is rounded to 18.5 cm: an RTK fix so is
    known to 5.3 cm (uniform over the step, step / sqrt(12)), whatever GST says; the EKF
    weighing such fixes by GST's 1.5 cm rejected most as glitches (tests/
    test_receiver_position_decimals.py)."""
    gga = s(f"GGA,123519.00,{lat},N,{lon},E,4,12,0.9,545.4,M,46.9,M,1.2,0031")
    gst = s("GST,123519.00,0.5,0.02,0.01,30.0,0.015,0.012,0.030")
    (fix,), _ = decode(stream(gga, gst))
    assert fix.position_step_m == pytest.approx(step_m)
    rounding = step_m / math.sqrt(12.0)
    assert fix.position_sigma_m == pytest.approx(
        (math.hypot(0.015, rounding), math.hypot(0.012, rounding), 0.030)
    )


@pytest.mark.parametrize(
    ("tail", "expected"),
    [
        ("-31.442,M,5.8,0002", (-31.442, 5.8, 2)),
        ("0.0,M,,1023", (0.0, None, 1023)),
        (",M,,", (None, None, None)),
        ("47.000,M,1.0,0000", (47.0, 1.0, 0)),
    ],
)
def test_geoid_separation_age_and_reference_station_of_gga(
    tail: str, expected: tuple[float | None, float | None, int | None]
) -> None:
    (fix,), _ = decode(stream(s(f"GGA,123519.00,4807.0380,N,01131.0000,E,2,08,0.9,545.4,M,{tail}")))
    assert (fix.geoid_sep_m, fix.age_s, fix.reference_station_id) == expected
    # without a separation the MSL altitude: a height of unknown datum (geoid_sep_m None), by
    # which the engines still navigate (receivers without a geoid model send none; before,
    # no position of theirs was used: tests/test_receiver_without_geoid.py)
    assert fix.alt_m == pytest.approx(545.4 + (expected[0] or 0.0))


def test_a_malformed_reference_station_is_a_parse_error() -> None:
    fixes, decoder = decode(
        stream(s("GGA,123519.00,4807.0380,N,01131.0000,E,2,08,0.9,5.0,M,1.0,M,,00A2"))
    )
    assert (fixes, decoder.counters.parse_errors) == ([], 1)


def test_epoch_emitted_with_its_last_sentence_once_the_set_is_learned() -> None:
    decoder = NmeaDecoder("test")
    first, second = epoch("123519.00"), epoch("123519.10")
    # first epoch: the set is not known yet, so it closes when the next epoch starts
    assert [decoder.feed(x.encode() + b"\r\n", 1.0) for x in first] == [[]] * 6
    assert [f.t_utc for f in decoder.feed(second[0].encode() + b"\r\n", 1.1)] == [T0]
    # second epoch: complete at its HDT, no wait for the third
    assert [decoder.feed(x.encode() + b"\r\n", 1.1) for x in second[1:5]] == [[]] * 4
    assert [f.t_utc for f in decoder.feed(second[5].encode() + b"\r\n", 1.15)] == [T0 + 0.1]
    assert decoder.flush() == []


def test_sentence_late_for_an_emitted_epoch_is_counted_and_awaited_next_time() -> None:
    gga = "GGA,{},4807.0380,N,01131.0000,E,1,08,0.9,545.4,M,46.9,M,,"
    rmc = "RMC,{},A,4807.0380,N,01131.0000,E,0.0,,230394,,,A"
    gst = "GST,{},0.5,0.02,0.01,30.0,0.015,0.012,0.030"
    order = [(gga, 19), (rmc, 19), (gga, 20), (rmc, 20), (gst, 20), (gga, 21), (rmc, 21), (gst, 21)]
    fixes, decoder = decode(stream(*(s(x.format(f"1235{sec}.00")) for x, sec in order)))
    assert [f.t_utc for f in fixes] == [T0, T0 + 1, T0 + 2]
    assert [f.sigma_n_m for f in fixes] == [None, None, 0.015]
    assert decoder.counters.unassigned == 1


def test_a_receiver_sending_gga_at_10_hz_and_the_rest_at_1_hz_keeps_every_velocity() -> None:
    """GGA every 0.1 s, RMC, VTG, GST and ZDA with the whole second's GGA only. With one
    sentence set learnt for every epoch, the GGA-only epochs taught {GGA}, the whole
    second's epoch went at its GGA and its RMC came late: no fix had a velocity, and both
    engines stayed ALIGNING. The set is now learnt per place in the second too: the whole
    second's epoch waits for its last sentence, the others go at their GGA."""
    decoder = NmeaDecoder("test")
    out: list[tuple[float, GnssFix]] = []
    for k in range(30):  # 3 s
        tod = f"1235{19 + k // 10}.{k % 10}0"
        t_host = 100.0 + 0.1 * k
        rmc, vtg, gga, gst, zda, _ = epoch(tod)
        lines = [gga, rmc, vtg, gst, zda] if k % 10 == 0 else [gga]
        for x in lines:
            out += [(t_host, f) for f in decoder.feed(x.encode() + b"\r\n", t_host)]
    out += [(math.nan, f) for f in decoder.flush()]
    assert [f.t_utc for _, f in out] == pytest.approx([T0 + 0.1 * k for k in range(30)])
    assert [f.sog_mps is not None for _, f in out] == [k % 10 == 0 for k in range(30)]
    assert decoder.counters.unassigned == 0
    # from the second second on, each epoch goes with its own last sentence
    assert all(t == f.t for t, f in out[10:29])


def test_midnight_rollover_without_date_in_gga() -> None:
    gga = "GGA,{},4807.0380,N,01131.0000,E,1,08,0.9,545.4,M,46.9,M,,"
    lines = [
        s(gga.format("235959.50")),
        s("RMC,235959.50,A,4807.0380,N,01131.0000,E,0.0,,311299,,,A"),
    ]
    lines += [s(gga.format(tod)) for tod in ("235959.75", "000000.00", "000000.25")]
    fixes, _ = decode(stream(*lines))
    midnight = float(calendar.timegm((2000, 1, 1, 0, 0, 0)))
    assert [f.t_utc for f in fixes] == [midnight - 0.5, midnight - 0.25, midnight, midnight + 0.25]
    assert [f.t for f in fixes] == [f.t_utc for f in fixes]  # no host time: t is the UTC


def test_gga_alone_has_no_utc_until_a_date_arrives() -> None:
    fixes, _ = decode(stream(s("GGA,000001.00,4807.0380,N,01131.0000,E,1,08,0.9,5.0,M,1.0,M,,")))
    assert [(f.t, f.t_utc, f.alt_m) for f in fixes] == [(1.0, None, 6.0)]  # t: time of day


def test_no_fix_yields_quality_none_with_empty_fields() -> None:
    lines = [s("GGA,,,,,,0,00,99.99,,,,,,", "GP"), s("RMC,,V,,,,,,,,,,N", "GP")]
    lines += [s("VTG,,T,,M,,N,,K,N", "GP")] + lines
    fixes, decoder = decode(stream(*lines), t_host=5.0)
    assert (
        fixes
        == [
            GnssFix(
                t=5.0,
                t_utc=None,
                quality=FixQuality.NONE,
                num_sats=0,
                hdop=99.99,
                mode="N",
                talker="GP",
            )
        ]
        * 2
    )
    assert decoder.counters.parse_errors == 0


def test_no_fix_hides_a_stale_position() -> None:
    lines = [s("GGA,212406.000,4807.0380,N,01131.0000,E,0,00,0.0,0.000,M,0.000,M,,0000", "GP")]
    lines += [s("RMC,212406.000,V,4807.0380,N,01131.0000,E,1.0,10.0,280316,,,N", "GP")]
    (fix,), _ = decode(stream(*lines))
    assert (fix.quality, fix.lat_deg, fix.lon_deg, fix.alt_m, fix.sog_mps) == (
        FixQuality.NONE,
        None,
        None,
        None,
        None,
    )
    # the separation is the fix's (as the height): 0.000 here is a placeholder; the station
    # id is kept as sent (what it means is for the encoder, which knows the quality)
    assert (fix.geoid_sep_m, fix.reference_station_id, fix.talker) == (None, 0, "GP")
    assert fix.t_utc == calendar.timegm((2016, 3, 28, 21, 24, 6))


def test_rmc_only_takes_quality_from_mode_and_vtg_fills_velocity() -> None:
    lines = [
        s("RMC,123519.00,A,4807.0380,S,01131.0000,W,,,230394,,,F"),
        s("VTG,180.0,T,,M,,N,36.0,K,F"),
    ]
    (fix,), _ = decode(stream(*lines))
    assert (fix.quality, fix.lat_deg, fix.lon_deg) == (
        FixQuality.RTK_FLOAT,
        -(48 + 7.038 / 60),
        -(11 + 31 / 60),
    )
    assert (fix.sog_mps, fix.cog_rad, fix.alt_m) == (10.0, math.pi, None)
    assert (fix.geoid_sep_m, fix.reference_station_id, fix.talker) == (None, None, None)  # GGA's


@pytest.mark.parametrize("eol", ["\r\n", "\n", "\r", "\n\r"])
def test_line_end_variants(eol: str) -> None:
    fixes, decoder = decode(stream(*epoch(), eol=eol))
    assert [f.t_utc for f in fixes] == [T0]
    assert decoder.counters.skipped_bytes == 0


def test_every_split_position_gives_the_same_fixes() -> None:
    data = stream(*epoch("123519.00"), *epoch("123519.10")[:3], eol="\r\n")
    data = b"\xb5\x62\x01\x07junk" + data + b"$GPGGA,12"
    reference, _ = decode(data)
    assert len(reference) == 2
    for cut in range(len(data) + 1):
        decoder = NmeaDecoder("test")
        assert decoder.feed(data[:cut]) + decoder.feed(data[cut:]) + decoder.flush() == reference
    decoder = NmeaDecoder("test")
    assert [
        f for i in range(len(data)) for f in decoder.feed(data[i : i + 1])
    ] + decoder.flush() == reference


def test_bad_checksum_dropped_counted_and_reported(caplog: pytest.LogCaptureFixture) -> None:
    good = s("HDT,270.0,T")
    bad = good[:-2] + "00"
    data = b"\r\n" + bad.encode() + b"\r\n"
    with caplog.at_level(logging.WARNING, logger="drivers.nmea"):
        _, decoder = decode(data)
    assert decoder.counters.checksum_errors == 1 and decoder.counters.sentences_ok == 0
    assert caplog.messages == [
        f"test byte 2: bad checksum in '{bad}': got *00, sentence dropped; expected *{good[-2:]}"
    ]


def test_sentence_without_checksum_accepted_unless_required(
    caplog: pytest.LogCaptureFixture,
) -> None:
    bare = "$GPGGA,222449,3349.0337,S,01843.9282,E,1,07,02.31,000115.4,M,0033.3,M,,"
    with caplog.at_level(logging.WARNING, logger="drivers.nmea"):
        (fix,), decoder = decode(bare.encode() + b"\n")
    assert (fix.quality, fix.num_sats, decoder.counters.no_checksum) == (FixQuality.GNSS, 7, 1)
    assert caplog.messages == [
        f"test byte 0: sentence without checksum accepted: '{bare}' "
        "(expected '*hh' before the line end)"
    ]
    fixes, decoder = decode(bare.encode() + b"\n", require_checksum=True)
    assert (fixes, decoder.counters.no_checksum, decoder.counters.sentences_ok) == ([], 1, 0)


def test_truncated_sentences(caplog: pytest.LogCaptureFixture) -> None:
    full = s("HDT,270.0,T")
    cut_by_binary = b"$GPGGA,1235" + b"\xd3\x00\x13>" + full.encode() + b"\n"
    cut_by_start = b"$GPGGA,030130" + full.encode() + b"\n"
    cut_short = b"$GPGGA,222449,3349.0337,S,01843.9282,E,1\n"  # no checksum: needs 14 fields
    with caplog.at_level(logging.WARNING, logger="drivers.nmea"):
        _, decoder = decode(cut_by_binary + cut_by_start + cut_short)
    c = decoder.counters
    assert (c.truncated, c.skipped_bytes, c.parse_errors, c.by_type) == (
        2,
        4,
        1,
        {"HDT": 2, "GGA": 1},
    )
    assert caplog.messages[0] == (
        "test byte 0: truncated sentence '$GPGGA,1235' dropped, cut by byte 0xD3; "
        "expected '*hh' and CR/LF"
    )
    assert caplog.messages[-1] == (
        f"test byte {len(cut_by_binary + cut_by_start)}: "
        f"cannot decode '{cut_short.decode().strip()}': "
        "6 fields, expected at least 14, sentence dropped; expected fields as NMEA 0183 "
        "defines them"
    )


def test_over_long_line_dropped_and_next_sentence_found() -> None:
    data = b"$GPTXT," + b"A" * 300 + b"\r\n" + stream(*epoch())
    fixes, decoder = decode(data)
    assert (len(fixes), decoder.counters.overlong, decoder.counters.skipped_bytes) == (1, 1, 0)


def test_parse_errors_and_unsupported(caplog: pytest.LogCaptureFixture) -> None:
    lines = [
        s("GGA,123519.00,9107.0380,N,01131.0000,E,1,08,0.9,545.4,M,46.9,M,,"),
        s("GSV,1,1,00", "GP"),
    ]
    lines += ["$PUBX,00*33", s("RMC,123519.00,A,4807.0380,N,01131.0000,E,x,,230394,,,A")]
    with caplog.at_level(logging.WARNING, logger="drivers.nmea"):
        fixes, decoder = decode(stream(*lines), t_host=100.0)
    c = decoder.counters
    assert (fixes, c.parse_errors, c.unsupported, c.by_type["PUBX"]) == ([], 2, 2, 1)
    assert caplog.messages == [
        f"test byte 0: cannot decode '{lines[0]}': '9107.0380' is beyond 90 deg, sentence "
        "dropped; expected fields as NMEA 0183 defines them"
    ]


def test_warnings_rate_limited_per_kind_over_input_time(caplog: pytest.LogCaptureFixture) -> None:
    bad = s("HDT,270.0,T")[:-2] + "00"
    decoder = NmeaDecoder("/dev/ttyUSB0")
    with caplog.at_level(logging.WARNING, logger="drivers.nmea"):
        for t in (0.0, 1.0, 9.9, 10.0):
            decoder.feed(bad.encode() + b"\n", t)
    assert decoder.counters.checksum_errors == 4
    assert [m.split(":")[0] for m in caplog.messages] == [
        "/dev/ttyUSB0 byte 0",
        "/dev/ttyUSB0 byte 54",
    ]
    assert caplog.messages[1].endswith("(2 more since the last report)")


def test_read_fixes_from_log_uses_host_stamps(tmp_path: Path) -> None:
    path = tmp_path / "gnss.nmea"
    first, second = epoch("123519.00"), epoch("123519.10")
    lines = [f"({1700000000.0 + i * 0.01:.6f}) {x}" for i, x in enumerate(first)] + second
    path.write_text("\n".join(lines) + "\n")
    fixes = list(read_fixes_from_log(path))
    assert [(f.t, f.t_utc) for f in fixes] == [(1700000000.05, T0), (T0 + 0.1, T0 + 0.1)]


@settings(max_examples=300, deadline=None)
@given(st.binary(max_size=600))
def test_arbitrary_bytes_never_raise(data: bytes) -> None:
    decoder = NmeaDecoder("fuzz")
    decoder.feed(data, 0.0)
    decoder.flush()


VALID = stream(*epoch("123519.00"), *epoch("123519.10"), *epoch("123519.20"))


@settings(max_examples=200, deadline=None)
@given(st.lists(st.binary(max_size=40), min_size=19, max_size=19))
def test_junk_between_sentences_does_not_hide_them(junk: list[bytes]) -> None:
    sentences = VALID.split(b"\r\n")[:-1]
    data = (
        b"".join(j + b"\r\n" + x + b"\r\n" for j, x in zip(junk, sentences, strict=False))
        + junk[-1]
    )
    fixes, _ = decode(data)
    assert [f.t_utc for f in fixes] == [T0, T0 + 0.1, T0 + 0.2]


@settings(max_examples=300, deadline=None)
@given(
    st.lists(
        st.tuples(st.integers(0, len(VALID)), st.integers(0, 3), st.binary(max_size=4)), max_size=8
    )
)
def test_mutated_stream_never_raises(edits: list[tuple[int, int, bytes]]) -> None:
    data = bytearray(VALID)
    for at, remove, insert in edits:
        data[at : at + remove] = insert
    fixes, decoder = decode(bytes(data))
    assert len(fixes) <= decoder.counters.sentences_ok


def test_a_date_too_large_for_any_calendar_is_a_parse_error_not_a_crash() -> None:
    """Seen: OverflowError ended navgw run's GNSS task and made replay exit with a traceback."""
    bad = "$GNZDA,221320.00,99999999999999999999,11,2023,00,00*7B"
    fixes, decoder = decode(stream(bad, *epoch()))
    assert decoder.counters.parse_errors == 1
    assert len(fixes) == 1 and fixes[0].quality is FixQuality.RTK_FIXED


def test_junk_sentence_types_do_not_grow_the_counters() -> None:
    junk = [s(f"X{i:04d},1", talker="") for i in range(5000)]
    fixes, decoder = decode(stream(*junk, *epoch()))
    by_type = decoder.counters.by_type
    assert len(by_type) <= 64 + 1 + 6 and sum(by_type.values()) == 5000 + 6
    assert by_type["GGA"] == by_type["RMC"] == 1 and len(fixes) == 1


@pytest.mark.parametrize("policy", list(ErrorPolicy))
def test_the_caller_chooses_what_bad_input_does(
    policy: ErrorPolicy, caplog: pytest.LogCaptureFixture
) -> None:
    """pynmeagps-style: raise at the first bad sentence, log it (default), or skip quietly;
    counted in every case, and the good sentences before it are kept."""
    good = stream(*epoch())
    bad = b"$GNHDT,270.0,T*00\r\n"
    decoder = NmeaDecoder("test", on_error=policy)
    with caplog.at_level(logging.WARNING, logger="drivers.nmea"):
        fixes = decoder.feed(good, 1.0)
        if policy is ErrorPolicy.RAISE:
            with pytest.raises(InputError, match="bad checksum") as err:
                decoder.feed(bad, 1.1)
            assert err.value.expected == "*2E" and err.value.where == f"test byte {len(good)}"
        else:
            decoder.feed(bad, 1.1)
    assert decoder.counters.checksum_errors == 1 and len(fixes + decoder.flush()) == 1
    assert len(caplog.messages) == (1 if policy is ErrorPolicy.LOG else 0)


# --- the fast path (issue 14): the same output as the careful path, for any input ---------------
#
# `feed_line` takes a line that is one sentence without framing it as bytes, and a fix sentence
# with an ordinary address without pynmea2.parse (its fields, split once, go by the positions
# of its pynmea2 class). `fast_path = False` sends every input the careful way, as before.

FIELDS = st.one_of(
    st.text(alphabet="0123456789.-+NSEWAVTMKRFD ", max_size=14),
    st.sampled_from(["", "nan", "inf", "1e3", "000000", "596000", "9000.0000", "\u0661\u0662"]),
    st.sampled_from(["99999999999999999999", "18100.0", "4807.0380", "01131.0000", "230394"]),
)
TIMES = ["123519.00", "123519.10", "123519.20", "", "235959.99", "000000.00"]
GOOD = [x for tod in TIMES for x in epoch(tod)] + [
    *epoch("123519.30", talker="GP"),
    *epoch("123519.40", talker="GA"),
    s("GGA,123519.50,4807.0380,N,01131.0000,E,2,08,0.9,545.4,M,-31.442,M,,1023", "GL"),
    s("GGA,123519.60,4807.0380,N,01131.0000,E,1,08,0.9,545.4,M,,M,,", "BD"),
    s("GGA,,,,,,0,00,99.99,,,,,,", "GP"),
    s("RMC,,V,,,,,,,,,,N", "GP"),
    s("GSV,1,1,00", "GP"),
    "$PUBX,00*33",
    s("TXT,01,01,02,u-blox", "GP"),
]


def _with_checksum(body: str) -> str:
    return f"${body}*{reduce(xor, body.encode('utf-8'), 0):02X}"  # (any text: edits add UTF-8)


@st.composite
def nmea_lines(draw: st.DrawFn) -> str:
    """A sentence as a receiver sends it, or damaged: fields, address, checksum, characters."""
    if draw(st.integers(0, 2)):
        body, _, _ = draw(st.sampled_from(GOOD))[1:].partition("*")
        fields = body.split(",")
        for _ in range(draw(st.sampled_from([0, 0, 0, 1, 2]))):
            fields[draw(st.integers(1, len(fields) - 1))] = draw(FIELDS)
        if draw(st.integers(0, 4)) == 0:
            fields = fields[: draw(st.integers(1, len(fields)))]  # cut short
        body = ",".join(fields)
    else:
        talker = draw(
            st.sampled_from(
                ["GN", "GP", "GL", "GA", "BD", "gp", "Gp", "pX", "PX", "P", "", "G_", "9z"]
            )
        )
        kind = draw(st.sampled_from(["GGA", "RMC", "VTG", "GST", "ZDA", "HDT", "GSV", "gga"]))
        body = talker + kind + "," + ",".join(draw(st.lists(FIELDS, max_size=16)))
    text = _with_checksum(body)
    damage = draw(st.integers(0, 14))
    if damage == 0:
        text = text[: text.index("*")]  # no checksum
    elif damage == 1:
        text = text[:-2] + draw(st.sampled_from(["00", "zz", "5", "ABC", "", "*5C"]))
    elif damage == 2:
        text = "!" + text[1:]
    elif damage == 3:
        at = draw(st.integers(0, len(text)))
        edit = draw(st.text(alphabet="$!*,. \x00\t\r\n\x7f\xe9\u0661Az9", min_size=1, max_size=3))
        text = text[:at] + edit + text[at + draw(st.integers(0, 2)) :]
    return text


INPUTS = st.lists(
    st.tuples(
        st.one_of(st.none(), st.floats(0.0, 2e9)),
        nmea_lines(),
        st.one_of(st.none(), st.integers(1)),
    ),
    max_size=20,
)
OPTIONS = st.fixed_dictionaries(
    {
        "require_checksum": st.booleans(),
        "max_sentence_len": st.sampled_from([256, 82, 30]),
        "on_error": st.sampled_from(list(ErrorPolicy)),
    }
)


class _Warnings(logging.Handler):
    def __init__(self) -> None:
        super().__init__()
        self.messages: list[str] = []

    def emit(self, record: logging.LogRecord) -> None:
        self.messages.append(record.getMessage())


def trace(
    inputs: Sequence[tuple[float | None, bytes | str, int | None]], *, fast: bool, **options: Any
) -> tuple[list[Any], dict[str, Any], list[str], list[tuple[float | None, str]]]:
    """All a decoder gives: per input its fixes or InputError; counters, warnings, sentences."""
    seen: list[tuple[float | None, str]] = []
    decoder = NmeaDecoder("eq", on_sentence=lambda t, x: seen.append((t, x)), **options)
    decoder.fast_path = fast
    warnings = _Warnings()
    logger = logging.getLogger("drivers.nmea")
    logger.addHandler(warnings)
    level, logger.level = logger.level, logging.WARNING
    out: list[Any] = []
    calls: list[Callable[[], list[GnssFix]]] = [
        partial(decoder.feed_line, item, t_host, record)
        if isinstance(item, str)
        else partial(decoder.feed, item, t_host)
        for t_host, item, record in inputs
    ]
    try:
        for call in [*calls, decoder.flush]:
            try:
                out.append(call())
            except InputError as err:
                out.append((err.what, err.where, err.expected))
    finally:
        logger.removeHandler(warnings)
        logger.level = level
    return out, asdict(decoder.counters), warnings.messages, seen


@settings(max_examples=400, deadline=None)
@given(INPUTS, OPTIONS)
def test_fast_path_of_log_lines_equals_the_careful_path(
    inputs: list[tuple[float | None, str, int | None]], options: dict[str, Any]
) -> None:
    fast = trace(inputs, fast=True, **options)
    assert fast == trace(inputs, fast=False, **options)


@settings(max_examples=300, deadline=None)
@given(INPUTS, OPTIONS, st.sampled_from(["\r\n", "\n", "\r", ""]), st.integers(1, 64))
def test_fast_path_of_byte_streams_equals_the_careful_path(
    inputs: list[tuple[float | None, str, int | None]],
    options: dict[str, Any],
    eol: str,
    chunk: int,
) -> None:
    data = "".join(text + eol for _, text, _ in inputs).encode("utf-8", "replace")
    chunks = [(float(i), data[i : i + chunk], None) for i in range(0, len(data), chunk)]
    assert trace(chunks, fast=True, **options) == trace(chunks, fast=False, **options)


def test_fast_path_is_taken_and_gives_every_field() -> None:
    """The usual log: one sentence a line, all fix types; fixes as the careful path's."""
    lines = [(1.0 + i / 100, x, i + 1) for i, x in enumerate(epoch() + epoch("123519.10"))]
    fast, careful = trace(lines, fast=True), trace(lines, fast=False)
    assert fast == careful and fast[1]["sentences_ok"] == 12 and fast[1]["fixes"] == 2
    with patch("pynmea2.parse", side_effect=AssertionError("parsed twice")):
        assert trace(lines, fast=True) == fast


def test_warnings_of_the_fast_path_name_the_record_or_the_byte(
    caplog: pytest.LogCaptureFixture,
) -> None:
    good, bad = s("HDT,270.0,T"), s("HDT,270.0,T")[:-2] + "00"
    decoder = NmeaDecoder("test", warn_interval_s=0.0)
    with caplog.at_level(logging.WARNING, logger="drivers.nmea"):
        decoder.feed_line(bad, 1.0, 7)
        decoder.feed_line(good, 2.0)
        decoder.feed_line(bad, 3.0)
    assert [m.split(": ")[0] for m in caplog.messages] == ["test record 7", f"test byte {2 * 18}"]


def test_a_proprietary_lookalike_of_a_fix_sentence_is_a_parse_error_not_a_crash(
    caplog: pytest.LogCaptureFixture,
) -> None:
    """'$pXGGA': pynmea2's regex reads a proprietary sentence 'pXGG' (it ignores case), our
    address rule a GGA: a KeyError out of the decoder before issue 14."""
    line = s("GGA,123519.00,4807.0380,N,01131.0000,E,1,08,0.9,545.4,M,46.9,M,,", talker="pX")
    for fast in (True, False):
        decoder = NmeaDecoder("test")
        decoder.fast_path = fast
        with caplog.at_level(logging.WARNING, logger="drivers.nmea"):
            assert decoder.feed_line(line, 1.0, 1) + decoder.flush() == []
        assert (decoder.counters.parse_errors, decoder.counters.by_type) == (1, {"GGA": 1})
    assert caplog.messages[-1].endswith(
        "pynmea2 reads a ProprietarySentence, without 'timestamp', sentence dropped; "
        "expected fields as NMEA 0183 defines them"
    )


@given(st.text(alphabet=st.characters(max_codepoint=127), max_size=300))
def test_checksum_is_the_xor_of_the_characters(body: str) -> None:
    assert nmea_checksum(body) == reduce(xor, body.encode("ascii"), 0)


# The field converters as they were before issue 14 (regex, then int/float per use)
def _old_tod(s: str) -> float | None:
    if not s:
        return None
    m = re.fullmatch(r"(\d\d)(\d\d)(\d\d(?:\.\d*)?)", s)
    if not m or int(m[1]) > 23 or int(m[2]) > 59 or float(m[3]) >= 61.0:
        raise ValueError(f"time {s!r} is not hhmmss.ss")
    return int(m[1]) * 3600.0 + int(m[2]) * 60.0 + float(m[3])


def _old_angle(limit_deg: float, negative: str, positive: str) -> Callable[..., float | None]:
    def convert(value: str, hemisphere: str) -> float | None:
        if not value and not hemisphere:
            return None
        m = re.fullmatch(r"(\d{1,3})(\d\d(?:\.\d*)?)", value)
        if not m or float(m[2]) >= 60.0 or hemisphere not in (negative, positive):
            raise ValueError(f"{value!r},{hemisphere!r} is not ddmm.mm,{positive}|{negative}")
        deg = int(m[1]) + float(m[2]) / 60.0
        if deg > limit_deg:
            raise ValueError(f"{value!r} is beyond {limit_deg:g} deg")
        return -deg if hemisphere == negative else deg

    return convert


def _outcome(convert: Callable[..., Any], *args: str) -> tuple[str, Any]:
    try:
        return "value", convert(*args)
    except (ValueError, OverflowError) as err:
        return type(err).__name__, str(err)


CONVERTER_TEXT = st.one_of(
    st.text(alphabet="0123456789.+-NSEW ", max_size=14),
    st.text(max_size=6),
    st.sampled_from(["235960.5", "240000", "4807.0380", "18000.0000", "9000.00001", "nan"]),
    st.sampled_from(
        ["\u0661\u0662\u0663\u0664.5", "\uff11\uff12\uff13\uff14\uff15\uff16", "12\u00b234.5"]
    ),
)


@settings(max_examples=300)
@given(CONVERTER_TEXT, st.sampled_from(["N", "S", "E", "W", "", "n", "NS"]))
def test_converters_remember_results_only(text: str, letter: str) -> None:
    """Cached converters give what they compute (an error is raised again each time) and what
    the converters before issue 14 gave."""
    for convert in (
        nmea._number, nmea._count, nmea._tod, nmea._ddmmyy, nmea._quality, nmea._letter,
        nmea._rad,
    ):  # fmt: skip
        for _ in range(2):
            assert _outcome(convert, text) == _outcome(convert.__wrapped__, text)
    for _ in range(2):
        assert _outcome(nmea._tod, text) == _outcome(_old_tod, text)
        assert _outcome(nmea._LAT, text, letter) == _outcome(
            _old_angle(90.0, "S", "N"), text, letter
        )
        assert _outcome(nmea._LON, text, letter) == _outcome(
            _old_angle(180.0, "W", "E"), text, letter
        )
        assert _outcome(nmea._zda_date, text, text[:2], letter) == _outcome(
            nmea._zda_date.__wrapped__, text, text[:2], letter
        )


@settings(max_examples=200, deadline=None)
@given(INPUTS, OPTIONS)
def test_feed_lines_is_feed_line_on_each_line(
    inputs: list[tuple[float | None, str, int | None]], options: dict[str, Any]
) -> None:
    """Replay's loop (feed_line's fast path inline) gives the careful path's fixes, counters,
    warnings and first error."""
    numbered = [(t_host, line, record) for record, (t_host, line, _) in enumerate(inputs, 7)]
    careful = trace(numbered, fast=False, **options)
    decoder = NmeaDecoder("eq", **options)
    warnings = _Warnings()
    logger = logging.getLogger("drivers.nmea")
    logger.addHandler(warnings)
    level, logger.level = logger.level, logging.WARNING
    fixes: list[GnssFix] = []
    try:
        for fix in decoder.feed_lines([(t, line) for t, line, _ in numbered], first_record=7):
            fixes.append(fix)
        fixes += decoder.flush()
        error = None
    except InputError as err:
        error = (err.what, err.where, err.expected)
    finally:
        logger.removeHandler(warnings)
        logger.level = level
    errors = [x for x in careful[0] if isinstance(x, tuple)]
    assert error == (errors[0] if errors else None)
    if error is None:
        assert (fixes, asdict(decoder.counters)) == ([f for x in careful[0] for f in x], careful[1])
        assert warnings.messages == careful[2]
