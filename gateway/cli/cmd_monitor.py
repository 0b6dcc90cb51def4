"""``navgw monitor``: a terminal view of a bus or a candump log, decoded through the DBC."""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import can

from gateway.config.config_schema import ConfigError
from gateway.config.gateway_config import load_config
from gateway.monitor.app import MonitorApp
from gateway.monitor.bus_state import BusState
from gateway.monitor.sources import BusSource, FrameSource, LogSource

DEFAULT_INTERFACE = "socketcan"
DEFAULT_CHANNEL = "can0"


def add_subparser(
    subparsers: argparse._SubParsersAction[argparse.ArgumentParser], help_text: str
) -> None:
    """Register ``monitor``."""
    p = subparsers.add_parser(
        "monitor",
        help=help_text,
        description="Show what navgw says on a CAN bus, or in a candump -L log of it, at a "
        "glance: mode, fix and health in words, attitude, position, speed, bias estimates "
        "and their convergence, each output's rate against its configured rate, the address "
        "claims on the bus, IMU samples lost, and a banner when frames stop. Keys: n shows "
        "the next navigation source on the bus, q quits.",
    )
    p.add_argument(
        "--interface",
        help=f"python-can interface of the bus (default {DEFAULT_INTERFACE})",
    )
    p.add_argument("--channel", help=f"python-can channel of the bus (default {DEFAULT_CHANNEL})")
    p.add_argument("--log", type=Path, help="read a candump -L log instead of a bus")
    p.add_argument("--speed", type=float, help="with --log: times real time (default 1; e.g. 10)")
    p.add_argument(
        "--config",
        type=Path,
        help="the unit's navgw.toml: its [output] rates are the ones measured rates are "
        "compared with (default: SPEC 4's)",
    )
    p.set_defaults(func=run)


def open_source(args: argparse.Namespace) -> FrameSource | str:
    """The source the options name, or what is wrong with them (a message for the user)."""
    if args.log is not None:
        if args.interface or args.channel:
            return "--log reads a file: give it without --interface and --channel"
        speed = 1.0 if args.speed is None else args.speed
        if not (speed > 0 and math.isfinite(speed)):
            return f"--speed {args.speed}: expected a number > 0 (times real time)"
        try:
            return LogSource(args.log, speed)
        except OSError as exc:
            return f"--log {args.log}: {exc.strerror or exc}; expected a readable candump -L log"
    if args.speed is not None:
        return "--speed is for --log: a bus is shown as it comes"
    interface = args.interface or DEFAULT_INTERFACE
    channel = args.channel or DEFAULT_CHANNEL
    try:
        return BusSource(interface, channel)
    except (can.CanError, OSError, ValueError, ImportError) as exc:
        return (
            f"cannot open CAN interface {interface!r} channel {channel!r}: {exc}; expected a "
            "python-can interface and channel that exist here (--interface, --channel), or "
            "--log FILE"
        )


def run(args: argparse.Namespace) -> int:
    """0 after the user quits; 2 when the options, the config or the source are wrong."""
    state = BusState()
    if args.config is not None:
        try:
            rates = load_config(args.config).output.rates_hz()
            state.configured_hz = {int(pgn): hz for pgn, hz in rates.items()}
        except ConfigError as exc:
            print(f"navgw monitor: {exc}", file=sys.stderr)
            return 2
    source = open_source(args)
    if isinstance(source, str):
        print(f"navgw monitor: {source}", file=sys.stderr)
        return 2
    try:
        MonitorApp(source, state).run()
    finally:
        source.close()
    return 0
