"""Scenario generation end to end: logs on disk decode through the drivers to the truth."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from drivers.imu_can import ImuDecoder, read_log
from drivers.nmea import read_fixes_from_log
from drivers.samples import FixQuality, ImuSample
from gateway.config.config_schema import ConfigError
from gateway.estimation.geodesy import lla_to_ned
from sim_bus.scenarios import SCENARIOS, generate, scenario_from_toml
from sim_bus.truth import Truth

MG = 0.00980665


@pytest.fixture(scope="module")
def short_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("short")
    generate(SCENARIOS["short"], out, seed=7)
    return out


def test_imu_log_decodes_to_truth_plus_bias_within_noise(short_run: Path) -> None:
    truth = Truth.load(short_run / "truth.npz")
    decoder = ImuDecoder()
    samples = [s for s in read_log(short_run / "imu.log", decoder) if isinstance(s, ImuSample)]
    assert len(samples) == len(truth)
    assert decoder.counters.lost == decoder.counters.duplicates == decoder.counters.malformed == 0
    dt = np.array([s.dt for s in samples])
    assert np.all(dt == 4.0 / 819.2)
    t = np.array([s.t for s in samples])
    # host sample times track the true instants to well under a sample period
    assert np.max(np.abs(t - truth.t)) < 1e-3
    w = np.array([s.w_ib_b for s in samples])
    f = np.array([s.f_ib_b for s in samples])
    # one-second means remove white noise and vibration: what is left is the bias
    n = round(1.0 / truth.dt_s)
    k = len(truth) // n * n
    gyro_err = (w - truth.w_ib_b - truth.bias_g_rps)[:k].reshape(-1, n, 3).mean(axis=1)
    accel_err = (f - truth.f_ib_b_imu - truth.bias_a_mps2)[:k].reshape(-1, n, 3).mean(axis=1)
    assert np.sqrt(np.mean(gyro_err**2)) < np.radians(0.05)  # ARW 2 deg/rt-h: ~0.03 deg/s in 1 s
    assert np.sqrt(np.mean(accel_err**2)) < 3 * MG
    # turn-on biases are really there (random, datasheet-like sigma)
    assert np.any(np.abs(truth.bias_g_rps[0]) > np.radians(0.005))


def test_nmea_log_decodes_to_antenna_truth(short_run: Path) -> None:
    truth = Truth.load(short_run / "truth.npz")
    fixes = list(read_fixes_from_log(short_run / "gnss.nmea"))
    duration = truth.t[-1] - truth.t[0]
    assert abs(len(fixes) - duration * 10) <= 2
    assert all(f.quality == FixQuality.RTK_FIXED for f in fixes)
    t_utc = np.array([f.t_utc for f in fixes])
    lla = np.array([[f.lat_deg, f.lon_deg, f.alt_m] for f in fixes])
    ant = np.column_stack([np.interp(t_utc, truth.t, truth.pos_ant_ned_m[:, i]) for i in range(3)])
    err = lla_to_ned(lla, truth.origin_lla) - ant
    assert np.sqrt(np.mean(err[:, :2] ** 2)) < 0.03  # RTK fixed, 1 cm per axis
    assert np.all(np.array([f.t for f in fixes]) > t_utc)  # received after the epoch


def test_same_seed_same_files_other_seed_differs(tmp_path: Path, short_run: Path) -> None:
    generate(SCENARIOS["short"], tmp_path / "a", seed=7)
    generate(SCENARIOS["short"], tmp_path / "b", seed=8)
    for name in ("imu.log", "gnss.nmea"):
        assert (tmp_path / "a" / name).read_bytes() == (short_run / name).read_bytes()
        assert (tmp_path / "b" / name).read_bytes() != (short_run / name).read_bytes()


def test_toml_overrides_a_base_scenario() -> None:
    sc = scenario_from_toml(
        {
            "base": "short",
            "imu": {"gyro_turn_on_bias_rps": [0.001, -0.002, 0.0]},
            "gnss": {"rate_hz": 5, "fix_schedule": [[10, 20, 0]]},
            "vehicle": {"n_passes": 2},
        }
    )
    assert sc.imu.gyro_turn_on_bias_rps == (0.001, -0.002, 0.0)
    assert sc.gnss.rate_hz == 5.0 and sc.gnss.fix_schedule[0].quality is FixQuality.NONE
    assert sc.vehicle.n_passes == 2
    assert sc.vehicle.swath_length_m == SCENARIOS["short"].vehicle.swath_length_m


@pytest.mark.parametrize(
    ("table", "message"),
    [
        ({"base": "moon"}, "scenario.base = 'moon': expected one of field"),
        ({"imu": {"gyro_bias": 1}}, "unknown key imu.gyro_bias: expected one of"),
        ({"gnss": {"rate_hz": 3}}, "[gnss] rate_hz=3.0: expected 1, 2, 4, 5, 10 or 20"),
        ({"gnss": {"slow_rate_hz": 0}}, "[gnss] slow_rate_hz=0.0 with rate_hz=10.0: expected"),
        ({"gnss": {"slow_rate_hz": 3}}, "[gnss] slow_rate_hz=3.0 with rate_hz=10.0: expected"),
        ({"gnss": {"slow_rate_hz": -1}}, "[gnss] slow_rate_hz=-1.0 with rate_hz=10.0: expected"),
        (
            {"gnss": {"dead_reckoning_limit_s": -1}},
            "[gnss] dead_reckoning_limit_s=-1.0: expected a finite time, s, 0 or more",
        ),
        ({"gnss": {"slow_sentences": ["GGA"]}}, "[gnss] slow_sentences=('GGA',): expected some"),
        ({"weather": {}}, "unknown key 'weather' in scenario"),
    ],
)
def test_bad_scenario_config_is_named(table: dict[str, object], message: str) -> None:
    with pytest.raises(ConfigError) as err:
        scenario_from_toml(table)
    assert str(err.value).startswith(message)


def test_cli_writes_files_and_rejects_unknown_scenario(tmp_path: Path) -> None:
    cfg = tmp_path / "s.toml"
    cfg.write_text('base = "short"\n[vehicle]\nn_passes = 1\nstart_stop_s = 5.0\n')
    ok = subprocess.run(
        [
            sys.executable,
            "-m",
            "gateway.cli.main",
            "sim",
            "--config",
            str(cfg),
            "--out",
            str(tmp_path / "o"),
        ],
        capture_output=True,
        text=True,
        check=False,
    )
    assert ok.returncode == 0, ok.stderr
    names = {p.name for p in (tmp_path / "o").iterdir()}
    assert names == {"imu.log", "gnss.nmea", "truth.npz", "navgw.toml"}
    bad = subprocess.run(
        [sys.executable, "-m", "gateway.cli.main", "sim", "moon"],
        capture_output=True,
        text=True,
        check=False,
    )
    assert bad.returncode == 2
    assert "unknown scenario 'moon': expected one of field, hillside" in bad.stderr
