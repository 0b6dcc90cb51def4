"""``navgw sim``: write the IMU log, NMEA log and truth of a named or configured scenario."""

from __future__ import annotations

import argparse
import shlex
import sys
import time
from pathlib import Path

from gateway.config.config_schema import ConfigError, load_toml
from sim_bus.scenarios import SCENARIOS, Scenario, SimRun, generate, scenario_from_toml


def add_subparser(
    subparsers: argparse._SubParsersAction[argparse.ArgumentParser], help_text: str
) -> None:
    """Register ``sim``."""
    listing = "\n".join(f"  {name:20s} {sc.description}" for name, sc in SCENARIOS.items())
    p = subparsers.add_parser(
        "sim",
        help=help_text,
        description="Simulate a field run and write imu.log (candump -L), gnss.nmea "
        "(host-stamped NMEA), truth.npz and navgw.toml (the gateway config of the simulated "
        "vehicle, for navgw replay --config) into the --out directory.\n\nscenarios:\n" + listing,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument(
        "scenario",
        nargs="?",
        metavar="NAME",
        help="built-in scenario, listed above (default field, or the --config file's base)",
    )
    p.add_argument("--out", type=Path, metavar="DIR", help="output directory (default ./sim-NAME)")
    p.add_argument("--seed", type=int, default=0, help="random seed of the run (default 0)")
    p.add_argument(
        "--config",
        type=Path,
        metavar="FILE",
        help="TOML file: [vehicle]/[imu]/[bridge]/[gnss] overrides of NAME "
        "(or of the file's base = NAME)",
    )
    p.set_defaults(func=run)


def _scenario(args: argparse.Namespace) -> Scenario:
    """NAME, with the --config file's overrides: the file's ``base`` if NAME is not given
    (a NAME the file's ``base`` contradicts is an error, not a silent choice)."""
    name: str | None = args.scenario
    if name is not None and name not in SCENARIOS:
        raise ConfigError(f"unknown scenario {name!r}: expected one of {', '.join(SCENARIOS)}")
    if args.config is None:
        return SCENARIOS[name or "field"]
    table = load_toml(args.config)
    if name is not None and table.get("base", name) != name:
        raise ConfigError(
            f"{args.config}: base = {table['base']!r}, but the command names {name!r}: "
            "give the scenario once"
        )
    return scenario_from_toml(table, str(args.config), default_base=name or "field")


def run(args: argparse.Namespace) -> int:
    """Generate the run; exit status 0, or 2 with a message on a bad scenario or config."""
    try:
        scenario = _scenario(args)
    except ConfigError as err:
        print(f"navgw sim: {err}", file=sys.stderr)
        return 2
    out_dir = args.out or Path(f"sim-{scenario.name.rstrip('*')}")
    t_wall = time.perf_counter()
    try:
        result = generate(scenario, out_dir, args.seed)
    except ValueError as err:  # the vehicle model's checks of what the config asks of it
        print(f"navgw sim: {scenario.name}: {err}", file=sys.stderr)
        return 2
    wall = time.perf_counter() - t_wall
    print(
        f"{scenario.name}: {result.duration_s:.0f} s simulated in {wall:.1f} s, "
        f"{result.imu_samples} IMU samples ({result.can_frames} CAN frames), "
        f"{result.nmea_lines} NMEA sentences\n"
        f"  {result.imu_log}\n  {result.gnss_log}\n  {result.truth_file}\n  {result.config_file}\n"
        f"replay it through the gateway with:\n  {replay_command(result, out_dir / 'replay.log')}"
    )
    return 0


def replay_command(run: SimRun, out_log: Path) -> str:
    """The ``navgw replay`` command line of a run, with the run's config (SPEC 5)."""
    return shlex.join(
        [
            "navgw", "replay", "--can", str(run.imu_log), "--nmea", str(run.gnss_log),
            "--config", str(run.config_file), "--out", str(out_log),
        ]
    )  # fmt: skip
