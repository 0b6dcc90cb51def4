"""The ``navgw`` command line: a thin layer over library functions that tests call directly.

Each command lives in its own module with ``add_subparser(subparsers)``, which registers the
command and sets ``func(args) -> int`` on the parsed namespace.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import sys
from collections.abc import Sequence

from gateway import __version__

#: Modules that each contribute one sub-command, in the order ``--help`` lists them.
COMMAND_MODULES = (
    "gateway.cli.cmd_run",
    "gateway.cli.cmd_demo",
    "gateway.cli.cmd_replay",
    "gateway.cli.cmd_config",
    "sim_bus.sim_cli",
)


def build_parser() -> argparse.ArgumentParser:
    """The full argument parser, with every sub-command registered."""
    parser = argparse.ArgumentParser(
        prog="navgw",
        description="GNSS/IMU gateway for precision agriculture (Tereshkov bias observer, "
        "terrain compensation, ISOBUS output).",
    )
    parser.add_argument("--version", action="version", version=f"navgw {__version__}")
    parser.add_argument("-v", "--verbose", action="count", default=0, help="more log output")
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMAND_MODULES:
        importlib.import_module(name).add_subparser(subparsers)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``navgw`` console script; returns the exit status."""
    parser = build_parser()
    args = parser.parse_args(argv)
    level = (logging.WARNING, logging.INFO, logging.DEBUG)[min(args.verbose, 2)]
    logging.basicConfig(
        level=level,
        format="%(levelname)s %(name)s: %(message)s",
    )
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    status: int = args.func(args)
    return status


if __name__ == "__main__":
    sys.exit(main())
