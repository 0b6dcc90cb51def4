"""Fuzzing the edges: whatever bytes arrive, the decoders and readers never raise.

Every input the gateway reads from outside (NMEA bytes, IMU frames, log lines, config files)
is driven with hypothesis-generated data. The properties: no exception escapes but the
documented one (InputError, ConfigError), counters add up, and nothing non-finite comes out.
``NAVGW_FUZZ_EXAMPLES`` sets the examples per property (default 300); ``benchmarks/fuzz.py``
runs them by the hundred thousand.
"""

from __future__ import annotations

import math
import os
from typing import Any

import can
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from drivers.errors import InputError
from drivers.imu_can import ImuCanIds, ImuDecoder
from drivers.logs.candump import parse_candump_line
from drivers.logs.nmea_log import parse_nmea_log_line
from drivers.nmea import NmeaDecoder, nmea_checksum
from drivers.samples import GnssFix, ImuSample
from gateway.config.config_schema import ConfigError
from gateway.config.gateway_config import config_from_table

EXAMPLES = int(os.environ.get("NAVGW_FUZZ_EXAMPLES", "300"))
FUZZ = settings(
    max_examples=EXAMPLES,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)

IDS = ImuCanIds.for_source_address(0x80)
TALKERS = ["GP", "GN", "GL", "XX", ""]
KINDS = ["GGA", "RMC", "VTG", "GST", "ZDA", "HDT", "TXT", "Q"]
FIELD = st.one_of(
    st.text(alphabet="0123456789.-+NSEWAVTMKRFD", max_size=24),
    st.sampled_from(["", "nan", "inf", "-0", "99999999999999999999", "1e308", "3600.00"]),
)


@st.composite
def sentences(draw: st.DrawFn) -> bytes:
    """A framed sentence with a valid checksum and random fields (or a damaged one)."""
    body = draw(st.sampled_from(TALKERS)) + draw(st.sampled_from(KINDS))
    body += "," + ",".join(draw(st.lists(FIELD, max_size=20)))
    text = f"${body}*{nmea_checksum(body):02X}"
    if draw(st.booleans()):
        cut = draw(st.integers(0, len(text)))
        text = text[:cut] + draw(st.text(max_size=5)) + text[cut:]
    eol = draw(st.sampled_from(["\r\n", "\n", "\r", ""]))
    return (text + eol).encode("utf-8", errors="replace")


def _finite_fix(fix: GnssFix) -> bool:
    values = [fix.t, fix.t_utc, fix.lat_deg, fix.lon_deg, fix.alt_m, fix.sog_mps, fix.cog_rad]
    return all(v is None or math.isfinite(v) for v in values)


@FUZZ
@given(st.lists(st.one_of(sentences(), st.binary(max_size=200)), max_size=30))
def test_nmea_decoder_takes_any_bytes(chunks: list[bytes]) -> None:
    decoder = NmeaDecoder("fuzz")
    fixes = []
    for k, chunk in enumerate(chunks):
        fixes += decoder.feed(chunk, 1_700_000_000.0 + 0.1 * k)
    fixes += decoder.flush()
    assert all(_finite_fix(f) for f in fixes)
    c = decoder.counters
    assert c.fixes == len(fixes) and sum(c.by_type.values()) >= c.sentences_ok


@st.composite
def imu_frames(draw: st.DrawFn) -> can.Message:
    frame_id = draw(st.sampled_from([IDS.gyro, IDS.accel, IDS.aux, 0x18EEFF1C, 0x123]))
    return can.Message(
        timestamp=draw(
            st.one_of(
                st.floats(1.7e9, 1.7e9 + 10.0),
                st.sampled_from([math.nan, math.inf, -math.inf, -1.0, 0.0]),
            )
        ),
        arbitration_id=frame_id,
        is_extended_id=frame_id > 0x7FF or draw(st.booleans()),
        data=draw(st.binary(max_size=8)),
        is_remote_frame=draw(st.booleans()) and draw(st.booleans()),
    )


@FUZZ
@given(st.lists(imu_frames(), max_size=60))
def test_imu_decoder_takes_any_frame(frames: list[can.Message]) -> None:
    decoder = ImuDecoder()
    samples = []
    for msg in frames:
        samples += [s for s in decoder.feed(msg) if isinstance(s, ImuSample)]
    decoder.finish()
    for s in samples:
        assert math.isfinite(s.t) and s.dt > 0.0
    assert [s.t for s in samples] == sorted(s.t for s in samples)


@FUZZ
@given(
    st.one_of(
        st.text(max_size=120),
        st.builds(
            "({}) {} {}#{}".format,
            st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.text(max_size=8)),
            st.text(alphabet="abcn0123", max_size=6),
            st.text(alphabet="0123456789ABCDEFx", max_size=9),
            st.text(alphabet="0123456789ABCDEFR#", max_size=20),
        ),
    )
)
def test_candump_lines_parse_or_say_why(line: str) -> None:
    try:
        msg = parse_candump_line(line, "fuzz:1")
    except InputError as err:
        assert "fuzz:1" in str(err) and len(str(err)) < 400
        return
    assert msg is None or (math.isfinite(msg.timestamp) and msg.timestamp >= 0.0)


@FUZZ
@given(st.text(max_size=200))
def test_nmea_log_lines_parse_or_say_why(line: str) -> None:
    try:
        parsed = parse_nmea_log_line(line, "fuzz:1")
    except InputError as err:
        assert "fuzz:1" in str(err) and len(str(err)) < 400
        return
    assert parsed is None or parsed[0] is None or math.isfinite(parsed[0])


TOML_VALUES = st.recursive(
    st.one_of(
        st.none(),
        st.booleans(),
        st.integers(-(10**20), 10**20),
        st.floats(allow_nan=True, allow_infinity=True),
        st.text(max_size=10),
    ),
    lambda inner: st.lists(inner, max_size=4),
    max_leaves=8,
)
SECTIONS = ["vehicle", "estimator", "imu", "gnss", "isobus", "output", "recording", "observer"]
KEYS = [
    "antenna_lever_arm_m", "imu_lever_arm_m", "engine", "interface", "channel", "port",
    "tau_s", "gate_sigma", "attitude_hz", "preferred_address", "enabled", "epoch_time", "x",
]  # fmt: skip


@FUZZ
@given(
    st.dictionaries(
        st.sampled_from([*SECTIONS, "ekf", "bogus"]),
        st.dictionaries(st.sampled_from(KEYS), TOML_VALUES, max_size=4),
        max_size=4,
    )
)
def test_config_tables_load_or_say_why(table: dict[str, Any]) -> None:
    try:
        config = config_from_table(table, "fuzz.toml")
    except ConfigError as err:
        assert str(err)
        return
    assert all(math.isfinite(v) for v in config.vehicle.antenna_lever_arm_m)
    assert config.observer.tau_s > 0.0


@pytest.mark.parametrize("name", ["$", "$GPGGA", "!", "\r\n", "*"])
def test_nmea_decoder_degenerate_chunks(name: str) -> None:
    decoder = NmeaDecoder("fuzz")
    assert decoder.feed(name.encode() * 1000, 1.0) + decoder.flush() == []
