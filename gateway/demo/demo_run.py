"""``navgw demo`` without a command line: a simulated field run through the LIVE service.

The simulator writes a run (IMU CAN log, NMEA log, truth); :class:`~gateway.demo.playback.
SyncedPlayback` plays the IMU frames onto a python-can ``virtual`` bus and the sentences onto
a real pty, ``speed`` times faster than real time;
:class:`~gateway.service.live_loop.GatewayService`
runs in this process on a :class:`~gateway.service.timebase.TimeBase` of the same speed and sends
its
frames on a second virtual bus (the ISOBUS), which is recorded. Meanwhile the solution is
sampled (:class:`Trace`) for a live view and a summary against truth; at the end the output
log is drawn as ``navgw plot`` draws it (:mod:`gateway.demo.run_plot`).
"""

from __future__ import annotations

import asyncio
import math
import os
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import can
import numpy as np
import numpy.typing as npt

from drivers.errors import InputError
from drivers.logs.candump import CandumpWriter
from drivers.units import RAD_TO_DEG
from gateway.config.gateway_config import (
    GatewayConfig,
    GnssSection,
    ImuSection,
    IsobusSection,
    StateSection,
    VehicleSection,
)
from gateway.demo.accuracy import TruthAt, attitude_error_rad, truth_at
from gateway.demo.playback import SyncedPlayback
from gateway.estimation.geodesy import horizontal_ned
from gateway.estimation.solution import Mode, Solution
from gateway.readback.run_series import read_run
from gateway.service.live_loop import GatewayService
from gateway.service.timebase import TimeBase
from sim_bus.scenarios import SCENARIOS, generate
from sim_bus.truth import Truth

Array = npt.NDArray[np.float64]

DEFAULT_SCENARIO = "field"
DEFAULT_MINUTES = 6.0  # long enough for the gyro and accelerometer biases to converge
DEFAULT_SPEED = 8.0  # 6 min in 45 s; faster magnifies the host's scheduling jitter more
#: The simulated receiver: ~40 ms latency plus the serial transmission of an epoch.
RECEIVER_LATENCY_S = 0.065
TRACE_HZ = 5.0  # solution samples per simulated second
SETTLE_S = 30.0  # after the first NAVIGATING, before errors count as "after alignment"
START_LEAD_S = 0.5  # wall time for the service to open its buses and port before playing
VIEW_S = 0.5  # live view refresh, wall seconds
OUTPUT_LOG = "navgw-output.log"
PLOT_FILE = "navgw-demo.png"


@dataclass(frozen=True)
class DemoOptions:
    """What to simulate and how fast; ``minutes`` None plays the whole scenario."""

    out_dir: Path = Path("navgw-demo")
    scenario: str = DEFAULT_SCENARIO
    seed: int = 0
    speed: float = DEFAULT_SPEED
    minutes: float | None = DEFAULT_MINUTES


@dataclass
class Trace:
    """The solution sampled at TRACE_HZ of simulated time, with the truth at the same times."""

    t: list[float] = field(default_factory=list)
    mode: list[Mode] = field(default_factory=list)
    rpy_rad: list[tuple[float, float, float]] = field(default_factory=list)
    bias_g_rps: list[Array] = field(default_factory=list)
    bias_a_mps2: list[Array] = field(default_factory=list)
    ne_m: list[tuple[float, float]] = field(default_factory=list)

    def add(self, sol: Solution, origin_lla: Array) -> None:
        """Append one solution that has attitude, biases and position."""
        if (
            sol.roll_rad is None
            or sol.pitch_rad is None
            or sol.yaw_rad is None
            or sol.bias_g_rps is None
            or sol.bias_a_mps2 is None
            or sol.lat_deg is None
            or sol.lon_deg is None
        ):
            return
        self.t.append(sol.t)
        self.mode.append(sol.mode)
        self.rpy_rad.append((sol.roll_rad, sol.pitch_rad, sol.yaw_rad))
        self.bias_g_rps.append(np.asarray(sol.bias_g_rps, dtype=float))
        self.bias_a_mps2.append(np.asarray(sol.bias_a_mps2, dtype=float))
        ne = horizontal_ned((sol.lat_deg, sol.lon_deg), origin_lla)
        self.ne_m.append((float(ne[0]), float(ne[1])))


@dataclass(frozen=True)
class DemoSummary:
    """The numbers the demo ends with."""

    wall_s: float
    sim_s: float
    imu_samples: int
    imu_lost: int
    gnss_fixes: int
    frames_sent: int
    inputs_dropped: int  # IMU samples that reached the core too late
    frames_shed: int  # IMU frames read too late, shed undecoded (their samples counted lost)
    final_mode: Mode
    navigating_after_s: float | None  # simulated seconds from the start
    bias_g_error_dps: tuple[float, float, float]  # final estimate minus truth, deg/s
    bias_a_error_mps2: tuple[float, float]  # x, y
    rms_rpy_deg: tuple[float, float, float]  # after alignment
    ref_point_rms_m: float  # horizontal, after alignment
    output_log: Path
    plot: Path | None
    plot_note: str = ""

    def text(self) -> str:
        """One screen."""
        g, a, r = self.bias_g_error_dps, self.bias_a_error_mps2, self.rms_rpy_deg
        nav = f"{self.navigating_after_s:.1f} s" if self.navigating_after_s is not None else "never"
        lines = [
            f"navgw demo: {self.sim_s:.0f} s simulated in {self.wall_s:.1f} s "
            f"({self.sim_s / max(self.wall_s, 1e-9):.1f}x real time), final mode "
            f"{self.final_mode.name.lower()}, navigating after {nav}",
            f"  inputs      {self.imu_samples} IMU samples ({self.imu_lost} lost), "
            f"{self.gnss_fixes} GNSS fixes, {self.inputs_dropped} dropped by overload (IMU "
            f"samples the gateway got too late to use; {self.frames_shed} frames read too late "
            "shed, their samples counted lost)",
            f"  output      {self.frames_sent} frames on the ISOBUS -> {self.output_log}",
            f"  bias error  gyro x {g[0]:+.4f} y {g[1]:+.4f} z {g[2]:+.4f} deg/s, "
            f"accel x {a[0]:+.4f} y {a[1]:+.4f} m/s^2 (final estimate minus truth)"
            if not math.isnan(g[0])
            else "  bias error  not measured: the run ended before the first bias estimate "
            "(a longer --minutes)",
            f"  attitude    RMS error after alignment (+{SETTLE_S:.0f} s): roll {r[0]:.3f}, "
            f"pitch {r[1]:.3f}, heading {r[2]:.3f} deg"
            if not math.isnan(r[0])
            else f"  attitude    RMS error not measured: the run ended before alignment "
            f"+ {SETTLE_S:.0f} s (a longer --minutes)",
            f"  position    reference point horizontal RMS error after alignment: "
            f"{self.ref_point_rms_m:.3f} m"
            if not math.isnan(self.ref_point_rms_m)
            else "  position    RMS error not measured (see attitude)",
            f"  plot        {self.plot}"
            if self.plot
            else f"  plot        skipped: {self.plot_note}",
        ]
        if self.inputs_dropped + self.frames_shed / 2 > 0.01 * max(self.imu_samples, 1):
            lines.append(
                "  note        this host could not keep up with the demo's speed: the gateway "
                "drops IMU samples it gets too late to send (stale frames would be wrong "
                "frames) and says DEGRADED; a lower --speed shows it as on a vehicle"
            )
        return "\n".join(lines)


def demo_config(truth: Truth, port: str, tag: str) -> GatewayConfig:
    """The gateway as an integrator would configure it for the simulated vehicle."""
    return GatewayConfig(
        vehicle=VehicleSection(
            antenna_lever_arm_m=_vec3(truth.antenna_lever_arm_m),
            imu_lever_arm_m=_vec3(truth.imu_lever_arm_m),
        ),
        imu=ImuSection(interface="virtual", channel=f"navgw-demo-imu-{tag}"),
        isobus=IsobusSection(interface="virtual", channel=f"navgw-demo-isobus-{tag}"),
        gnss=GnssSection(port=port, receiver_latency_s=RECEIVER_LATENCY_S),
        state=StateSection(enabled=False),  # a simulated IMU's biases are no vehicle's
    )


def _vec3(a: Array) -> tuple[float, float, float]:
    return (float(a[0]), float(a[1]), float(a[2]))


def view_text(service: GatewayService, truth: Truth, t0: float) -> str:
    """The live view: three lines, estimates with the truth in parentheses."""
    sol = service.core.solution()
    now = service.timebase.now()
    fix = sol.fix_quality.name.lower().replace("_", " ") if sol.fix_quality else "none"
    head = (
        f"sim {now - t0:6.1f} s  mode {sol.mode.name.lower():12s} fix {fix:10s} "
        f"frames out {service.stats.frames_sent}"
    )
    if sol.roll_rad is None or sol.pitch_rad is None:
        return head + "\n  attitude: not yet\n  biases:   not yet"
    tr = truth_at(truth, np.array([sol.t]))
    rpy_true = tr.rpy_rad[0] * RAD_TO_DEG
    yaw = f"{sol.yaw_rad * RAD_TO_DEG:6.1f}" if sol.yaw_rad is not None else "   n/a"
    att = (
        f"  attitude deg   roll {sol.roll_rad * RAD_TO_DEG:+6.2f} ({rpy_true[0]:+6.2f})  pitch "
        f"{sol.pitch_rad * RAD_TO_DEG:+6.2f} ({rpy_true[1]:+6.2f})  heading {yaw} "
        f"({rpy_true[2] % 360:6.1f})"
    )
    if sol.bias_g_rps is None or sol.bias_a_mps2 is None:
        return head + "\n" + att + "\n  biases:   not yet"
    g, g_true = np.asarray(sol.bias_g_rps) * RAD_TO_DEG, tr.bias_g_rps[0] * RAD_TO_DEG
    a, a_true = np.asarray(sol.bias_a_mps2), tr.bias_a_mps2[0]
    bias = "  bias  gyro deg/s " + " ".join(
        f"{axis} {g[i]:+.4f} ({g_true[i]:+.4f})" for i, axis in enumerate("xyz")
    )
    bias += "   accel m/s^2 " + " ".join(
        f"{axis} {a[i]:+.3f} ({a_true[i]:+.3f})" for i, axis in enumerate("xy")
    )
    return "\n".join([head, att, bias])


class OutputLog(can.Listener):
    """Writes what the service sends on the ISOBUS, stamped with simulated time.

    Runs in python-can's notifier thread, off the service's event loop.
    """

    def __init__(self, writer: CandumpWriter, timebase: TimeBase) -> None:
        self.writer = writer
        self.timebase = timebase

    def on_message_received(self, msg: can.Message) -> None:
        msg.timestamp = self.timebase.at(msg.timestamp)
        msg.channel = None  # the writer's name for the ISOBUS, not the virtual channel's
        self.writer.write(msg)


async def _sample(service: GatewayService, trace: Trace, origin_lla: Array) -> None:
    while True:
        await asyncio.sleep(service.timebase.wall_s(1.0 / TRACE_HZ))
        trace.add(service.core.solution(), origin_lla)


async def _view(
    service: GatewayService, truth: Truth, t0: float, show: Callable[[str], None]
) -> None:
    while True:
        await asyncio.sleep(VIEW_S)
        show(view_text(service, truth, t0))


async def run_demo(options: DemoOptions, show: Callable[[str], None]) -> DemoSummary:
    """Simulate, play through the live service, and summarise; ``show`` gets the live view."""
    wall0 = time.perf_counter()
    out = options.out_dir
    run = generate(SCENARIOS[options.scenario], out / "sim", options.seed)
    truth = Truth.load(run.truth_file)
    duration_s = options.minutes * 60.0 if options.minutes is not None else None
    tag = f"{os.getpid()}-{id(options)}"
    trace = Trace()
    with (
        can.Bus(
            interface="virtual", channel=f"navgw-demo-imu-{tag}", preserve_timestamps=True
        ) as imu_bus,
        can.Bus(interface="virtual", channel=f"navgw-demo-isobus-{tag}") as isobus,
        CandumpWriter(out / OUTPUT_LOG, "can0") as writer,
        SyncedPlayback(run.imu_log, run.gnss_log, imu_bus, options.speed, duration_s) as playback,
    ):
        timebase = playback.start(time.time() + START_LEAD_S)
        service = GatewayService(demo_config(truth, playback.device, tag), timebase=timebase)
        notifier = can.Notifier(isobus, [OutputLog(writer, timebase)])
        helpers = [
            asyncio.create_task(_sample(service, trace, truth.origin_lla)),
            asyncio.create_task(_view(service, truth, playback.t0, show)),
        ]
        running = asyncio.create_task(service.run())
        try:
            while not playback.wait(0) and not running.done():
                await asyncio.sleep(0.1)
            await asyncio.sleep(0.2)  # the last frames through the loop
        finally:
            service.request_stop()
            status = await running
            for task in helpers:
                task.cancel()
            await asyncio.gather(*helpers, return_exceptions=True)
            notifier.stop()
    if status != 0:
        raise RuntimeError("the gateway service failed (see its log)")
    show(view_text(service, truth, playback.t0))
    plot, note = plot_output(out / OUTPUT_LOG, truth, out / PLOT_FILE)
    return summarise(
        service, trace, truth, playback.t0, time.perf_counter() - wall0, out, plot, note
    )


def _errors(trace: Trace, truth: Truth) -> tuple[Array, TruthAt]:
    tr = truth_at(truth, np.asarray(trace.t))
    return attitude_error_rad(trace.rpy_rad, tr.rpy_rad) * RAD_TO_DEG, tr


def summarise(
    service: GatewayService,
    trace: Trace,
    truth: Truth,
    t0: float,
    wall_s: float,
    out: Path,
    plot: Path | None,
    plot_note: str,
) -> DemoSummary:
    """The numbers of one demo run."""
    t = np.asarray(trace.t)
    nav = [ti - t0 for ti, m in zip(trace.t, trace.mode, strict=True) if m is Mode.NAVIGATING]
    nan3 = (math.nan, math.nan, math.nan)
    rms, ref_rms, g_err, a_err = nan3, math.nan, nan3, (math.nan, math.nan)
    if len(t):
        err, tr = _errors(trace, truth)
        after = (t - t0 >= nav[0] + SETTLE_S) if nav else np.zeros(len(t), dtype=bool)
        if after.any():
            r = np.sqrt(np.mean(err[after] ** 2, axis=0))
            rms = (float(r[0]), float(r[1]), float(r[2]))
            d_ne = np.asarray(trace.ne_m)[after] - tr.pos_ned_m[after, :2]
            ref_rms = float(np.sqrt(np.mean(np.sum(d_ne**2, axis=1))))
        g = (trace.bias_g_rps[-1] - tr.bias_g_rps[-1]) * RAD_TO_DEG
        a = trace.bias_a_mps2[-1] - tr.bias_a_mps2[-1]
        g_err, a_err = (float(g[0]), float(g[1]), float(g[2])), (float(a[0]), float(a[1]))
    core, imu = service.core.stats, service.imu_decoder.counters
    return DemoSummary(
        wall_s=wall_s,
        sim_s=(trace.t[-1] - t0) if trace.t else 0.0,
        imu_samples=core.imu_samples,
        imu_lost=imu.lost,
        gnss_fixes=core.gnss_fixes,
        frames_sent=service.stats.frames_sent,
        inputs_dropped=service.core.stats.imu_dropped,
        frames_shed=service.stats.frames_shed,
        final_mode=service.core.solution().mode,
        navigating_after_s=nav[0] if nav else None,
        bias_g_error_dps=g_err,
        bias_a_error_mps2=a_err,
        rms_rpy_deg=rms,
        ref_point_rms_m=ref_rms,
        output_log=out / OUTPUT_LOG,
        plot=plot,
        plot_note=plot_note,
    )


def plot_output(log: Path, truth: Truth, path: Path) -> tuple[Path | None, str]:
    """The run's picture (:mod:`gateway.demo.run_plot`, as ``navgw plot`` draws it) from the
    output log, from its first frame on, with the errors against truth."""
    try:
        from gateway.demo.run_plot import save_run_plot
    except ImportError:
        return None, "matplotlib is not installed (pip install 'navgw[plots]')"
    try:
        return save_run_plot(read_run(log), path, truth), ""
    except InputError as exc:
        return None, str(exc)
