"""One table row per recording and engine: what replay counted and what its output log says.

Counts come from the :class:`~gateway.offline.log_replay.ReplaySummary`, fix qualities and
temperatures from the :class:`~gateway.fleet.input_tally.InputTally`, and the navigation
figures from the output log read back (:func:`gateway.readback.run_series.read_run`), as a
person would read them off the bus: NAVGW_STATUS's mode and convergence flags, the bias
frames, each output's rate. Times are seconds from the recording's first input. A recording
that could not be replayed is a row with ``error`` set and every figure None.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from drivers.samples import FixQuality
from gateway.fleet.input_tally import InputTally
from gateway.offline.log_replay import ReplaySummary
from gateway.readback.run_series import RunSeries

#: The window (s) at the end of a run over which the bias estimates' spread is taken.
FINAL_WINDOW_S = 60.0
STATUS = "NAVGW_STATUS"
MODES = ("INITIALISING", "ALIGNING", "NAVIGATING", "COASTING", "DEGRADED", "FAULT")
#: Output messages whose rates are columns (``rate_<name>_hz``), SPEC 4's periodic set.
RATED = (
    "ATTITUDE",
    "RATE_OF_TURN",
    "VESSEL_HEADING",
    "POSITION_RAPID_UPDATE",
    "COG_SOG_RAPID_UPDATE",
    "GNSS_POSITION_DATA",
    "NAVGW_GYRO_BIAS",
    "NAVGW_ACCEL_BIAS",
    "NAVGW_STATUS",
)


@dataclass(frozen=True)
class FleetRow:
    """One recording replayed with one engine. Units are in the names; None: not measured."""

    recording: str
    engine: str
    parts: int  # rotated file pairs joined
    error: str | None = None  # why the recording could not be replayed
    # what replay read (ReplaySummary)
    duration_s: float | None = None  # log time from the first input to the last
    wall_s: float | None = None
    imu_samples: int | None = None
    imu_lost: int | None = None
    imu_duplicates: int | None = None
    imu_out_of_order: int | None = None
    imu_malformed_frames: int | None = None
    bad_can_lines: int | None = None
    gnss_fixes: int | None = None
    nmea_checksum_errors: int | None = None
    nmea_parse_errors: int | None = None
    nmea_junk_bytes: int | None = None
    bad_nmea_lines: int | None = None
    engine_restarts: int | None = None
    frames_out: int | None = None
    # the inputs (InputTally): shares of the GNSS fixes by quality, IMU temperature
    fix_rtk_fixed_share: float | None = None
    fix_rtk_float_share: float | None = None
    fix_dgnss_share: float | None = None
    fix_single_share: float | None = None
    fix_none_share: float | None = None
    fix_other_share: float | None = None  # PPS, dead reckoning, manual, simulation
    temp_min_c: float | None = None
    temp_max_c: float | None = None
    # the output log: time in each NAVGW_STATUS mode
    initialising_s: float | None = None
    aligning_s: float | None = None
    navigating_s: float | None = None
    coasting_s: float | None = None
    degraded_s: float | None = None
    fault_s: float | None = None
    # first time each convergence flag was set (None: never)
    gyro_xy_converged_s: float | None = None
    gyro_z_converged_s: float | None = None
    accel_xy_converged_s: float | None = None
    # the last bias estimates sent, and their standard deviation over the last FINAL_WINDOW_S
    gyro_bias_x_dps: float | None = None
    gyro_bias_y_dps: float | None = None
    gyro_bias_z_dps: float | None = None
    accel_bias_x_mps2: float | None = None
    accel_bias_y_mps2: float | None = None
    accel_bias_z_mps2: float | None = None
    gyro_bias_x_spread_dps: float | None = None
    gyro_bias_y_spread_dps: float | None = None
    gyro_bias_z_spread_dps: float | None = None
    accel_bias_x_spread_mps2: float | None = None
    accel_bias_y_spread_mps2: float | None = None
    accel_bias_z_spread_mps2: float | None = None
    # messages per second over the run
    rate_attitude_hz: float | None = None
    rate_rate_of_turn_hz: float | None = None
    rate_vessel_heading_hz: float | None = None
    rate_position_rapid_update_hz: float | None = None
    rate_cog_sog_rapid_update_hz: float | None = None
    rate_gnss_position_data_hz: float | None = None
    rate_navgw_gyro_bias_hz: float | None = None
    rate_navgw_accel_bias_hz: float | None = None
    rate_navgw_status_hz: float | None = None
    # RMS difference of this engine's attitude from the other's (--engine both only)
    roll_rms_diff_deg: float | None = None
    pitch_rms_diff_deg: float | None = None
    heading_rms_diff_deg: float | None = None


def error_row(recording: str, engine: str, parts: int, error: str) -> FleetRow:
    """The row of a recording that could not be replayed."""
    return FleetRow(recording, engine, parts, error=error)


def measured_row(
    recording: str,
    engine: str,
    parts: int,
    summary: ReplaySummary,
    tally: InputTally,
    run: RunSeries,
) -> FleetRow:
    """The row of one replay: its summary, its inputs' tally and its output log."""
    imu, gnss, stats = summary.imu, summary.gnss, summary.stats
    other = set(FixQuality) - {
        FixQuality.RTK_FIXED, FixQuality.RTK_FLOAT, FixQuality.DGNSS, FixQuality.GNSS,
        FixQuality.NONE,
    }  # fmt: skip
    counted = FleetRow(
        recording,
        engine,
        parts,
        duration_s=summary.log_span_s,
        wall_s=summary.wall_s,
        imu_samples=stats.imu_samples,
        imu_lost=imu.lost,
        imu_duplicates=imu.duplicates,
        imu_out_of_order=imu.out_of_order,
        imu_malformed_frames=imu.malformed,
        bad_can_lines=summary.bad_can_lines,
        gnss_fixes=stats.gnss_fixes,
        nmea_checksum_errors=gnss.checksum_errors,
        nmea_parse_errors=gnss.parse_errors,
        nmea_junk_bytes=gnss.skipped_bytes,
        bad_nmea_lines=summary.bad_nmea_lines,
        engine_restarts=stats.engine_restarts,
        frames_out=stats.frames_out,
        fix_rtk_fixed_share=tally.share(FixQuality.RTK_FIXED),
        fix_rtk_float_share=tally.share(FixQuality.RTK_FLOAT),
        fix_dgnss_share=tally.share(FixQuality.DGNSS),
        fix_single_share=tally.share(FixQuality.GNSS),
        fix_none_share=tally.share(FixQuality.NONE),
        fix_other_share=tally.share(*other),
        temp_min_c=_finite(tally.temp_min_c),
        temp_max_c=_finite(tally.temp_max_c),
    )
    read_back: dict[str, Any] = {  # float | None each; the names are FleetRow fields
        **_mode_times(run),
        **_convergence(run),
        **_biases(run),
        **{f"rate_{name.lower()}_hz": _rate(run, name) for name in RATED},
    }
    return dataclasses.replace(counted, **read_back)


def _finite(x: float) -> float | None:
    return x if math.isfinite(x) else None


def _mode_times(run: RunSeries) -> dict[str, float | None]:
    """Seconds in each mode: a NAVGW_STATUS mode holds until the next one (the last until
    the log's end)."""
    t = run.times(STATUS)
    held = np.diff(np.append(t, run.t_end))
    modes = np.array(run.labels(STATUS, "MODE"))
    return {f"{mode.lower()}_s": float(held[modes == mode].sum()) for mode in MODES}


def _convergence(run: RunSeries) -> dict[str, float | None]:
    t = run.times(STATUS) - run.t0
    out: dict[str, float | None] = {}
    for flag in ("GYRO_XY", "GYRO_Z", "ACCEL_XY"):
        up = np.flatnonzero(np.nan_to_num(run.numbers(STATUS, f"{flag}_CONVERGED")) > 0)
        out[f"{flag.lower()}_converged_s"] = float(t[up[0]]) if len(up) else None
    return out


def _biases(run: RunSeries) -> dict[str, float | None]:
    out: dict[str, float | None] = {}
    for message, kind, unit in (
        ("NAVGW_GYRO_BIAS", "gyro", "dps"),
        ("NAVGW_ACCEL_BIAS", "accel", "mps2"),
    ):
        t = run.times(message)
        final = t >= run.t_end - FINAL_WINDOW_S
        for axis in "xyz":
            values = run.numbers(message, f"{kind.upper()}_BIAS_{axis.upper()}")
            window = values[final & np.isfinite(values)]
            out[f"{kind}_bias_{axis}_{unit}"] = _finite(float(values[-1])) if len(values) else None
            out[f"{kind}_bias_{axis}_spread_{unit}"] = (
                float(np.std(window)) if len(window) else None
            )
    return out


def _rate(run: RunSeries, name: str) -> float | None:
    span = run.t_end - run.t0
    return len(run.times(name)) / span if span > 0 else None
