"""The learned-state store (issue 17): round trip, atomic writes, every reason a stored state
is refused (one warning naming it, a cold start), the bias model, ``navgw state show|clear``.
"""

from __future__ import annotations

import json
import logging
import math
import os
import signal
import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

import pytest

from gateway.cli.main import main
from gateway.config.gateway_config import (
    GatewayConfig,
    ImuSection,
    IsobusSection,
    StateSection,
    VehicleSection,
    load_config,
)
from gateway.fusion.rest_check import RestRecord
from gateway.state.keeper import StateKeeper
from gateway.state.store import (
    EARTH_RATE_RPS,
    STATE_FILE,
    BandEntry,
    Biases,
    BiasGrowth,
    Identity,
    LastPose,
    Mounting,
    StoredState,
    leftover_temporaries,
    merged,
    read_state,
    seed_for,
    to_json,
    write_state,
)

DEG = math.pi / 180.0
T0 = 1_700_000_000.0
CONFIG = GatewayConfig(
    vehicle=VehicleSection(antenna_lever_arm_m=(0.3, 0.0, -3.0), imu_lever_arm_m=(0.5, 0.1, -1.0))
)
IDENTITY = Identity.from_config(CONFIG)
GROWTH = BiasGrowth.from_config(CONFIG)


def entry(temp_c: float = 34.0, t_s: float = T0, sigma_a: float = 0.004) -> BandEntry:
    return BandEntry(
        temp_c=temp_c,
        t_s=t_s,
        engine="ekf",
        gyro_rps=Biases((0.1 * DEG, -0.05 * DEG, 0.02 * DEG), (0.008 * DEG,) * 3),
        accel_mps2=Biases((0.04, -0.03, 0.01), (sigma_a, sigma_a, 0.002)),
    )


STATE = StoredState(
    identity=IDENTITY,
    bands=(entry(24.0, T0 - 3600.0), entry(34.0)),
    written_s=T0,
    last=LastPose(T0, 52.2, 10.5, 80.25, 271.5),
    mounting=Mounting((0.5, -1.25, 90.0), (0.05, 0.05, 0.2), (0.0, 0.0, 0.0)),
    rest=RestRecord(
        T0,
        52.2,
        10.5,
        0.014,
        (0.19, -0.35, -9.79),
        (1e-3, -2e-3, 5e-4),
        (0.001,) * 3,
        (3e-4,) * 3,
        30.0,
    ),
)


def test_round_trip_keeps_every_field(tmp_path: Path) -> None:
    path = tmp_path / STATE_FILE
    write_state(path, STATE)
    assert read_state(path) == STATE
    doc = json.loads(path.read_text())
    assert doc["schema_version"] == 1 and len(doc["bands"]) == 2
    assert doc["mounting"] == {
        "rpy_deg": [0.5, -1.25, 90.0],
        "sigma_deg": [0.05, 0.05, 0.2],
        "base_rpy_deg": [0.0, 0.0, 0.0],
    }
    assert leftover_temporaries(path) == []
    assert doc["rest"]["f_b_mps2"] == [0.19, -0.35, -9.79] and doc["rest"]["duration_s"] == 30.0
    # the mounting and the rest are optional, the rest also as a key (a file of an older navgw)
    bare = replace(STATE, mounting=None, last=None, rest=None)
    write_state(path, bare)
    assert read_state(path) == bare
    older = json.loads(path.read_text())
    del older["rest"]
    path.write_text(json.dumps(older))
    assert read_state(path) == bare
    # a mounting entry that does not say what it was estimated against is none (schema 1)
    del doc["mounting"]["base_rpy_deg"]
    path.write_text(json.dumps(doc))
    assert read_state(path) == replace(STATE, mounting=None)


WRITER = """
import sys, time
from dataclasses import replace
from pathlib import Path
from tests.test_state_store import STATE, entry
from gateway.state.store import write_state
path = Path(sys.argv[1])
big = replace(STATE, bands=tuple(entry(float(t) / 10.0, 1e9 + t) for t in range(400)))
print("ready", flush=True)
n = 0
while True:
    write_state(path, STATE if n % 2 else big)
    n += 1
"""


def test_a_write_killed_at_any_moment_leaves_the_old_or_the_new_state(tmp_path: Path) -> None:
    """A writer killed (SIGKILL: no clean-up) in the middle of its writes, at ten different
    moments: the file is always one complete state, never a mix or a truncated one; what
    the kill leaves is a temporary file beside it, which is never read as the state."""
    path = tmp_path / STATE_FILE
    write_state(path, STATE)
    root = Path(__file__).resolve().parent.parent
    for i in range(10):
        proc = subprocess.Popen(
            [sys.executable, "-c", WRITER, str(path)], cwd=root, stdout=subprocess.PIPE, text=True
        )
        assert proc.stdout is not None and proc.stdout.readline().strip() == "ready"
        time.sleep(0.05 + 0.037 * i)
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait()
        proc.stdout.close()
        state = read_state(path)
        assert state == STATE or len(state.bands) == 400
    # a temporary left by a crash is not the state, and `navgw state clear` takes it too
    (tmp_path / f".{STATE_FILE}.crash.tmp").write_text('{"schema_version": 1, "ident')
    assert read_state(path).identity == IDENTITY
    assert main(["state", "clear", "--dir", str(tmp_path)]) == 0
    assert not path.exists() and leftover_temporaries(path) == []


def _doc(**changes: Any) -> dict[str, Any]:
    doc = to_json(STATE)
    for key, value in changes.items():
        target = doc
        *parents, last = key.split("__")
        for p in parents:
            target = target[int(p)] if isinstance(target, list) else target[p]
        if value is KeyError:
            del target[last]
        else:
            target[last] = value
    return doc


CORRUPT = [
    ("not json", "{ this is not json", "not valid JSON"),
    ("empty", "", "the file is empty"),
    ("binary", b"\xff\xfe\x00garbage", "not a text file"),
    ("schema", _doc(schema_version=2), "schema_version = 2: expected 1"),
    ("missing", _doc(identity=KeyError), "field identity is missing"),
    ("missing in a band", _doc(bands__1__accel_sigma_mps2=KeyError), "bands[1].accel_sigma_mps2"),
    ("nan", _doc(bands__0__gyro_bias_rps=[float("nan"), 0.0, 0.0]), "expected a finite number"),
    ("physics", _doc(bands__1__accel_bias_mps2=[3.0, 0.0, 0.0]), "expected a value in [-1, 1]"),
    ("sigma 0", _doc(bands__1__gyro_sigma_rps=[0.0, 1e-4, 1e-4]), "expected sigmas > 0"),
    ("type", _doc(bands=7), "bands is 7: expected a list"),
    ("deep", "[" * 100_000 + "]" * 100_000, "JSON nested too deep"),
]


@pytest.mark.parametrize(
    ("content", "reason"), [c[1:] for c in CORRUPT], ids=[c[0] for c in CORRUPT]
)
def test_a_corrupt_store_is_one_warning_and_a_cold_start(
    tmp_path: Path, caplog: pytest.LogCaptureFixture, content: Any, reason: str
) -> None:
    path = tmp_path / STATE_FILE
    if isinstance(content, bytes):
        path.write_bytes(content)
    else:
        path.write_text(content if isinstance(content, str) else json.dumps(content))
    keeper = StateKeeper(CONFIG, tmp_path)
    with caplog.at_level(logging.INFO, logger="gateway.state"):
        assert keeper.load() is None
    warnings = [r for r in caplog.records if r.levelno >= logging.WARNING]
    assert len(warnings) == 1, caplog.text
    text = warnings[0].getMessage()
    assert str(path) in text and reason in text and "cold start" in text
    assert keeper.stored is None and keeper.warm_start(34.0, T0) is None


def _vehicle(**changes: Any) -> GatewayConfig:
    return replace(CONFIG, vehicle=replace(CONFIG.vehicle, **changes))


FOREIGN = [
    (
        "another unit",
        replace(CONFIG, isobus=IsobusSection(identity_number=7)),
        "identity_number is 1 in the store, 7 in the config",
    ),
    (
        "another bridge",
        replace(CONFIG, imu=ImuSection(bridge_source_address=0x81)),
        "bridge_source_address is 128 in the store, 129",
    ),
    (
        "lever arm",
        _vehicle(antenna_lever_arm_m=(0.3, 0.0, -2.5)),
        "antenna_lever_arm_m is [0.3, 0, -3] in the store, [0.3, 0, -2.5]",
    ),
]


@pytest.mark.parametrize(
    ("config", "reason"), [c[1:] for c in FOREIGN], ids=[c[0] for c in FOREIGN]
)
def test_a_store_of_another_imu_or_configuration_is_refused(
    tmp_path: Path, caplog: pytest.LogCaptureFixture, config: GatewayConfig, reason: str
) -> None:
    write_state(tmp_path / STATE_FILE, STATE)
    keeper = StateKeeper(config, tmp_path)
    with caplog.at_level(logging.WARNING, logger="gateway.state"):
        assert keeper.load() is None
    assert len(caplog.records) == 1
    assert "another IMU or configuration" in caplog.records[0].getMessage()
    assert reason in caplog.records[0].getMessage()
    assert StateKeeper(CONFIG, tmp_path).load() == STATE  # the right config takes it
    assert keeper.mounting is None  # the mounting estimate is that IMU's too


def test_biases_of_another_mounting_start_cold_and_the_mounting_estimate_is_kept(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """The biases are stored in body axes: under another mounting in effect they are not
    used (one warning); the mounting estimate is, and the next save writes both with the
    mounting in effect."""
    write_state(tmp_path / STATE_FILE, STATE)
    keeper = StateKeeper(_vehicle(imu_mounting_rpy_deg=(0.0, 0.0, 90.0)), tmp_path)
    with caplog.at_level(logging.WARNING, logger="gateway.state"):
        assert keeper.load() is None
    (warning,) = (r.getMessage() for r in caplog.records)
    assert "biases learned under another IMU mounting ([0.00, 0.00, 0.00] deg; " in warning
    assert "[0.00, 0.00, 90.00] deg in effect): cold start for the biases" in warning
    assert keeper.stored is None and keeper.mounting == STATE.mounting


def test_temperature_far_from_what_was_learned_or_too_old_is_refused(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    write_state(tmp_path / STATE_FILE, STATE)
    keeper = StateKeeper(CONFIG, tmp_path)
    assert keeper.load() == STATE
    with caplog.at_level(logging.WARNING, logger="gateway.state"):
        assert keeper.warm_start(50.5, T0) is None  # 16.5 degC from 34: beyond one band
        assert keeper.warm_start(34.0, T0 + 31 * 86400.0) is None  # max_age_days = 30
    first, second = (r.getMessage() for r in caplog.records)
    assert "the IMU is at 50.5 degC, its biases were learned at 24.0, 34.0 degC" in first
    assert "learned 31.0 days ago: expected at most 30 days" in second
    assert keeper.warm_start(43.0, T0) is not None  # the next band up, 9 degC away: taken
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="gateway.state"):
        assert keeper.warm_start(math.nan, T0) is None  # TEMP_OUT garbage is no band
    assert "the IMU reports nan degC: expected a temperature in [-60, 150]" in caplog.text


def test_the_seed_is_the_band_of_the_temperature_grown_by_age_and_temperature() -> None:
    width, max_age = 10.0, 30 * 86400.0
    learned, chosen = seed_for(STATE, 27.0, T0 + 600.0, GROWTH, width, max_age)
    assert chosen.temp_c == 24.0  # its own band, though 34 is as near as 24
    # by hand: Gauss-Markov wander (0.007 deg/s / 0.6174, T = 100 s) over 4200 s (~2 sigma^2),
    # 3 degC x 0.01 deg/s/degC, Earth rate; accelerometer 0.1 mg / 0.6174 and 0.1 mg/degC
    gm_g = 0.007 * DEG / 0.6174
    expect_g = math.sqrt(
        (0.008 * DEG) ** 2
        + 2 * gm_g**2 * (1 - math.exp(-4200.0 / 100.0))
        + (3 * 0.01 * DEG) ** 2
        + EARTH_RATE_RPS**2
    )
    assert learned.sigma_g_rps[0] == pytest.approx(expect_g, rel=1e-9)
    gm_a = 0.1e-3 * 9.80665 / 0.6174
    expect_a = math.sqrt(0.004**2 + 2 * gm_a**2 + (3 * 0.1e-3 * 9.80665) ** 2)
    assert learned.sigma_a_mps2[0] == pytest.approx(expect_a, rel=1e-6)
    assert learned.bias_a_mps2 == chosen.accel_mps2.bias  # values as stored
    # never below the stored sigma, even at once and at the same temperature
    now, _ = seed_for(STATE, 34.0, T0, GROWTH, width, max_age)
    assert min(now.sigma_a_mps2[i] - STATE.bands[1].accel_mps2.sigma[i] for i in range(3)) >= 0
    # a clock that went back (an ECU without a set clock): the age counts as forever
    back, _ = seed_for(STATE, 34.0, T0 - 1e6, GROWTH, width, max_age)
    assert back.sigma_a_mps2[0] == pytest.approx(math.sqrt(0.004**2 + 2 * gm_a**2), rel=1e-6)


def test_merge_keeps_the_better_axis_and_says_if_anything_was_learned() -> None:
    width = 10.0
    # a fresh session's cold guess (sigma 0.1) overwrites nothing
    cold = entry(35.0, T0 + 60.0, sigma_a=0.1)
    cold = replace(
        cold,
        engine="observer",
        gyro_rps=Biases((0.0,) * 3, (0.3 * DEG,) * 3),
        accel_mps2=Biases((0.0,) * 3, (0.1,) * 3),
    )
    same, improved = merged(STATE, IDENTITY, cold, GROWTH, width)
    assert not improved
    kept = same.bands[1]
    assert kept.accel_mps2.bias == STATE.bands[1].accel_mps2.bias
    assert kept.accel_mps2.sigma[0] > STATE.bands[1].accel_mps2.sigma[0]  # grown to now
    assert same.bands[0] == STATE.bands[0]  # another band untouched
    # a better x axis is taken, the rest stays
    better = replace(cold, accel_mps2=Biases((0.05, 0.0, 0.0), (0.002, 0.1, 0.1)))
    new, improved = merged(STATE, IDENTITY, better, GROWTH, width)
    assert improved
    assert new.bands[1].accel_mps2.bias == (0.05, -0.03, 0.01)
    assert new.bands[1].accel_mps2.sigma[0] == 0.002
    assert new.bands[1].engine == "ekf+observer" and same.bands[1].engine == "ekf"
    # a new temperature band is a new entry; another identity starts a new store
    warm, improved = merged(STATE, IDENTITY, entry(45.0, T0 + 60.0), GROWTH, width)
    assert improved and [e.temp_c for e in warm.bands] == [24.0, 34.0, 45.0]
    other = replace(IDENTITY, identity_number=9)
    fresh, improved = merged(STATE, other, cold, GROWTH, width)
    assert improved and fresh.identity == other and len(fresh.bands) == 1


def test_state_section_of_the_config(tmp_path: Path) -> None:
    toml = tmp_path / "navgw.toml"
    toml.write_text('[state]\ndirectory = "/tmp/x"\nsave_interval_s = 60.0\nenabled = true\n')
    assert load_config(toml).state == StateSection(
        enabled=True, directory="/tmp/x", save_interval_s=60.0
    )
    # on: a seed is used only once checked at rest where the vehicle stopped (rest_check)
    assert StateSection().enabled
    toml.write_text("[state]\nsave_interval_s = 1.0\n")
    with pytest.raises(ValueError, match=r"state.save_interval_s = 1.0: expected a value in"):
        load_config(toml)


def test_navgw_state_show_and_clear(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    config = tmp_path / "navgw.toml"
    config.write_text(
        f"[vehicle]\nantenna_lever_arm_m = [0.3, 0.0, -3.0]\nimu_lever_arm_m = [0.5, 0.1, -1.0]\n"
        f'[state]\ndirectory = "{tmp_path}"\n'
    )
    assert main(["state", "show", "--config", str(config)]) == 0
    assert "no learned state at" in capsys.readouterr().out
    write_state(tmp_path / STATE_FILE, STATE)
    assert main(["state", "show", "--config", str(config)]) == 0
    out = capsys.readouterr().out
    assert "IMU bridge 0x80, gateway identity 1: fits the config" in out
    assert "band 20 to 30 degC: learned at 24.0 degC by the ekf" in out
    assert "band 30 to 40 degC: learned at 34.0 degC by the ekf" in out
    assert "gyro bias x, y, z  +0.1000+/-0.0080, -0.0500+/-0.0080, +0.0200+/-0.0080 deg/s" in out
    assert "accel bias x, y, z +0.0400+/-0.0040, -0.0300+/-0.0040, +0.0100+/-0.0020 m/s^2" in out
    assert "last position 52.2000000 10.5000000 80.25 m, heading 271.5 deg" in out
    assert "mounting estimate roll, pitch, yaw +0.500+/-0.050, -1.250+/-0.050" in out
    assert "against the configured [vehicle] imu_mounting_rpy_deg = [0.00, 0.00, 0.00]" in out
    assert "not applied at start: not determined: 1-sigma yaw 0.200 deg, above 0.15" in out
    assert "last rest 52.2000000 10.5000000 for 30 s" in out
    assert "mean specific force x, y, z +19.37, -35.69, -998.30 mg" in out
    # shown against another config: it says what does not fit
    assert main(["state", "show", "--dir", str(tmp_path)]) == 0
    assert "does not fit the config: imu_lever_arm_m is [0.5, 0.1, -1]" in capsys.readouterr().out
    # corrupt: says why, exit 1
    (tmp_path / STATE_FILE).write_text("{")
    assert main(["state", "show", "--config", str(config)]) == 1
    assert "unusable (not valid JSON" in capsys.readouterr().out
    assert main(["state", "clear", "--config", str(config)]) == 0
    assert f"removed {tmp_path / STATE_FILE}" in capsys.readouterr().out
    assert main(["state", "clear", "--config", str(config)]) == 0
    assert "nothing to remove" in capsys.readouterr().out


def test_a_missing_directory_is_one_warning_and_nothing_written(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    keeper = StateKeeper(CONFIG, tmp_path / "absent")
    with caplog.at_level(logging.WARNING, logger="gateway.state"):
        assert keeper.load() is None
    assert len(caplog.records) == 1 and "is not a directory" in caplog.records[0].getMessage()
    assert not keeper.usable_directory and not (tmp_path / "absent").exists()
