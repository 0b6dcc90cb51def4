"""Independent reading of the gateway's output: candump logs decoded by the nmea2000 package.

The package embeds canboat's PGN database, so these checks do not share code or DBC with
the encoders under test.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt
from nmea2000 import NMEA2000Decoder

from sim_bus.canlog import read_candump
from sim_bus.truth import Truth


@dataclass
class Decoded:
    """One decoded NMEA 2000 message: time of its (last) frame, canboat id, field values."""

    t: float
    pgn: int
    id: str
    fields: dict[str, object]


def decode_log(path: str | Path) -> list[Decoded]:
    """Every message of a candump log that canboat's database knows (fast packets joined)."""
    decoder = NMEA2000Decoder()
    out = []
    for frame in read_candump(path):
        message = decoder.decode(frame)
        if message is not None:
            fields = {f.id: f.value for f in message.fields}
            out.append(Decoded(frame.timestamp, message.PGN, message.id, fields))
    return out


def attitude_errors_deg(
    messages: list[Decoded], truth: Truth, after_s: float
) -> npt.NDArray[np.float64]:
    """(n, 3) roll, pitch, yaw errors in degrees of 127257 frames later than ``after_s``."""
    rows = [m for m in messages if m.id == "attitude" and m.t - truth.t[0] > after_s]
    t = np.array([m.t for m in rows])
    est = np.array(
        [[m.fields["roll"], m.fields["pitch"], m.fields["yaw"]] for m in rows], dtype=float
    )
    true = np.column_stack([np.interp(t, truth.t, truth.rpy_rad[:, i]) for i in range(3)])
    err = est - true
    err[:, 2] = (err[:, 2] + np.pi) % (2 * np.pi) - np.pi
    return np.degrees(err)


def position_errors_m(
    messages: list[Decoded], truth: Truth, after_s: float
) -> npt.NDArray[np.float64]:
    """Horizontal errors (m) of 129025 reference-point positions later than ``after_s``."""
    from gateway.geodesy import lla_to_ned

    rows = [m for m in messages if m.id == "positionRapidUpdate" and m.t - truth.t[0] > after_s]
    t = np.array([m.t for m in rows])
    lla = np.array([[m.fields["latitude"], m.fields["longitude"], 0.0] for m in rows], dtype=float)
    ned = lla_to_ned(lla, truth.origin_lla)
    true = np.column_stack([np.interp(t, truth.t, truth.pos_ned_m[:, i]) for i in range(2)])
    return np.hypot(*(ned[:, :2] - true).T)
