"""A cold IMU warming up: its biases follow its temperature, and both engines follow them.

A cold start on a 9 deg slope (``slope-start`` seed 702) with the unit at 5 degC warming to
45 degC with a 5 min time constant (8 degC a minute at first), its biases following by
coefficients drawn at the datasheet class's 0.01 deg/s and 0.1 mg per degC 1-sigma
(robustness ``imu-warm-up``): through ``navgw replay``, the frames decoded by the
independent ``nmea2000`` package. The engines' bias walks were the in-run wander's alone
(0.007 deg/s over 100 s) and eq. (11)'s time constant the paper's 40 s, so the biases
lagged the warm-up: roll RMS over the second half 0.159 (observer) and 0.143 deg (EKF), yaw
0.138 and 0.215. Now the IMU_AUX temperature's rate adds the datasheet coefficients' walk
(gateway/estimation/temperature.py): 0.090 and 0.098, yaw 0.122 and 0.068.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import pytest

from gateway.config.gateway_config import Engine, load_config
from gateway.offline.log_replay import replay
from sim_bus.scenarios import SimRun, generate, scenario_from_toml
from sim_bus.truth import Truth
from tests.n2k_check import (
    heading_beyond_navigating,
    tilt_beyond_stated,
)
from tests.sim_replay import replay_run, second_half_rms_deg

WARM_UP = {
    "temp_start_c": 5.0,
    "temp_end_c": 45.0,
    "temp_tau_s": 300.0,
    "gyro_bias_tempco_sigma_rps_per_c": 0.01 * math.pi / 180.0,
    "accel_bias_tempco_sigma_mps2_per_c": 0.1e-3 * 9.80665,
}


@pytest.fixture(scope="module")
def warming(tmp_path_factory: pytest.TempPathFactory) -> SimRun:
    scenario = scenario_from_toml({"base": "slope-start", "name": "warm", "imu": WARM_UP})
    return generate(scenario, tmp_path_factory.mktemp("warm"), seed=702)


@pytest.mark.parametrize("engine", list(Engine))
def test_both_engines_follow_a_warming_unit_s_biases(
    warming: SimRun, engine: Engine, tmp_path: Path
) -> None:
    out = tmp_path / "out.log"
    truth = replay_run(warming, engine, out)
    roll, pitch, yaw = second_half_rms_deg(out, truth)
    assert roll < 0.115 and pitch < 0.115 and yaw < 0.13, (roll, pitch, yaw)
    checked, beyond = tilt_beyond_stated(out, truth)
    assert checked > 8_000 and beyond == []
    assert heading_beyond_navigating(out, truth)[1] == []


@pytest.mark.parametrize("engine", list(Engine))
def test_coefficients_configured_at_the_range_s_end_send_nothing_beyond(
    warming: SimRun, engine: Engine, tmp_path: Path
) -> None:
    """[imu] coefficients ten and twenty times the unit's (0.1 deg/s and 2 mg per degC, the
    most the config takes): the engines' bias walks are that much faster, and the attitude
    noisier, but stated so. At 1 deg/s and 100 mg per degC their bias estimates went beyond
    the sensor's range (withheld): the config refuses such values."""
    config = load_config(warming.config_file).with_engine(engine)
    imu = dataclasses.replace(
        config.imu, gyro_bias_tempco_dps_per_c=0.1, accel_bias_tempco_mg_per_c=2.0
    )
    out = tmp_path / "out.log"
    replay(warming.imu_log, warming.gnss_log, out, dataclasses.replace(config, imu=imu))
    truth = Truth.load(warming.truth_file)
    checked, beyond = tilt_beyond_stated(out, truth)
    assert checked > 7_000 and beyond == []
    assert heading_beyond_navigating(out, truth)[1] == []
