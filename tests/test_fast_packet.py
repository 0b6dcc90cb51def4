"""Fast-packet fragmentation, checked against canboat's own reassembler."""

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from nmea2000 import _canboat

from gateway.isobus.fast_packet import MAX_PAYLOAD_BYTES, FastPacketFragmenter, frame_count

PGN = 129029


def test_47_bytes_take_7_frames_with_headers_and_padding() -> None:
    payload = bytes(range(47))
    frames = FastPacketFragmenter().fragment(PGN, 0x1C, payload)
    assert len(frames) == frame_count(47) == 7
    assert frames[0] == bytes([0x00, 47, 0, 1, 2, 3, 4, 5])
    assert frames[1] == bytes([0x01, 6, 7, 8, 9, 10, 11, 12])
    # last frame: 47 - 6 - 5 * 7 = 6 payload bytes, one pad byte
    assert frames[6] == bytes([0x06, 41, 42, 43, 44, 45, 46, 0xFF])
    assert all(len(f) == 8 for f in frames)


def test_sequence_counter_per_pgn_and_source_wraps_at_8() -> None:
    frag = FastPacketFragmenter()
    seqs = [frag.fragment(PGN, 0x1C, bytes(20))[0][0] >> 5 for _ in range(10)]
    assert seqs == [0, 1, 2, 3, 4, 5, 6, 7, 0, 1]
    assert frag.fragment(PGN, 0x80, bytes(20))[0][0] >> 5 == 0  # other source
    assert frag.fragment(129540, 0x1C, bytes(20))[0][0] >> 5 == 0  # other PGN
    later = frag.fragment(PGN, 0x1C, bytes(20))
    assert [f[0] for f in later] == [0x40, 0x41, 0x42]


@pytest.mark.parametrize("length", [9, 13, 14, 43, 47, MAX_PAYLOAD_BYTES])
def test_canboat_reassembles_what_we_fragment(length: int) -> None:
    payload = bytes((7 * i + 3) & 0xFF for i in range(length))
    reassembler = _canboat.Reassembler()
    frag = FastPacketFragmenter()
    for _ in range(3):  # consecutive packets with increasing sequence numbers
        results = [reassembler.push(PGN, f, 0x1C) for f in frag.fragment(PGN, 0x1C, payload)]
        assert results[:-1] == [None] * (len(results) - 1)
        assert results[-1] == payload


def test_payload_too_long_or_empty_is_refused() -> None:
    with pytest.raises(ValueError, match="224 bytes"):
        FastPacketFragmenter().fragment(PGN, 0x1C, bytes(224))
    with pytest.raises(ValueError, match="0 bytes"):
        FastPacketFragmenter().fragment(PGN, 0x1C, b"")


def reference(payload: bytes, seq: int) -> list[bytes]:
    """The frames as the module docstring states them, built byte by byte."""
    frames = [bytes([seq << 5 | 0, len(payload)]) + payload[:6]]
    for n, start in enumerate(range(6, len(payload), 7), start=1):
        frames.append(bytes([seq << 5 | n]) + payload[start : start + 7])
    return [frame + bytes([0xFF] * (8 - len(frame))) for frame in frames]


@settings(max_examples=300, deadline=None)
@given(
    st.lists(
        st.tuples(st.sampled_from([0x1C, 0x80]), st.binary(min_size=1, max_size=223)),
        min_size=1,
        max_size=20,
    )
)
def test_frames_are_the_documented_layout_with_counters_per_source(
    packets: list[tuple[int, bytes]],
) -> None:
    frag, seqs = FastPacketFragmenter(), {0x1C: 0, 0x80: 0}
    reassembler = _canboat.Reassembler()
    for source, payload in packets:
        frames = frag.fragment(PGN, source, payload)
        assert frames == reference(payload, seqs[source])
        assert all(type(f) is bytes and len(f) == 8 for f in frames)
        assert len(frames) == frame_count(len(payload))
        seqs[source] = (seqs[source] + 1) % 8
        if len(payload) > 8:  # a packet canboat reassembles (shorter ones fit one frame)
            results = [reassembler.push(PGN, f, source) for f in frames]
            assert results[-1] == payload
