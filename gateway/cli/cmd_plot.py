"""``navgw plot``: one picture of a run from its output log (and the simulator's truth)."""

from __future__ import annotations

import argparse
import sys
import zipfile
from pathlib import Path

from drivers.errors import InputError
from gateway.demo.run_plot import save_run_plot
from gateway.readback.run_series import read_run
from sim_bus.truth import Truth


def add_subparser(
    subparsers: argparse._SubParsersAction[argparse.ArgumentParser], help_text: str
) -> None:
    """Register ``plot``."""
    p = subparsers.add_parser(
        "plot",
        help=help_text,
        description="Draw a run from a candump -L log of navgw's output (navgw replay --out, "
        "the demo's navgw-output.log): the reference point's track coloured by fix quality, "
        "mode and fix over time, roll, pitch and heading, the bias estimates with their "
        "convergence, the output rates; with --truth (a simulated run's truth.npz), the "
        "errors. Needs matplotlib (the plots extra).",
    )
    p.add_argument("log", type=Path, help="navgw's output frames, candump -L")
    p.add_argument("--truth", type=Path, help="truth.npz of the simulated run (navgw sim)")
    p.add_argument("--out", type=Path, help="image to write (default: LOG with .png)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """0 when the picture is written; 1 when an input cannot be used."""
    out = args.out or args.log.with_suffix(".png")
    try:
        truth = _truth(args.truth) if args.truth is not None else None
        series = read_run(args.log)
        if truth is not None and not (truth.t[0] <= series.t_end and series.t0 <= truth.t[-1]):
            raise InputError(
                f"the truth covers {truth.t[0]:.3f}-{truth.t[-1]:.3f} s, the log "
                f"{series.t0:.3f}-{series.t_end:.3f} s",
                str(args.truth),
                "the truth.npz of the run that made the log (the same clock)",
            )
        save_run_plot(series, out, truth)
    except InputError as exc:
        print(f"navgw plot: {exc}", file=sys.stderr)
        return 1
    except ValueError as exc:  # matplotlib: an image format it cannot write
        print(f"navgw plot: --out {out}: {exc}", file=sys.stderr)
        return 1
    except OSError as exc:
        print(f"navgw plot: {exc.filename or out}: {exc.strerror or exc}", file=sys.stderr)
        return 1
    print(out)
    return 0


def _truth(path: Path) -> Truth:
    """The truth file, or InputError saying what is wrong with it."""
    try:
        return Truth.load(path)
    except (KeyError, ValueError, zipfile.BadZipFile) as exc:
        raise InputError(
            f"not a simulator truth file ({exc})", str(path), "a truth.npz written by navgw sim"
        ) from None
