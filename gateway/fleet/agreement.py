"""How far two engines' attitudes are apart over one recording, from their output logs.

Both replays are driven by the same inputs, so their ATTITUDE frames share their times; the
second engine's values are still interpolated onto the first's times, so that a frame one
withheld (the output guard) does not shift the pairing. Only instants where both sent a
value count (the second's within :data:`MAX_GAP_S` on both sides); heading differences are
wrapped to +-180 deg.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from drivers.units import RAD_TO_DEG, wrap_pi
from gateway.readback.run_series import RunSeries

ATTITUDE = "ATTITUDE"
SIGNALS = ("ROLL", "PITCH", "YAW")
#: Longest stretch (s) of the second run's values interpolated over: five 50 Hz periods.
MAX_GAP_S = 0.1


@dataclass(frozen=True)
class AttitudeAgreement:
    """RMS of the roll, pitch and heading differences (deg); NaN with no common instant."""

    roll_rms_diff_deg: float
    pitch_rms_diff_deg: float
    heading_rms_diff_deg: float


def attitude_agreement(a: RunSeries, b: RunSeries) -> AttitudeAgreement:
    """RMS attitude difference of run ``b`` from run ``a`` over ``a``'s ATTITUDE times
    within ``b``'s."""
    t_a, t_b = a.times(ATTITUDE), b.times(ATTITUDE)
    rms = []
    for signal in SIGNALS:
        x_a, x_b = a.numbers(ATTITUDE, signal), b.numbers(ATTITUDE, signal)
        ok_b = np.isfinite(x_b)
        if ok_b.sum() < 2:
            rms.append(math.nan)
            continue
        t_ok = t_b[ok_b]
        after = np.clip(np.searchsorted(t_ok, t_a), 1, len(t_ok) - 1)
        inside = (
            np.isfinite(x_a)
            & (t_a >= t_ok[0])
            & (t_a <= t_ok[-1])
            & (t_ok[after] - t_ok[after - 1] <= MAX_GAP_S)
        )
        # unwrap before interpolating so that yaw's +-pi jump is not averaged through
        on_a = np.interp(t_a[inside], t_ok, np.unwrap(x_b[ok_b]))
        diff = np.asarray(wrap_pi(x_a[inside] - on_a))
        rms.append(float(np.sqrt(np.mean(diff**2))) * RAD_TO_DEG if len(diff) else math.nan)
    return AttitudeAgreement(*rms)
