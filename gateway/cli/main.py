"""The ``navgw`` command line: a thin layer over library functions that tests call directly.

Each command lives in its own module with ``add_subparser(subparsers, help_text)``, which
registers the command and sets ``func(args) -> int`` on the parsed namespace.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import sys
from collections.abc import Sequence
from types import ModuleType

from gateway import __version__

#: Sub-commands in the order ``--help`` lists them: the module that implements each, and its
#: one-line help. Only the module of the command being run is imported: `navgw run` and
#: `navgw --help` load neither the simulator, scipy, matplotlib nor textual
#: (tests/test_cli_imports.py).
COMMANDS = {
    "run": (
        "gateway.cli.cmd_run",
        "run the live gateway: IMU and ISOBUS on CAN, GNSS on a serial port",
    ),
    "demo": (
        "gateway.cli.cmd_demo",
        "watch the gateway navigate a simulated field run (no hardware needed)",
    ),
    "replay": (
        "gateway.cli.cmd_replay",
        "run recorded logs through the gateway, write its output frames",
    ),
    "calibrate": ("gateway.cli.cmd_calibrate", "estimate the IMU mounting from a recorded drive"),
    "config": ("gateway.cli.cmd_config", "print an example config, or check a config file"),
    "state": (
        "gateway.cli.cmd_state",
        "show or clear the learned IMU biases kept for a warm start",
    ),
    "sim": ("gateway.cli.cmd_sim", "simulate a field run: IMU CAN log, NMEA log and truth"),
    "monitor": (
        "gateway.cli.cmd_monitor",
        "watch a bus or an output log: mode, fix, attitude, biases, rates, claims",
    ),
    "plot": ("gateway.cli.cmd_plot", "draw a run from its output log (and the truth)"),
    "fleet": (
        "gateway.cli.cmd_fleet",
        "replay many recordings on a Dask cluster into one table (Parquet)",
    ),
}


#: Off-vehicle dependencies and the extra that installs each (pyproject.toml).
OPTIONAL = {
    "scipy": "sim",
    "matplotlib": "plots",
    "textual": "monitor",
    "dask": "fleet",
    "distributed": "fleet",
    "pyarrow": "fleet",
}


def build_parser(argv: Sequence[str] = ()) -> argparse.ArgumentParser:
    """The argument parser: every sub-command listed, the one named in ``argv`` in full."""
    parser = argparse.ArgumentParser(
        prog="navgw",
        description="GNSS/IMU gateway for precision agriculture (Tereshkov bias observer, "
        "terrain compensation, ISOBUS output).",
    )
    parser.add_argument("--version", action="version", version=f"navgw {__version__}")
    parser.add_argument("-v", "--verbose", action="count", default=0, help="more log output")
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND")
    command = next((a for a in argv if not a.startswith("-")), None)
    for name, (module, help_text) in COMMANDS.items():
        if name == command:
            _load(module, name).add_subparser(subparsers, help_text)
        else:
            subparsers.add_parser(name, help=help_text)
    return parser


def _load(module: str, command: str) -> ModuleType:
    """The module of ``command``; a missing optional dependency ends with how to get it."""
    try:
        return importlib.import_module(module)
    except ModuleNotFoundError as err:
        if err.name is None or err.name.split(".")[0] not in OPTIONAL:
            raise
        extra = OPTIONAL[err.name.split(".")[0]]
        raise SystemExit(
            f"navgw {command} needs {err.name}, which the lean (ECU) install leaves out: "
            f"pip install 'navgw[{extra}]'"
        ) from err


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``navgw`` console script; returns the exit status."""
    argv = sys.argv[1:] if argv is None else argv
    parser = build_parser(argv)
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
