"""``navgw fleet --plot``: the main figures' distributions across recordings, one panel each.

One histogram per figure of :data:`PANELS`, one colour per engine, from the rows without an
error. Drawn on a bare :class:`matplotlib.figure.Figure` (no pyplot state); matplotlib is the
``plots`` extra, imported only by this module.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

from matplotlib.figure import Figure

from gateway.fleet.rows import FleetRow

#: FleetRow field -> panel title.
PANELS = {
    "navigating_s": "time navigating (s)",
    "gyro_z_converged_s": "gyro z bias converged after (s)",
    "accel_xy_converged_s": "accel xy bias converged after (s)",
    "gyro_bias_z_dps": "final gyro z bias (deg/s)",
    "accel_bias_x_mps2": "final accel x bias (m/s^2)",
    "imu_lost": "IMU samples lost",
    "fix_rtk_fixed_share": "share of fixes RTK fixed",
    "heading_rms_diff_deg": "heading RMS difference between engines (deg)",
    "temp_max_c": "highest IMU temperature (deg C)",
}
BINS = 20


def save_histograms(rows: Sequence[FleetRow], path: Path) -> Path:
    """Write the figure of ``rows`` as an image (PNG by the name); returns the path."""
    figure = Figure(figsize=(12, 9), layout="constrained")
    axes = figure.subplots(3, 3).ravel()
    engines = sorted({row.engine for row in rows if row.error is None})
    for ax, (field, title) in zip(axes, PANELS.items(), strict=True):
        for engine in engines:
            values = [
                float(v)
                for row in rows
                if row.engine == engine and row.error is None
                if isinstance(v := getattr(row, field), int | float) and math.isfinite(v)
            ]
            if values:
                ax.hist(values, bins=BINS, alpha=0.6, label=engine)
        ax.set_title(title, fontsize="medium")
        ax.set_ylabel("recordings")
    axes[0].legend(fontsize="small")
    figure.suptitle(f"navgw fleet: {len({row.recording for row in rows})} recordings")
    figure.savefig(path, dpi=80)
    return path
