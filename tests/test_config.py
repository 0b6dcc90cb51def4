"""Service configuration: SPEC 5 keys, one place for defaults, messages that name the problem."""

from __future__ import annotations

import dataclasses
import re
from pathlib import Path

import pytest

from gateway.cli.main import main
from gateway.config.config_schema import ConfigError, tomllib
from gateway.config.gateway_config import (
    ENGINE_SECTIONS,
    RETIRED_KEYS,
    Engine,
    GatewayConfig,
    config_from_table,
    example_toml,
    load_config,
)
from gateway.isobus.j1939 import Pgn


def test_spec5_vehicle_keys_reach_the_engine_config() -> None:
    cfg = config_from_table(
        {
            "vehicle": {"antenna_lever_arm_m": [0.0, 0.0, -3.0], "imu_lever_arm_m": [0, 0, -1]},
            "gnss": {"receiver_latency_s": 0.08},
            "observer": {"tau_s": 5.0},
        }
    )
    for engine in Engine:
        tuning = cfg.with_engine(engine).engine_settings()
        assert tuning.antenna_lever_arm_m == (0.0, 0.0, -3.0)
        assert tuning.imu_lever_arm_m == (0.0, 0.0, -1.0)
        assert tuning.receiver_latency_s == 0.08
    assert cfg.observer.tau_s == 5.0 and cfg.observer.tau_g_s == 40.0


def test_example_is_complete_valid_and_equal_to_the_defaults() -> None:
    text = example_toml()
    assert config_from_table(tomllib.loads(text)) == GatewayConfig()
    for key in ("antenna_lever_arm_m", "imu_mounting_rpy_deg", "attitude_hz = 50.0", "tau_g_s"):
        assert key in text


def test_example_explains_every_engine_key_in_plain_text(tmp_path: Path) -> None:
    """[observer] and [ekf] keys had no comments and their headers showed Sphinx roles."""
    text = example_toml()
    assert ":class:" not in text and "`" not in text
    commented_key = re.compile(r"^(?:# )?(\w+) = .+  # \S")
    for name, cls in ENGINE_SECTIONS.items():
        shared = set(GatewayConfig().shared(cls))  # given in [vehicle], [gnss], [imu] instead
        lines = text.split(f"\n[{name}]\n")[1].split("\n\n")[0].splitlines()
        assert lines[0] == (
            f'# tuning of engine = "{name}"; its lever arms, GNSS timing and IMU figures are set '
            "in [vehicle] and [gnss] and [imu]"
        )
        keys = [m[1] for line in lines[1:] if (m := commented_key.match(line))]
        assert len(keys) == len(lines) - 1, [line for line in lines if "  # " not in line]
        assert set(keys) == {f.name for f in dataclasses.fields(cls)} - shared
    path = tmp_path / "navgw.toml"
    path.write_text(text)
    assert main(["config", "--check", str(path)]) == 0


def test_output_rates_map_to_pgns() -> None:
    rates = config_from_table({"output": {"attitude_hz": 20, "status_hz": 0}}).output.rates_hz()
    assert rates[Pgn.ATTITUDE] == 20.0 and rates[Pgn.NAVGW_STATUS] == 0.0
    assert rates[Pgn.GNSS_POSITION_DATA] == 10.0


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("[vehicel]\n", "unknown section [vehicel] in"),
        (
            "[vehicle]\nantenna_lever_arm_m = [0, 0]\n",
            "vehicle.antenna_lever_arm_m = [0, 0]: expected a list of 3",
        ),
        (
            "[observer]\nantenna_lever_arm_m = [0, 0, 1]\n",
            "observer.antenna_lever_arm_m: set it once, in [vehicle]",
        ),
        (
            '[estimator]\nengine = "kalman"\n',
            "estimator.engine = 'kalman': expected one of 'observer', 'ekf'",
        ),
        (
            "[isobus]\npreferred_address = 300\n",
            "isobus.preferred_address = 300: expected a value in [0, 253]",
        ),
        ("[output]\nattitude_hz = -1\n", "output.attitude_hz = -1: expected a value in"),
        ("[gnss\n", "not valid TOML"),
        ("[observer]\ntau_s = 0\n", "observer.tau_s = 0: expected a number > 0"),
        ("[ekf]\ngate_sigma = -5.0\n", "ekf.gate_sigma = -5.0: expected a number > 0"),
        ("[ekf]\nvibration_gyro_dps = -0.1\n", "expected a number >= 0"),
        ("[observer]\ntau_g_s = nan\n", "observer.tau_g_s = nan: expected a finite number"),
        (
            "[vehicle]\nantenna_lever_arm_m = [0, 0, inf]\n",
            "vehicle.antenna_lever_arm_m[2] = inf: expected a finite number",
        ),
    ],
)
def test_bad_files_name_file_key_value_and_expectation(
    tmp_path: Path, text: str, message: str
) -> None:
    path = tmp_path / "navgw.toml"
    path.write_text(text)
    with pytest.raises(ConfigError) as err:
        load_config(path)
    assert str(err.value).startswith(str(path)) and message in str(err.value)


def test_missing_file_and_engine_override(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="cannot read config file"):
        load_config(tmp_path / "absent.toml")
    assert GatewayConfig().with_engine(Engine.EKF).estimator.engine is Engine.EKF


def test_a_binary_config_is_a_clear_error(tmp_path: Path) -> None:
    path = tmp_path / "navgw.toml"
    path.write_bytes(b"\x89PNG\r\n\x1a\n\x00\xff")
    with pytest.raises(ConfigError, match=r"not a text file .* expected a TOML config"):
        load_config(path)


def test_zero_vibration_and_any_bearing_are_accepted(tmp_path: Path) -> None:
    path = tmp_path / "navgw.toml"
    path.write_text("[ekf]\nvibration_gyro_dps = 0.0\n[observer]\nab_line_bearing_deg = -45.0\n")
    config = load_config(path)
    assert config.ekf.vibration_gyro_dps == 0.0 and config.observer.ab_line_bearing_deg == -45.0


def test_a_retired_key_is_ignored_with_a_warning_and_the_rest_still_read(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """`navgw config --example` writes every key, so a config of an earlier release may set
    one that is gone: an upgrade must not stop the service on it."""
    (section, retired), *_ = ((s, k) for s, keys in RETIRED_KEYS.items() for k in keys)
    path = tmp_path / "old.toml"
    path.write_text(f"[{section}]\n{retired} = 5e-4\nalign_min_speed_mps = 3.0\n")
    with caplog.at_level("WARNING", logger="gateway.config.gateway_config"):
        config = load_config(path)
    assert getattr(config, section).align_min_speed_mps == 3.0
    assert f"{path}: {section}.{retired} is ignored" in caplog.text
    assert main(["config", "--check", str(path)]) == 0


def test_a_moved_key_keeps_its_meaning_in_its_new_place(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """The temperature coefficients were [state]'s while only the warm start used them; an
    older config's value is taken as [imu]'s, the engines' and the store's alike, unless
    [imu] sets it too."""
    path = tmp_path / "old.toml"
    path.write_text("[state]\ngyro_bias_tempco_dps_per_c = 0.02\nmax_age_days = 7.0\n")
    with caplog.at_level("WARNING", logger="gateway.config.gateway_config"):
        config = load_config(path)
    assert config.imu.gyro_bias_tempco_dps_per_c == 0.02 and config.state.max_age_days == 7.0
    assert config.engine_settings().gyro_bias_tempco_dps_per_c == 0.02
    assert f"{path}: state.gyro_bias_tempco_dps_per_c is now imu." in caplog.text
    path.write_text(
        "[state]\ngyro_bias_tempco_dps_per_c = 0.02\n[imu]\ngyro_bias_tempco_dps_per_c = 0.03\n"
    )
    assert load_config(path).imu.gyro_bias_tempco_dps_per_c == 0.03
    assert main(["config", "--check", str(path)]) == 0
