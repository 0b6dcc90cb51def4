"""A receiver that prints its position with 4 decimals of a minute: rounded to 18.5 cm north
(11 cm east here), while its GST states an RTK fix's 1-2 cm.

Both engines weighed the fixes by GST alone. `short` seed 3 so: the EKF rejected most fixes
as glitches and reset on them by turns, DEGRADED and NAVIGATING every few tenths of a
second, its reference point 42 cm RMS over the second half with 52 positions beyond what
their mode states; the observer left a third of its attitude frames without a stated
accuracy. The decoder now reads the step of the position as printed
(``GnssFix.position_step_m``) and its rounding joins the fix's sigma: both at the floor the
rounding sets (its 5.3 cm north).

Replayed through ``navgw replay``'s code, the frames decoded by the independent ``nmea2000``
package.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from gateway.config.gateway_config import Engine
from sim_bus.scenarios import SimRun
from tests.n2k_check import decode_log, position_errors_m
from tests.sim_replay import beyond_stated, replay_run, second_half_rms_deg, short_with_receiver


@pytest.fixture(scope="module")
def four_decimals(tmp_path_factory: pytest.TempPathFactory) -> SimRun:
    return short_with_receiver(tmp_path_factory.mktemp("decimals"), 3, position_decimals=4)


def test_the_receiver_prints_four_decimals(four_decimals: SimRun) -> None:
    gga = [line for line in four_decimals.gnss_log.read_text().splitlines() if "GGA," in line]
    fields = [line.split(",") for line in gga if ",4," in line]
    assert len(fields) > 1000
    assert all(len(f[2].split(".")[1]) == 4 and len(f[4].split(".")[1]) == 4 for f in fields)


@pytest.mark.parametrize("engine", list(Engine))
def test_both_engines_weigh_a_rounded_position_by_its_step(
    four_decimals: SimRun, engine: Engine, tmp_path: Path
) -> None:
    out = tmp_path / "out.log"
    truth = replay_run(four_decimals, engine, out)
    roll, pitch, yaw = second_half_rms_deg(out, truth)
    assert roll < 0.1 and pitch < 0.1 and yaw < 0.15, (roll, pitch, yaw)
    half_s = 0.5 * float(truth.t[-1] - truth.t[0])
    errors = position_errors_m(decode_log(out), truth, half_s)
    assert errors.size > 2000 and np.sqrt(np.mean(errors**2)) < 0.07
    checked, beyond = beyond_stated(out, truth)
    assert checked > 5000 and beyond == [], (checked, beyond[:5])
