"""``navgw run``: the live gateway on real interfaces, until SIGTERM or SIGINT."""

from __future__ import annotations

import argparse
import asyncio
import logging
import os
import sys
from pathlib import Path

from gateway.config.config_schema import ConfigError
from gateway.config.gateway_config import Engine, load_config
from gateway.service.live_loop import serve

#: journald adds its own timestamps and reads the level from the line; a terminal gets times.
JOURNAL_FORMAT = "%(levelname)s %(name)s: %(message)s"
TERMINAL_FORMAT = "%(asctime)s " + JOURNAL_FORMAT


def add_subparser(
    subparsers: argparse._SubParsersAction[argparse.ArgumentParser], help_text: str
) -> None:
    """Register ``run``."""
    p = subparsers.add_parser(
        "run",
        help=help_text,
        description="Read the IMU bridge (CAN) and the GNSS receiver (serial NMEA), run the "
        "fusion loop and send its frames on the ISOBUS until SIGTERM or SIGINT (exit 0). "
        "Missing devices are waited for; under systemd (Type=notify) it reports READY, "
        "STATUS and WATCHDOG. Logs go to stderr, without timestamps under journald.",
    )
    p.add_argument("--config", type=Path, help="gateway config (TOML); default: all defaults")
    p.add_argument("--engine", choices=[e.value for e in Engine], help="override [estimator]")
    p.set_defaults(func=run)


def configure_logging(verbose: int) -> None:
    """INFO (DEBUG with -vv) to stderr, journald-friendly when ``$JOURNAL_STREAM`` is set."""
    fmt = JOURNAL_FORMAT if os.environ.get("JOURNAL_STREAM") else TERMINAL_FORMAT
    level = logging.DEBUG if verbose > 1 else logging.INFO
    logging.basicConfig(level=level, format=fmt, force=True)


def run(args: argparse.Namespace) -> int:
    """0 after SIGTERM/SIGINT; 1 if an internal task died; 2 on a bad config."""
    configure_logging(args.verbose)
    try:
        config = load_config(args.config)
        if args.engine:
            config = config.with_engine(Engine(args.engine))
        return asyncio.run(serve(config))
    except ConfigError as err:
        print(f"navgw run: {err}", file=sys.stderr)
        return 2
    except OSError as err:  # the recording directory
        print(f"navgw run: {err.filename}: {err.strerror}", file=sys.stderr)
        return 2
