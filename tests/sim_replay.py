"""A simulated run through ``navgw replay``'s code with one engine: the tests' one way to it."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import numpy as np

from gateway.config.gateway_config import Engine, load_config
from gateway.offline.log_replay import replay
from sim_bus.scenarios import SCENARIOS, SimRun, generate
from sim_bus.truth import Truth
from tests.n2k_check import (
    attitude_errors_deg,
    decode_log,
    heading_beyond_navigating,
    position_beyond_mode,
    tilt_beyond_stated,
)


def short_with_receiver(out_dir: Path, seed: int, **receiver: Any) -> SimRun:
    """The `short` scenario with its receiver's ``GnssReceiverConfig`` fields changed,
    simulated with ``seed`` into ``out_dir``."""
    base = SCENARIOS["short"]
    gnss = dataclasses.replace(base.gnss, **receiver)
    return generate(dataclasses.replace(base, name="short-receiver", gnss=gnss), out_dir, seed)


def replay_run(run: SimRun, engine: Engine, out: Path) -> Truth:
    """Replay ``run``'s logs with its navgw.toml and ``engine`` into ``out`` (candump -L);
    the run's truth."""
    replay(run.imu_log, run.gnss_log, out, load_config(run.config_file).with_engine(engine))
    return Truth.load(run.truth_file)


def replayed_with_receiver(
    out_dir: Path, seed: int, engine: Engine, **receiver: Any
) -> tuple[Path, Truth]:
    """:func:`short_with_receiver` replayed by ``engine``: its frames (candump -L) and truth."""
    out = out_dir / "out.log"
    return out, replay_run(short_with_receiver(out_dir / "run", seed, **receiver), engine, out)


def second_half_rms_deg(out: Path, truth: Truth) -> tuple[float, float, float]:
    """Roll, pitch and yaw RMS (deg) of the 127257 frames in ``out`` over the run's second
    half, decoded by the independent ``nmea2000`` package."""
    half_s = 0.5 * float(truth.t[-1] - truth.t[0])
    errors = attitude_errors_deg(decode_log(out), truth, half_s)
    roll, pitch, yaw = np.sqrt(np.mean(np.square(errors), axis=0))
    return float(roll), float(pitch), float(yaw)


def beyond_stated(out: Path, truth: Truth) -> tuple[int, list[str]]:
    """The never-lie checks of ``out`` (tests/n2k_check.py): the attitude frames that state an
    accuracy, and one line for each roll/pitch, heading or reference point beyond it."""
    checked, tilt = tilt_beyond_stated(out, truth)
    heading = heading_beyond_navigating(out, truth)[1]
    return checked, tilt + heading + position_beyond_mode(out, truth)[1]
