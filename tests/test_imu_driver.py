"""IMU driver on simulator frames: exact values, timing, impairments counted, filters, player."""

from __future__ import annotations

import asyncio
import dataclasses
import itertools
import logging
import math
import pickle
from collections.abc import AsyncGenerator
from dataclasses import replace
from pathlib import Path
from typing import Any

import can
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import dbc
from drivers.errors import ErrorPolicy, InputError
from drivers.imu_can import (
    ImuCanConfig,
    ImuCanIds,
    ImuDecoder,
    read_bus,
    read_log,
    sample_period_s,
)
from drivers.logs.candump import read_candump, write_candump
from drivers.samples import Float3, ImuAux, ImuSample
from drivers.units import DEG_TO_RAD
from gateway.config.driver_settings import imu_config
from gateway.config.gateway_config import GatewayConfig, VehicleSection
from sim_bus.adis16334 import (
    ACCEL_LSB_MPS2,
    GYRO_LSB_RPS,
    Adis16334Config,
    Adis16334Output,
    counts_from_words,
    simulate,
)
from sim_bus.can_player import play
from sim_bus.imu_frames import frames

G = 9.80665
DT = 4 / 819.2
_channels = itertools.count()


def sim(seconds: float = 2.0, **cfg: Any) -> tuple[Adis16334Output, list[can.Message]]:
    n = round(seconds / DT)
    t = 1.7e9 + np.arange(n) * DT
    w = np.tile(np.array([3.0, -1.5, 12.0]) * DEG_TO_RAD, (n, 1))
    f = np.tile([0.8, -0.3, -G], (n, 1))
    out = simulate(t, w, f, replace(Adis16334Config(), **cfg))
    return out, list(frames(out))


def exact_si(out: Adis16334Output, k: int) -> tuple[np.ndarray, np.ndarray]:
    """What the driver must return: the register counts through the DBC scaling, in SI."""
    g = counts_from_words(out.gyro_words[k]) * 0.05 * (math.pi / 180.0)
    a = counts_from_words(out.accel_words[k]) * 0.001 * G
    return g, a


def run_bus(msgs: list[can.Message], decoder: ImuDecoder, idle_s: float = 0.3) -> list:
    """Send ``msgs`` on one virtual bus and collect what read_bus yields on another."""
    channel = f"imu{next(_channels)}"

    async def main() -> list:
        items: list = []
        with (
            can.Bus(interface="virtual", channel=channel) as rx,
            can.Bus(interface="virtual", channel=channel, preserve_timestamps=True) as tx,
        ):
            for m in msgs:
                tx.send(m)
            agen = read_bus(rx, decoder)
            assert isinstance(agen, AsyncGenerator)  # an async generator function: aclose()
            try:
                while True:
                    items.append(await asyncio.wait_for(agen.__anext__(), idle_s))
            except TimeoutError:
                pass
            finally:
                await agen.aclose()
        decoder.finish()
        return items

    return asyncio.run(main())


def samples(items: list) -> list[ImuSample]:
    return [i for i in items if isinstance(i, ImuSample)]


def test_clean_stream_yields_every_sample_exactly() -> None:
    out, msgs = sim(2.0)
    dec = ImuDecoder()
    items = run_bus(msgs, dec)
    s = samples(items)
    assert len(s) == len(out) and [x.seq for x in s] == list(out.seq)
    for k in (0, 1, 255, 256, len(out) - 1):
        g, a = exact_si(out, k)
        np.testing.assert_allclose(s[k].w_ib_b, g, rtol=0, atol=1e-15)
        np.testing.assert_allclose(s[k].f_ib_b, a, rtol=0, atol=1e-15)
    t = np.array([x.t for x in s])
    assert all(x.dt == DT for x in s)
    assert np.abs(t - out.t).max() < 2.5e-4  # bridge jitter is 0.2 ms; anchor on min latency
    assert np.abs(t[50:] - out.t[50:]).max() < 5e-5
    aux = [i for i in items if isinstance(i, ImuAux)]
    assert len(aux) == 2 and aux[0].smpl_prd == 0x0201 and 4.9 < aux[0].supply_v < 5.1
    c = dec.counters
    assert (c.samples, c.lost, c.duplicates, c.out_of_order, c.malformed, c.unpaired) == (
        len(out),
        0,
        0,
        0,
        0,
        0,
    )


def test_mounting_rotation_from_config() -> None:
    out, msgs = sim(
        0.2,
        imu_mounting_rpy_deg=(10.0, -5.0, 30.0),
        vibration=None,
        gyro_arw_rad_per_sqrt_s=0.0,
        accel_vrw_mps_per_sqrt_s=0.0,
    )
    mounted = GatewayConfig(vehicle=VehicleSection(imu_mounting_rpy_deg=(10.0, -5.0, 30.0)))
    dec = ImuDecoder(imu_config(mounted))  # the config key's path to the driver
    s = samples([i for m in msgs for i in dec.feed(m)])
    np.testing.assert_allclose(
        s[0].w_ib_b,
        np.array([3.0, -1.5, 12.0]) * DEG_TO_RAD + out.bias_g_rps[0],
        atol=3 * GYRO_LSB_RPS,
    )
    np.testing.assert_allclose(
        s[0].f_ib_b, np.array([0.8, -0.3, -G]) + out.bias_a_mps2[0], atol=3 * ACCEL_LSB_MPS2
    )


def test_impairments_are_counted_exactly_and_never_crash() -> None:
    out, msgs = sim(2.0, vibration=None)
    pairs = [m for m in msgs if m.arbitration_id != 0x18FF1280]
    g = lambda k: pairs[2 * k]  # noqa: E731
    a = lambda k: pairs[2 * k + 1]  # noqa: E731
    bad_dlc = can.Message(
        timestamp=a(50).timestamp, arbitration_id=a(50).arbitration_id, data=bytes(a(50).data)[:7]
    )
    bad_res = can.Message(
        timestamp=g(60).timestamp,
        arbitration_id=g(60).arbitration_id,
        data=bytes(g(60).data)[:7] + b"\x02",
    )
    stream: list[can.Message] = []
    for k in range(len(out)):
        if k == 10:  # lost sample
            continue
        if k == 20:  # gyro half lost: unpaired accel, lost sample
            stream.append(a(k))
            continue
        if k == 40:  # 40 and 41 swapped: 41 emitted, 40 late
            stream += [g(41), a(41), g(40), a(40)]
            continue
        if k == 41:
            continue
        if k == 50:  # wrong DLC accel: malformed, unpaired gyro, lost sample
            stream += [g(k), bad_dlc]
            continue
        if k == 60:  # reserved bits wrong: malformed, unpaired accel, lost sample
            stream += [bad_res, a(k)]
            continue
        stream += [g(k), a(k)]
        if k == 30:  # duplicated sample
            stream += [g(k), a(k)]
    dec = ImuDecoder()
    s = samples(run_bus(stream, dec))
    c = dec.counters
    assert (c.lost, c.duplicates, c.out_of_order, c.malformed, c.unpaired) == (4, 1, 1, 2, 3)
    assert c.samples == len(out) - 5 == len(s)
    assert c.samples + c.lost + c.out_of_order == len(out)
    assert np.all(np.diff([x.t for x in s]) > 0)


def test_long_gap_counts_lost_across_seq_wraps_once_arrivals_stay_late() -> None:
    out, msgs = sim(6.0)
    pairs = [m for m in msgs if m.arbitration_id != 0x18FF1280]
    keep = pairs[: 2 * 100] + pairs[2 * 700 :]  # 600 samples (2.9 s, SEQ wraps twice) missing
    dec = ImuDecoder()
    s = samples([i for m in keep for i in dec.feed(m)])
    assert dec.counters.lost == 600 and dec.counters.reanchors == 1
    t = np.array([x.t for x in s])
    err = t - np.concatenate([out.t[:100], out.t[700:]])
    # SEQ alone gives 88 lost; the two further wraps show as arrivals that stay 512 dt late,
    # decided after wrap_check_s of them: the samples before that were emitted 512 dt early.
    early = np.flatnonzero(np.abs(err) > 3e-4)
    assert early[0] == 100 and len(early) == early[-1] - 99
    assert len(early) <= math.ceil(ImuCanConfig().wrap_check_s / DT) + 1
    np.testing.assert_allclose(err[early], -512 * DT, atol=3e-4)
    assert np.all(np.diff(t) > 0)


def test_unrelated_traffic_is_filtered_before_the_decoder() -> None:
    out, msgs = sim(0.5)
    noise = [
        can.Message(
            timestamp=m.timestamp, arbitration_id=i, is_extended_id=i > 0x7FF, data=b"\0" * 8
        )
        for m in msgs[::4]
        for i in (0x18FEF100, 0x123, 0x0CFF1081, 0x0CFF2080)
    ]
    mixed = sorted(msgs + noise, key=lambda m: m.timestamp)
    dec = ImuDecoder()
    s = samples(run_bus(mixed, dec))
    assert len(s) == len(out) and dec.counters.ignored == 0
    assert dec.counters.frames == len(msgs)
    other_priority = ImuCanIds.for_source_address(0x80).gyro | (7 << 26)
    assert ImuDecoder().feed(can.Message(arbitration_id=other_priority, data=bytes(8))) == []


def test_log_source_equals_bus_source(tmp_path: Path) -> None:
    out, msgs = sim(1.0)
    path = tmp_path / "imu.log"
    write_candump(path, msgs)
    with path.open("a") as fh:
        fh.write("this is not a frame\n")
    from_log = samples(list(read_log(path)))
    from_bus = samples(run_bus(msgs, ImuDecoder()))
    assert len(from_log) == len(out)
    for x, y in zip(from_log, from_bus, strict=True):
        assert x.seq == y.seq and np.array_equal(x.w_ib_b, y.w_ib_b) and abs(x.t - y.t) < 1e-6


def received(bus: can.BusABC) -> can.Message:
    """The next frame waiting on ``bus``, which must be there."""
    msg = bus.recv(0)
    assert msg is not None
    return msg


def test_can_player_delivers_every_frame_in_order(tmp_path: Path) -> None:
    _out, msgs = sim(0.3)
    path = tmp_path / "p.log"
    write_candump(path, msgs)
    for speed in (None, 10.0):
        with (
            can.Bus(interface="virtual", channel=f"play{speed}") as rx,
            can.Bus(interface="virtual", channel=f"play{speed}") as tx,
        ):
            assert play(read_candump(path), tx, speed=speed) == len(msgs)
            got = [received(rx) for _ in msgs]
            assert rx.recv(0) is None
        assert [(m.arbitration_id, bytes(m.data)) for m in got] == [
            (m.arbitration_id, bytes(m.data)) for m in msgs
        ]
        if speed:
            span = got[-1].timestamp - got[0].timestamp
            assert span == pytest.approx((msgs[-1].timestamp - msgs[0].timestamp) / speed, abs=0.01)


ours = st.sampled_from([0x0CFF1080, 0x0CFF1180, 0x18FF1280, 0x1CFF1080])


@settings(max_examples=300, deadline=None)
@given(
    st.lists(
        st.tuples(
            st.one_of(ours, st.integers(0, 0x1FFFFFFF)),
            st.binary(max_size=8),
            st.booleans(),
            st.booleans(),
            st.floats(-1e3, 1e10, allow_nan=False),
        ),
        max_size=40,
    )
)
def test_arbitrary_frames_never_raise_out_of_the_decoder(
    frames_in: list[tuple[int, bytes, bool, bool, float]],
) -> None:
    dec = ImuDecoder()
    for can_id, data, ext, remote, t in frames_in:
        msg = can.Message(
            timestamp=t,
            arbitration_id=can_id if ext else can_id & 0x7FF,
            is_extended_id=ext,
            is_remote_frame=remote and not data,
            data=None if remote and not data else data,
        )
        for item in dec.feed(msg):
            assert isinstance(item, ImuSample | ImuAux)
    dec.finish()


@pytest.mark.parametrize("policy", list(ErrorPolicy))
def test_malformed_frames_follow_the_callers_policy(
    policy: ErrorPolicy, caplog: pytest.LogCaptureFixture
) -> None:
    """A gyro frame of 7 bytes: InputError under RAISE, one warning under LOG, silence under
    IGNORE; counted as malformed in every case."""
    ids = ImuCanIds.for_source_address()
    dec = ImuDecoder(ImuCanConfig(ids=ids, on_error=policy))
    short = can.Message(timestamp=5.0, arbitration_id=ids.gyro, data=bytes(7))
    with caplog.at_level(logging.WARNING, logger="drivers.imu_can"):
        if policy is ErrorPolicy.RAISE:
            with pytest.raises(InputError, match="malformed") as err:
                dec.feed(short)
            assert "8 bytes" in err.value.expected
        else:
            assert dec.feed(short) == []
    assert dec.counters.malformed == 1
    assert len(caplog.messages) == (1 if policy is ErrorPolicy.LOG else 0)


# The compiled fast path gives the samples the generic path gave: for every payload, the DBC
# values (cantools' own decode) in SI, through the mounting rotation as numpy computes it
# (C @ v, the identity included), bit for bit, with the same flags.

IMU_DBC = dbc.load(dbc.IMU_DBC)
GYRO_MSG, ACCEL_MSG = (IMU_DBC.get_message_by_name(n) for n in ("IMU_GYRO", "IMU_ACCEL"))
IDS = ImuCanIds.for_source_address()
#: Axis words at the ends of the 14-bit range and around 0, with EA and ND each set or clear.
EXTREME_WORDS = [
    (raw & 0x3FFF) | flags
    for raw in (-8192, -8191, -1, 0, 1, 8190, 8191)
    for flags in (0, 0x4000, 0x8000, 0xC000)
]
words = st.one_of(st.integers(0, 0xFFFF), st.sampled_from(EXTREME_WORDS))
angles = st.floats(-180.0, 180.0, allow_nan=False)


def mounting(rpy_deg: tuple[float, float, float] | None) -> ImuCanConfig:
    """The driver settings for a mounting (None: none), as the gateway config makes them."""
    vehicle = VehicleSection(imu_mounting_rpy_deg=rpy_deg or (0.0, 0.0, 0.0))
    config = imu_config(GatewayConfig(vehicle=vehicle))
    assert (rpy_deg is not None) or config.c_b_imu == ImuCanConfig().c_b_imu
    return config


def pair_frames(
    gyro: tuple[int, int, int], accel: tuple[int, int, int], seq: int, dec: int, t: float
) -> tuple[can.Message, can.Message]:
    g = b"".join(w.to_bytes(2, "little") for w in gyro) + bytes([seq, 0xF0 | dec])
    a = b"".join(w.to_bytes(2, "little") for w in accel) + bytes([seq, 0xFF])
    return (
        can.Message(timestamp=t, arbitration_id=IDS.gyro, data=g),
        can.Message(timestamp=t + 1e-4, arbitration_id=IDS.accel, data=a),
    )


def reference(config: ImuCanConfig, gyro: can.Message, accel: can.Message) -> dict[str, Any]:
    """What the sample must be, from cantools' decode, computed as the generic decoder did:
    C @ (np.array(DBC values) * SI per unit), each half's flags from its DBC values."""
    c = np.array(config.c_b_imu, dtype=float)
    out: dict[str, Any] = {"alarm": False, "saturated": False, "new_data": True}
    for msg, name, si, key in ((gyro, "GYRO", DEG_TO_RAD, "w"), (accel, "ACCL", G, "f")):
        definition = GYRO_MSG if name == "GYRO" else ACCEL_MSG
        values = definition.decode(bytes(msg.data), decode_choices=False)
        assert isinstance(values, dict)
        raw = [v for a in "XYZ" if isinstance(v := values[f"{a}{name}_OUT"], float)]
        assert len(raw) == 3
        out[key] = c @ (np.array(raw, dtype=float) * si)
        sig = definition.get_signal_by_name(f"X{name}_OUT")
        assert sig.minimum is not None and sig.maximum is not None
        low, high = sig.minimum + sig.scale / 2, sig.maximum - sig.scale / 2
        out["alarm"] |= any(values[f"{a}{name}_EA"] for a in "XYZ")
        out["new_data"] &= all(values[f"{a}{name}_ND"] for a in "XYZ")
        out["saturated"] |= any(v <= low or v >= high for v in raw)
    return out


def same_array(x: Float3, y: np.ndarray) -> bool:
    """Three plain floats, bit for bit those of ``y`` (3,)."""
    return (
        type(x) is tuple
        and all(type(v) is float for v in x)
        and y.dtype == np.float64
        and np.array(x).tobytes() == y.tobytes()
    )


@settings(max_examples=300, deadline=None)
@given(
    gyro=st.tuples(words, words, words),
    accel=st.tuples(words, words, words),
    seq=st.integers(0, 255),
    dec=st.integers(0, 15),
    accel_first=st.booleans(),
    rpy=st.one_of(st.none(), st.tuples(angles, angles, angles)),
)
def test_samples_are_the_dbc_values_in_si_and_mounted_bit_for_bit(
    gyro: tuple[int, int, int],
    accel: tuple[int, int, int],
    seq: int,
    dec: int,
    accel_first: bool,
    rpy: tuple[float, float, float] | None,
) -> None:
    config = mounting(rpy)
    decoder = ImuDecoder(replace(config, on_error=ErrorPolicy.IGNORE))
    g, a = pair_frames(gyro, accel, seq, dec, 1.7e9)
    items = [i for m in ((a, g) if accel_first else (g, a)) for i in decoder.feed(m)]
    assert len(items) == 1 and isinstance(items[0], ImuSample)
    s, ref = items[0], reference(config, g, a)
    assert same_array(s.w_ib_b, ref["w"]) and same_array(s.f_ib_b, ref["f"])
    assert (s.seq, s.alarm, s.saturated) == (seq, ref["alarm"], ref["saturated"])
    assert type(s.alarm) is bool and type(s.saturated) is bool and type(s.seq) is int
    assert s.dt == sample_period_s(dec) and s.t == 1.7e9 - ImuCanConfig().bridge_latency_s
    c = decoder.counters
    assert (c.alarms, c.saturated, c.no_new_data) == (
        ref["alarm"],
        ref["saturated"],
        not ref["new_data"],
    )


@pytest.mark.parametrize("rpy", [None, (10.0, -5.0, 30.0)])
def test_every_axis_value_in_every_position_bit_for_bit(
    rpy: tuple[float, float, float] | None,
) -> None:
    """All 2^14 register values of each axis word, gyro and accel: skipping the identity
    mounting is exact for each (and the rotation is numpy's C @ v as before). Each value is
    sent twice: the register's wrap is a jump no vehicle makes, which the first of the two
    may be held for (drivers.axis_checks); the second is taken as sent."""
    config = mounting(rpy)
    decoder = ImuDecoder(config)
    n, saturated = 1 << 14, 0
    for r in range(n):
        gyro = tuple(0x8000 | (r + k * 5461) % n for k in range(3))
        accel = tuple(0x8000 | (n - 1 - r + k * 3) % n for k in range(3))
        for i in (2 * r, 2 * r + 1):
            g, a = pair_frames(gyro, accel, i % 256, 2, 1.7e9 + i * DT)  # type: ignore[arg-type]
            (s,) = [i for m in (g, a) for i in decoder.feed(m)]
        assert isinstance(s, ImuSample)
        ref = reference(config, g, a)
        assert same_array(s.w_ib_b, ref["w"]) and same_array(s.f_ib_b, ref["f"]), r
        assert s.saturated == ref["saturated"]
        saturated += ref["saturated"]
    c = decoder.counters
    assert (c.samples, c.lost, c.reanchors, c.no_new_data, c.alarms) == (2 * n, 0, 0, 0, 0)
    assert c.saturated == 2 * saturated >= 12  # each end of the register, on each axis
    # each axis's wrap of the register (8191 -> -8192, r = 2731, 8192, 13654 on the gyro's,
    # 8192, 8195, 8198 on the accel's), held for one sample: gyro and accel x share r = 8192
    assert c.spikes == 5


def test_samples_are_plain_imu_samples() -> None:
    """The decoder fills ImuSample's slots itself (its dataclass __init__ cost 0.9 us): the
    sample is the one the constructor makes, frozen, comparable, copyable and picklable."""
    _out, msgs = sim(0.1)
    for s in samples([i for m in msgs for i in ImuDecoder().feed(m)])[:3]:
        fields = {f.name: getattr(s, f.name) for f in dataclasses.fields(ImuSample)}
        made = ImuSample(**fields)
        assert type(s) is ImuSample and repr(s) == repr(made)
        assert {f: getattr(made, f) for f in fields} == fields
        with pytest.raises(dataclasses.FrozenInstanceError):
            s.seq = 3  # type: ignore[misc]
        back = pickle.loads(pickle.dumps(s))
        assert repr(back) == repr(s) and repr(replace(s, seq=7)) == repr(replace(made, seq=7))


def lone_half_dropped_at(msgs: list[can.Message]) -> int:
    """Index of the frame on whose arrival the first unpaired half is counted."""
    decoder = ImuDecoder()
    for k, m in enumerate(msgs):
        decoder.feed(m)
        if decoder.counters.unpaired:
            return k
    raise AssertionError("no half was dropped")


def test_a_lone_half_is_dropped_after_the_pair_timeout_and_two_frames() -> None:
    """A gyro half without its accel frame waits pair_timeout_s of arrival time, but at least
    2 more frames (module docstring, Pairing); pairs keep completing meanwhile."""
    timeout = ImuCanConfig().pair_timeout_s
    lone = pair_frames((0x8000,) * 3, (0x8000,) * 3, 0, 2, 1.7e9)[0]
    msgs = [lone]
    for k in range(1, 40):
        msgs += pair_frames((0x8000,) * 3, (0x8000,) * 3, k, 2, 1.7e9 + k * DT)
    first_late = next(i for i, m in enumerate(msgs) if m.timestamp - timeout > 1.7e9)
    assert first_late > 3 and lone_half_dropped_at(msgs) == first_late
    # frames after a gap, so each arrives long after the lone half: it still waits 2 frames
    # (a host stall may fall between the two frames of one sample)
    stalled = [
        can.Message(timestamp=1.7e9 + 5.0, arbitration_id=lone.arbitration_id, data=lone.data)
    ]
    stalled += [
        can.Message(timestamp=m.timestamp + 10.0, arbitration_id=m.arbitration_id, data=m.data)
        for m in msgs[1:]
    ]
    assert lone_half_dropped_at(stalled) == 3


def test_a_lone_half_in_a_burst_is_dropped_after_256_frames() -> None:
    """In a burst (all frames stamped at once) arrival time stands still: a half waits at most
    256 frames, so it cannot meet the same SEQ one wrap later."""
    t = 1.7e9
    lone = pair_frames((0x8000,) * 3, (0x8000,) * 3, 0, 2, t)[0]
    msgs = [lone]
    for k in range(1, 200):
        g, a = pair_frames((0x8000,) * 3, (0x8000,) * 3, k % 256, 2, t)
        msgs += [g, can.Message(timestamp=t, arbitration_id=a.arbitration_id, data=a.data)]
    assert lone_half_dropped_at(msgs) == 257
