"""DBC files: the single source of truth for every frame layout navgw reads or writes.

``load("navgw_imu.dbc")`` returns a cantools database; frames match by their PGN only
(``frame_id_mask=0x03FFFF00``), so the priority and source address of a frame may differ
from the defaults written in the file.
"""

from __future__ import annotations

from functools import cache
from importlib import resources
from pathlib import Path

import cantools

IMU_DBC = "navgw_imu.dbc"
OUTPUT_DBC = "navgw_output.dbc"
#: Reassembled payloads of the multi-frame (fast-packet) PGNs, under their frames' ids: a
#: DBC holds one message per id, and OUTPUT_DBC describes those frames one by one.
OUTPUT_PAYLOADS_DBC = "navgw_output_payloads.dbc"

#: Mask that keeps only the PGN part (data page and PDU format/specific) of a 29-bit J1939 id.
PGN_MASK = 0x03FFFF00


def path(name: str) -> Path:
    """Filesystem path of a DBC file shipped with the package."""
    return Path(str(resources.files(__name__).joinpath(name)))


@cache
def load(name: str) -> cantools.database.can.Database:
    """Load (once) a shipped DBC file, matching frames by PGN regardless of priority and SA."""
    db = cantools.database.load_file(path(name), frame_id_mask=PGN_MASK)
    assert isinstance(db, cantools.database.can.Database), f"{name} is not a CAN database"
    return db
