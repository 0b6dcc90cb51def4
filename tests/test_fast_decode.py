"""The DBC-driven fast decoder equals cantools on every eligible message and payload."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

import dbc
from dbc.fast_decode import LittleEndianDecoder

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
