"""``navgw demo``: a simulated field run through the live service, no hardware needed."""

from __future__ import annotations

import argparse
import asyncio
import logging
import sys
from collections.abc import Callable
from pathlib import Path

from gateway.demo.demo_run import (
    DEFAULT_MINUTES,
    DEFAULT_SCENARIO,
    DEFAULT_SPEED,
    DemoOptions,
    run_demo,
)
from sim_bus.scenarios import SCENARIOS

SERVICE_LOG = "navgw-demo.log"
PLAIN_EVERY = 4  # without a terminal, print every 4th view (every 2 s)


def add_subparser(
    subparsers: argparse._SubParsersAction[argparse.ArgumentParser], help_text: str
) -> None:
    """Register ``demo``."""
    p = subparsers.add_parser(
        "demo",
        help=help_text,
        description="Simulate a field run, play its IMU frames onto a virtual CAN bus and its "
        "NMEA sentences onto a pseudo-terminal faster than real time, run the live gateway "
        "service on them, and show its estimates next to the simulator's truth. Ends with "
        "the output frames (candump -L), a picture of the run as navgw plot draws it "
        "(PNG, needs matplotlib) and a summary, all in --out.",
    )
    p.add_argument(
        "--scenario",
        choices=sorted(SCENARIOS),
        default=DEFAULT_SCENARIO,
        help=f"built-in scenario (default {DEFAULT_SCENARIO})",
    )
    p.add_argument("--seed", type=int, default=0, help="random seed of the run (default 0)")
    p.add_argument(
        "--speed",
        type=float,
        default=DEFAULT_SPEED,
        help=f"times real time (default {DEFAULT_SPEED:g})",
    )
    p.add_argument(
        "--minutes",
        type=float,
        default=DEFAULT_MINUTES,
        help=f"simulated minutes to play, 0 for all (default {DEFAULT_MINUTES:g})",
    )
    p.add_argument(
        "--out",
        type=Path,
        default=Path("navgw-demo"),
        help="output directory (default ./navgw-demo)",
    )
    p.set_defaults(func=run)


def _viewer(tty: bool) -> Callable[[str], None]:
    """Redraw the view in place on a terminal; plain lines, less often, otherwise."""
    state = {"lines": 0, "calls": 0}

    def show(text: str) -> None:
        state["calls"] += 1
        if tty:
            up = f"\x1b[{state['lines']}F\x1b[J" if state["lines"] else ""
            sys.stdout.write(up + text + "\n")
            state["lines"] = text.count("\n") + 1
        elif state["calls"] % PLAIN_EVERY == 1:
            sys.stdout.write(text + "\n\n")
        sys.stdout.flush()

    return show


def run(args: argparse.Namespace) -> int:
    """0 when the demo ran; 2 on bad options."""
    if not args.speed > 0:
        print(f"navgw demo: --speed {args.speed}: expected > 0", file=sys.stderr)
        return 2
    args.out.mkdir(parents=True, exist_ok=True)
    log_file = args.out / SERVICE_LOG
    logging.basicConfig(
        level=logging.INFO,
        format="%(asctime)s %(levelname)s %(name)s: %(message)s",
        handlers=[logging.FileHandler(log_file, mode="w")],
        force=True,
    )
    options = DemoOptions(
        out_dir=args.out,
        scenario=args.scenario,
        seed=args.seed,
        speed=args.speed,
        minutes=args.minutes or None,
    )
    print(
        f"navgw demo: scenario {args.scenario}, {args.speed:g}x real time; "
        f"service log in {log_file}\n"
    )
    summary = asyncio.run(run_demo(options, _viewer(sys.stdout.isatty())))
    print("\n" + summary.text())
    return 0
