"""``navgw plot``: a replayed simulated run drawn in one figure; its panels, their data, and the
errors against truth; bad inputs end with a message."""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np
import pytest
from matplotlib.axes import Axes
from matplotlib.collections import PathCollection

from drivers.logs.candump import read_candump
from drivers.units import RAD_TO_DEG
from gateway.cli.main import main
from gateway.demo.run_plot import TITLES, run_figure
from gateway.estimation.geodesy import lla_to_ned
from gateway.readback.run_series import read_run
from sim_bus.truth import Truth
from tests.output_run import OutputRun, make_output_run

NOT_AVAILABLE = 0x7FFFFFFF


@pytest.fixture(scope="module")
def run(tmp_path_factory: pytest.TempPathFactory) -> OutputRun:
    return make_output_run(tmp_path_factory.mktemp("plot"))


def panels(fig: object) -> dict[str, Axes]:
    axes = fig.axes  # type: ignore[attr-defined]
    by_title = {ax.get_title(loc="left"): ax for ax in axes}
    return {key: by_title[title] for key, title in TITLES.items() if title in by_title}


def positions(log: Path) -> np.ndarray:
    """(n, 2) latitude, longitude of every 129025 frame that has one, by hand (int32, 1e-7
    deg; 0x7FFFFFFF not available)."""
    rows = [
        struct.unpack("<2i", bytes(m.data))
        for m in read_candump(log)
        if (m.arbitration_id >> 8) & 0x3FFFF == 129025
    ]
    return np.array([r for r in rows if NOT_AVAILABLE not in r], dtype=float) * 1e-7


def test_navgw_plot_writes_the_png(run: OutputRun, tmp_path: Path) -> None:
    out = tmp_path / "run.png"
    assert main(["plot", str(run.log), "--truth", str(run.truth), "--out", str(out)]) == 0
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and out.stat().st_size > 50_000


def test_the_panels_hold_the_run(run: OutputRun) -> None:
    series = read_run(run.log)
    truth = Truth.load(run.truth)
    fig = run_figure(series, truth)
    axes = panels(fig)
    assert set(axes) == set(TITLES)  # every panel, errors included
    span = series.t_end - series.t0
    assert span == pytest.approx(truth.t[-1] - truth.t[0], abs=0.5)

    # the track: every position, metres from the first, coloured by fix quality
    lat_lon = positions(run.log)
    ned = lla_to_ned(np.column_stack([lat_lon, np.zeros(len(lat_lon))]), [*lat_lon[0], 0.0])
    track = axes["track"]
    dots = [c for c in track.collections if isinstance(c, PathCollection)]
    xy = np.concatenate([c.get_offsets() for c in dots])
    assert len(xy) == len(lat_lon)
    assert xy[:, 0].min() == pytest.approx(ned[:, 1].min(), abs=1e-6)  # east
    assert xy[:, 1].max() == pytest.approx(ned[:, 0].max(), abs=1e-6)  # north
    assert np.ptp(xy[:, 1]) > 40  # the short scenario's 50 m passes
    labels = {c.get_label() for c in dots}
    assert "rtk fixed" in labels

    # mode bands from the first frame: initialising, aligning, then navigating (the observer
    # aligns its heading on the last second's courses, within NAVIGATING's 1-sigma)
    bands = [str(c.get_label()) for c in axes["bands"].collections]
    modes = [b for b in bands if b.startswith("mode: ")]
    assert modes[:3] == ["mode: initialising", "mode: aligning", "mode: navigating"]
    start = np.asarray(axes["bands"].collections[0].get_paths()[0].vertices)[:, 0].min()
    assert start == pytest.approx(0.0, abs=0.5)

    # roll and pitch from the first attitude frame to the last, in degrees
    roll = axes["attitude"].get_lines()[0]
    t = np.asarray(roll.get_xdata())
    assert t[0] == pytest.approx(0.27, abs=0.3) and t[-1] == pytest.approx(span, abs=0.1)
    assert np.nanmax(np.abs(roll.get_ydata())) < 10
    assert np.nanmax(np.abs(roll.get_ydata())) == pytest.approx(
        np.nanmax(np.abs(series.numbers("ATTITUDE", "ROLL"))) * RAD_TO_DEG
    )

    # bias estimates (x, y, z) and the truth dashed; rates near 100 % of configured
    gyro = axes["gyro"].get_lines()
    assert [str(x.get_label()) for x in gyro if not str(x.get_label()).startswith("_")] == [
        "x", "y", "z",
    ]  # fmt: skip
    assert sum(line.get_linestyle() == "--" for line in gyro) == 3  # the truth of each
    rates = [line for line in axes["rates"].get_lines() if str(line.get_label()).endswith("Hz)")]
    assert len(rates) == 9
    for line in rates:
        steady = np.asarray(line.get_ydata())[2:]  # after the claim and the first bins
        assert np.all(np.abs(steady - 100) < 5), line.get_label()

    # errors against truth: small once navigating
    nav = t > 60
    for line in axes["attitude_error"].get_lines()[:2]:  # roll, pitch
        err = np.asarray(line.get_ydata())[nav]
        assert np.sqrt(np.nanmean(err**2)) < 0.5, line.get_label()
    (pos,) = axes["position_error"].get_lines()
    assert np.nanmax(np.asarray(pos.get_ydata())[np.asarray(pos.get_xdata()) > 60]) < 0.3


def test_the_truth_is_drawn_over_the_logs_span_only(run: OutputRun, tmp_path: Path) -> None:
    """A demo plays part of a simulated run: its plot ends where the log ends, not where the
    truth does."""
    lines = run.log.read_text().splitlines(keepends=True)
    t0 = float(lines[0].split(")")[0].strip("("))
    part = tmp_path / "first-40-s.log"
    part.write_text("".join(x for x in lines if float(x.split(")")[0].strip("(")) < t0 + 40.0))
    series = read_run(part)
    truth = Truth.load(run.truth)
    assert truth.t[-1] - series.t0 > 100.0  # the truth goes on well past the log
    for line in panels(run_figure(series, truth))["gyro"].get_lines():
        if line.get_linestyle() == "--":
            x = np.asarray(line.get_xdata())
            assert x[0] >= -0.1 and x[-1] <= series.t_end - series.t0 + 0.1


def test_without_truth_no_error_panels(run: OutputRun) -> None:
    axes = panels(run_figure(read_run(run.log)))
    assert set(axes) == set(TITLES) - {"attitude_error", "position_error"}


@pytest.mark.parametrize(
    ("case", "message"),
    [
        ("missing", "nowhere.log: No such file or directory"),
        ("imu", "no navigation output"),
        ("truth", "not a simulator truth file"),
        ("format", "--out"),
    ],
)
def test_bad_input_says_what_and_exits_1(
    case: str, message: str, run: OutputRun, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    argv = {
        "missing": [str(tmp_path / "nowhere.log")],
        "imu": [str(run.directory / "imu.log")],  # the IMU bridge's frames, not navgw's
        "truth": [str(run.log), "--truth", str(run.log)],
        "format": [str(run.log), "--out", str(tmp_path / "run.nope")],
    }[case]
    assert main(["plot", *argv]) == 1
    err = capsys.readouterr().err
    assert err.startswith("navgw plot: ") and message in err and "Traceback" not in err
