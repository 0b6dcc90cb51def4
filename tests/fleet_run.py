"""A small fleet on disk for the fleet tests: every kind of recording, one of them corrupt.

- ``sim-a/``: a ``navgw sim`` run directory (its vehicle's navgw.toml beside the logs);
- ``recorder/``: a second run as ``[recording]`` writes it, rotated into two pairs at
  mid-run (one recording of two parts), then a pair of the third run (a recording of its own:
  its logs do not continue the second's);
- ``manifest.toml``: names the third run's logs once more, with its config;
- ``broken/``: a run directory whose IMU log is garbage (an error row, never a failed job).

:func:`expected` replays each original, unsplit recording with :func:`replay` as ``navgw
replay`` does: the rows must agree with it.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from gateway.config.gateway_config import Engine, GatewayConfig, load_config
from gateway.offline.log_replay import ReplaySummary, replay
from gateway.readback.run_series import RunSeries, read_run
from sim_bus.scenarios import SCENARIOS, generate

STEM_1 = "navgw-000001-20231114T221320Z"
STEM_2 = "navgw-000002-20231114T221420Z"
STEM_3 = "navgw-000003-20231114T223000Z"


@dataclass(frozen=True)
class Fleet:
    """Where the fleet is, and the originals each recording replays like."""

    root: Path
    originals: dict[str, tuple[Path, Path, GatewayConfig]]  # recording name -> logs, config
    broken: str  # the corrupt recording's name

    @property
    def paths(self) -> list[Path]:
        """What ``navgw fleet`` is given: the directory, and the manifest in it."""
        return [self.root, self.root / "manifest.toml"]


def make_fleet(root: Path) -> Fleet:
    """Write the fleet under ``root`` (~1 s: three short simulated runs)."""
    runs = root / "originals"
    for seed, name in ((1, "a"), (2, "b"), (3, "c")):
        generate(SCENARIOS["short"], runs / name, seed=seed)
    fleet = root / "fleet"
    sim_a = fleet / "sim-a"
    sim_a.mkdir(parents=True)
    for file in ("imu.log", "gnss.nmea", "navgw.toml"):
        (sim_a / file).write_bytes((runs / "a" / file).read_bytes())
    recorder = fleet / "recorder"
    recorder.mkdir()
    _split(runs / "b", recorder, (STEM_1, STEM_2))
    _split(runs / "c", recorder, (STEM_3,))
    (fleet / "manifest.toml").write_text(
        f'[[recording]]\nname = "tractor-c"\ncan = "recorder/{STEM_3}.imu.log"\n'
        f'nmea = ["recorder/{STEM_3}.gnss.nmea"]\nconfig = "../originals/c/navgw.toml"\n'
    )
    broken = fleet / "broken"
    broken.mkdir()
    (broken / "imu.log").write_bytes(b"\x00\x01 not a candump log\n" * 50)
    (broken / "gnss.nmea").write_bytes((runs / "a" / "gnss.nmea").read_bytes())
    defaults = GatewayConfig()
    log = ("imu.log", "gnss.nmea")
    return Fleet(
        fleet,
        {
            str(sim_a): (
                runs / "a" / log[0],
                runs / "a" / log[1],
                load_config(sim_a / "navgw.toml"),
            ),
            str(recorder / STEM_1): (runs / "b" / log[0], runs / "b" / log[1], defaults),
            str(recorder / STEM_3): (runs / "c" / log[0], runs / "c" / log[1], defaults),
            "tractor-c": (
                runs / "c" / log[0],
                runs / "c" / log[1],
                load_config(runs / "c" / "navgw.toml"),
            ),
        },
        str(broken),
    )


def expected(fleet: Fleet, name: str, engine: Engine, out: Path) -> tuple[ReplaySummary, RunSeries]:
    """The single-recording replay of ``name``'s original logs, and its output read back."""
    can_log, nmea_log, config = fleet.originals[name]
    summary = replay(can_log, nmea_log, out, config.with_engine(engine))
    return summary, read_run(out)


def _split(run: Path, into: Path, stems: tuple[str, ...]) -> None:
    """The run's two logs as the recorder rotates them: one pair per stem, cut by time."""
    for source, suffix in (("imu.log", ".imu.log"), ("gnss.nmea", ".gnss.nmea")):
        lines = (run / source).read_text().splitlines(keepends=True)
        cut = 1_700_000_060.0 if len(stems) == 2 else float("inf")
        parts = (
            [line for line in lines if float(line[1:].split(")")[0]) < cut],
            [line for line in lines if float(line[1:].split(")")[0]) >= cut],
        )
        for stem, part in zip(stems, parts, strict=False):
            (into / (stem + suffix)).write_text("".join(part))
