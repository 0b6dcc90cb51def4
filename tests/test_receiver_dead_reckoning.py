"""A receiver that carries its last fix on through an outage, as dead reckoning.

A u-blox without sensors of its own goes on sending fixes for up to its drLimit after the
satellites are lost: GGA quality 6, RMC/VTG mode E, its last position moved on at its last
velocity, course and all. Both engines took those epochs as measurements (3 m, 0.3 m/s): in
a U-turn the held course pulled them off the turn. ``short`` seed 3, 12 s without
satellites through the first U-turn (52-64 s), carried on for up to 20 s: the observer's
position went 28-32 m off, every RTK fix after the outage was rejected as a glitch for a
minute, and roll/pitch RMS over the second half was 0.41/0.52 deg; the EKF's 0.10/0.11
(0.05/0.06 without the receiver's dead reckoning). On `outages` seed 732 the EKF's yaw RMS
was 76 deg. Such epochs now measure nothing (:data:`drivers.samples.MEASURING_QUALITIES`):
the engines coast on their own IMU through them, as through epochs without a fix.

Replayed through ``navgw replay``'s code, the frames decoded by the independent ``nmea2000``
package.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from drivers.samples import FixQuality
from gateway.config.gateway_config import Engine
from sim_bus.gnss_receiver import FixInterval
from sim_bus.scenarios import SimRun
from tests.n2k_check import decode_log, position_errors_m
from tests.sim_replay import beyond_stated, replay_run, second_half_rms_deg, short_with_receiver

OUTAGE_S = (52.0, 64.0)  # the first U-turn of `short`, 19 deg/s at 2 m/s


def _run(tmp_path_factory: pytest.TempPathFactory, limit_s: float) -> SimRun:
    return short_with_receiver(
        tmp_path_factory.mktemp(f"dr{limit_s:g}"),
        3,
        fix_schedule=(FixInterval(*OUTAGE_S, FixQuality.NONE),),
        dead_reckoning_limit_s=limit_s,
    )


@pytest.fixture(scope="module")
def carried_on(tmp_path_factory: pytest.TempPathFactory) -> SimRun:
    return _run(tmp_path_factory, 20.0)


@pytest.fixture(scope="module")
def silent(tmp_path_factory: pytest.TempPathFactory) -> SimRun:
    return _run(tmp_path_factory, 0.0)


def test_the_receiver_carries_its_last_fix_on_through_the_outage(carried_on: SimRun) -> None:
    lines = carried_on.gnss_log.read_text().splitlines()
    gga = [line.split("$")[1].split("*")[0].split(",") for line in lines if "GGA," in line]
    quality = [int(f[6]) for f in gga]
    assert quality.count(int(FixQuality.DEAD_RECKONING)) == 120  # the whole 12 s at 10 Hz
    assert quality.count(int(FixQuality.NONE)) == 0


@pytest.mark.parametrize("engine", list(Engine))
def test_the_receivers_dead_reckoning_is_coasted_through_as_an_outage(
    carried_on: SimRun, silent: SimRun, engine: Engine, tmp_path: Path
) -> None:
    out, out_silent = tmp_path / "dr.log", tmp_path / "silent.log"
    truth = replay_run(carried_on, engine, out)
    replay_run(silent, engine, out_silent)
    rms = np.array(second_half_rms_deg(out, truth))
    rms_silent = np.array(second_half_rms_deg(out_silent, truth))
    assert np.all(np.abs(rms - rms_silent) < 0.005), (rms, rms_silent)
    assert rms[0] < 0.15 and rms[1] < 0.15, rms
    after = position_errors_m(decode_log(out), truth, OUTAGE_S[1] + 5.0)
    assert after.size > 2000 and np.max(after) < 0.1
    checked, beyond = beyond_stated(out, truth)
    assert checked > 5000 and beyond == [], beyond[:5]
