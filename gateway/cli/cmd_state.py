"""``navgw state show|clear``: the learned biases the gateway keeps for its warm start."""

from __future__ import annotations

import argparse
import math
import sys
import time
from datetime import datetime, timezone
from pathlib import Path

from drivers.units import MG_MPS2
from gateway.config.config_schema import ConfigError
from gateway.config.gateway_config import GatewayConfig, load_config
from gateway.state.keeper import mounting_problem
from gateway.state.store import (
    STATE_FILE,
    BandEntry,
    Identity,
    Mounting,
    StoredState,
    StoreError,
    angles_text,
    band_of,
    leftover_temporaries,
    read_state,
)


def add_subparser(
    subparsers: argparse._SubParsersAction[argparse.ArgumentParser], help_text: str
) -> None:
    """Register ``state``."""
    p = subparsers.add_parser(
        "state",
        help=help_text,
        description="show: print the learned state (per IMU temperature band the gyro and "
        "accelerometer biases with their 1-sigma, how old, the last position and heading, "
        "the IMU mounting estimate and whether a start with the config applies it) and "
        "whether it fits the config. clear: remove it (the next start is cold).",
    )
    p.add_argument("action", choices=["show", "clear"])
    p.add_argument("--config", type=Path, help="gateway config (TOML): [state] directory")
    p.add_argument("--dir", type=Path, metavar="DIR", help="state directory (overrides config)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """show: 0 (also when there is none), 1 if the file is unusable; clear: 0, 2 if it
    cannot be removed; 2 on a bad config."""
    try:
        config = load_config(args.config)
    except ConfigError as err:
        print(f"navgw state: {err}", file=sys.stderr)
        return 2
    directory = args.dir if args.dir is not None else Path(config.state.directory)
    path = directory / STATE_FILE
    if args.action == "clear":
        return clear(path)
    return show(path, config)


def clear(path: Path) -> int:
    """Remove the file and any temporaries an interrupted write left; say what went."""
    targets = [p for p in (path, *leftover_temporaries(path)) if p.exists()]
    if not targets:
        print(f"no learned state at {path}: nothing to remove")
        return 0
    for target in targets:
        try:
            target.unlink()
        except OSError as err:
            print(f"navgw state: cannot remove {target}: {err.strerror}", file=sys.stderr)
            return 2
        print(f"removed {target}")
    print("the next start is cold")
    return 0


def show(path: Path, config: GatewayConfig) -> int:
    """Print the state in ``path`` readably (its problem if it is unusable)."""
    try:
        state = read_state(path)
    except FileNotFoundError:
        print(f"no learned state at {path}: the gateway starts cold")
        return 0
    except (StoreError, OSError) as err:
        reason = err.strerror if isinstance(err, OSError) else str(err)
        print(f"{path}: unusable ({reason}); the gateway ignores it and starts cold")
        return 1
    print(state_text(state, path, config))
    return 0


def state_text(state: StoredState, path: Path, config: GatewayConfig, now: float = 0.0) -> str:
    """The store as ``navgw state show`` prints it (``now``: host time; 0: the clock's)."""
    now = now or time.time()
    mismatch = state.identity.mismatch(Identity.from_config(config))
    fits = f"does not fit the config: {mismatch}" if mismatch else "fits the config"
    ident = state.identity
    width = config.state.temperature_band_c
    lines = [
        f"{path} (written {_when(state.written_s, now)})",
        f"  IMU bridge 0x{ident.bridge_source_address:02X}, gateway identity "
        f"{ident.identity_number}: {fits}",
    ]
    if not state.bands:
        lines.append("  no biases learned yet")
    for e in state.bands:
        lo = band_of(e.temp_c, width) * width
        lines += _band_lines(e, lo, lo + width, now)
    if state.last is not None:
        last = state.last
        heading = "unknown" if last.heading_deg is None else f"{last.heading_deg:.1f} deg"
        lines.append(
            f"  last position {last.lat_deg:.7f} {last.lon_deg:.7f} {last.alt_m:.2f} m, "
            f"heading {heading} ({_when(last.t_s, now)}; shown only, not used at start)"
        )
    if state.rest is None:
        lines.append("  no rest stored: the biases are not used at start (nothing to check them)")
    else:
        r = state.rest
        f_mg = ", ".join(f"{x / MG_MPS2:+.2f}" for x in r.f_b_mps2)
        lines.append(
            f"  last rest {r.lat_deg:.7f} {r.lon_deg:.7f} for {r.duration_s:.0f} s "
            f"({_when(r.t_s, now)}): mean specific force x, y, z {f_mg} mg; a start there "
            "that measures the same uses the biases"
        )
    if state.mounting is not None:
        problem = mounting_problem(config, state)
        lines += _mounting_lines(state.mounting, problem, config.calibration.apply)
    return "\n".join(lines)


def _mounting_lines(m: Mounting, problem: str | None, apply: bool) -> list[str]:
    """The stored mounting estimate, and what a start does with it: ``problem``, why it
    may not be applied (:func:`mounting_problem`); ``apply``, [calibration] apply."""
    rpy = ", ".join(f"{v:+.3f}+/-{s:.3f}" for v, s in zip(m.rpy_deg, m.sigma_deg, strict=True))
    if problem is not None:
        use = f"not applied at start: {problem}"
    elif apply:
        use = "applied at start instead of the configured mounting ([calibration] apply)"
    else:
        use = "would be applied at start with [calibration] apply = true"
    return [
        f"  mounting estimate roll, pitch, yaw {rpy} deg, against the configured "
        f"[vehicle] imu_mounting_rpy_deg = {angles_text(m.base_rpy_deg)}",
        f"    {use}",
    ]


def _band_lines(e: BandEntry, lo: float, hi: float, now: float) -> list[str]:
    gyro = ", ".join(
        f"{math.degrees(b):+.4f}+/-{math.degrees(s):.4f}"
        for b, s in zip(e.gyro_rps.bias, e.gyro_rps.sigma, strict=True)
    )
    accel = ", ".join(
        f"{b:+.4f}+/-{s:.4f}" for b, s in zip(e.accel_mps2.bias, e.accel_mps2.sigma, strict=True)
    )
    return [
        f"  band {lo:g} to {hi:g} degC: learned at {e.temp_c:.1f} degC by the {e.engine}, "
        f"{_when(e.t_s, now)}",
        f"    gyro bias x, y, z  {gyro} deg/s",
        f"    accel bias x, y, z {accel} m/s^2",
    ]


def _when(t_s: float, now: float) -> str:
    """UTC time and age of host-clock time ``t_s``."""
    stamp = datetime.fromtimestamp(t_s, tz=timezone.utc).strftime("%Y-%m-%d %H:%M:%S UTC")
    age_s = now - t_s
    if age_s < 0:
        return f"{stamp}, in the future of this clock"
    if age_s < 3600:
        return f"{stamp}, {age_s / 60:.0f} min ago"
    if age_s < 2 * 86400:
        return f"{stamp}, {age_s / 3600:.1f} h ago"
    return f"{stamp}, {age_s / 86400:.1f} days ago"
