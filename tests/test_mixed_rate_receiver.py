"""A receiver that sends its positions faster than its velocity: GGA at 10 Hz, RMC, VTG, GST
and ZDA at 1 Hz (the gpsd regression log rst39.log is one such receiver).

Both engines stayed ALIGNING for a whole run: nothing but NAVGW_STATUS and the first
levelling's attitude went out. The decoder learnt one sentence set for every epoch, {GGA}
from the GGA-only ones, so each whole second's epoch went at its GGA and its RMC came late:
no fix carried a velocity. And the observer ended its chain of eq. (3) differences at every
epoch without a velocity, so with the velocity once a second its tilt loop never closed.
Now the set is learnt per place in the second, and an epoch with a position alone leaves the
chain, the control period and the gates as they were.

``short`` seed 3 with that receiver through ``navgw replay``, the frames decoded by the
independent ``nmea2000`` package: as a 1 Hz receiver's (robustness ``gnss-1hz``: observer
roll/pitch/yaw RMS 0.064/0.078/0.196 deg, EKF 0.050/0.055/0.072), positions at 10 Hz.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from gateway.config.gateway_config import Engine
from gateway.estimation.solution import Mode
from sim_bus.scenarios import SimRun, generate, scenario_from_toml
from tests.n2k_check import (
    decode_log,
    heading_beyond_navigating,
    position_beyond_mode,
    position_errors_m,
    status_modes,
    tilt_beyond_stated,
)
from tests.sim_replay import replay_run, second_half_rms_deg

SLOW = ["RMC", "VTG", "GST", "ZDA"]
RECEIVER = {"slow_sentences": SLOW, "slow_rate_hz": 1.0}


@pytest.fixture(scope="module")
def mixed_rate(tmp_path_factory: pytest.TempPathFactory) -> SimRun:
    scenario = scenario_from_toml({"base": "short", "name": "rmc-1hz", "gnss": RECEIVER})
    return generate(scenario, tmp_path_factory.mktemp("mixed"), seed=3)


@pytest.fixture(scope="module")
def mixed_rate_stop(tmp_path_factory: pytest.TempPathFactory) -> SimRun:
    """The same drive with a 3-minute stop half-way along its second pass (56-236 s)."""
    scenario = scenario_from_toml(
        {
            "base": "short",
            "name": "rmc-1hz-stop",
            "gnss": RECEIVER,
            "vehicle": {"mid_stop_pass": 1, "mid_stop_s": 180.0},
        }
    )
    return generate(scenario, tmp_path_factory.mktemp("mixed-stop"), seed=3)


def test_the_receiver_sends_the_slow_sentences_on_whole_seconds(mixed_rate: SimRun) -> None:
    lines = mixed_rate.gnss_log.read_text().splitlines()
    kinds = [line.split("$")[1][2:5] for line in lines]
    n_gga = kinds.count("GGA")
    assert n_gga > 1200
    for kind in SLOW:
        assert abs(kinds.count(kind) - n_gga / 10) <= 1, kind
    whole = {line.split(",")[1] for line in lines if "RMC," in line}
    assert whole and all(t.endswith(".00") for t in whole)


@pytest.mark.parametrize("engine", list(Engine))
def test_both_engines_navigate_on_a_velocity_once_a_second(
    mixed_rate: SimRun, engine: Engine, tmp_path: Path
) -> None:
    out = tmp_path / "out.log"
    truth = replay_run(mixed_rate, engine, out)
    roll, pitch, yaw = second_half_rms_deg(out, truth)
    assert roll < 0.12 and pitch < 0.12 and yaw < 0.35, (roll, pitch, yaw)
    half_s = 0.5 * float(truth.t[-1] - truth.t[0])
    ref_cm = position_errors_m(decode_log(out), truth, half_s) * 100.0
    ref_cm = ref_cm[np.isfinite(ref_cm)]
    assert ref_cm.size > 2000 and np.sqrt(np.mean(ref_cm**2)) < 5.0
    checked, beyond = tilt_beyond_stated(out, truth)
    assert checked > 5000 and beyond == [], beyond[:5]
    assert heading_beyond_navigating(out, truth)[1] == []
    assert position_beyond_mode(out, truth)[1] == []


@pytest.mark.parametrize("engine", list(Engine))
def test_a_long_stop_keeps_the_heading_with_a_velocity_once_a_second(
    mixed_rate_stop: SimRun, engine: Engine, tmp_path: Path
) -> None:
    """The EKF's zero-rate updates span two epochs whose speeds were still; an epoch with a
    position alone cleared the spans, so no stop held the z gyro bias: DEGRADED from 50 s
    into the stop to its end, the heading 0.68 deg off and yaw RMS over the second half
    0.45 deg. Now such an epoch leaves the rest as it is: NAVIGATING through the stop."""
    out = tmp_path / "out.log"
    truth = replay_run(mixed_rate_stop, engine, out)
    stop = truth.t[truth.stationary] - truth.t[0]
    stop = stop[(stop > 50.0) & (stop < 250.0)]  # the stop, not the start's rest
    assert 170.0 < stop[-1] - stop[0] < 190.0
    modes = [(t - truth.t[0], m) for t, m in status_modes(out)]
    assert all(m == int(Mode.NAVIGATING) for t, m in modes if stop[0] + 5.0 < t < stop[-1])
    assert second_half_rms_deg(out, truth)[2] < 0.2
    assert tilt_beyond_stated(out, truth)[1] == []
    assert heading_beyond_navigating(out, truth)[1] == []
