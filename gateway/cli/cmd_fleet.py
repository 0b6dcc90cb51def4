"""``navgw fleet``: re-process many recordings on a Dask cluster into one Parquet table."""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from drivers.errors import InputError
from gateway.config.config_schema import ConfigError
from gateway.config.gateway_config import Engine, load_config
from gateway.fleet.cluster import run_fleet
from gateway.fleet.recordings import find_recordings
from gateway.fleet.table import summary_text, write_parquet
from gateway.fleet.task import FleetJob

BOTH = "both"


def add_subparser(
    subparsers: argparse._SubParsersAction[argparse.ArgumentParser], help_text: str
) -> None:
    """Register ``fleet``."""
    p = subparsers.add_parser(
        "fleet",
        help=help_text,
        description="Find recordings ([recording] pairs, rotated parts joined in order; navgw "
        "sim run directories; manifests), replay each as one Dask task with navgw replay's "
        "code, and write one row per recording and engine to a Parquet table: duration, IMU "
        "samples and losses, fix-quality shares, time in each mode, convergence times, final "
        "biases and their spread, temperature range, output rates, malformed input, and with "
        "--engine both the engines' attitude RMS difference. Needs the fleet extra.",
    )
    p.add_argument(
        "recordings", nargs="+", type=Path, metavar="RECORDINGS",
        help="directories searched for recordings, or manifest files (TOML [[recording]])",
    )  # fmt: skip
    p.add_argument("--out", required=True, type=Path, help="the table to write (Parquet)")
    p.add_argument("--config", type=Path, help="gateway config for all (default: each own)")
    p.add_argument(
        "--engine", choices=[*(e.value for e in Engine), BOTH],
        help="engine(s) to run (default: --config's [estimator], else observer)",
    )  # fmt: skip
    p.add_argument("--scheduler", metavar="ADDRESS", help="an existing Dask scheduler")
    p.add_argument(
        "--workers", type=int, metavar="N",
        help=f"local worker processes without --scheduler (default: cores, {os.cpu_count()})",
    )  # fmt: skip
    p.add_argument("--logs", type=Path, metavar="DIR", help="keep the output logs here")
    p.add_argument("--plot", action="store_true", help="histograms, PNG beside --out")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """0 when the table is written (error rows included); 2 on bad arguments or input that
    stops the whole job (no recordings, a bad --config, an unreachable scheduler)."""
    try:
        job = _job(args)
        recordings = find_recordings(args.recordings)
        if not args.out.parent.is_dir():
            raise InputError("no such directory", str(args.out.parent), "--out in a directory")
        result = run_fleet(recordings, job, args.scheduler, args.workers)
        write_parquet(result.rows, args.out)
        print(summary_text(result.rows, result.wall_s, result.workers), file=sys.stderr)
        if args.plot:
            from gateway.fleet.histograms import save_histograms  # matplotlib, only for --plot

            print(save_histograms(result.rows, args.out.with_suffix(".png")), file=sys.stderr)
    except (ConfigError, InputError) as err:
        print(f"navgw fleet: {err}", file=sys.stderr)
        return 2
    except OSError as err:  # includes an unreachable scheduler (distributed's timeouts)
        print(f"navgw fleet: {err.filename or args.scheduler or ''}: {err}", file=sys.stderr)
        return 2
    print(args.out)
    return 0


def _job(args: argparse.Namespace) -> FleetJob:
    config = load_config(args.config) if args.config else None
    engines: tuple[Engine, ...]
    if args.engine == BOTH:
        engines = (Engine.OBSERVER, Engine.EKF)
    else:
        default = config.estimator.engine if config else Engine.OBSERVER
        engines = (Engine(args.engine) if args.engine else default,)
    if args.workers is not None and args.workers < 1:
        raise InputError(f"--workers {args.workers}", "the command line", "1 or more")
    if args.logs:
        args.logs.mkdir(parents=True, exist_ok=True)
    return FleetJob(engines, config, args.logs.resolve() if args.logs else None)
