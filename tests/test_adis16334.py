"""ADIS16334 error model: register format, noise figures, biases, mounting, alarms, speed."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

import dbc
from drivers.imu_can import DiagStat, sample_period_s
from drivers.units import DEG_TO_RAD
from sim_bus.adis16334 import (
    ACCEL_LSB_MPS2,
    EA_BIT,
    GM_ALLAN_FLOOR,
    GYRO_LSB_RPS,
    ND_BIT,
    Adis16334Config,
    EngineVibration,
    counts_from_words,
    simulate,
)

G = 9.80665
QUIET = Adis16334Config(
    gyro_turn_on_bias_rps=(0.0, 0.0, 0.0),
    accel_turn_on_bias_mps2=(0.0, 0.0, 0.0),
    gyro_bias_stability_rps=0.0,
    accel_bias_stability_mps2=0.0,
    gyro_arw_rad_per_sqrt_s=0.0,
    accel_vrw_mps_per_sqrt_s=0.0,
    vibration=None,
)


def truth(
    seconds: float,
    w_dps: tuple[float, float, float] = (1.0, -2.0, 3.0),
    f: tuple[float, float, float] = (0.5, -0.2, -G),
    dec: int = 2,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    dt = sample_period_s(dec)
    n = round(seconds / dt)
    t = 1.7e9 + np.arange(n) * dt
    return t, np.tile(np.asarray(w_dps) * DEG_TO_RAD, (n, 1)), np.tile(np.asarray(f), (n, 1))


def allan_dev(x: np.ndarray, m: int) -> np.ndarray:
    """Non-overlapping Allan deviation of rate samples x (n, 3) for clusters of m samples."""
    k = len(x) // m
    means = x[: k * m].reshape(k, m, -1).mean(axis=1)
    return np.sqrt(0.5 * np.mean(np.diff(means, axis=0) ** 2, axis=0))


def test_lsbs_agree_with_the_dbc() -> None:
    db = dbc.load(dbc.IMU_DBC)
    gyro = db.get_message_by_name("IMU_GYRO").get_signal_by_name("XGYRO_OUT")
    accel = db.get_message_by_name("IMU_ACCEL").get_signal_by_name("XACCL_OUT")
    assert gyro.scale * DEG_TO_RAD == pytest.approx(GYRO_LSB_RPS, rel=1e-15)
    assert accel.scale * G == pytest.approx(ACCEL_LSB_MPS2, rel=1e-15)


def test_noise_free_words_are_the_quantised_truth_with_nd_set() -> None:
    t, w, f = truth(3.0)
    out = simulate(t, w, f, QUIET)
    assert np.all(out.gyro_words & ND_BIT) and not np.any(out.gyro_words & EA_BIT)
    assert np.array_equal(counts_from_words(out.gyro_words)[0], [20, -40, 60])
    assert np.array_equal(
        counts_from_words(out.accel_words)[0], np.rint(np.array(f[0]) / ACCEL_LSB_MPS2)
    )
    assert list(out.seq[254:258]) == [254, 255, 0, 1]
    assert np.all(out.bias_g_rps == 0) and np.all(out.diag_stat == 0)


def test_white_noise_matches_the_random_walk_figures() -> None:
    cfg = replace(
        QUIET, gyro_arw_rad_per_sqrt_s=2.0 * DEG_TO_RAD / 60, accel_vrw_mps_per_sqrt_s=0.12 / 60
    )
    t, w, f = truth(200.0)
    out = simulate(t, w, f, cfg)
    dt = cfg.dt_s
    e_w = counts_from_words(out.gyro_words) * GYRO_LSB_RPS - w
    e_f = counts_from_words(out.accel_words) * ACCEL_LSB_MPS2 - f
    sigma_w = cfg.gyro_arw_rad_per_sqrt_s / np.sqrt(dt)
    sigma_f = np.hypot(cfg.accel_vrw_mps_per_sqrt_s / np.sqrt(dt), ACCEL_LSB_MPS2 / np.sqrt(12))
    np.testing.assert_allclose(e_w.std(axis=0), sigma_w, rtol=0.03)
    np.testing.assert_allclose(e_f.std(axis=0), sigma_f, rtol=0.03)
    # Allan deviation of white rate noise at tau = 1 s equals the ARW in rad/sqrt(s)
    m = round(1.0 / dt)
    np.testing.assert_allclose(allan_dev(e_w, m), cfg.gyro_arw_rad_per_sqrt_s, rtol=0.2)


@pytest.mark.parametrize("dec", [0, 4])
def test_engine_vibration_passes_the_decimation_filter_as_at_the_default_rate(dec: int) -> None:
    """The engine's vibration is given as output at DEC 2; the decimation filter averages
    2^DEC internal samples. At DEC 0 and 4 its 28 Hz tone has the amplitude of the mean of
    2^DEC internal samples (1.03 and 0.59 times DEC 2's) and its broadband noise the same
    density (1-sigma per sample sqrt(DEC 2's period / the period) times DEC 2's: 2 and 0.5).
    Per sample at every rate, it was four times the density at 51.2 Hz, a quarter at 819.2."""
    tone = EngineVibration(accel_amplitude_mps2=(0.0, 0.0, 0.6), accel_broadband_mps2=0.0)
    broadband = EngineVibration(accel_amplitude_mps2=(0.0, 0.0, 0.0), accel_broadband_mps2=0.3)

    def amplitude_and_density(d: int) -> tuple[float, float]:
        t, w, f = truth(20.0, dec=d)
        z = counts_from_words(simulate(t, w, f, replace(QUIET, dec=d, vibration=tone)).accel_words)
        y = z[:, 2] * ACCEL_LSB_MPS2 - f[:, 2]
        arg = 2.0 * np.pi * 28.0 * (t - t[0])
        basis = np.column_stack([np.sin(arg), np.cos(arg), np.ones_like(arg)])
        sin_cos = np.linalg.lstsq(basis, y, rcond=None)[0][:2]
        x = counts_from_words(
            simulate(t, w, f, replace(QUIET, dec=d, vibration=broadband, seed=9)).accel_words
        )
        noise = x[:, 0] * ACCEL_LSB_MPS2 - f[:, 0]
        return float(np.hypot(*sin_cos)), float(noise.std() * np.sqrt(sample_period_s(d)))

    def mean_gain(d: int) -> float:  # of 2^d internal samples at 819.2 Hz, on 28 Hz
        return float(abs(np.exp(2j * np.pi * 28.0 * np.arange(2**d) / 819.2).mean()))

    amp_2, density_2 = amplitude_and_density(2)
    amp, density = amplitude_and_density(dec)
    assert amp_2 == pytest.approx(0.6, rel=0.01)
    assert amp / amp_2 == pytest.approx(mean_gain(dec) / mean_gain(2), rel=0.02)
    assert density == pytest.approx(density_2, rel=0.05)


def test_in_run_bias_allan_floor_equals_the_bias_stability() -> None:
    cfg = replace(QUIET, gyro_bias_stability_rps=0.007 * DEG_TO_RAD, bias_correlation_time_s=0.5)
    t, w, f = truth(2000.0)
    b = simulate(t, w, f, cfg).bias_g_rps
    peak = allan_dev(b, round(1.89 * 0.5 / cfg.dt_s))
    np.testing.assert_allclose(peak, cfg.gyro_bias_stability_rps, rtol=0.2)
    assert b.std(axis=0) == pytest.approx(np.full(3, 0.007 * DEG_TO_RAD / GM_ALLAN_FLOOR), rel=0.2)


def test_measurement_minus_truth_is_the_reported_bias() -> None:
    cfg = replace(QUIET, gyro_turn_on_bias_rps=None, accel_turn_on_bias_mps2=None, seed=7)
    t, w, f = truth(2.0)
    out = simulate(t, w, f, cfg)
    e_w = counts_from_words(out.gyro_words) * GYRO_LSB_RPS - w - out.bias_g_rps
    e_f = counts_from_words(out.accel_words) * ACCEL_LSB_MPS2 - f - out.bias_a_mps2
    assert np.abs(e_w).max() <= GYRO_LSB_RPS / 2 + 1e-12
    assert np.abs(e_f).max() <= ACCEL_LSB_MPS2 / 2 + 1e-12
    assert 0 < np.abs(out.bias_g_rps[0]).max() < 1.0 * DEG_TO_RAD
    assert simulate(t, w, f, cfg).gyro_words.tobytes() == out.gyro_words.tobytes()  # seeded


def test_mounting_rotation_sensor_measures_in_imu_axes() -> None:
    cfg = replace(QUIET, imu_mounting_rpy_deg=(0.0, 0.0, 90.0), gyro_turn_on_bias_rps=(0.01, 0, 0))
    t, w, f = truth(1.0, w_dps=(2.0, 0.0, 0.0), f=(0.0, 0.0, -G))
    out = simulate(t, w, f, cfg)
    # yaw 90: body x is IMU -y, so 2 deg/s about body x reads -2 deg/s on the IMU's y axis;
    # the 0.01 rad/s bias on the IMU's x axis (11 LSB) is body +y
    assert list(counts_from_words(out.gyro_words)[0]) == [11, -40, 0]
    np.testing.assert_allclose(out.bias_g_rps[0], [0.0, 0.01, 0.0], atol=1e-15)


def test_over_range_saturates_latches_diag_and_sets_ea_until_read() -> None:
    t, w, f = truth(3.0)
    w[300] = [1000 * DEG_TO_RAD, 0, 0]  # the decimation filter passes 5/8 of it at 300
    out = simulate(t, w, f, QUIET)
    assert counts_from_words(out.gyro_words)[300, 0] == 8191
    reads = out.aux.index
    assert reads[0] == 0 and np.all(np.diff(reads) >= 204)
    alarm = (out.gyro_words[:, 0] & EA_BIT) != 0
    nxt = reads[np.searchsorted(reads, 300)]
    assert not alarm[:300].any() and alarm[300 : nxt + 1].all() and not alarm[nxt + 1 :].any()
    assert out.aux.diag_stat.tolist().count(DiagStat.OVERRANGE) == 1


@pytest.mark.parametrize("dec", [2, 3])
def test_a_sample_is_the_mean_over_its_period_as_the_decimation_filter_makes_it(dec: int) -> None:
    """A 2 Hz rocking rate: each sample is the mean of the 2^DEC internal 819.2 Hz samples up
    to its instant (within an LSB), not the rate at that instant, which leads it by about
    half a period (a strapdown integration takes a sample for its period's mean)."""
    t, w, f = truth(2.0, dec=dec)
    k = 2.0 * np.pi * 2.0
    amp = 25.0 * DEG_TO_RAD
    w[:, 0] = amp * np.sin(k * (t - t[0]))
    out = simulate(t, w, f, replace(QUIET, dec=dec))
    x = counts_from_words(out.gyro_words)[1:, 0] * GYRO_LSB_RPS
    m = 2**dec
    internal = t[1:, None] - t[0] - np.arange(m)[None, :] / 819.2
    mean = amp * np.sin(k * internal).mean(axis=1)
    chord = amp * (k * (t[1] - t[0])) ** 2 / 8.0  # the sine off the line between two samples
    assert np.abs(x - mean).max() <= 0.5 * GYRO_LSB_RPS + chord  # and the rounding
    assert np.abs(w[1:, 0] - mean).max() > 0.9 * amp * k * (m - 1) / (2 * 819.2)


def test_aux_registers_and_dec() -> None:
    cfg = replace(Adis16334Config(), dec=3)
    t, w, f = truth(5.0, dec=3)
    out = simulate(t, w, f, cfg)
    temp = ((out.aux.temp_out.astype(int) & 0xFFF) ^ 0x800) - 0x800
    assert np.all((25 + temp * 0.06785 >= 25) & (25 + temp * 0.06785 <= 40))
    np.testing.assert_allclose((out.aux.supply_out & 0xFFF) * 0.002418, 5.0, atol=0.01)
    assert np.all(out.aux.smpl_prd == 0x0301) and len(out.aux.index) == 5


def test_the_biases_follow_the_warm_up_by_coefficients_of_the_datasheet_s_size() -> None:
    """A unit warming from 5 to 45 degC: each bias moves by its drawn coefficient times the
    temperature TEMP_OUT reports, and a unit without coefficients (the default) not at all."""
    warm = replace(
        QUIET,
        temp_start_c=5.0,
        temp_end_c=45.0,
        temp_tau_s=300.0,
        gyro_bias_tempco_sigma_rps_per_c=0.01 * DEG_TO_RAD,
        accel_bias_tempco_sigma_mps2_per_c=0.1e-3 * G,
        seed=3,
    )
    t, w, f = truth(600.0, dec=4)
    out = simulate(t, w, f, warm)
    counts = ((out.aux.temp_out.astype(int) & 0xFFF) ^ 0x800) - 0x800
    warmed = 25.0 + 0.06785 * counts - 5.0
    assert warmed[0] == pytest.approx(0.0, abs=0.2) and warmed[-1] == pytest.approx(34.6, abs=0.2)
    for bias, sigma in ((out.bias_g_rps, 0.01 * DEG_TO_RAD), (out.bias_a_mps2, 0.1e-3 * G)):
        k = bias[out.aux.index] / warmed[:, None].clip(1.0)  # per degC, per axis
        assert np.all(np.abs(k[-1]) < 4 * sigma) and np.any(np.abs(k[-1]) > 0.3 * sigma)
        np.testing.assert_allclose(
            k[warmed > 5.0], np.broadcast_to(k[-1], k[warmed > 5.0].shape), rtol=0.05
        )
    e_w = counts_from_words(out.gyro_words) * GYRO_LSB_RPS - w - out.bias_g_rps
    assert np.abs(e_w).max() <= GYRO_LSB_RPS / 2 + 1e-12  # the truth's bias is the one applied
    still = simulate(t, w, f, replace(warm, gyro_bias_tempco_sigma_rps_per_c=0.0,
                                      accel_bias_tempco_sigma_mps2_per_c=0.0))  # fmt: skip
    assert np.all(still.bias_g_rps == 0.0) and np.all(still.bias_a_mps2 == 0.0)
