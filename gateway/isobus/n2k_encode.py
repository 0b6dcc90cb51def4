"""Encoders: a ``Solution`` (+ what the loop knows) to the CAN frames of SPEC 4.

Each PGN has one small function that maps the solution to physical values named as the DBC
signals (SI, except where the DBC says otherwise: deg for latitude and bias rates); the DBC
and ``FrameCodec`` do the rest (scaling, "not available", out of range, reserved bits).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from enum import IntEnum

import can
import cantools

import dbc
from drivers.samples import CORRECTED_QUALITIES, FixQuality, Float3
from drivers.units import SECONDS_PER_DAY, wrap_pi
from gateway.estimation.solution import Solution
from gateway.isobus.fast_packet import FastPacketFragmenter
from gateway.isobus.frame_codec import FrameCodec, Value
from gateway.isobus.j1939 import (
    DEFAULT_MANUFACTURER_CODE,
    DEFAULT_SOURCE_ADDRESS,
    IndustryGroup,
    Pgn,
    can_id,
)

TIME_LSB_S = 1e-4  # 129029 time of day resolution


class DirectionReference(IntEnum):
    """canboat DIRECTION_REFERENCE (127250 reference, 129026 COG reference)."""

    TRUE = 0
    MAGNETIC = 1


class GnssMethod(IntEnum):
    """canboat GNS_METHOD, 129029 method."""

    NO_GNSS = 0
    GNSS_FIX = 1
    DGNSS_FIX = 2
    PRECISE_GNSS = 3
    RTK_FIXED = 4
    RTK_FLOAT = 5
    ESTIMATED_DR = 6
    MANUAL_INPUT = 7
    SIMULATE = 8


class GnssType(IntEnum):
    """canboat GNS, 129029 GNSS type and reference station type (only the values navgw sends)."""

    GPS = 0
    GLONASS = 1
    GALILEO = 8


class GnssIntegrity(IntEnum):
    """canboat GNS_INTEGRITY, 129029 integrity: navgw does no RAIM."""

    NO_CHECKING = 0


#: GGA fix quality to the 129029 method.
GNSS_METHOD_OF_FIX = {
    FixQuality.NONE: GnssMethod.NO_GNSS,
    FixQuality.GNSS: GnssMethod.GNSS_FIX,
    FixQuality.DGNSS: GnssMethod.DGNSS_FIX,
    FixQuality.PPS: GnssMethod.PRECISE_GNSS,
    FixQuality.RTK_FIXED: GnssMethod.RTK_FIXED,
    FixQuality.RTK_FLOAT: GnssMethod.RTK_FLOAT,
    FixQuality.DEAD_RECKONING: GnssMethod.ESTIMATED_DR,
    FixQuality.MANUAL: GnssMethod.MANUAL_INPUT,
    FixQuality.SIMULATION: GnssMethod.SIMULATE,
}

#: GGA talker id to the 129029 GNSS type, for the talkers that name one system GNS lists
#: (GN, several systems, does not say which; BeiDou (GB, BD), QZSS and NavIC are not in GNS).
GNSS_TYPE_OF_TALKER = {"GP": GnssType.GPS, "GL": GnssType.GLONASS, "GA": GnssType.GALILEO}
#: Fix qualities whose satellite systems the talker names alone. Not DGNSS: its corrections
#: may come from SBAS, which GNS counts in the type ("GPS+SBAS/WAAS"); nor dead reckoning,
#: no fix, manual or simulated positions.
TYPED_BY_TALKER = frozenset(
    {FixQuality.GNSS, FixQuality.PPS, FixQuality.RTK_FIXED, FixQuality.RTK_FLOAT}
)


@dataclass(frozen=True, slots=True)
class LoopStatus:
    """What the fusion loop knows and the estimator does not."""

    source_address: int = DEFAULT_SOURCE_ADDRESS  # the address claimed (or being claimed)
    address_claimed: bool = False
    imu_samples_lost: int = 0  # in the last second


Values = dict[str, Value]
Builder = Callable[[Solution, LoopStatus, int], Values]


def _wrap_pi(angle_rad: float | None) -> float | None:
    """Angle in [-pi, pi): 127257 yaw is a signed 16-bit field (+/-3.2764 rad)."""
    return None if angle_rad is None else wrap_pi(angle_rad)


def _wrap_2pi(angle_rad: float | None) -> float | None:
    """Angle in [0, 2 pi): heading and course are unsigned fields."""
    return None if angle_rad is None else angle_rad % (2 * math.pi)


def _axes(prefix: str, vec: Float3 | None, scale: float) -> Values:
    """``{prefix}_X/Y/Z`` from a body-frame vector, or all not available."""
    return {
        f"{prefix}_{axis}": None if vec is None else vec[i] * scale for i, axis in enumerate("XYZ")
    }


def attitude(s: Solution, _: LoopStatus, sid: int) -> Values:
    """127257: yaw (true), pitch, roll."""
    return {"SID": sid, "YAW": _wrap_pi(s.yaw_rad), "PITCH": s.pitch_rad, "ROLL": s.roll_rad}


def rate_of_turn(s: Solution, _: LoopStatus, sid: int) -> Values:
    """127251: bias-corrected yaw rate, clockwise positive."""
    return {"SID": sid, "RATE": s.yaw_rate_rps}


def vessel_heading(s: Solution, _: LoopStatus, sid: int) -> Values:
    """127250: true heading; no magnetic deviation or variation."""
    return {
        "SID": sid,
        "HEADING": _wrap_2pi(s.yaw_rad),
        "DEVIATION": None,
        "VARIATION": None,
        "REFERENCE": DirectionReference.TRUE,
    }


def position_rapid(s: Solution, _: LoopStatus, __: int) -> Values:
    """129025: reference point latitude and longitude."""
    return {"LATITUDE": s.lat_deg, "LONGITUDE": s.lon_deg}


def cog_sog_rapid(s: Solution, _: LoopStatus, sid: int) -> Values:
    """129026: reference point course (true) and speed; no course while stationary."""
    cog, sog = s.cog_sog or (None, None)
    return {
        "SID": sid,
        "COG_REFERENCE": DirectionReference.TRUE,
        "COG": None if s.stationary else cog,
        "SOG": sog,
    }


def gnss_position(s: Solution, _: LoopStatus, sid: int) -> Values:
    """129029 payload: UTC date/time of the solution, full-precision position, fix info.

    Each fix field describes the position sent (the output guard makes a coasting one dead
    reckoning): the GNSS type from the talker only where it is one system and the quality
    says the talker's systems are all there is; the station id only for a corrected fix; the
    altitude and the geoid separation together or neither (a receiver that sends no
    separation gives its MSL altitude, and the field is the ellipsoid's). The age of
    corrections only for a corrected fix too (an autonomous fix's "0.0" would claim
    corrections one has not got). The reference station type (the station's systems) is
    nowhere in NMEA 0183: not available."""
    days, ticks = divmod(round(s.t / TIME_LSB_S), round(SECONDS_PER_DAY / TIME_LSB_S))
    datum_known = s.alt_m is not None and s.geoid_sep_m is not None
    quality = s.fix_quality
    method = None if quality is None else GNSS_METHOD_OF_FIX[quality]
    gnss_type = GNSS_TYPE_OF_TALKER.get(s.talker or "") if quality in TYPED_BY_TALKER else None
    corrected = quality in CORRECTED_QUALITIES
    station = s.reference_station_id if corrected else None
    age = s.age_s if corrected else None  # some receivers send 0.0 without corrections
    return {
        "SID": sid,
        "DATE": days,
        "TIME": ticks * TIME_LSB_S,
        "LATITUDE": s.lat_deg,
        "LONGITUDE": s.lon_deg,
        "ALTITUDE": s.alt_m if datum_known else None,
        "GNSS_TYPE": gnss_type,
        "METHOD": method,
        "INTEGRITY": GnssIntegrity.NO_CHECKING,
        "NUMBER_OF_SVS": s.num_sats,
        "HDOP": s.hdop,
        "PDOP": None,
        "GEOIDAL_SEPARATION": s.geoid_sep_m if datum_known else None,
        # one reference-station set: the station and age of corrections; without either the
        # set is padding
        "REFERENCE_STATIONS": 0 if age is None and station is None else 1,
        "REFERENCE_STATION_TYPE": None,
        "REFERENCE_STATION_ID": station,
        "AGE_OF_DGNSS_CORRECTIONS": age,
    }


def gyro_bias(s: Solution, _: LoopStatus, __: int) -> Values:
    """NAVGW_GYRO_BIAS: gyro bias estimate, deg/s on the bus."""
    return _axes("GYRO_BIAS", s.bias_g_rps, math.degrees(1.0))


def accel_bias(s: Solution, _: LoopStatus, __: int) -> Values:
    """NAVGW_ACCEL_BIAS: accelerometer bias estimate, m/s^2."""
    return _axes("ACCEL_BIAS", s.bias_a_mps2, 1.0)


def status(s: Solution, loop: LoopStatus, __: int) -> Values:
    """NAVGW_STATUS: mode, fix quality, flags, samples lost, tilt sigma (deg on the bus)."""
    c = s.convergence
    return {
        "MODE": s.mode,
        "FIX_QUALITY": s.fix_quality,
        "IMU_OK": s.imu_ok,
        "GNSS_OK": s.gnss_ok,
        "REVERSING": s.reversing,
        "STATIONARY": s.stationary,
        "IMU_ALARM": s.imu_alarm,
        "ADDRESS_CLAIMED": loop.address_claimed,
        "ENGINE_EKF": s.is_ekf,
        "GYRO_XY_CONVERGED": c.gyro_xy,
        "GYRO_Z_CONVERGED": c.gyro_z,
        "ACCEL_XY_CONVERGED": c.accel_xy,
        "BIAS_LEARNING_FROZEN": c.learning_frozen,
        "IMU_SAMPLES_LOST": min(max(loop.imu_samples_lost, 0), 255),  # SPEC: saturating
        "SIGMA_TILT": None if s.sigma_tilt_rad is None else math.degrees(s.sigma_tilt_rad),
    }


@dataclass(frozen=True, slots=True)
class Layout:
    """How one PGN is built: its DBC message, value builder, and header and SID use."""

    message: str  # in the output DBC; a fast-packet one's payload in the payloads DBC
    build: Builder
    proprietary: bool = False
    fast_packet: bool = False


LAYOUTS: Mapping[Pgn, Layout] = {
    Pgn.ATTITUDE: Layout("ATTITUDE", attitude),
    Pgn.RATE_OF_TURN: Layout("RATE_OF_TURN", rate_of_turn),
    Pgn.VESSEL_HEADING: Layout("VESSEL_HEADING", vessel_heading),
    Pgn.POSITION_RAPID_UPDATE: Layout("POSITION_RAPID_UPDATE", position_rapid),
    Pgn.COG_SOG_RAPID_UPDATE: Layout("COG_SOG_RAPID_UPDATE", cog_sog_rapid),
    Pgn.GNSS_POSITION_DATA: Layout("GNSS_POSITION_DATA", gnss_position, fast_packet=True),
    Pgn.NAVGW_GYRO_BIAS: Layout("NAVGW_GYRO_BIAS", gyro_bias, proprietary=True),
    Pgn.NAVGW_ACCEL_BIAS: Layout("NAVGW_ACCEL_BIAS", accel_bias, proprietary=True),
    Pgn.NAVGW_STATUS: Layout("NAVGW_STATUS", status, proprietary=True),
}


#: The frames of one PGN for one instant: ``(solution, loop, sid) -> frames``.
Framer = Callable[[Solution, LoopStatus, int], list[can.Message]]


class OutputEncoder:
    """Builds the frames of one PGN for one instant; owns the fast-packet counters.

    Each PGN is prepared once (:meth:`framer`): its builder, its packer compiled from the DBC
    (:class:`FrameCodec`), its priority, and its 29-bit id per source address, so that an
    instant costs the builder, the packer and ``can.Message``."""

    def __init__(
        self,
        manufacturer_code: int = DEFAULT_MANUFACTURER_CODE,
        database: cantools.database.can.Database | None = None,
        payloads: cantools.database.can.Database | None = None,
    ) -> None:
        """``database``, ``payloads``: the output DBC and its payloads DBC (fast-packet PGNs'
        messages are their reassembled payloads), the shipped ones by default."""
        if not 0 <= manufacturer_code < 1 << 11:
            raise ValueError(f"manufacturer code {manufacturer_code} is not 0-2047 (11 bits)")
        frames_db = database or dbc.load(dbc.OUTPUT_DBC)
        payloads_db = payloads or dbc.load(dbc.OUTPUT_PAYLOADS_DBC)
        self._codecs = {
            pgn: FrameCodec(
                (payloads_db if layout.fast_packet else frames_db).get_message_by_name(
                    layout.message
                )
            )
            for pgn, layout in LAYOUTS.items()
        }
        self._header: Values = {
            "MANUFACTURER_CODE": manufacturer_code,
            "INDUSTRY_CODE": IndustryGroup.AGRICULTURE,
        }
        self._fragmenter = FastPacketFragmenter()
        self._framers = {pgn: self._prepare(pgn) for pgn in LAYOUTS}

    def payload(self, pgn: Pgn, solution: Solution, loop: LoopStatus, sid: int) -> bytes:
        """The PGN's payload bytes (129029 reassembled, not yet fragmented)."""
        values = LAYOUTS[pgn].build(solution, loop, sid)
        if LAYOUTS[pgn].proprietary:
            values.update(self._header)
        return self._codecs[pgn].packer(values)

    def frames(self, pgn: Pgn, solution: Solution, loop: LoopStatus, sid: int) -> list[can.Message]:
        """The frames to send for ``pgn``, stamped with the solution time."""
        return self._framers[pgn](solution, loop, sid)

    def framer(self, pgn: Pgn) -> Framer:
        """``frames`` for one PGN, without looking the PGN up (for the scheduler)."""
        return self._framers[pgn]

    def _prepare(self, pgn: Pgn) -> Framer:
        layout, codec = LAYOUTS[pgn], self._codecs[pgn]
        build, pack, fragment = layout.build, codec.packer, self._fragmenter.fragment
        header = self._header if layout.proprietary else None
        priority = (codec.message.frame_id >> 26) & 0x7
        ids: dict[int, int] = {}  # source address: 29-bit id
        message = can.Message

        def frame_id(source: int) -> int:
            found = ids.get(source)
            if found is None:
                found = ids[source] = can_id(pgn, source, priority)
            return found

        # can.Message's first parameters, in its order: timestamp, arbitration_id,
        # is_extended_id, is_remote_frame, is_error_frame, channel, dlc (None: the data's
        # length), data. Positional, because keywords cost a fifth more per frame.
        def single(solution: Solution, loop: LoopStatus, sid: int) -> list[can.Message]:
            values = build(solution, loop, sid)
            if header is not None:
                values.update(header)
            data = pack(values)
            arbitration_id = ids.get(loop.source_address) or frame_id(loop.source_address)
            return [message(solution.t, arbitration_id, True, False, False, None, None, data)]

        def fast_packet(solution: Solution, loop: LoopStatus, sid: int) -> list[can.Message]:
            values = build(solution, loop, sid)
            if header is not None:
                values.update(header)
            data = pack(values)
            source = loop.source_address
            arbitration_id = ids.get(source) or frame_id(source)
            t = solution.t
            return [
                message(t, arbitration_id, True, False, False, None, None, chunk)
                for chunk in fragment(pgn, source, data)
            ]

        return fast_packet if layout.fast_packet else single
