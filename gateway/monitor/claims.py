"""Address claims seen on a bus (PGN 60928): who holds which address, NAMEs decoded.

The NAME's fields are the DBC message ADDRESS_CLAIM's signals (the layout of
:class:`gateway.isobus.address_claim.Name`). A NAME holds one address at a time, so a claim
moves its NAME: the entry of its old address goes. A claim from the null address 254 is a
cannot-claim: the node found no free address.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum

import cantools

from gateway.isobus.address_claim import DeviceClass, NameFunction
from gateway.isobus.j1939 import NULL_ADDRESS, IndustryGroup
from gateway.readback.frame_decoder import Decoded


@dataclass(frozen=True, slots=True)
class Claim:
    """The last claim of one address: the NAME's fields (raw DBC values), its 64-bit value
    (lower wins an address) and when it was heard."""

    address: int
    fields: dict[str, int]
    value: int
    t: float

    @property
    def cannot_claim(self) -> bool:
        """Sent from the null address: the node has no address."""
        return self.address == NULL_ADDRESS

    def describe(self) -> str:
        """The NAME in words, e.g. ``identity 1, manufacturer 2046, function 145 ownship
        position gnss, class 60 navigation, agriculture, self-configurable``."""
        f = self.fields
        instances = (
            f", function instance {f['FUNCTION_INSTANCE']}, ECU instance {f['ECU_INSTANCE']}"
            if f["FUNCTION_INSTANCE"] or f["ECU_INSTANCE"]
            else ""
        )
        return (
            f"identity {f['IDENTITY_NUMBER']}, manufacturer {f['MANUFACTURER_CODE']}, "
            f"function {_word(NameFunction, f['FUNCTION'])}, "
            f"class {_word(DeviceClass, f['VEHICLE_SYSTEM'])}{instances}, "
            f"{_word(IndustryGroup, f['INDUSTRY_GROUP'], number=False)}"
            f"{', self-configurable' if f['ARBITRARY_ADDRESS_CAPABLE'] else ''}"
        )


def _word(enum: type[IntEnum], value: int, number: bool = True) -> str:
    """``value`` and, where ``enum`` names it, its name in words."""
    try:
        word = enum(value).name.lower().replace("_", " ")
    except ValueError:
        return str(value)
    return f"{value} {word}" if number else word


class ClaimTable:
    """Address -> the last claim heard for it."""

    def __init__(self, database: cantools.database.can.Database) -> None:
        self._message = database.get_message_by_name("ADDRESS_CLAIM")
        self.by_address: dict[int, Claim] = {}

    def on_claim(self, decoded: Decoded) -> Claim:
        """Record a decoded ADDRESS_CLAIM message; the claim it makes."""
        raw = self._message.decode(decoded.data, decode_choices=False)
        assert isinstance(raw, dict)
        claim = Claim(
            decoded.frame_id.source,
            {signal: int(value) for signal, value in raw.items() if isinstance(value, int | float)},
            int.from_bytes(decoded.data[:8], "little"),
            decoded.t,
        )
        for address, old in list(self.by_address.items()):
            if old.value == claim.value:
                del self.by_address[address]
        self.by_address[claim.address] = claim
        return claim
