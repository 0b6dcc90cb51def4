"""Bridge frames: byte layout against the DBC, round trip within one LSB, ids, timing."""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np
import pytest

import dbc
from drivers.units import DEG_TO_RAD
from sim_bus.adis16334 import Adis16334Config, Adis16334Output, counts_from_words, simulate
from sim_bus.imu_frames import BridgeConfig, frames

G = 9.80665
DB = dbc.load(dbc.IMU_DBC)


def sim(
    seconds: float = 3.0, **cfg: Any
) -> tuple[np.ndarray, np.ndarray, np.ndarray, Adis16334Output]:
    dt = 4 / 819.2
    n = round(seconds / dt)
    t = 1.7e9 + np.arange(n) * dt
    w = np.tile(np.array([10.0, -20.0, 5.0]) * DEG_TO_RAD, (n, 1))
    f = np.tile([1.0, -0.5, -G], (n, 1))
    return t, w, f, simulate(t, w, f, replace(Adis16334Config(), **cfg))


def dbc_encode_raw(name: str, words: list[int], **fields: int) -> bytes:
    """Reference: the same frame through cantools, word by word (value, EA, ND)."""
    axis = "GYRO" if name == "IMU_GYRO" else "ACCL"
    raw: dict[str, int] = dict(fields)
    for a, w in zip("XYZ", words, strict=True):
        v = w & 0x3FFF
        raw[f"{a}{axis}_OUT"] = v - 0x4000 if v & 0x2000 else v
        raw[f"{a}{axis}_EA"] = (w >> 14) & 1
        raw[f"{a}{axis}_ND"] = (w >> 15) & 1
    return bytes(DB.get_message_by_name(name).encode(raw, scaling=False))


def test_fast_path_bytes_equal_the_dbc_encode() -> None:
    *_, out = sim(1.5)
    rng = np.random.default_rng(3)
    out.gyro_words[:] = rng.integers(0, 1 << 16, out.gyro_words.shape, dtype=np.uint16)
    out.accel_words[:] = rng.integers(0, 1 << 16, out.accel_words.shape, dtype=np.uint16)
    out.gyro_words[:4] = [[0x1FFF, 0x2000, 0xFFFF], [0, 0x8000, 0x4000], [0x3FFF, 1, 2], [5, 6, 7]]
    msgs = list(frames(out))
    gyro = [m for m in msgs if m.arbitration_id == 0x0CFF1080]
    accel = [m for m in msgs if m.arbitration_id == 0x0CFF1180]
    aux = [m for m in msgs if m.arbitration_id == 0x18FF1280]
    assert len(gyro) == len(accel) == len(out) and len(aux) == 2
    for k in range(len(out)):
        seq = int(out.seq[k])
        ref_g = dbc_encode_raw(
            "IMU_GYRO", out.gyro_words[k].tolist(), SEQ=seq, DEC=out.dec, RESERVED=0xF
        )
        ref_a = dbc_encode_raw("IMU_ACCEL", out.accel_words[k].tolist(), SEQ=seq, RESERVED=0xFF)
        assert bytes(gyro[k].data) == ref_g and bytes(accel[k].data) == ref_a
    assert bytes(accel[0].data)[7] == 0xFF and bytes(gyro[0].data)[7] == 0xF2
    for m, i in zip(aux, out.aux.index, strict=True):
        diag = int(out.aux.diag_stat[list(out.aux.index).index(i)])
        values = DB.get_message_by_name("IMU_AUX").decode(bytes(m.data), scaling=False)
        assert isinstance(values, dict)  # a plain message, not a container
        assert values["SMPL_PRD"] == 0x0201 and values["DIAG_OVERRANGE"] == (diag >> 4) & 1


def test_frames_decode_back_to_the_measurements_within_one_lsb() -> None:
    _t, w, f, out = sim(vibration=None, gyro_arw_rad_per_sqrt_s=0.0, accel_vrw_mps_per_sqrt_s=0.0)
    msgs = list(frames(out))
    gyro = DB.get_message_by_name("IMU_GYRO")
    accel = DB.get_message_by_name("IMU_ACCEL")
    k = 0
    for m in msgs:
        if m.arbitration_id == 0x0CFF1080:
            v = gyro.decode(bytes(m.data))
            assert isinstance(v, dict)
            w_dps = np.array([v["XGYRO_OUT"], v["YGYRO_OUT"], v["ZGYRO_OUT"]])
            expected = np.rad2deg(w[k] + out.bias_g_rps[k])
            assert np.abs(w_dps - expected).max() <= 0.05 and v["SEQ"] == k % 256
        elif m.arbitration_id == 0x0CFF1180:
            v = accel.decode(bytes(m.data))
            assert isinstance(v, dict)
            f_g = np.array([v["XACCL_OUT"], v["YACCL_OUT"], v["ZACCL_OUT"]])
            assert np.abs(f_g * G - f[k] - out.bias_a_mps2[k]).max() <= 0.001 * G
            k += 1
    assert k == len(out)
    assert np.array_equal(
        counts_from_words(out.gyro_words)[0], np.rint(np.rad2deg(w[0] + out.bias_g_rps[0]) / 0.05)
    )


def test_timestamps_ids_and_order() -> None:
    t, _, _, out = sim()
    cfg = BridgeConfig(source_address=0x42, channel="can1")
    msgs = list(frames(out, cfg))
    ts = np.array([m.timestamp for m in msgs])
    assert np.all(np.diff(ts) > 0)
    assert {m.arbitration_id for m in msgs} == {0x0CFF1042, 0x0CFF1142, 0x18FF1242}
    assert all(m.is_extended_id and m.dlc == 8 and m.channel == "can1" for m in msgs)
    g = np.array([m.timestamp for m in msgs if m.arbitration_id == 0x0CFF1042])
    a = np.array([m.timestamp for m in msgs if m.arbitration_id == 0x0CFF1142])
    assert np.all((g - t >= 0.0005) & (g - t < 0.0007))
    assert np.mean(a - g) == pytest.approx(0.0003 + 0.000025, abs=2e-5)
