"""The DBC-driven fast decoder equals cantools on every eligible message and payload."""

from __future__ import annotations

import struct
from functools import cache
from typing import Any

import pytest
from hypothesis import given
from hypothesis import strategies as st

import dbc
from dbc.fast_decode import AllOf, AnyOf, LittleEndianDecoder, Lookup, Output, Raw

IMU = dbc.load(dbc.IMU_DBC)


@pytest.mark.parametrize("name", ["IMU_GYRO", "IMU_ACCEL", "IMU_AUX"])
@given(data=st.binary(min_size=8, max_size=8))
def test_equals_cantools_decode(name: str, data: bytes) -> None:
    message = IMU.get_message_by_name(name)
    assert LittleEndianDecoder(message).decode(data) == message.decode(data, decode_choices=False)


def test_hand_checked_gyro_words() -> None:
    # SPEC 1 example frame: X = 12 LSB (0.6 deg/s), Y = -12 LSB with EA and ND, Z = 58 LSB
    values = LittleEndianDecoder(IMU.get_message_by_name("IMU_GYRO")).decode(
        bytes.fromhex("0C00F4FF3A0001F2")
    )
    assert values["XGYRO_OUT"] == pytest.approx(0.6)
    assert values["YGYRO_OUT"] == pytest.approx(-0.6)
    assert (values["YGYRO_EA"], values["YGYRO_ND"]) == (1, 1)
    assert values["ZGYRO_OUT"] == pytest.approx(2.9)
    assert (values["SEQ"], values["DEC"], values["RESERVED"]) == (1, 2, 0xF)


def test_refuses_big_endian_or_multiplexed_layouts() -> None:
    fast_packet = dbc.load(dbc.OUTPUT_DBC).get_message_by_name("GNSS_POSITION_DATA_FP")
    with pytest.raises(ValueError, match="only plain little-endian signals"):
        LittleEndianDecoder(fast_packet)


# The compiled unpacker (LittleEndianDecoder.compile) against cantools' own decode of the DBC,
# field by field. Payloads: random (hypothesis) and, as explicit examples, all zeros, all ones,
# every single bit set and every single bit clear (so every flag bit alone, both ways), and each
# 14-bit axis word at its extremes (-8192, -8191, -1, 0, 1, 8190, 8191) with EA/ND set or clear.

_ONE_BITS = [(1 << k).to_bytes(8, "little") for k in range(64)]
_ALL_BUT_ONE = [(~(1 << k) & (1 << 64) - 1).to_bytes(8, "little") for k in range(64)]
_EXTREME_WORDS = [
    ((raw & 0x3FFF) | flags).to_bytes(2, "little")
    for raw in (-8192, -8191, -1, 0, 1, 8190, 8191)
    for flags in (0, 0x4000, 0x8000, 0xC000)
]
_EXTREMES = [
    w
    + _EXTREME_WORDS[(k + 5) % len(_EXTREME_WORDS)]
    + _EXTREME_WORDS[(k + 11) % len(_EXTREME_WORDS)]
    + bytes([k * 9 % 256, 0xF0 | k % 16])
    for k, w in enumerate(_EXTREME_WORDS)
]
PAYLOADS = [bytes(8), b"\xff" * 8, *_ONE_BITS, *_ALL_BUT_ONE, *_EXTREMES]


def _cantools(name: str, data: bytes, scaling: bool = True) -> dict[str, float | int]:
    return _numbers(IMU.get_message_by_name(name).decode(data, False, scaling))


def _numbers(values: Any) -> dict[str, float | int]:
    """cantools' decode of a plain message: {signal: int or float}."""
    assert isinstance(values, dict)
    assert all(type(v) in (int, float) for v in values.values())
    return values


@cache
def _every_field(name: str) -> tuple[LittleEndianDecoder, list[str], Any]:
    """The decoder of ``name``, its signals, and an unpacker of every one of them twice: as
    raw bits and through a table of its physical values."""
    decoder = LittleEndianDecoder(IMU.get_message_by_name(name))
    names = [s.name for s in IMU.get_message_by_name(name).signals]
    outputs = [Raw(n) for n in names] + [Lookup(n, decoder.physical_table(n)) for n in names]
    return decoder, names, decoder.compile(outputs)


@pytest.mark.parametrize("name", ["IMU_GYRO", "IMU_ACCEL", "IMU_AUX"])
@pytest.mark.parametrize("data", PAYLOADS)
def test_compiled_fields_equal_cantools_on_extremes_and_every_bit(name: str, data: bytes) -> None:
    check_fields(name, data)


@pytest.mark.parametrize("name", ["IMU_GYRO", "IMU_ACCEL", "IMU_AUX"])
@given(data=st.binary(min_size=8, max_size=8))
def test_compiled_fields_equal_cantools(name: str, data: bytes) -> None:
    check_fields(name, data)


def check_fields(name: str, data: bytes) -> None:
    decoder, names, unpack = _every_field(name)
    expected, unscaled = _cantools(name, data), _cantools(name, data, scaling=False)
    got = unpack(bytearray(data))  # as python-can holds it
    assert got == unpack(data) and len(got) == 2 * len(names)
    for k, n in enumerate(names):
        raw, value = got[k], got[len(names) + k]
        length = IMU.get_message_by_name(name).get_signal_by_name(n).length
        assert isinstance(raw, int) and raw % (1 << length) == unscaled[n] % (1 << length), n
        # the same value and type (int where scale 1 and offset 0), bit for bit
        assert type(value) is type(expected[n]) and repr(value) == repr(expected[n]), n
        assert repr(decoder.physical(n, raw)) == repr(value)


@cache
def _any_all(name: str) -> tuple[list[tuple[str, ...]], Any]:
    """Groups of signals of ``name`` and an unpacker of AnyOf/AllOf of each: merged into one
    word test (flags at the same bit of each word) or not (mixed bits, multi-bit signals,
    tables), the last through a table of "the physical value is negative"."""
    message = IMU.get_message_by_name(name)
    decoder = LittleEndianDecoder(message)
    names = [s.name for s in message.signals]
    flags = [n for n in names if message.get_signal_by_name(n).length == 1]
    groups = [tuple(n for n in flags if n.endswith(x)) for x in ("_EA", "_ND")]
    groups = [g for g in groups if g] + [
        tuple(flags),
        tuple(names),
        tuple(names[:2]),
        tuple(names[:1]),
    ]
    negative = {n: tuple(v < 0 for v in decoder.physical_table(n)) for n in names}
    outputs: list[Output] = []
    for g in groups:
        outputs += [AnyOf(tuple(Raw(n) for n in g)), AllOf(tuple(Raw(n) for n in g))]
        outputs += [AnyOf(tuple(Lookup(n, negative[n]) for n in g))]
        outputs += [AllOf(tuple(Lookup(n, negative[n]) for n in g))]
    return groups, decoder.compile(outputs)


@pytest.mark.parametrize("name", ["IMU_GYRO", "IMU_ACCEL", "IMU_AUX"])
@given(data=st.one_of(st.sampled_from(PAYLOADS), st.binary(min_size=8, max_size=8)))
def test_compiled_any_and_all_equal_pythons_on_the_cantools_values(name: str, data: bytes) -> None:
    values, raw = _cantools(name, data), _cantools(name, data, scaling=False)
    groups, unpack = _any_all(name)
    got = iter(unpack(data))
    for g in groups:
        assert next(got) is any(raw[n] for n in g)  # raw bits not all zero
        assert next(got) is all(raw[n] for n in g)
        assert next(got) is any(values[n] < 0 for n in g)
        assert next(got) is all(values[n] < 0 for n in g)
    assert next(got, None) is None


def test_gyro_unpacker_reads_words_with_one_struct_call_and_merges_flag_tests() -> None:
    decoder = LittleEndianDecoder(IMU.get_message_by_name("IMU_GYRO"))
    unpack = decoder.compile(
        [
            *(Raw(f"{a}GYRO_OUT") for a in "XYZ"),
            Raw("SEQ"),
            Raw("DEC"),
            Raw("RESERVED"),
            AnyOf((Raw("XGYRO_EA"), Raw("YGYRO_EA"), Raw("ZGYRO_EA"))),
            AllOf((Raw("XGYRO_ND"), Raw("YGYRO_ND"), Raw("ZGYRO_ND"))),
        ]
    )
    source = unpack.__doc__ or ""
    assert source.count("= _read(data)") == 1  # one struct call reads every word
    assert "(w0 | w1 | w2) & 16384 != 0" in source and "(w0 & w1 & w2) & 32768 != 0" in source
    # SPEC 1 example frame: X = 12 LSB, Y = -12 LSB with EA and ND, Z = 58, SEQ 1, DEC 2
    frame = bytes.fromhex("0C00F4FF3A0001F2")
    assert unpack(frame) == (12, 0x3FF4, 58, 1, 2, 0xF, True, False)
    assert unpack(bytes.fromhex("0CC0F4FF3AC001F2"))[-1] is True  # ND on all three words


def test_compiles_any_little_endian_layout_of_the_output_dbc() -> None:
    """Other layouts: fields across words of 1, 2, 4 or 8 bytes at any byte, and 3-byte fields
    (then the whole payload is one integer), over the output DBC's frames and payloads."""
    checked = 0
    outputs = (dbc.load(dbc.OUTPUT_DBC), dbc.load(dbc.OUTPUT_PAYLOADS_DBC))
    for message in (m for db in outputs for m in db.messages):
        try:
            decoder = LittleEndianDecoder(message)
        except ValueError:
            continue
        names = [s.name for s in message.signals]
        unpack = decoder.compile([Raw(n) for n in names])
        for seed in range(20):
            data = bytes((seed * 37 + 11 * k + k * k * seed) % 256 for k in range(message.length))
            expected = _numbers(message.decode(data, decode_choices=False))
            got = [decoder.physical(n, raw) for n, raw in zip(names, unpack(data), strict=True)]
            assert got == [expected[n] for n in names]
        checked += 1
    assert checked >= 8


def test_compile_refuses_what_it_cannot_compile() -> None:
    decoder = LittleEndianDecoder(IMU.get_message_by_name("IMU_GYRO"))
    with pytest.raises(KeyError, match="no signal"):
        decoder.compile([Raw("NOPE")])
    with pytest.raises(ValueError, match="table of 3"):
        decoder.compile([Lookup("SEQ", (1, 2, 3))])
    with pytest.raises(ValueError, match="of no term"):
        decoder.compile([AnyOf(())])
    with pytest.raises(ValueError, match="table of bools"):
        decoder.compile([AnyOf((Lookup("SEQ", tuple(range(256))),))])
    with pytest.raises(ValueError, match="outside 8 bits"):
        decoder.physical("SEQ", 256)
    with pytest.raises(struct.error):
        decoder.compile([Raw("SEQ")])(bytes(7))
