"""``navgw config``: print the commented example config, or check a config file."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from gateway.config.config_schema import ConfigError
from gateway.config.gateway_config import example_toml, load_config
from gateway.service.bus_links import BusPlan


def add_subparser(
    subparsers: argparse._SubParsersAction[argparse.ArgumentParser], help_text: str
) -> None:
    """Register ``config``."""
    p = subparsers.add_parser(
        "config",
        help=help_text,
        description="--example prints a complete config with every default and its meaning; "
        "--check FILE validates FILE as 'navgw run' would (exit 0 if usable, 2 with a "
        "message naming the key if not).",
    )
    what = p.add_mutually_exclusive_group(required=True)
    what.add_argument("--example", action="store_true", help="print the example config")
    what.add_argument("--check", type=Path, metavar="FILE", help="validate FILE")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Print the example, or check the file: 0 if usable, 2 with a message if not."""
    if args.example:
        sys.stdout.write(example_toml())
        return 0
    try:
        config = load_config(args.check)
        plan = BusPlan.from_config(config)
    except ConfigError as err:
        print(f"navgw config: {err}", file=sys.stderr)
        return 2
    isobus = "same bus" if plan.shared else str(plan.isobus)
    print(
        f"{args.check}: ok (engine {config.estimator.engine.value}, IMU {plan.imu}, "
        f"ISOBUS {isobus}, GNSS {config.gnss.port} {config.gnss.baudrate} baud)"
    )
    return 0
