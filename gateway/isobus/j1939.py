"""J1939 / ISO 11783 identifiers: the PGNs navgw sends or answers, and 29-bit ids.

A 29-bit id is ``priority << 26 | PGN << 8 | SA``. For a PDU1 PGN (PDU format byte < 240)
the low byte of the PGN is the destination address instead (J1939-21): the PGN itself then
ends in 0x00 and the id carries the destination there. The packing is cantools'
(:mod:`cantools.j1939`); a gateway uses a handful of ids, so both directions are cached.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum
from functools import cache

from cantools import j1939

DEFAULT_SOURCE_ADDRESS = 0x1C  # navgw's preferred address (SPEC 4)
DEFAULT_MANUFACTURER_CODE = 2046  # SPEC 4: none assigned
NETWORK_MANAGEMENT_PRIORITY = 6  # address claim and request (J1939-81)
NULL_ADDRESS = 254  # source of a node without an address (cannot-claim, start-up request)
GLOBAL_ADDRESS = 255  # destination "every node"
PDU2_MIN_FORMAT = 240  # PDU format byte from which a PGN is broadcast only (PDU2)


class Pgn(IntEnum):
    """Parameter group numbers of SPEC 4 and of network management (ISO 11783-3/-5, NMEA 2000)."""

    ISO_ACKNOWLEDGEMENT = 59392
    ISO_REQUEST = 59904
    TP_DATA_TRANSFER = 60160
    TP_CONNECTION_MANAGEMENT = 60416
    ADDRESS_CLAIM = 60928
    COMMANDED_ADDRESS = 65240
    PGN_LIST = 126464
    HEARTBEAT = 126993
    PRODUCT_INFORMATION = 126996
    CONFIGURATION_INFORMATION = 126998
    ATTITUDE = 127257
    RATE_OF_TURN = 127251
    VESSEL_HEADING = 127250
    POSITION_RAPID_UPDATE = 129025
    COG_SOG_RAPID_UPDATE = 129026
    GNSS_POSITION_DATA = 129029
    NAVGW_GYRO_BIAS = 0xFF20
    NAVGW_ACCEL_BIAS = 0xFF21
    NAVGW_STATUS = 0xFF22


class IndustryGroup(IntEnum):
    """ISO 11783 / NMEA 2000 industry group (NAME bits 60-62, proprietary header bits 13-15)."""

    GLOBAL = 0
    ON_HIGHWAY = 1
    AGRICULTURE = 2
    CONSTRUCTION = 3
    MARINE = 4
    INDUSTRIAL = 5


@cache
def can_id(pgn: int, source: int, priority: int, destination: int = GLOBAL_ADDRESS) -> int:
    """The 29-bit id of a frame; ``destination`` is used only for PDU1 PGNs."""
    reserved, data_page, pdu_format, pdu_specific = j1939.pgn_unpack(pgn)
    if pdu_format < PDU2_MIN_FORMAT:
        pdu_specific = destination
    return int(j1939.frame_id_pack(priority, reserved, data_page, pdu_format, pdu_specific, source))


@dataclass(frozen=True, slots=True)
class FrameId:
    """The parts of a 29-bit id; ``destination`` is GLOBAL_ADDRESS for PDU2 PGNs."""

    priority: int
    pgn: int
    source: int
    destination: int

    @classmethod
    @cache
    def parse(cls, arbitration_id: int) -> FrameId:
        """Split a 29-bit id into priority, PGN (low byte 0 for PDU1), source, destination."""
        parts = j1939.frame_id_unpack(arbitration_id & 0x1FFFFFFF)
        pdu1 = parts.pdu_format < PDU2_MIN_FORMAT
        return cls(
            parts.priority,
            j1939.pgn_from_frame_id(arbitration_id & 0x1FFFFFFF),
            parts.source_address,
            parts.pdu_specific if pdu1 else GLOBAL_ADDRESS,
        )
