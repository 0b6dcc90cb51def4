"""``navgw calibrate``: the IMU mounting from one recorded drive, as the config line to paste."""

from __future__ import annotations

import argparse
import dataclasses
import logging
import sys
from dataclasses import dataclass
from pathlib import Path

from drivers.errors import DriverError
from drivers.samples import GnssFix, ImuSample
from gateway.calibration.mounting import (
    AXES,
    CalibrationConfig,
    MountingEstimator,
    MountingResult,
    total_mounting_rpy_deg,
)
from gateway.calibration.receiver_latency import (
    LATENCY_DRIVE,
    MAX_LATENCY_SIGMA_S,
    LatencyEstimator,
    LatencyResult,
)
from gateway.config.config_schema import ConfigError
from gateway.config.driver_settings import imu_config
from gateway.config.gateway_config import Engine, GatewayConfig, load_config
from gateway.estimation.ekf.ekf_config import EkfConfig
from gateway.estimation.observer.observer_config import ObserverConfig
from gateway.offline.log_inputs import LogInputs

Vec3 = tuple[float, float, float]

#: Passes over the logs at most: each starts from the mounting the one before found.
MAX_PASSES = 3
#: Exit status when some axis is not determined (the drive lacks a manoeuvre).
UNDETERMINED = 3


@dataclass(frozen=True)
class Calibration:
    """The mounting to configure (SPEC 5, deg; None if nothing could be estimated), the last
    pass's result, how many passes ran, what the logs held, and the epochs' timing (the
    receiver latency to configure on a host clock that does not follow UTC)."""

    mounting_rpy_deg: Vec3 | None
    result: MountingResult | None
    passes: int
    imu_samples: int
    gnss_fixes: int
    latency: LatencyResult | None = None

    @property
    def determined(self) -> bool:
        """Every axis determined, and the receiver latency where it is needed."""
        return (
            self.result is not None
            and self.result.determined
            and (self.latency is None or self.latency.determined)
        )


def add_subparser(
    subparsers: argparse._SubParsersAction[argparse.ArgumentParser], help_text: str
) -> None:
    """Register ``calibrate``."""
    p = subparsers.add_parser(
        "calibrate",
        help=help_text,
        description="Estimate the IMU mounting rotation ([vehicle] imu_mounting_rpy_deg) from "
        "a recorded drive: turns both ways, forward driving with RTK fixed, the same line "
        "driven in both directions, ideally across a side slope. Where the host clock did not "
        "follow UTC, also the receiver latency ([gnss] receiver_latency_s and its sigma). "
        "Prints the config lines to paste (exit 0), or what the drive still lacks (exit "
        f"{UNDETERMINED}). The --config gives the lever arms, the GNSS timing and the mounting "
        "the recording was made with.",
    )
    p.add_argument("--can", required=True, type=Path, help="IMU bridge frames, candump -L")
    p.add_argument("--nmea", required=True, type=Path, help="NMEA log, optionally host-stamped")
    p.add_argument("--config", type=Path, help="gateway config (TOML)")
    p.add_argument(
        "--max-sigma",
        type=float,
        default=CalibrationConfig.max_sigma_deg,
        metavar="DEG",
        help="an axis counts as determined within this 1-sigma (default %(default)s deg)",
    )
    p.set_defaults(func=run)


def calibrate(
    can_log: Path, nmea_log: Path, config: GatewayConfig, max_sigma_deg: float
) -> Calibration:
    """Run the calibration over the logs, again from each pass's mounting while the samples
    were too far off the body for the fine tilt, and from each pass's receiver latency while
    it moved beyond its 1-sigma (``MAX_PASSES`` at most): the observer the mounting is found
    with is DEGRADED on the move with an unmeasured latency (its positions beyond RTK
    class), and the EKF's latency is off with a mounting degrees off (9 ms at 4-6 deg)."""
    settings = CalibrationConfig(observer=_observer(config), max_sigma_deg=max_sigma_deg)
    mounting = config.vehicle.imu_mounting_rpy_deg
    configured_s = config.gnss.receiver_latency_s
    for n in range(1, MAX_PASSES + 1):
        vehicle = dataclasses.replace(config.vehicle, imu_mounting_rpy_deg=mounting)
        config = dataclasses.replace(config, vehicle=vehicle)
        settings = dataclasses.replace(settings, observer=_observer(config))
        estimator = MountingEstimator(settings)
        timing = LatencyEstimator(_ekf(config))
        samples = fixes = 0
        for item in LogInputs(can_log, nmea_log, imu_config(config)):
            if isinstance(item, ImuSample):
                estimator.imu(item)
                timing.imu(item)
                samples += 1
            elif isinstance(item, GnssFix):
                estimator.gnss(item)
                timing.gnss(item)
                fixes += 1
        result = estimator.result()
        latency = dataclasses.replace(timing.result(), configured_s=configured_s)
        if result.rpy_deg is None or samples == 0 or fixes == 0:
            return Calibration(None, result, n, samples, fixes, latency)
        mounting = total_mounting_rpy_deg(mounting, result.rpy_deg)
        moved = latency.needed and latency.determined and _latency_moved(config, latency)
        if moved:
            assert latency.latency_s is not None and latency.config_sigma_s is not None
            gnss = dataclasses.replace(
                config.gnss,
                receiver_latency_s=latency.latency_s,
                receiver_latency_sigma_s=latency.config_sigma_s,
            )
            config = dataclasses.replace(config, gnss=gnss)
        if not result.needs_rerun and not moved:
            break
    return Calibration(mounting, result, n, samples, fixes, latency)


def _observer(config: GatewayConfig) -> ObserverConfig:
    settings = config.with_engine(Engine.OBSERVER).engine_settings()
    assert isinstance(settings, ObserverConfig)
    return settings


def _ekf(config: GatewayConfig) -> EkfConfig:
    settings = config.with_engine(Engine.EKF).engine_settings()
    assert isinstance(settings, EkfConfig)
    return settings


def _latency_moved(config: GatewayConfig, latency: LatencyResult) -> bool:
    """The latency measured is not the one ``config`` ran with: beyond the configured
    1-sigma, or that 1-sigma too wide for the observer's positions (not measured)."""
    assert latency.latency_s is not None
    used, used_sigma = config.gnss.receiver_latency_s, config.gnss.receiver_latency_sigma_s
    return used_sigma > MAX_LATENCY_SIGMA_S or abs(latency.latency_s - used) > used_sigma


def report_text(cal: Calibration) -> str:
    """Per axis: the mounting, its 1-sigma and what it still needs; the drive's content;
    the receiver latency where the host clock does not follow UTC."""
    r = cal.result
    if r is None or cal.mounting_rpy_deg is None:
        return "no estimate"
    lines = [f"IMU mounting after {cal.passes} passes (ZYX, deg, 1-sigma):"]
    for axis, angle, sigma, missing in zip(
        AXES, cal.mounting_rpy_deg, r.sigma_deg, r.missing, strict=True
    ):
        note = f"  still missing: {'; '.join(missing)}" if missing else ""
        spread = f"{sigma:.2f}" if sigma < 100.0 else "?"
        lines.append(f"  {axis:5s} {angle:8.2f} +/- {spread}{note}")
    lines.append(
        f"  drive: {r.turned_right_deg:.0f} deg turned right, {r.turned_left_deg:.0f} left; "
        f"{r.forward_m:.0f} m forward with RTK fixed, {r.both_ways_m:.0f} m of it on ground "
        "driven both ways"
    )
    if r.needs_rerun:
        lines.append(f"  still {MAX_PASSES} passes away from the body's axes: run again")
    if cal.latency is not None:
        lines.append(latency_text(cal.latency))
    return "\n".join(lines)


def latency_text(latency: LatencyResult) -> str:
    """The report's line on the epochs' timing."""
    if not latency.needed:
        return "GNSS epochs on the receiver's UTC (the host clock follows it): no latency to set"
    if latency.latency_s is None or latency.sigma_s is None:
        return f"receiver latency: not learnt  still missing: {LATENCY_DRIVE}"
    note = "" if latency.determined else f"  still missing: {LATENCY_DRIVE}"
    return (
        f"receiver latency (the host clock does not follow UTC) {latency.latency_s * 1e3:.1f} "
        f"ms +/- {latency.sigma_s * 1e3:.1f}, configured {latency.configured_s * 1e3:.1f}{note}"
    )


def config_line(cal: Calibration) -> str:
    """The TOML to paste: the [vehicle] keys with the mounting (its sigma as a comment) and
    its roll/pitch 1-sigma, which the gateway states with roll and pitch; on a host clock
    that does not follow UTC the [gnss] receiver latency and the 1-sigma to state with it."""
    assert cal.mounting_rpy_deg is not None and cal.result is not None
    angles = ", ".join(f"{a:.2f}" for a in cal.mounting_rpy_deg)
    sigma = cal.result.sigma_deg
    sigmas = ", ".join(f"{s:.2f}" for s in sigma)
    text = (
        f"[vehicle]\nimu_mounting_rpy_deg = [{angles}]  # navgw calibrate, 1-sigma {sigmas} deg\n"
        f"imu_mounting_sigma_deg = {max(sigma[0], sigma[1]):.2f}"
    )
    latency = cal.latency
    if latency is None or not latency.needed:
        return text
    assert latency.latency_s is not None and latency.config_sigma_s is not None
    return text + (
        f"\n[gnss]\nreceiver_latency_s = {latency.latency_s:.4f}  # navgw calibrate, 1-sigma "
        f"over the drive {latency.sigma_s:.4f} s\n"
        f"receiver_latency_sigma_s = {latency.config_sigma_s:.4f}"
    )


def run(args: argparse.Namespace) -> int:
    """Exit 0 with the config line on stdout; 3 when some axis is not determined (what the
    drive lacks on stderr); 2 with a message on a bad config or unreadable input."""
    engines = logging.getLogger("gateway.estimation")
    level = engines.level
    if not args.verbose:  # the engine inside is a tool here: its warnings are not the user's
        engines.setLevel(logging.ERROR)
    try:
        return _calibrate_and_report(args)
    finally:  # main() may run in a process that goes on (tests, a notebook)
        engines.setLevel(level)


def _calibrate_and_report(args: argparse.Namespace) -> int:
    try:
        cal = calibrate(args.can, args.nmea, load_config(args.config), args.max_sigma)
    except (ConfigError, DriverError) as err:
        print(f"navgw calibrate: {err}", file=sys.stderr)
        return 2
    except OSError as err:
        print(f"navgw calibrate: {err.filename}: {err.strerror}", file=sys.stderr)
        return 2
    unread = [
        *([f"{args.can}: no IMU sample; expected candump -L lines of the bridge's IMU_GYRO/"
           "IMU_ACCEL frames (SPEC 1, 3)"] if cal.imu_samples == 0 else []),
        *([f"{args.nmea}: no GNSS fix; expected NMEA 0183 GGA/RMC lines (SPEC 2, 3)"]
          if cal.gnss_fixes == 0 else []),
    ]  # fmt: skip
    if unread:
        print("navgw calibrate: " + "\n  ".join(unread), file=sys.stderr)
        return 2
    print(report_text(cal), file=sys.stderr)
    if not cal.determined or cal.mounting_rpy_deg is None:
        assert cal.result is not None
        manoeuvres, lacking = cal.result.manoeuvres, []
        if not cal.result.determined:
            lacking.append("not every axis is determined")
        if cal.latency is not None and not cal.latency.determined:
            manoeuvres = [*manoeuvres, LATENCY_DRIVE]
            lacking.append("the receiver latency is not")
        todo = "\n".join(f"  - {m}" for m in manoeuvres) or "  - run again"
        print(
            f"navgw calibrate: {', '.join(lacking)}; drive again and\n{todo}",
            file=sys.stderr,
        )
        return UNDETERMINED
    print(config_line(cal))
    return 0
