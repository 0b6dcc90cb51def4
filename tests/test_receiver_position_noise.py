"""A receiver whose positions are white from epoch to epoch: 2 cm per horizontal axis on
top of RTK's wander, no GST (GGA's default RTK sigma, 2 cm, is then right in size but not
in kind).

The engines split a fix's sigma into a white share (0.3) and a wander: an RTK solution
moves by millimetres from one epoch to the next. The EKF gated such positions at 5 sigma of
that share, rejected a third of them and flapped between NAVIGATING and DEGRADED a few
times a second (2,800 of 6,100 attitude frames without a stated accuracy on `short` seed
5). Both engines now take the white share the receiver's track shows where it is more
(``gateway.estimation.gnss_error.PositionNoise``; docs/ROBUSTNESS.md "Inputs").
Replayed through ``navgw replay``'s code, decoded by the independent ``nmea2000`` package.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from gateway.config.gateway_config import Engine
from tests.n2k_check import DEGRADED, status_modes
from tests.sim_replay import beyond_stated, replay_run, short_with_receiver


@pytest.mark.parametrize("seed", [5, 7])
@pytest.mark.parametrize("engine", list(Engine))
def test_a_receiver_with_white_positions_is_weighed_by_its_noise(
    engine: Engine, seed: int, tmp_path: Path
) -> None:
    run = short_with_receiver(tmp_path / "run", seed, position_white_sigma_m=0.02, gst=False)
    out = tmp_path / "out.log"
    truth = replay_run(run, engine, out)
    checked, beyond = beyond_stated(out, truth)
    assert checked > 6000 and beyond == [], (checked, beyond[:5])
    status = status_modes(out)
    modes = np.array([m for _, m in status])
    onsets = np.flatnonzero((modes[1:] == DEGRADED) & (modes[:-1] != DEGRADED))
    assert len(onsets) <= 1, [round(status[i + 1][0] - truth.t[0], 1) for i in onsets]
