"""A new user's first commands: ``navgw sim``, the replay it prints, and the demo's summary."""

from __future__ import annotations

import math
import shlex
from pathlib import Path

import pytest

from gateway.cli.main import main
from gateway.config.gateway_config import load_config
from gateway.demo.demo_run import DemoSummary
from gateway.estimation.solution import Mode

#: The shortest run: one pass of the short scenario, on a vehicle of its own geometry.
SCENARIO = """base = "short"
[vehicle]
n_passes = 1
start_stop_s = 5.0
antenna_lever_arm_m = [0.4, -0.2, -2.5]
imu_lever_arm_m = [0.6, 0.0, -0.8]
[bridge]
source_address = 0x81
"""


def test_sim_writes_its_vehicle_config_and_the_replay_command_that_uses_it(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    scenario, out = tmp_path / "scenario.toml", tmp_path / "run"
    scenario.write_text(SCENARIO)
    assert main(["sim", "--config", str(scenario), "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    config = load_config(out / "navgw.toml")
    assert config.vehicle.antenna_lever_arm_m == (0.4, -0.2, -2.5)
    assert config.vehicle.imu_lever_arm_m == (0.6, 0.0, -0.8)
    assert config.imu.bridge_source_address == 0x81
    assert 0.04 < config.gnss.receiver_latency_s < 0.1  # 40 ms + an epoch at 115200 baud
    assert main(["config", "--check", str(out / "navgw.toml")]) == 0

    command = shlex.split(printed.splitlines()[-1])
    assert command[:2] == ["navgw", "replay"]
    assert command[command.index("--config") + 1] == str(out / "navgw.toml")
    capsys.readouterr()
    assert main(command[1:]) == 0
    replayed = capsys.readouterr().err
    assert "frames" in replayed and "lever_arm" not in replayed  # no zero-lever-arm warning


def test_the_named_scenario_is_the_base_of_a_config_without_one(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``navgw sim short --config mounted.toml`` simulates ``short`` with the file's
    overrides (it simulated the 16-minute field run instead); a file whose ``base`` is
    another scenario than the one named is an error naming both."""
    overrides = tmp_path / "mounted.toml"
    overrides.write_text("[vehicle]\nn_passes = 1\nstart_stop_s = 5.0\n")
    assert main(["sim", "short", "--config", str(overrides), "--out", str(tmp_path / "a")]) == 0
    name, simulated = capsys.readouterr().out.split(" s simulated")[0].split(": ")
    assert name == "short*" and float(simulated) < 60.0  # one short pass, not field's 16 min
    contradicting = tmp_path / "field.toml"
    contradicting.write_text('base = "field"\n')
    assert main(["sim", "short", "--config", str(contradicting)]) == 2
    err = capsys.readouterr().err
    assert "base = 'field', but the command names 'short'" in err


@pytest.mark.parametrize(
    ("vehicle", "said"),
    [
        ("implement_lift_deg = 1.0\nimplement_lift_s = 0.0", "implement_lift_s=0.0"),
        ("turn_transition_m = 100.0", "turn_transition_m=100.0 must be in"),
    ],
)
def test_a_vehicle_the_model_cannot_drive_is_a_message_not_a_traceback(
    vehicle: str, said: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Values of the right type that the vehicle model cannot drive (a hitch lifting in no
    time divided by zero) exit 2 with the key and what was expected."""
    config = tmp_path / "bad.toml"
    config.write_text(f'base = "short"\n[vehicle]\n{vehicle}\n')
    assert main(["sim", "--config", str(config), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("navgw sim: short*: ") and said in err, err


def test_sim_help_names_the_out_option_as_a_directory(
    capsys: pytest.CaptureFixture[str],
) -> None:
    with pytest.raises(SystemExit):
        main(["sim", "--help"])
    assert "--out DIR" in capsys.readouterr().out


def summary(**values: object) -> DemoSummary:
    """A demo summary with made-up counts and the given errors."""
    fields: dict[str, object] = {
        "wall_s": 6.0,
        "sim_s": 60.0,
        "imu_samples": 12000,
        "imu_lost": 0,
        "gnss_fixes": 600,
        "frames_sent": 15000,
        "inputs_dropped": 0,
        "frames_shed": 0,
        "final_mode": Mode.ALIGNING,
        "navigating_after_s": None,
        "bias_g_error_dps": (0.01, -0.02, 0.003),
        "bias_a_error_mps2": (0.02, -0.09),
        "rms_rpy_deg": (0.1, 0.2, 0.3),
        "ref_point_rms_m": 0.04,
        "output_log": Path("navgw-output.log"),
        "plot": None,
        "plot_note": "no solution to plot",
    }
    return DemoSummary(**{**fields, **values})  # type: ignore[arg-type]


def test_demo_summary_of_a_run_too_short_to_measure_says_so_without_nan() -> None:
    nan3 = (math.nan, math.nan, math.nan)
    text = summary(
        bias_g_error_dps=nan3,
        bias_a_error_mps2=nan3[:2],
        rms_rpy_deg=nan3,
        ref_point_rms_m=math.nan,
    ).text()
    assert "nan" not in text.lower()
    for line in ("bias error  not measured", "attitude    RMS error not measured"):
        assert line in text
    measured = summary().text()
    assert "could not keep up" not in measured
    assert "gyro x +0.0100 y -0.0200 z +0.0030 deg/s" in measured
    assert "roll 0.100, pitch 0.200, heading 0.300 deg" in measured


@pytest.mark.parametrize(("dropped", "shed"), [(121, 0), (0, 242), (61, 122)])
def test_demo_summary_says_when_the_host_could_not_keep_up(dropped: int, shed: int) -> None:
    """More than 1 % of the IMU input shed as stale, samples at the core or frames read."""
    text = summary(inputs_dropped=dropped, frames_shed=shed).text()
    assert "could not keep up" in text and f"{shed} frames read too late shed" in text
    assert "could not keep up" not in summary(inputs_dropped=60, frames_shed=118).text()
