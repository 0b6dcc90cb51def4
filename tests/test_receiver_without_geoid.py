"""A receiver that sends no geoid separation in its GGA (no geoid model: telit-he910,
quectelLC79D-1, iTrek, rst39 and more of the gpsd logs).

The decoder took the height as unknown without the separation, and both engines use no
position without a height: `short` seed 3 so, neither sent a position, the EKF no heading
either (it aligns on a position) and its roll/pitch went 0.62/0.56 deg RMS over the second
half. The altitude is now taken as it is sent: a height of unknown datum, right in its
changes, which is all the engines need; 129029 says "not available" for the altitude (its
field is the WGS-84 ellipsoid's) and the geoid separation.

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
def without(tmp_path_factory: pytest.TempPathFactory) -> SimRun:
    return short_with_receiver(tmp_path_factory.mktemp("geoid"), 3, geoid_separation_m=None)


@pytest.fixture(scope="module")
def with_separation(tmp_path_factory: pytest.TempPathFactory) -> SimRun:
    return short_with_receiver(tmp_path_factory.mktemp("geoid47"), 3, geoid_separation_m=47.0)


def test_the_receiver_sends_the_separation_blank(without: SimRun) -> None:
    gga = [line for line in without.gnss_log.read_text().splitlines() if "GGA," in line]
    fields = [line.split("*")[0].split(",") for line in gga if ",4," in line]
    assert len(fields) > 1000 and all(f[11] == "" and f[9] != "" for f in fields)


@pytest.mark.parametrize("engine", list(Engine))
def test_both_engines_navigate_without_the_geoid_separation(
    without: SimRun, with_separation: SimRun, engine: Engine, tmp_path: Path
) -> None:
    out, out_with = tmp_path / "without.log", tmp_path / "with.log"
    truth = replay_run(without, engine, out)
    replay_run(with_separation, engine, out_with)
    rms = np.array(second_half_rms_deg(out, truth))
    assert np.allclose(rms, second_half_rms_deg(out_with, truth), atol=0.002), rms
    assert rms[0] < 0.1 and rms[1] < 0.1 and rms[2] < 0.2, rms
    half_s = 0.5 * float(truth.t[-1] - truth.t[0])
    messages = decode_log(out)
    errors = position_errors_m(messages, truth, half_s)
    assert errors.size > 2000 and np.sqrt(np.mean(errors**2)) < 0.03
    gnss = [m for m in messages if m.id == "gnssPositionData"]
    assert len(gnss) > 100 and all(m.fields["latitude"] is not None for m in gnss[-100:])
    assert all(m.fields.get("altitude") is None for m in gnss)
    assert all(m.fields.get("geoidalSeparation") is None for m in gnss)
    with_alt = [m for m in decode_log(out_with) if m.id == "gnssPositionData"]
    last = with_alt[-1].fields  # the same receiver with a separation
    assert last["altitude"] is not None and last["geoidalSeparation"] is not None
    assert beyond_stated(out, truth)[1] == []
