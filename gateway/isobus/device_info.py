"""What navgw says about itself on the bus: NMEA 2000 device information, through the DBC.

Product Information (126996), Configuration Information (126998), PGN List (126464),
Heartbeat (126993) and the ISO Acknowledgement (59392), each encoded from its DBC message
(canboat's layouts) by :class:`~gateway.isobus.frame_codec.FrameCodec`; payloads longer than
8 bytes go out as fast-packet frames (their reassembled layouts are in the payloads DBC).

Text, as canboat reads it:

- STRING_FIX (126996's four 32-byte fields): ASCII, padded with 0xFF, the NMEA 2000 "unknown"
  that canboat and the ``nmea2000`` package take as the end of the string; an empty field is
  all 0xFF (unknown).
- STRING_LAU (126998): a length byte counting itself and the encoding byte, 1 (ASCII), the
  text. The payload ends after the last text, as the PGN list ends after its last PGN: the
  DBC describes the longest payload, and the bytes not used are not sent.

Fixed values: NMEA 2000 version 2.100 (the edition of the PGN layouts the frames follow, as
canboat's database has them; not a certification), certification level not available (navgw
is not NMEA certified), installation descriptions empty (no PGN 126208 writes are taken).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from enum import IntEnum

import can
import cantools

import dbc
from gateway.isobus.fast_packet import FastPacketFragmenter
from gateway.isobus.frame_codec import FrameCodec, Value
from gateway.isobus.j1939 import GLOBAL_ADDRESS, Pgn, can_id

TEXT_BYTES = 32  # canboat STRING_FIX length of each 126996 text, and our 126998 text limit
_CHUNK_BYTES = 4  # a text travels in 4-byte DBC signals NAME_1..NAME_8
STRING_FIX_PAD = 0xFF
NMEA2000_VERSION = 2.1  # 2.100, sent as 2100 (resolution 0.001)
HEARTBEAT_INTERVAL_S = 60.0  # NMEA 2000 standard interval of PGN 126993
SEQUENCE_MODULO = 253  # heartbeat sequence counter 0-252 (253-255 are special values)
LAU_HEADER_BYTES = 2  # STRING_LAU: length and encoding bytes
LAU_ASCII = 1
NO_GROUP_FUNCTION = 0xFF  # 59392 group function of an answer to a request
MANUFACTURER_INFORMATION = "navgw: GNSS/IMU ISOBUS gateway"
DEFAULT_PRODUCT_CODE = 1
DEFAULT_MODEL_ID = "navgw GNSS/IMU gateway"
DEFAULT_LOAD_EQUIVALENCY = 1  # 50 mA: over- rather than under-states the bus power drawn
#: Fast-packet PGNs go out as fast packets whatever their length: a receiver knows the framing
#: from the PGN (a PGN list of two entries is 7 bytes, still in fast-packet frames).
FAST_PACKET_PGNS = frozenset({Pgn.PRODUCT_INFORMATION, Pgn.CONFIGURATION_INFORMATION, Pgn.PGN_LIST})


class AckControl(IntEnum):
    """ISO Acknowledgement (59392) control byte (canboat ISO_CONTROL)."""

    ACK = 0
    NAK = 1
    ACCESS_DENIED = 2
    ADDRESS_BUSY = 3


class PgnListFunction(IntEnum):
    """PGN List (126464) function code (canboat PGN_LIST_FUNCTION)."""

    TRANSMIT = 0
    RECEIVE = 1


def text_problem(text: str) -> str | None:
    """What a text field cannot carry (None if fine): printable ASCII, at most 32 bytes."""
    if len(text) > TEXT_BYTES:
        return f"at most {TEXT_BYTES} characters"
    if not (text.isascii() and text.isprintable()):
        return "printable ASCII characters only"
    return None


@dataclass(frozen=True, slots=True)
class ProductInfo:
    """The 126996 fields an integrator sets; the rest are fixed (see the module docstring)."""

    product_code: int = DEFAULT_PRODUCT_CODE  # 0-65532, the manufacturer's number for it
    model_id: str = DEFAULT_MODEL_ID
    software_version: str = ""  # the navgw package version
    model_version: str = ""  # hardware version
    serial_code: str = ""  # the NAME identity number, in decimal
    load_equivalency: int = DEFAULT_LOAD_EQUIVALENCY  # units of 50 mA, 0-252

    def __post_init__(self) -> None:
        for name in ("model_id", "software_version", "model_version", "serial_code"):
            if problem := text_problem(getattr(self, name)):
                raise ValueError(f"product information {name}: {problem}")


def _text(prefix: str, text: str) -> dict[str, Value]:
    """A text as its DBC signals ``{prefix}_1..8``: ASCII, padded with 0xFF to 32 bytes."""
    raw = text.encode("ascii").ljust(TEXT_BYTES, bytes([STRING_FIX_PAD]))
    return {
        f"{prefix}_{i + 1}": int.from_bytes(raw[start : start + _CHUNK_BYTES], "little")
        for i, start in enumerate(range(0, TEXT_BYTES, _CHUNK_BYTES))
    }


class DeviceInfoEncoder:
    """Frames of the device-information PGNs for a source address; owns their fast-packet
    counters."""

    def __init__(
        self,
        product: ProductInfo,
        frames_db: cantools.database.can.Database | None = None,
        payloads_db: cantools.database.can.Database | None = None,
    ) -> None:
        frames = frames_db or dbc.load(dbc.OUTPUT_DBC)
        payloads = payloads_db or dbc.load(dbc.OUTPUT_PAYLOADS_DBC)
        self._codecs = {  # fast-packet payloads in the payloads DBC, single frames in the other
            pgn: FrameCodec(
                (payloads if pgn in FAST_PACKET_PGNS else frames).get_message_by_name(pgn.name)
            )
            for pgn in (*FAST_PACKET_PGNS, Pgn.HEARTBEAT, Pgn.ISO_ACKNOWLEDGEMENT)
        }
        self.max_pgns = sum(
            s.name.startswith("PGN_") for s in self._codecs[Pgn.PGN_LIST].message.signals
        )
        self._fragmenter = FastPacketFragmenter()
        self._product = {
            "NMEA2000_VERSION": NMEA2000_VERSION,
            "PRODUCT_CODE": product.product_code,
            **_text("MODEL_ID", product.model_id),
            **_text("SOFTWARE_VERSION", product.software_version),
            **_text("MODEL_VERSION", product.model_version),
            **_text("MODEL_SERIAL_CODE", product.serial_code),
            "CERTIFICATION_LEVEL": None,
            "LOAD_EQUIVALENCY": product.load_equivalency,
        }
        self._product_payload = self._codecs[Pgn.PRODUCT_INFORMATION].encode(self._product)

    def product_information(self, source: int, now: float) -> list[can.Message]:
        """126996 (fast packet, to global)."""
        return self._frames(Pgn.PRODUCT_INFORMATION, self._product_payload, source, now)

    def configuration_information(self, source: int, now: float) -> list[can.Message]:
        """126998 (fast packet, to global): no installation descriptions, our manufacturer
        information."""
        text = MANUFACTURER_INFORMATION
        values: dict[str, Value] = {
            "INSTALLATION_DESCRIPTION_1_LENGTH": LAU_HEADER_BYTES,
            "INSTALLATION_DESCRIPTION_1_ENCODING": LAU_ASCII,
            "INSTALLATION_DESCRIPTION_2_LENGTH": LAU_HEADER_BYTES,
            "INSTALLATION_DESCRIPTION_2_ENCODING": LAU_ASCII,
            "MANUFACTURER_INFORMATION_LENGTH": LAU_HEADER_BYTES + len(text),
            "MANUFACTURER_INFORMATION_ENCODING": LAU_ASCII,
            **_text("MANUFACTURER_INFORMATION", text),
        }
        payload = self._codecs[Pgn.CONFIGURATION_INFORMATION].encode(values)
        return self._frames(
            Pgn.CONFIGURATION_INFORMATION, payload[: 3 * LAU_HEADER_BYTES + len(text)], source, now
        )

    def pgn_list(
        self,
        function: PgnListFunction,
        pgns: Iterable[int],
        source: int,
        now: float,
        destination: int = GLOBAL_ADDRESS,
    ) -> list[can.Message]:
        """126464 (fast packet; PDU1, so ``destination`` counts)."""
        listed = list(pgns)
        if len(listed) > self.max_pgns:
            raise ValueError(f"a PGN list holds at most {self.max_pgns} PGNs, not {len(listed)}")
        values: dict[str, Value] = {"FUNCTION_CODE": function}
        # the unused entries are cut off below: their value does not matter
        values.update({f"PGN_{i + 1}": 0 for i in range(self.max_pgns)})
        values.update({f"PGN_{i + 1}": pgn for i, pgn in enumerate(listed)})
        payload = self._codecs[Pgn.PGN_LIST].encode(values)[: 1 + 3 * len(listed)]
        return self._frames(Pgn.PGN_LIST, payload, source, now, destination)

    def heartbeat(self, sequence: int, fault: bool, source: int, now: float) -> list[can.Message]:
        """126993: interval, sequence counter, controller states unknown to the core (the
        CAN controller's error state is not visible here), equipment status."""
        values: Mapping[str, Value] = {
            "DATA_TRANSMIT_OFFSET": HEARTBEAT_INTERVAL_S,
            "SEQUENCE_COUNTER": sequence % SEQUENCE_MODULO,
            "CONTROLLER_1_STATE": None,
            "CONTROLLER_2_STATE": None,
            "EQUIPMENT_STATUS": int(fault),
        }
        payload = self._codecs[Pgn.HEARTBEAT].encode(values)
        return self._frames(Pgn.HEARTBEAT, payload, source, now)

    def acknowledgement(
        self, control: AckControl, pgn: int, requester: int, source: int, now: float
    ) -> list[can.Message]:
        """59392 to global (J1939-21), naming the requester and the PGN requested."""
        values: Mapping[str, Value] = {
            "CONTROL": control,
            "GROUP_FUNCTION": NO_GROUP_FUNCTION,
            "ADDRESS": requester,
            "PGN": pgn,
        }
        payload = self._codecs[Pgn.ISO_ACKNOWLEDGEMENT].encode(values)
        return self._frames(Pgn.ISO_ACKNOWLEDGEMENT, payload, source, now)

    def _frames(
        self, pgn: Pgn, payload: bytes, source: int, now: float, destination: int = GLOBAL_ADDRESS
    ) -> list[can.Message]:
        priority = (self._codecs[pgn].message.frame_id >> 26) & 0x7
        arbitration_id = can_id(pgn, source, priority, destination)
        fast = pgn in FAST_PACKET_PGNS
        chunks = self._fragmenter.fragment(pgn, source, payload) if fast else [payload]
        return [
            can.Message(timestamp=now, arbitration_id=arbitration_id, is_extended_id=True, data=c)
            for c in chunks
        ]
