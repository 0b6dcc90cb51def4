"""``navgw replay``: SPEC 5, recorded logs through the live fusion code to an output log."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Iterable, Iterator
from pathlib import Path

from drivers.errors import DriverError
from drivers.logs.candump import time_span
from gateway.config.config_schema import ConfigError
from gateway.config.gateway_config import Engine, load_config
from gateway.offline.log_inputs import Input, LogInputs
from gateway.offline.log_replay import ReplaySummary, replay, unreadable


def add_subparser(
    subparsers: argparse._SubParsersAction[argparse.ArgumentParser], help_text: str
) -> None:
    """Register ``replay``."""
    p = subparsers.add_parser(
        "replay",
        help=help_text,
        description="Read an IMU CAN log (candump -L) and an NMEA log, merge them by time, run "
        "the live fusion code with the clock taken from the logs, and write every frame the "
        "gateway would have sent (candump -L) to OUT. Deterministic.",
    )
    p.add_argument("--can", required=True, type=Path, help="IMU bridge frames, candump -L")
    p.add_argument("--nmea", required=True, type=Path, help="NMEA log, optionally host-stamped")
    p.add_argument("--out", required=True, type=Path, help="output frames, candump -L")
    p.add_argument("--config", type=Path, help="gateway config (TOML)")
    p.add_argument("--engine", choices=[e.value for e in Engine], help="override [estimator]")
    p.add_argument(
        "--state-dir",
        type=Path,
        metavar="DIR",
        help="start from the learned state in DIR (a warm start, as the service's) and save "
        "what was learned there at the end; default: a cold start, no state kept",
    )
    p.set_defaults(func=run)


def _progress(items: Iterable[Input], inputs: LogInputs) -> Iterator[Input]:
    """A progress bar in log seconds on a terminal; the plain iterator otherwise."""
    if not sys.stderr.isatty():
        yield from items
        return
    from tqdm import tqdm

    span = time_span(inputs.can_log)
    with tqdm(total=round(span[1] - span[0]) if span else 0, unit="s", desc="replay") as bar:
        t0 = None
        for item in items:
            t0 = item.t if t0 is None else t0
            if item.t - t0 - bar.n >= 1.0:
                bar.update(int(item.t - t0) - bar.n)
            yield item


def summary_text(s: ReplaySummary) -> str:
    """The end-of-run summary, one screen."""
    imu, gnss = s.imu, s.gnss
    return "\n".join(
        [
            f"replayed {s.log_span_s:.1f} s of logs in {s.wall_s:.1f} s "
            f"({s.speedup:.0f}x real time)",
            f"  IMU:  {s.stats.imu_samples} samples, {imu.lost} lost, {imu.duplicates} duplicate, "
            f"{imu.out_of_order} out of order, {imu.malformed} malformed frames, "
            f"{imu.saturated} saturated, {imu.stuck} stuck, {s.bad_can_lines} bad log lines"
            + (f"; {n} host clock step(s) taken out (see above)" if (n := imu.clock_steps) else "")
            + (f"; {n} frame(s) stamped before their partner" if (n := imu.bad_stamps) else ""),
            f"  GNSS: {s.stats.gnss_fixes} fixes, {gnss.checksum_errors} checksum errors, "
            f"{gnss.parse_errors} parse errors, {gnss.skipped_bytes} junk bytes, "
            f"{s.bad_nmea_lines} bad log lines",
            f"  out:  {s.stats.frames_out} frames"
            + (f", {n} engine faults (raised: see above)" if (n := s.stats.engine_faults) else ""),
        ]
    )


def run(args: argparse.Namespace) -> int:
    """Exit 0 on success; 2 with a message on a bad config or unreadable input (a log that
    gave no IMU sample or no GNSS fix: empty, garbage, binary, or the two swapped)."""
    try:
        config = load_config(args.config)
        if args.engine:
            config = config.with_engine(Engine(args.engine))
        if warning := config.lever_arm_warning():
            print(
                f"navgw replay: warning: {warning}; set [vehicle] in a --config file (navgw "
                "sim writes its vehicle's: navgw.toml beside the logs)",
                file=sys.stderr,
            )
        result = replay(args.can, args.nmea, args.out, config, _progress, args.state_dir)
    except (ConfigError, DriverError) as err:
        print(f"navgw replay: {err}", file=sys.stderr)
        return 2
    except OSError as err:
        print(f"navgw replay: {err.filename}: {err.strerror}", file=sys.stderr)
        return 2
    print(summary_text(result), file=sys.stderr)
    if args.state_dir is not None:
        start = "warm start" if result.warm_start else "cold start"
        saved = "learned state saved" if result.state_saved else "nothing new saved"
        print(f"  state: {start}, {saved} ({args.state_dir})", file=sys.stderr)
    unread = unreadable(result, args.can, args.nmea)
    if unread:
        print(f"navgw replay: {unread}", file=sys.stderr)
        return 2
    return 0
