"""`navgw run` and `navgw --help` load neither the simulator, scipy, matplotlib, the
monitor's Textual nor the fleet's Dask and pyarrow (issues 13, 18, 19): the ECU install
stays lean and the service starts fast.
Each case runs in a fresh interpreter."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

PROBE = """
import json, sys
from gateway.cli.main import build_parser, main
argv = json.loads(sys.argv[1])
if argv == ["--help"]:
    try:
        main(argv)
    except SystemExit:
        pass
else:
    build_parser(argv).parse_args(argv)
heavy = sorted(
    m for m in sys.modules
    if m.split(".")[0]
    in ("sim_bus", "scipy", "matplotlib", "textual", "dask", "distributed", "pyarrow", "pandas")
    or m.startswith(("gateway.monitor", "gateway.readback", "gateway.fleet"))
)
print(json.dumps(heavy))
"""


@pytest.mark.parametrize(
    "argv", [["--help"], ["run", "--config", "navgw.toml"], ["replay", "--can", "a", "--nmea",
             "b", "--out", "c"], ["config", "--example"],
             ["calibrate", "--can", "a", "--nmea", "b"]]
)  # fmt: skip
def test_the_service_and_help_import_no_simulator(argv: list[str]) -> None:
    out = subprocess.run(
        [sys.executable, "-c", PROBE, json.dumps(argv)], capture_output=True, text=True, check=True
    )
    assert json.loads(out.stdout.strip().splitlines()[-1]) == []


def test_the_simulator_commands_still_work_when_asked_for() -> None:
    """The lazy registration still builds the full parser of the command being run."""
    out = subprocess.run(
        [sys.executable, "-m", "gateway.cli.main", "sim", "--help"],
        capture_output=True, text=True, check=True,
    )  # fmt: skip
    assert "--out DIR" in out.stdout and "field" in out.stdout


@pytest.mark.parametrize(
    ("command", "option"),
    [("monitor", "--log LOG"), ("plot", "--truth"), ("fleet", "--scheduler ADDRESS")],
)
def test_the_off_vehicle_viewers_are_there_when_asked_for(command: str, option: str) -> None:
    out = subprocess.run(
        [sys.executable, "-m", "gateway.cli.main", command, "--help"],
        capture_output=True, text=True, check=True,
    )  # fmt: skip
    assert option in out.stdout
