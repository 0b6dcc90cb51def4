"""The SPI-to-CAN bridge: ADIS16334 register words to IMU_GYRO/IMU_ACCEL/IMU_AUX frames.

The bridge forwards the register words unchanged as 16-bit little-endian words (SPEC 1), so the
payloads are packed with numpy in one go instead of a cantools encode per frame (~5 us each,
184k samples x 2 frames); tests check the bytes against the DBC encode. Frame timestamps are
the sample instant plus the bridge latency and a small positive jitter; IMU_ACCEL follows
IMU_GYRO by ``accel_delay_s`` and IMU_AUX follows the IMU_ACCEL of the sample it was read after.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import can
import numpy as np

from drivers.imu_can import ImuCanIds
from sim_bus.adis16334 import Adis16334Output

#: Byte 7 of IMU_GYRO: reserved high nibble sent as 1s, DEC in the low nibble.
GYRO_RESERVED = 0xF0
#: Byte 7 of IMU_ACCEL: reserved, sent as 1s.
ACCEL_RESERVED = 0xFF


@dataclass(frozen=True)
class BridgeConfig:
    """Bridge timing and addressing."""

    source_address: int = 0x80
    latency_s: float = 0.0005  # sample instant -> IMU_GYRO on the wire
    jitter_s: float = 0.0002  # extra delay, uniform in [0, jitter_s)
    accel_delay_s: float = 0.0003  # IMU_GYRO -> IMU_ACCEL
    channel: str | None = None
    seed: int = 1


_PAYLOAD = np.dtype([("words", "<u2", (3,)), ("seq", "u1"), ("last", "u1")])


def gyro_payloads(out: Adis16334Output) -> bytes:
    """IMU_GYRO payloads of all samples, 8 bytes each, concatenated."""
    p = np.empty(len(out), dtype=_PAYLOAD)
    p["words"], p["seq"], p["last"] = out.gyro_words, out.seq, GYRO_RESERVED | (out.dec & 0x0F)
    return p.tobytes()


def accel_payloads(out: Adis16334Output) -> bytes:
    """IMU_ACCEL payloads of all samples, 8 bytes each, concatenated."""
    p = np.empty(len(out), dtype=_PAYLOAD)
    p["words"], p["seq"], p["last"] = out.accel_words, out.seq, ACCEL_RESERVED
    return p.tobytes()


def aux_payloads(out: Adis16334Output) -> bytes:
    """IMU_AUX payloads (TEMP_OUT, SUPPLY_OUT, DIAG_STAT, SMPL_PRD), 8 bytes each."""
    a = out.aux
    words = np.stack([a.temp_out, a.supply_out, a.diag_stat, a.smpl_prd], axis=1)
    return words.astype("<u2").tobytes()


def frames(out: Adis16334Output, config: BridgeConfig | None = None) -> Iterator[can.Message]:
    """All bridge frames of ``out`` in transmission order (timestamps increasing)."""
    config = config or BridgeConfig()
    ids = ImuCanIds.for_source_address(config.source_address)
    rng = np.random.default_rng(config.seed)
    n = len(out)
    t_gyro = out.t + config.latency_s + rng.uniform(0.0, config.jitter_s, n)
    t_accel = t_gyro + config.accel_delay_s + rng.uniform(0.0, config.jitter_s / 4, n)
    gyro, accel, aux = gyro_payloads(out), accel_payloads(out), aux_payloads(out)
    aux_at = dict(zip(out.aux.index.tolist(), range(len(out.aux.index)), strict=True))
    channel = config.channel
    Message = can.Message
    for k, (tg, ta) in enumerate(zip(t_gyro.tolist(), t_accel.tolist(), strict=True)):
        o = 8 * k
        yield Message(timestamp=tg, arbitration_id=ids.gyro, data=gyro[o : o + 8], channel=channel)
        yield Message(
            timestamp=ta, arbitration_id=ids.accel, data=accel[o : o + 8], channel=channel
        )
        m = aux_at.get(k)
        if m is not None:
            yield Message(
                timestamp=ta + config.accel_delay_s,
                arbitration_id=ids.aux,
                data=aux[8 * m : 8 * m + 8],
                channel=channel,
            )
