"""Output encoders, checked with the independent ``nmea2000`` decoder (canboat's database)."""

import math
from dataclasses import replace

import can
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from nmea2000 import NMEA2000Decoder, backend

from drivers.samples import FixQuality, GnssFix
from gateway.estimation.engine_base import ImuHealth, common_fields
from gateway.estimation.solution import Convergence, Mode, Solution
from gateway.fusion.output_guard import OutputGuard
from gateway.isobus.frame_codec import RESERVED_PREFIX
from gateway.isobus.j1939 import Pgn
from gateway.isobus.n2k_encode import (
    GNSS_METHOD_OF_FIX,
    GNSS_TYPE_OF_TALKER,
    LAYOUTS,
    LoopStatus,
    OutputEncoder,
)
from tests.test_nmea_real_logs import decode as decode_log
from tests.test_output_dbc import encoded_message, expected_raw

T = 1_700_000_000.1234  # 2023-11-14 22:13:20.1234 UTC
FULL = Solution(
    t=T,
    mode=Mode.NAVIGATING,
    roll_rad=0.0123,
    pitch_rad=-0.0456,
    yaw_rad=4.0,  # > pi: 127257 sends it as 4 - 2 pi
    yaw_rate_rps=-0.2345,
    lat_deg=52.123456789012345,
    lon_deg=-10.987654321098765,
    alt_m=80.123456,
    vel_ned_mps=(3.0, -4.0, 0.1),
    bias_g_rps=(math.radians(0.1234), math.radians(-0.5), math.radians(4.0)),  # z beyond +/-3.2764
    bias_a_mps2=(0.0123, -0.2, 1.5),
    sigma_tilt_rad=math.radians(0.37),
    fix_quality=FixQuality.RTK_FIXED,
    num_sats=17,
    hdop=0.73,
    age_s=1.4,
    geoid_sep_m=47.25,
    reference_station_id=1023,
    talker="GP",
    gnss_ok=True,
    imu_ok=True,
    is_ekf=True,
    convergence=Convergence(gyro_xy=True, gyro_z=False, accel_xy=True, learning_frozen=False),
)
EMPTY = Solution(t=T, mode=Mode.INITIALISING)
LOOP = LoopStatus(source_address=0x1C, address_claimed=True, imu_samples_lost=3)


def decode(solution: Solution, loop: LoopStatus = LOOP, sid: int = 42) -> dict[str, dict]:
    """The standard PGNs of ``solution`` through nmea2000: message id -> {field id: field}."""
    encoder, decoder = OutputEncoder(), NMEA2000Decoder()
    out = {}
    for pgn in LAYOUTS:
        for frame in encoder.frames(pgn, solution, loop, sid):
            message = decoder.decode(frame)
            if message is not None:
                out[message.id] = {f.id: f for f in message.fields}
    return out


def value(decoded: dict[str, dict], message: str, field: str) -> object:
    return decoded[message][field].value


def test_standard_pgns_round_trip_within_one_lsb() -> None:
    d = decode(FULL)
    assert value(d, "attitude", "sid") == 42
    assert value(d, "attitude", "yaw") == pytest.approx(4.0 - 2 * math.pi, abs=1e-4)
    assert value(d, "attitude", "pitch") == pytest.approx(-0.0456, abs=1e-4)
    assert value(d, "attitude", "roll") == pytest.approx(0.0123, abs=1e-4)
    assert value(d, "rateOfTurn", "rate") == pytest.approx(-0.2345, abs=3.125e-8)
    assert value(d, "vesselHeading", "heading") == pytest.approx(4.0, abs=1e-4)
    assert value(d, "vesselHeading", "deviation") is None
    assert value(d, "vesselHeading", "variation") is None
    assert value(d, "vesselHeading", "reference") == "True"
    assert value(d, "positionRapidUpdate", "latitude") == pytest.approx(52.1234568, abs=1e-7)
    assert value(d, "positionRapidUpdate", "longitude") == pytest.approx(-10.9876543, abs=1e-7)
    assert value(d, "cogSogRapidUpdate", "cogReference") == "True"
    assert value(d, "cogSogRapidUpdate", "cog") == pytest.approx(
        math.atan2(-4.0, 3.0) % (2 * math.pi), abs=1e-4
    )
    assert value(d, "cogSogRapidUpdate", "sog") == pytest.approx(5.0, abs=0.01)
    for message in ("attitude", "rateOfTurn", "vesselHeading", "cogSogRapidUpdate"):
        assert value(d, message, "sid") == 42


def test_gnss_position_data_reassembled_full_precision() -> None:
    d = decode(FULL)["gnssPositionData"]
    assert d["sid"].value == 42
    assert d["date"].raw_value == 19675  # days since 1970-01-01
    assert d["time"].raw_value == pytest.approx(80000.1234, abs=1e-4)
    assert d["latitude"].value == pytest.approx(52.123456789012345, abs=1e-14)
    assert d["longitude"].value == pytest.approx(-10.987654321098765, abs=1e-14)
    assert d["altitude"].value == pytest.approx(80.123456, abs=1e-6)
    assert d["gnssType"].value == "GPS"
    assert d["method"].value == "RTK Fixed Integer"
    assert d["integrity"].value == "No integrity checking"
    assert d["numberOfSvs"].value == 17
    assert d["hdop"].value == pytest.approx(0.73, abs=0.01)
    assert d["pdop"].value is None
    assert d["geoidalSeparation"].value == pytest.approx(47.25, abs=0.01)
    assert d["referenceStations"].value == 1
    station = d["##list##"].value[0]
    assert station["ageOfDgnssCorrections"].value == pytest.approx(1.4, abs=0.01)
    assert station["referenceStationId"].value == 1023
    assert station["referenceStationType"].value is None


def test_gnss_method_follows_canboat_enum_for_every_fix_quality() -> None:
    labels = dict(backend.DATABASE.lookup("GNS_METHOD"))
    expected = {
        FixQuality.NONE: "no GNSS",
        FixQuality.GNSS: "GNSS fix",
        FixQuality.DGNSS: "DGNSS fix",
        FixQuality.PPS: "Precise GNSS",
        FixQuality.RTK_FIXED: "RTK Fixed Integer",
        FixQuality.RTK_FLOAT: "RTK float",
        FixQuality.DEAD_RECKONING: "Estimated (DR) mode",
        FixQuality.MANUAL: "Manual Input",
        FixQuality.SIMULATION: "Simulate mode",
    }
    assert {q: labels[int(m)] for q, m in GNSS_METHOD_OF_FIX.items()} == expected


def test_gnss_type_follows_canboat_enum() -> None:
    labels = dict(backend.DATABASE.lookup("GNS"))
    assert {t: labels[int(g)] for t, g in GNSS_TYPE_OF_TALKER.items()} == {
        "GP": "GPS",
        "GL": "GLONASS",
        "GA": "Galileo",
    }


def gnss_fields(solution: Solution) -> dict[str, object]:
    """129029 of ``solution`` through nmea2000: GNSS type, geoid separation, and the
    reference-station set (None each when the set is padding)."""
    d = decode(solution)["gnssPositionData"]
    stations = d["##list##"].value if d["referenceStations"].value else []
    assert len(stations) == d["referenceStations"].value
    station = {k: f.value for k, f in (stations[0] if stations else {}).items()}
    return {
        "type": d["gnssType"].value,
        "geoid": d["geoidalSeparation"].value,
        "stations": d["referenceStations"].value,
        "station_type": station.get("referenceStationType"),
        "station": station.get("referenceStationId"),
        "age": station.get("ageOfDgnssCorrections"),
    }


@pytest.mark.parametrize(
    ("talker", "quality", "gnss_type", "station"),
    [
        ("GP", FixQuality.GNSS, "GPS", None),  # no corrections: no station
        ("GP", FixQuality.DGNSS, None, 7),  # GPS or GPS+SBAS/WAAS: not known
        ("GL", FixQuality.RTK_FLOAT, "GLONASS", 7),
        ("GA", FixQuality.PPS, "Galileo", None),
        ("GN", FixQuality.RTK_FIXED, None, 7),  # several systems: which, GGA does not say
        ("GB", FixQuality.RTK_FIXED, None, 7),  # BeiDou: not in canboat's GNS
        ("GP", FixQuality.DEAD_RECKONING, None, None),  # the receiver's own dead reckoning
        ("GP", FixQuality.NONE, None, None),
        (None, FixQuality.RTK_FIXED, None, 7),
    ],
)
def test_gnss_type_and_station_only_where_the_fix_says_them(
    talker: str | None, quality: FixQuality, gnss_type: str | None, station: int | None
) -> None:
    sol = replace(FULL, talker=talker, fix_quality=quality, reference_station_id=7, age_s=None)
    got = gnss_fields(sol)
    assert (got["type"], got["station"], got["stations"]) == (
        gnss_type,
        station,
        int(bool(station)),
    )
    assert got["geoid"] == pytest.approx(47.25, abs=0.01)
    assert got["station_type"] is None  # the station's systems: not in NMEA 0183


@pytest.mark.parametrize(
    ("quality", "age"),
    [(FixQuality.GNSS, None), (FixQuality.PPS, None), (FixQuality.DGNSS, 2.0),
     (FixQuality.RTK_FLOAT, 2.0), (FixQuality.RTK_FIXED, 2.0)],
)  # fmt: skip
def test_age_of_corrections_only_for_a_corrected_fix(
    quality: FixQuality, age: float | None
) -> None:
    """Receivers send an age (often 0.0) with an autonomous fix: it would claim corrections."""
    got = gnss_fields(replace(FULL, fix_quality=quality, age_s=2.0, reference_station_id=None))
    assert got["age"] == (None if age is None else pytest.approx(age, abs=0.01))
    assert got["stations"] == int(age is not None)


def test_geoid_separation_only_with_the_altitude() -> None:
    assert gnss_fields(replace(FULL, alt_m=None))["geoid"] is None
    assert gnss_fields(replace(FULL, geoid_sep_m=-31.44))["geoid"] == pytest.approx(-31.44)


def test_no_altitude_without_the_geoid_separation() -> None:
    """A receiver that sends no separation gives its altitude above the geoid (MSL), or
    above an ellipsoid it does not name: 129029's altitude is the WGS-84 ellipsoid's, so it
    goes out "not available" (47 m off here) while the position goes out as ever."""
    d = decode(replace(FULL, geoid_sep_m=None))["gnssPositionData"]
    assert d["altitude"].value is None and d["geoidalSeparation"].value is None
    assert d["latitude"].value == pytest.approx(FULL.lat_deg, abs=1e-9)
    full = decode(FULL)["gnssPositionData"]
    assert full["altitude"].value == pytest.approx(FULL.alt_m, abs=1e-3)


def solution_of(fix: GnssFix) -> Solution:
    """The solution an engine reports with ``fix`` as its last: the fix fields as every engine
    copies them, the receiver's position (lever arms are tested elsewhere)."""
    common = common_fields(fix.t, fix, ImuHealth(fault_s=1.0))
    return Solution(
        **common, mode=Mode.NAVIGATING, lat_deg=fix.lat_deg, lon_deg=fix.lon_deg, alt_m=fix.alt_m
    )


@pytest.mark.parametrize(
    ("name", "which", "expected"),
    [  # real receivers (tests/data/nmea); expected 129029 fields as nmea2000 reads them
        ("nmea-rtk.log", FixQuality.RTK_FIXED,  # $GNGGA,...,4,19,0.7,280.827,M,-31.442,M,5.8,0002
         {"type": None, "geoid": -31.44, "stations": 1, "station": 2, "age": 5.8}),
        ("rst39.log", FixQuality.DGNSS,  # $GPGGA,...,2,08,1.0,221.890,M,,,3,0138
         {"type": None, "geoid": None, "stations": 1, "station": 138, "age": 3.0}),
        ("ublox-f9p-hpnmea.log", FixQuality.DGNSS,  # $GNGGA,...,2,12,0.49,...,-21.350,M,,0278
         {"type": None, "geoid": -21.35, "stations": 1, "station": 278, "age": None}),
        ("ch-4711.log", "GL",  # $GLGGA,135654.997,...,1,04,02.3,165.6,M,14.6,M,,
         {"type": "GLONASS", "geoid": 14.6, "stations": 0, "station": None, "age": None}),
        ("telit-he910.log", FixQuality.GNSS,  # $GPGGA,...,1,05,1.75,109.0,M,,M,,0000
         {"type": "GPS", "geoid": None, "stations": 0, "station": None, "age": None}),
        ("telit-pls83-w.log", FixQuality.GNSS,  # $GPGGA and $GAGGA of one solution
         {"type": None, "geoid": 50.0, "stations": 0, "station": None, "age": None}),
    ],
)  # fmt: skip
def test_129029_of_real_receivers(
    name: str, which: FixQuality | str, expected: dict[str, object]
) -> None:
    fixes, _ = decode_log(name)
    fix = next(
        f for f in fixes if (f.quality if isinstance(which, FixQuality) else f.talker) == which
        and f.lat_deg is not None and f.num_sats is not None  # a GGA, with a position
    )  # fmt: skip
    got = gnss_fields(solution_of(fix))
    assert got == pytest.approx(expected | {"station_type": None}, abs=0.006)


def test_while_coasting_no_gnss_type_and_no_station_but_the_geoid() -> None:
    """The guard makes a coasting solution dead reckoning: no satellites' systems, no
    corrections; the geoid separation still holds metres from the last fix."""
    coasting = OutputGuard().check(replace(FULL, mode=Mode.COASTING, coasting=True))
    got = gnss_fields(coasting)
    assert (got["type"], got["stations"], got["station"], got["age"]) == (None, 0, None, None)
    assert got["geoid"] == pytest.approx(47.25, abs=0.01)


def test_unknown_solution_fields_decode_as_missing_never_zero() -> None:
    d = decode(EMPTY)
    for message, fields in {
        "attitude": ("yaw", "pitch", "roll"),
        "rateOfTurn": ("rate",),
        "vesselHeading": ("heading", "deviation", "variation"),
        "positionRapidUpdate": ("latitude", "longitude"),
        "cogSogRapidUpdate": ("cog", "sog"),
        "gnssPositionData": (
            "latitude",
            "longitude",
            "altitude",
            "gnssType",
            "numberOfSvs",
            "hdop",
            "geoidalSeparation",
        ),
    }.items():
        for field in fields:
            assert value(d, message, field) is None, (message, field)
    assert value(d, "gnssPositionData", "method") is None
    assert value(d, "gnssPositionData", "referenceStations") == 0
    # reserved bits are ones
    assert d["attitude"]["reserved_56"].raw_value == 0xFF
    assert d["rateOfTurn"]["reserved_40"].raw_value == 0xFFFFFF
    assert d["cogSogRapidUpdate"]["reserved_48"].raw_value == 0xFFFF


def test_course_not_available_while_stationary() -> None:
    d = decode(Solution(t=T, mode=Mode.NAVIGATING, vel_ned_mps=(0.0, 0.0, 0.0), stationary=True))
    assert value(d, "cogSogRapidUpdate", "cog") is None
    assert value(d, "cogSogRapidUpdate", "sog") == 0


def test_payloads_equal_canboats_own_encoding() -> None:
    """Same values through canboat's encoder give the same bytes as ours."""
    encoder = OutputEncoder()
    ours = {pgn: encoder.payload(pgn, FULL, LOOP, 42) for pgn in LAYOUTS}
    db = backend.DATABASE
    assert ours[Pgn.ATTITUDE] == db.encode(
        "attitude", {"sid": 42, "yaw": 4.0 - 2 * math.pi, "pitch": -0.0456, "roll": 0.0123}
    )
    assert ours[Pgn.RATE_OF_TURN] == db.encode("rateOfTurn", {"sid": 42, "rate": -0.2345})
    assert ours[Pgn.VESSEL_HEADING] == db.encode(
        "vesselHeading", {"sid": 42, "heading": 4.0, "reference": 0}
    )
    assert ours[Pgn.POSITION_RAPID_UPDATE] == db.encode(
        "positionRapidUpdate", {"latitude": FULL.lat_deg, "longitude": FULL.lon_deg}
    )


@given(st.floats(min_value=-1e6, max_value=1e6, allow_nan=False))
def test_out_of_range_never_wraps(pitch_rad: float) -> None:
    payload = OutputEncoder().payload(
        Pgn.ATTITUDE, Solution(t=T, mode=Mode.NAVIGATING, pitch_rad=pitch_rad), LOOP, 0
    )
    raw = int.from_bytes(payload[3:5], "little", signed=True)
    if abs(pitch_rad) <= 3.2764:
        assert abs(raw * 1e-4 - pitch_rad) <= 0.5e-4 + 1e-12
    else:
        assert raw == 0x7FFE  # NMEA 2000 "out of range": decoders report it as missing
        assert backend.decode(127257, payload).fields[2].value is None


def proprietary(pgn: Pgn, solution: Solution, loop: LoopStatus = LOOP) -> bytes:
    frames = OutputEncoder().frames(pgn, solution, loop, 0)
    assert len(frames) == 1
    assert frames[0].arbitration_id == 6 << 26 | pgn << 8 | 0x1C
    return bytes(frames[0].data)


HEADER = bytes([0xFE, 0x5F])  # 2046 | 0b11 << 11 | 2 << 13, little-endian


def test_gyro_and_accel_bias_bytes() -> None:
    gyro = proprietary(Pgn.NAVGW_GYRO_BIAS, FULL)
    assert gyro == HEADER + (1234).to_bytes(2, "little") + (-5000).to_bytes(
        2, "little", signed=True
    ) + (0x7FFE).to_bytes(2, "little")  # z: out of range, not wrapped
    accel = proprietary(Pgn.NAVGW_ACCEL_BIAS, FULL)
    assert accel == HEADER + bytes.fromhex("7b00") + (-2000).to_bytes(2, "little", signed=True) + (
        15000
    ).to_bytes(2, "little")
    assert proprietary(Pgn.NAVGW_GYRO_BIAS, EMPTY) == HEADER + bytes.fromhex("ff7fff7fff7f")


def test_status_bytes() -> None:
    data = proprietary(Pgn.NAVGW_STATUS, FULL)
    assert data[:2] == HEADER
    assert data[2] == 2  # navigating
    assert data[3] == 4  # RTK fixed
    assert data[4] == 0b1110_0011  # reserved, EKF, claimed, -, -, -, GNSS ok, IMU ok
    assert data[5] == 0b1111_0101  # reserved x4, frozen 0, accel xy, gyro z 0, gyro xy
    assert data[6] == 3
    assert data[7] == 37  # 0.37 deg
    lost = LoopStatus(address_claimed=False, imu_samples_lost=1000)
    data = proprietary(Pgn.NAVGW_STATUS, Solution(t=T, mode=Mode.FAULT, sigma_tilt_rad=0.05), lost)
    assert data[2:] == bytes([5, 0xFF, 0x80, 0xF0, 255, 0xFF])  # sigma 2.86 deg -> unknown


def test_status_at_tilt_sigma_limit() -> None:
    def sigma_byte(deg: float) -> int:
        s = Solution(t=T, mode=Mode.NAVIGATING, sigma_tilt_rad=math.radians(deg))
        return proprietary(Pgn.NAVGW_STATUS, s)[7]

    assert [sigma_byte(x) for x in (0.0, 2.54, 2.55, 10.0)] == [0, 254, 255, 255]


def test_the_tilt_sigma_is_rounded_up_never_to_a_better_accuracy() -> None:
    """The bus states roll/pitch within its 0.01 deg steps: 0.064 deg goes out as 0.07 (the
    nearest, 0.06, claimed an accuracy the engine did not have); a sigma on a step stays it,
    one just above 2.54 deg is beyond the field (unknown or >= 2.55)."""

    def sigma_byte(deg: float) -> int:
        s = Solution(t=T, mode=Mode.NAVIGATING, sigma_tilt_rad=math.radians(deg))
        return proprietary(Pgn.NAVGW_STATUS, s)[7]

    steps = [sigma_byte(x) for x in (0.064, 0.0601, 0.07, 0.06, 0.37, 0.001, 2.541)]
    assert steps == [7, 7, 7, 6, 37, 1, 255]


def test_nmea2000_recognises_the_proprietary_header() -> None:
    decoder = NMEA2000Decoder()
    for pgn in (Pgn.NAVGW_GYRO_BIAS, Pgn.NAVGW_ACCEL_BIAS, Pgn.NAVGW_STATUS):
        (frame,) = OutputEncoder(manufacturer_code=2046).frames(pgn, FULL, LOOP, 0)
        fields = {f.id: f for f in decoder.decode(frame).fields}
        assert fields["manufacturerCode"].raw_value == 2046
        assert fields["reserved_11"].raw_value == 3
        assert fields["industryCode"].value == "Agriculture"


def test_frames_use_the_loop_source_address_and_solution_time() -> None:
    loop = LoopStatus(source_address=0x85, address_claimed=True)
    frames = OutputEncoder().frames(Pgn.GNSS_POSITION_DATA, FULL, loop, 1)
    assert len(frames) == 7
    assert {f.arbitration_id for f in frames} == {3 << 26 | 129029 << 8 | 0x85}
    assert {f.timestamp for f in frames} == {T}
    assert all(isinstance(f, can.Message) and f.is_extended_id for f in frames)


def test_manufacturer_code_must_fit_11_bits() -> None:
    with pytest.raises(ValueError, match="2048"):
        OutputEncoder(manufacturer_code=2048)


# OutputEncoder (compiled packers, prepared ids, issue 14) against the way it built frames
# before: the builder's values, the policy's raw values (tests/test_output_dbc.py), cantools'
# encode of the DBC message, the fast-packet split as fast_packet.py's docstring states it,
# and one can.Message per 8 bytes.


def reference_payload(
    pgn: Pgn, solution: Solution, loop: LoopStatus, sid: int, manufacturer_code: int = 2046
) -> bytes:
    layout = LAYOUTS[pgn]
    message = encoded_message(layout.message)
    values = layout.build(solution, loop, sid)
    if layout.proprietary:
        values |= {"MANUFACTURER_CODE": manufacturer_code, "INDUSTRY_CODE": 2}
    raw = {
        s.name: (1 << s.length) - 1
        if s.name.startswith(RESERVED_PREFIX)
        else expected_raw(s, values[s.name])
        for s in message.signals
    }
    return bytes(message.encode(raw, scaling=False, strict=False))


def reference_fast_packet(payload: bytes, seq: int) -> list[bytes]:
    frames = [bytes([seq << 5, len(payload)]) + payload[:6]]
    for index, start in enumerate(range(6, len(payload), 7), start=1):
        frames.append(bytes([seq << 5 | index]) + payload[start : start + 7])
    return [frame.ljust(8, b"\xff") for frame in frames]


def maybe(values: st.SearchStrategy[float]) -> st.SearchStrategy[float | None]:
    return st.one_of(st.none(), values, st.sampled_from([math.nan, math.inf, -math.inf]))


def axes() -> st.SearchStrategy[np.ndarray | None]:
    axis = st.one_of(st.floats(-0.1, 0.1), st.floats(-1e3, 1e3), st.floats())
    return st.one_of(st.none(), st.lists(axis, min_size=3, max_size=3).map(np.array))


solutions = st.builds(
    Solution,
    t=st.one_of(st.floats(0, 4e9), st.sampled_from([T, 0.0, 1_700_000_000.0])),
    mode=st.sampled_from(Mode),
    roll_rad=maybe(st.floats(-4, 4)),
    pitch_rad=maybe(st.floats(-1e6, 1e6)),
    yaw_rad=maybe(st.one_of(st.floats(-10, 10), st.floats(-1e9, 1e9))),
    yaw_rate_rps=maybe(st.floats(-100, 100)),
    lat_deg=maybe(st.floats(-95, 95)),
    lon_deg=maybe(st.floats(-185, 185)),
    alt_m=maybe(st.floats(-2e6, 2e6)),
    vel_ned_mps=st.one_of(
        st.none(), st.tuples(st.floats(-700, 700), st.floats(-700, 700), st.floats(-9, 9))
    ),
    bias_g_rps=axes(),
    bias_a_mps2=axes(),
    sigma_tilt_rad=maybe(st.floats(0, 0.1)),
    fix_quality=st.one_of(st.none(), st.sampled_from(FixQuality)),
    num_sats=st.one_of(st.none(), st.integers(-1, 300)),
    hdop=maybe(st.floats(-400, 400)),
    age_s=maybe(st.floats(-1, 700)),
    geoid_sep_m=maybe(st.floats(-200, 200)),
    reference_station_id=st.one_of(st.none(), st.integers(-1, 5000)),
    talker=st.one_of(st.none(), st.sampled_from(["GP", "GL", "GA", "GN", "GB", "BD", "gp"])),
    gnss_ok=st.booleans(),
    imu_ok=st.booleans(),
    stationary=st.booleans(),
    is_ekf=st.booleans(),
    convergence=st.builds(Convergence, *[st.booleans()] * 4),
)
loops = st.builds(
    LoopStatus, st.sampled_from([0x1C, 0x80, 0xF7]), st.booleans(), st.integers(-5, 1000)
)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    st.lists(st.tuples(solutions, loops, st.integers(0, 252)), min_size=1, max_size=6),
    st.integers(0, 2047),
)
@np.errstate(over="ignore", invalid="ignore")
def test_frames_equal_the_reference_encoding(
    instants: list[tuple[Solution, LoopStatus, int]], manufacturer_code: int
) -> None:
    encoder = OutputEncoder(manufacturer_code)
    seqs: dict[tuple[Pgn, int], int] = {}
    for solution, loop, sid in instants:
        for pgn in LAYOUTS:
            payload = reference_payload(pgn, solution, loop, sid, manufacturer_code)
            assert encoder.payload(pgn, solution, loop, sid) == payload
            if LAYOUTS[pgn].fast_packet:
                seq = seqs.get((pgn, loop.source_address), 0)
                seqs[pgn, loop.source_address] = (seq + 1) % 8
                chunks = reference_fast_packet(payload, seq)
            else:
                chunks = [payload]
            priority = encoded_message(LAYOUTS[pgn].message).frame_id >> 26 & 7
            frames = encoder.frames(pgn, solution, loop, sid)
            assert [bytes(f.data) for f in frames] == chunks
            for f in frames:
                assert f.arbitration_id == priority << 26 | pgn << 8 | loop.source_address
                assert (f.timestamp, f.is_extended_id, f.dlc) == (solution.t, True, 8)
                assert isinstance(f.data, bytearray)
                assert not (f.is_remote_frame or f.is_error_frame or f.is_fd)
                assert (f.channel, f.is_rx) == (None, True)  # python-can's defaults, as before
