"""The output DBC describes SPEC 4, and ``cantools decode`` reads a candump of our output."""

import math
import subprocess
import sys
from collections.abc import Mapping
from dataclasses import replace
from pathlib import Path

import cantools
import numpy as np
import pytest
from cantools.database.can import Message, Signal
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import dbc
from drivers.samples import FixQuality
from gateway.estimation.solution import Mode, Solution
from gateway.isobus.frame_codec import (
    NOT_AVAILABLE,
    OUT_OF_RANGE,
    RESERVED_PREFIX,
    EncodeError,
    FrameCodec,
)
from gateway.isobus.j1939 import FrameId, Pgn
from gateway.isobus.n2k_encode import LAYOUTS, LoopStatus, OutputEncoder
from gateway.isobus.output_scheduler import DEFAULT_RATES_HZ, OutputScheduler

DB = dbc.load(dbc.OUTPUT_DBC)
PAYLOADS = dbc.load(dbc.OUTPUT_PAYLOADS_DBC)


def encoded_message(name: str) -> Message:
    """A message the encoder packs: a frame of the output DBC, or a reassembled payload."""
    try:
        return DB.get_message_by_name(name)
    except KeyError:
        return PAYLOADS.get_message_by_name(name)


EXPECTED = {  # name: (priority, PGN, cycle time ms)
    "ATTITUDE": (3, 127257, 20),
    "RATE_OF_TURN": (2, 127251, 20),
    "VESSEL_HEADING": (2, 127250, 100),
    "POSITION_RAPID_UPDATE": (2, 129025, 20),
    "COG_SOG_RAPID_UPDATE": (2, 129026, 100),
    "GNSS_POSITION_DATA_FP": (3, 129029, 100),
    "ADDRESS_CLAIM": (6, 60928, None),
    "ISO_REQUEST": (6, 59904, None),
    "NAVGW_GYRO_BIAS": (6, 0xFF20, 1000),
    "NAVGW_ACCEL_BIAS": (6, 0xFF21, 1000),
    "NAVGW_STATUS": (6, 0xFF22, 100),
}


@pytest.mark.parametrize("name", EXPECTED)
def test_every_spec_frame_is_a_j1939_pg_with_priority_pgn_and_cycle(name: str) -> None:
    message = DB.get_message_by_name(name)
    priority, pgn, cycle = EXPECTED[name]
    frame_id = FrameId.parse(message.frame_id)
    assert (frame_id.priority, frame_id.pgn) == (priority, pgn)
    assert message.protocol == "j1939"
    assert message.cycle_time == cycle
    assert message.comment
    if pgn in DEFAULT_RATES_HZ:
        assert cycle == round(1000 / DEFAULT_RATES_HZ[Pgn(pgn)])
        assert frame_id.source == 0x1C


def test_reassembled_129029_payload_has_the_id_of_its_frames_on_the_bus() -> None:
    payload = PAYLOADS.get_message_by_name("GNSS_POSITION_DATA")
    frames = DB.get_message_by_name("GNSS_POSITION_DATA_FP")
    assert payload.length == 47
    assert payload.frame_id == frames.frame_id == 0x0DF8051C  # priority 3, PGN 129029, SA 0x1C
    assert (payload.protocol, payload.cycle_time) == ("j1939", 100)
    assert PAYLOADS.get_message_by_frame_id(0x0DF8051C) is payload
    assert "GNSS_POSITION_DATA" not in {m.name for m in DB.messages}  # one message per id
    assert payload.comment is not None and frames.comment is not None
    assert "fast-packet" in payload.comment and "navgw_output_payloads.dbc" in frames.comment


def test_reassembled_payload_decodes_with_cantools() -> None:
    sol = Solution(t=1_700_000_000.5, mode=Mode.NAVIGATING, lat_deg=48.1, lon_deg=11.6, alt_m=520.0)
    sol = replace(sol, geoid_sep_m=47.0)
    payload = OutputEncoder().payload(Pgn.GNSS_POSITION_DATA, sol, LoopStatus(), 9)
    decoded = PAYLOADS.get_message_by_frame_id(0x0DF8051C).decode(payload)
    assert isinstance(decoded, dict)  # a plain message, not a container
    assert decoded["SID"] == 9
    assert decoded["LATITUDE"] == pytest.approx(48.1, abs=1e-12)
    assert decoded["ALTITUDE"] == pytest.approx(520.0, abs=1e-6)
    assert decoded["GEOIDAL_SEPARATION"] == pytest.approx(47.0)
    for name in ("METHOD", "HDOP", "GNSS_TYPE", "REFERENCE_STATION_ID"):
        assert str(decoded[name]) == "NOT_AVAILABLE", name
    rtk = replace(
        sol, fix_quality=FixQuality.RTK_FIXED, geoid_sep_m=-31.44, reference_station_id=2,
        talker="GP", age_s=5.8,
    )  # fmt: skip
    decoded = PAYLOADS.get_message_by_name("GNSS_POSITION_DATA").decode(
        OutputEncoder().payload(Pgn.GNSS_POSITION_DATA, rtk, LoopStatus(), 9)
    )
    assert isinstance(decoded, dict)
    assert (str(decoded["GNSS_TYPE"]), str(decoded["METHOD"])) == ("GPS", "RTK_FIXED")
    assert decoded["GEOIDAL_SEPARATION"] == pytest.approx(-31.44)
    assert (decoded["REFERENCE_STATIONS"], decoded["REFERENCE_STATION_ID"]) == (1, 2)
    assert str(decoded["REFERENCE_STATION_TYPE"]) == "NOT_AVAILABLE"
    assert decoded["AGE_OF_DGNSS_CORRECTIONS"] == pytest.approx(5.8)


def test_frames_on_the_bus_reassemble_into_the_payload_of_their_id() -> None:
    """What a candump user does: the 7 frames of one 129029 (any source address), joined as
    fast_packet.py's docstring says, decode by their frame id with the payloads DBC."""
    sol = Solution(t=1_700_000_000.5, mode=Mode.NAVIGATING, lat_deg=48.1, lon_deg=11.6, alt_m=520.0)
    sol = replace(sol, fix_quality=FixQuality.GNSS, talker="GL", geoid_sep_m=14.6)
    loop = LoopStatus(source_address=0x85)
    frames = OutputEncoder().frames(Pgn.GNSS_POSITION_DATA, sol, loop, 3)
    (frame_id,) = {f.arbitration_id for f in frames}
    assert frame_id == 0x0DF80585
    assert DB.get_message_by_frame_id(frame_id).name == "GNSS_POSITION_DATA_FP"
    joined = bytes(frames[0].data[2:]) + b"".join(bytes(f.data[1:]) for f in frames[1:])
    decoded = PAYLOADS.get_message_by_frame_id(frame_id).decode(joined[: frames[0].data[1]])
    assert isinstance(decoded, dict)
    assert (decoded["SID"], str(decoded["GNSS_TYPE"]), str(decoded["METHOD"])) == (
        3,
        "GLONASS",
        "GNSS_FIX",
    )
    assert decoded["GEOIDAL_SEPARATION"] == pytest.approx(14.6)
    assert decoded["REFERENCE_STATIONS"] == 0


def test_every_encoded_message_is_in_the_dbc() -> None:
    frames = {layout.message for layout in LAYOUTS.values() if not layout.fast_packet}
    payloads = {layout.message for layout in LAYOUTS.values() if layout.fast_packet}
    assert frames <= {m.name for m in DB.messages}
    assert payloads <= {m.name for m in PAYLOADS.messages}


def test_cantools_decode_reads_a_candump_log_of_the_output(tmp_path: Path) -> None:
    sols = [
        Solution(
            t=1_700_000_000.0 + k / 100,
            mode=Mode.NAVIGATING,
            roll_rad=0.05,
            pitch_rad=-0.02,
            yaw_rad=1.5,
            yaw_rate_rps=0.01,
            lat_deg=52.5,
            lon_deg=13.4,
            vel_ned_mps=(1.0, 0.0, 0.0),
        )
        for k in range(100)
    ]
    scheduler = OutputScheduler()
    loop = LoopStatus(source_address=0x1C, address_claimed=True)
    lines = [
        f"({f.timestamp:.6f}) can0 {f.arbitration_id:08X}#{bytes(f.data).hex().upper()}"
        for s in sols
        for f in scheduler.frames(s, loop)
    ]
    result = subprocess.run(
        [sys.executable, "-m", "cantools", "decode", "--single-line", "-m", "0x03FFFF00"]
        + [str(dbc.path(dbc.OUTPUT_DBC))],
        input="\n".join(lines) + "\n",
        capture_output=True,
        text=True,
        timeout=60,
        check=True,
    )
    out = result.stdout.splitlines()
    assert len(out) == len(lines)
    by_name: dict[str, str] = {}
    for line in out:
        for name in EXPECTED:
            if f" {name}(" in line:
                by_name.setdefault(name, line)
    assert "YAW: 1.5 rad" in by_name["ATTITUDE"]
    assert "ROLL: 0.05 rad" in by_name["ATTITUDE"]
    assert "LATITUDE: 52.5 deg" in by_name["POSITION_RAPID_UPDATE"]
    assert "REFERENCE: TRUE" in by_name["VESSEL_HEADING"]
    assert "DEVIATION: NOT_AVAILABLE" in by_name["VESSEL_HEADING"]
    assert "SOG: 1.0 m/s" in by_name["COG_SOG_RAPID_UPDATE"]
    assert "FP_LENGTH: 47 B" in by_name["GNSS_POSITION_DATA_FP"]
    assert "INDUSTRY_CODE: AGRICULTURE" in by_name["NAVGW_STATUS"]
    assert "MODE: NAVIGATING" in by_name["NAVGW_STATUS"]
    assert "MANUFACTURER_CODE: 2046" in by_name["NAVGW_GYRO_BIAS"]
    assert not [line for line in out if "Unknown" in line or "error" in line.lower()]


# The packers compiled from the DBC (frame_codec.py, issue 14) against cantools' own encode
# and decode of the same DBC. The expected raw value of each field is the policy of
# frame_codec's docstring, written out here independently of the packers: None and NaN are
# NOT_AVAILABLE; a scaled value that is not finite, or rounds (half to even; up for a SIGMA*
# field, an accuracy) outside the range [min|max], is OUT_OF_RANGE, or NOT_AVAILABLE for a
# field without that code; a field with neither cannot carry it (EncodeError). Reserved
# fields are all ones.

#: Every message the gateway encodes through FrameCodec.
ENCODED = sorted({layout.message for layout in LAYOUTS.values()} | {"ADDRESS_CLAIM"})


def raw_limits(signal: Signal) -> tuple[int, int]:
    """The raw range of ``[min|max]`` (the bits' range where the DBC gives none)."""
    bits = (-(1 << (signal.length - 1)), (1 << (signal.length - 1)) - 1)
    if not signal.is_signed:
        bits = (0, (1 << signal.length) - 1)
    lo = bits[0] if signal.minimum is None else signal.minimum
    hi = bits[1] if signal.maximum is None else signal.maximum
    scale, offset = float(signal.scale), float(signal.offset)
    return math.ceil((lo - offset) / scale - 1e-9), math.floor((hi - offset) / scale + 1e-9)


def special(signal: Signal, name: str) -> int | None:
    return next((int(raw) for raw, label in (signal.choices or {}).items() if label == name), None)


def expected_raw(signal: Signal, value: object) -> int:
    """The raw value the policy sends for ``value`` (raises EncodeError if it cannot)."""
    not_available, out_of_range = special(signal, NOT_AVAILABLE), special(signal, OUT_OF_RANGE)
    lo, hi = raw_limits(signal)
    if value is None or (isinstance(value, float) and math.isnan(value)):
        candidates = [not_available]
    else:
        scaled = (value - float(signal.offset)) / float(signal.scale)  # type: ignore[operator]
        if math.isfinite(scaled):
            sent = math.ceil(scaled - 1e-9) if signal.name.startswith("SIGMA") else round(scaled)
            if lo <= sent <= hi:
                return sent
        candidates = [out_of_range, not_available]
    for raw in candidates:
        if raw is not None:
            return raw
    raise EncodeError(f"signal {signal.name} cannot carry {value!r} and has no special value")


def boundary_values(signal: Signal) -> list[float]:
    """Values at the range's ends and where rounding changes, a float step either side."""
    lo, hi = raw_limits(signal)
    scale, offset = float(signal.scale), float(signal.offset)
    out = []
    for raw in (lo, hi, lo - 1, hi + 1, 0):
        for edge in (raw - 0.5, raw, raw + 0.5):
            x = edge * scale + offset
            out += [x, math.nextafter(x, -math.inf), math.nextafter(x, math.inf)]
    return out


def physical_values(signal: Signal) -> st.SearchStrategy[object]:
    lo, hi = raw_limits(signal)
    scale, offset = float(signal.scale), float(signal.offset)
    low, high = (lo - 2) * scale + offset, (hi + 2) * scale + offset
    wide = 4 * max(abs(low), abs(high), 1.0)
    return st.one_of(
        st.none(),
        st.sampled_from([math.nan, -math.nan, math.inf, -math.inf, 0.0, -0.0]),
        st.floats(min_value=low, max_value=high),  # in range and a little beyond
        st.floats(min_value=-wide, max_value=wide),  # far beyond
        st.floats(),  # anything a float can be, NaN and infinities included
        st.sampled_from(boundary_values(signal)),
        st.integers(min_value=lo - 3, max_value=hi + 3).map(lambda raw: raw * scale + offset),
        st.integers(min_value=math.floor(low) - 3, max_value=math.ceil(high) + 3),
        st.booleans(),
        st.floats(min_value=low, max_value=high).map(np.float64),  # numpy scalars, as engines
        st.floats(allow_nan=True, width=32).map(np.float32),  # hand them (not float: NaN is OOR)
    )


@st.composite
def message_and_values(draw: st.DrawFn) -> tuple[Message, dict[str, object]]:
    message = encoded_message(draw(st.sampled_from(ENCODED)))
    values = {
        s.name: draw(physical_values(s))
        for s in message.signals
        if not s.name.startswith(RESERVED_PREFIX)
    }
    return message, values


CODECS = {name: FrameCodec(encoded_message(name)) for name in ENCODED}


def assert_packs_as_cantools(message: Message, values: Mapping[str, object]) -> None:
    """The codec's bytes are cantools' encoding of the policy's raw values, and cantools'
    decode reads every field back; or both the policy and the codec raise the same error."""
    try:
        raw = {
            s.name: (1 << s.length) - 1
            if s.name.startswith(RESERVED_PREFIX)
            else expected_raw(s, values[s.name])
            for s in message.signals
        }
    except EncodeError as error:  # the policy cannot send it: the codec raises the same
        with pytest.raises(EncodeError) as raised:
            CODECS[message.name].encode(values)  # type: ignore[arg-type]
        assert str(raised.value) == str(error)
        return
    data = CODECS[message.name].encode(values)  # type: ignore[arg-type]
    assert data == message.encode(raw, scaling=False, strict=False), values
    assert len(data) == message.length
    decoded = message.decode(data, decode_choices=False, scaling=False)
    assert isinstance(decoded, dict)
    for s in message.signals:
        assert decoded[s.name] == raw[s.name], (s.name, values.get(s.name))


@settings(max_examples=600, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(message_and_values())
@np.errstate(over="ignore", invalid="ignore")  # float32 values beyond float32 once scaled
def test_compiled_packers_equal_cantools_field_by_field(
    case: tuple[Message, dict[str, object]],
) -> None:
    assert_packs_as_cantools(*case)


@pytest.mark.parametrize("name", ENCODED)
def test_compiled_packers_at_every_boundary(name: str) -> None:
    """Each field at and around its range's ends and rounding points, the others in range."""
    message = encoded_message(name)
    fields = [s for s in message.signals if not s.name.startswith(RESERVED_PREFIX)]
    for signal in fields:
        for x in [*boundary_values(signal), None, math.nan, math.inf, -math.inf]:
            values = {s.name: x if s is signal else raw_limits(s)[0] * s.scale for s in fields}
            assert_packs_as_cantools(message, values)


def test_packer_errors_are_the_codecs_errors() -> None:
    codec = CODECS["NAVGW_STATUS"]
    with pytest.raises(EncodeError, match=r"no value for \['IMU_OK', 'MODE'\]"):
        codec.encode({n: 0 for n in codec.signal_names - {"MODE", "IMU_OK"}})
    with pytest.raises(EncodeError, match="IMU_OK cannot carry None"):
        codec.encode({n: None if n == "IMU_OK" else 0 for n in codec.signal_names})
    with pytest.raises(EncodeError, match="MODE cannot carry 300"):  # no special value: raise
        codec.encode({n: 300 if n == "MODE" else 0 for n in codec.signal_names})
    text: dict[str, object] = {n: "1" if n == "MODE" else 0 for n in codec.signal_names}
    with pytest.raises(TypeError):
        codec.encode(text)  # type: ignore[arg-type]
    values = {n: 0 for n in codec.signal_names} | {"NOT_A_SIGNAL": 5}  # extra names: ignored
    assert codec.encode(values) == codec.encode({n: 0 for n in codec.signal_names})


BIG_ENDIAN_DBC = """VERSION ""
BU_: NAVGW
BO_ 2566857500 TEST: 4 NAVGW
 SG_ SPEED : 7|16@0+ (0.01,0) [0|655.32] "m/s" Vector__XXX
 SG_ RESERVED : 23|8@0+ (1,0) [255|255] "" Vector__XXX
 SG_ HEADING : 31|8@0+ (1,0) [0|252] "" Vector__XXX
VAL_ 2566857500 SPEED 65535 "NOT_AVAILABLE" 65534 "OUT_OF_RANGE" ;
VAL_ 2566857500 HEADING 255 "NOT_AVAILABLE" 254 "OUT_OF_RANGE" ;
"""


def test_every_encoded_message_has_a_packer_and_others_keep_cantools() -> None:
    assert all(CODECS[name].source is not None for name in ENCODED)
    db = cantools.database.load_string(BIG_ENDIAN_DBC)
    assert isinstance(db, cantools.database.can.Database)
    message = db.get_message_by_name("TEST")
    codec = FrameCodec(message)
    assert codec.source is None  # big-endian: cantools packs, as before
    for speed, heading in [(12.34, 7), (None, None), (700.0, 300), (math.nan, 252)]:
        values = {"SPEED": speed, "HEADING": heading}
        raw = {"RESERVED": 255} | {
            n: expected_raw(message.get_signal_by_name(n), v) for n, v in values.items()
        }
        assert codec.encode(values) == message.encode(raw, scaling=False, strict=False)
