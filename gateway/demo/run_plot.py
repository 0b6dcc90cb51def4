"""One picture of a run, from its output log alone (``navgw plot``, and the demo's PNG).

Panels, each titled (:data:`TITLES`): the reference point's track on a local map (metres
east and north of its first position) coloured by fix quality; mode and fix quality over
time as bands; roll and pitch; heading; gyro and accelerometer bias estimates with the times
the convergence flags rose; each output's rate against its configured one. With the
simulator's truth: the truth on the bias panels (dashed), the attitude error and the
reference point's horizontal error, computed by :mod:`gateway.demo.accuracy` as the
benchmark's numbers are. Time is seconds from the log's first frame, so alignment is in.

Drawn on a bare :class:`matplotlib.figure.Figure` (no pyplot state); matplotlib is the
``plots`` extra, imported only by this module.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.typing import HashableList

from drivers.units import RAD_TO_DEG
from gateway.demo.accuracy import attitude_error_rad, horizontal_error_m, truth_at
from gateway.estimation.geodesy import horizontal_ned
from gateway.isobus.j1939 import Pgn
from gateway.isobus.output_scheduler import DEFAULT_RATES_HZ
from gateway.readback.run_series import Array, RunSeries
from sim_bus.truth import Truth

TITLES = {
    "track": "Reference point track, coloured by fix quality",
    "bands": "Mode and fix quality",
    "attitude": "Roll and pitch",
    "heading": "Heading",
    "gyro": "Gyro bias estimate (| convergence flag rose)",
    "accel": "Accelerometer bias estimate (| convergence flag rose)",
    "rates": "Output rates against their configured rates",
    "attitude_error": "Attitude error (estimate - truth)",
    "position_error": "Reference point horizontal error (estimate - truth)",
}
MODE_COLOURS = {
    "INITIALISING": "0.75",
    "ALIGNING": "gold",
    "NAVIGATING": "tab:green",
    "COASTING": "tab:orange",
    "DEGRADED": "tab:pink",
    "FAULT": "tab:red",
}
FIX_COLOURS = {
    "RTK_FIXED": "tab:blue",
    "RTK_FLOAT": "tab:cyan",
    "DGNSS": "tab:purple",
    "GNSS": "tab:brown",
    "PPS": "tab:olive",
    "DEAD_RECKONING": "darkorange",
    "NONE": "tab:red",
}
OTHER_COLOUR = "0.4"
RATE_BIN_S = 5.0
TRUTH_STEP = 20  # truth rows are IMU samples (~205 Hz): every 20th is plenty to draw
TRACK_POINTS = 5000  # the track is decimated to at most this many points
ERROR_LIMIT_DEG = 3.0  # attitude error axis: alignment may start far off
STATUS = "NAVGW_STATUS"


def _text(name: str) -> str:
    return name.lower().replace("_", " ")


def run_figure(run: RunSeries, truth: Truth | None = None) -> Figure:
    """The figure of ``run`` (with the errors against ``truth`` if given)."""
    mosaic: list[HashableList[str]] = [
        ["track", "bands"],
        ["track", "attitude"],
        ["track", "heading"],
        ["rates", "gyro"],
        ["rates", "accel"],
    ]
    heights = [0.4, 1.0, 1.0, 1.0, 1.0]
    if truth is not None:
        mosaic.append(["position_error", "attitude_error"])
        heights.append(1.0)
    fig = Figure(figsize=(16, 3 * sum(heights)), layout="constrained")
    axes = fig.subplot_mosaic(mosaic, height_ratios=heights)
    for key in ("bands", "heading", "gyro", "accel", "rates", *(("attitude_error",
                "position_error") if truth is not None else ())):  # fmt: skip
        axes[key].sharex(axes["attitude"])
    for key, ax in axes.items():
        ax.set_title(TITLES[key], loc="left", fontsize="medium")
        ax.grid(True, alpha=0.3)
    _track(axes["track"], run)
    _bands(axes["bands"], run)
    _attitude(axes["attitude"], axes["heading"], run)
    _biases(axes["gyro"], axes["accel"], run, truth)
    _rates(axes["rates"], run)
    if truth is not None:
        _errors(axes["attitude_error"], axes["position_error"], run, truth)
    for key in ("accel", "attitude_error", "position_error", "rates"):
        if key in axes:
            axes[key].set_xlabel(f"time from the first frame, s (t0 {run.t0:.3f})")
    fig.suptitle(
        f"navgw run {run.path.name}: source 0x{run.source:02X}, {run.t_end - run.t0:.0f} s, "
        f"{run.stats.decoded} messages ({run.stats.unknown} unknown, "
        f"{run.stats.malformed} malformed frames)"
    )
    return fig


def save_run_plot(run: RunSeries, path: str | Path, truth: Truth | None = None) -> Path:
    """Write :func:`run_figure` as an image (PNG by the name); returns the path."""
    path = Path(path)
    run_figure(run, truth).savefig(path, dpi=80)
    return path


def _fix_at(run: RunSeries, t: Array) -> list[str]:
    """The fix quality NAVGW_STATUS said last before each ``t`` (``n/a`` before any)."""
    status_t, fix = run.times(STATUS), run.labels(STATUS, "FIX_QUALITY")
    index = np.searchsorted(status_t, t, side="right") - 1
    return [fix[i] if i >= 0 else "n/a" for i in index]


def _track(ax: Axes, run: RunSeries) -> None:
    t = run.times("POSITION_RAPID_UPDATE")
    lat = run.numbers("POSITION_RAPID_UPDATE", "LATITUDE")
    lon = run.numbers("POSITION_RAPID_UPDATE", "LONGITUDE")
    ok = np.isfinite(lat) & np.isfinite(lon)
    step = max(1, int(np.count_nonzero(ok)) // TRACK_POINTS)
    t, lat, lon = t[ok][::step], lat[ok][::step], lon[ok][::step]
    ax.set_xlabel("east, m")
    ax.set_ylabel("north, m")
    ax.set_aspect("equal", adjustable="datalim")
    if not len(t):
        ax.text(0.5, 0.5, "no position sent", transform=ax.transAxes, ha="center")
        return
    ned = horizontal_ned(np.column_stack([lat, lon]), (lat[0], lon[0], 0.0))
    fix = np.array(_fix_at(run, t))
    for name in dict.fromkeys(fix):
        mine = fix == name
        ax.scatter(ned[mine, 1], ned[mine, 0], s=3, color=FIX_COLOURS.get(name, OTHER_COLOUR),
                   label=_text(name))  # fmt: skip
    ax.plot(ned[0, 1], ned[0, 0], "k^", label="start")
    ax.legend(loc="best", fontsize="small", markerscale=3)


def _bands(ax: Axes, run: RunSeries) -> None:
    t = run.times(STATUS) - run.t0
    rows = (("fix", "FIX_QUALITY", FIX_COLOURS), ("mode", "MODE", MODE_COLOURS))
    for row, (what, signal, colours) in enumerate(rows):
        labels = run.labels(STATUS, signal)
        for name, start, end in _runs(t, labels, run.t_end - run.t0):
            ax.broken_barh([(start, end - start)], (row + 0.1, 0.8),
                           color=colours.get(name, OTHER_COLOUR),
                           label=f"{what}: {_text(name)}")  # fmt: skip
    handles, names = ax.get_legend_handles_labels()
    unique = dict(zip(names, handles, strict=True))
    ax.legend(unique.values(), unique.keys(), loc="upper left", bbox_to_anchor=(1.0, 1.3),
              fontsize="x-small", frameon=False)  # fmt: skip
    ax.set_yticks([0.5, 1.5], ["fix", "mode"])
    ax.set_ylim(0, 2)


def _runs(t: Array, labels: list[str], t_end: float) -> list[tuple[str, float, float]]:
    """(label, start, end) of each stretch of equal labels; the last one ends at ``t_end``."""
    out: list[tuple[str, float, float]] = []
    for i, label in enumerate(labels):
        if out and out[-1][0] == label:
            continue
        if out:
            out[-1] = (out[-1][0], out[-1][1], float(t[i]))
        out.append((label, float(t[i]), t_end))
    return out


def _attitude(ax: Axes, heading_ax: Axes, run: RunSeries) -> None:
    t = run.times("ATTITUDE") - run.t0
    for signal in ("ROLL", "PITCH"):
        ax.plot(t, run.numbers("ATTITUDE", signal) * RAD_TO_DEG, lw=0.8, label=_text(signal))
    ax.set_ylabel("deg")
    ax.legend(loc="upper right", fontsize="small")
    heading_t = run.times("VESSEL_HEADING") - run.t0
    heading = run.numbers("VESSEL_HEADING", "HEADING") * RAD_TO_DEG
    heading_ax.plot(heading_t, heading, ".", ms=1, color="tab:blue")
    heading_ax.set_ylabel("deg, true")
    heading_ax.set_ylim(0, 360)


def _biases(gyro_ax: Axes, accel_ax: Axes, run: RunSeries, truth: Truth | None) -> None:
    for ax, message, prefix, flags, unit, column, scale in (
        (gyro_ax, "NAVGW_GYRO_BIAS", "GYRO_BIAS_", ("GYRO_XY_CONVERGED", "GYRO_Z_CONVERGED"),
         "deg/s", "bias_g_rps", RAD_TO_DEG),
        (accel_ax, "NAVGW_ACCEL_BIAS", "ACCEL_BIAS_", ("ACCEL_XY_CONVERGED",), "m/s^2",
         "bias_a_mps2", 1.0),
    ):  # fmt: skip
        t = run.times(message) - run.t0
        for i, axis in enumerate("xyz"):
            (line,) = ax.plot(t, run.numbers(message, prefix + axis.upper()), label=axis)
            if truth is not None:  # over the log's span only (a demo plays part of a run)
                first, last = np.searchsorted(truth.t, (run.t0, run.t_end))
                rows = slice(int(first), int(last), TRUTH_STEP)
                true = getattr(truth, column)[rows, i] * scale
                ax.plot(truth.t[rows] - run.t0, true, "--", lw=0.8, color=line.get_color())
        for flag in flags:
            for rise in _rises(run, flag):
                ax.axvline(rise, color="k", lw=0.8, ls=":")
                ax.annotate(_text(flag), (rise, 1.0), xycoords=("data", "axes fraction"),
                            fontsize="x-small", rotation=90, va="top")  # fmt: skip
        ax.set_ylabel(unit)
        ax.legend(loc="upper right", fontsize="small")


def _rises(run: RunSeries, flag: str) -> Array:
    """Times (from t0) at which a NAVGW_STATUS flag went from 0 to 1."""
    t = run.times(STATUS) - run.t0
    value = np.nan_to_num(run.numbers(STATUS, flag)) > 0
    up = np.flatnonzero(value[1:] & ~value[:-1]) + 1
    return np.concatenate([t[:1] if len(value) and value[0] else t[:0], t[up]])


def _rates(ax: Axes, run: RunSeries) -> None:
    edges = np.arange(0.0, run.t_end - run.t0, RATE_BIN_S)  # whole bins only
    for name, series in run.messages.items():
        if series.pgn not in DEFAULT_RATES_HZ or len(edges) < 2:
            continue
        counts, _ = np.histogram(np.asarray(series.t) - run.t0, edges)
        configured = DEFAULT_RATES_HZ[Pgn(series.pgn)]
        ax.step(edges[:-1], 100.0 * counts / RATE_BIN_S / configured, where="post", lw=0.9,
                label=f"{_text(name)} ({configured:g} Hz)")  # fmt: skip
    ax.axhline(100.0, color="k", ls=":", lw=0.8)
    ax.set_ylim(0, 150)
    ax.set_ylabel(f"% of configured, {RATE_BIN_S:g} s bins")
    ax.legend(loc="lower right", fontsize="x-small", ncols=2)


def _errors(att_ax: Axes, pos_ax: Axes, run: RunSeries, truth: Truth) -> None:
    t = run.times("ATTITUDE")
    rpy = np.column_stack(
        [run.numbers("ATTITUDE", s) for s in ("ROLL", "PITCH", "YAW")]
    )  # fmt: skip
    err = attitude_error_rad(rpy, truth_at(truth, t).rpy_rad) * RAD_TO_DEG
    for i, name in enumerate(("roll", "pitch", "heading")):
        att_ax.plot(t - run.t0, err[:, i], lw=0.8, label=name)
    att_ax.set_ylim(-ERROR_LIMIT_DEG, ERROR_LIMIT_DEG)
    att_ax.set_ylabel("deg")
    att_ax.legend(loc="upper right", fontsize="small")
    t = run.times("POSITION_RAPID_UPDATE")
    lat = run.numbers("POSITION_RAPID_UPDATE", "LATITUDE")
    lon = run.numbers("POSITION_RAPID_UPDATE", "LONGITUDE")
    ne = horizontal_ned(np.column_stack([lat, lon]), truth.origin_lla)
    pos_ax.plot(t - run.t0, horizontal_error_m(ne, truth_at(truth, t).pos_ned_m[:, :2]), lw=0.8)
    pos_ax.set_ylabel("m")
