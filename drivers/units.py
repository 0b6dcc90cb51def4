"""Units and angles: named conversions, so that no module says DEG and means its inverse.

SI inside the product (ALGORITHMS.md); degrees, mg and per-root-hour figures only at the
edges (datasheet-style config keys, the bus's fields, printed summaries). The lowest layer,
so that drivers, estimation, the ISOBUS side and the simulator share one definition.
"""

from __future__ import annotations

import math
from typing import TypeVar

import numpy as np
import numpy.typing as npt

DEG_TO_RAD = math.pi / 180.0
RAD_TO_DEG = 180.0 / math.pi
GRAVITY_MPS2 = 9.80665  # standard gravity; ALGORITHMS.md: g = [0, 0, +9.80665] in NED
MG_MPS2 = GRAVITY_MPS2 * 1e-3  # one milli-g
SECONDS_PER_DAY = 86400.0
SQRT_SECONDS_PER_HOUR = 60.0  # a datasheet's x/sqrt(h) is x/60 per sqrt(s)

Angle = TypeVar("Angle", float, npt.NDArray[np.float64])


def wrap_pi(angle_rad: Angle) -> Angle:
    """Angle(s) wrapped to [-pi, pi); a float stays a float, an array an array."""
    return (angle_rad + math.pi) % (2.0 * math.pi) - math.pi
