"""The device stream rejects types only the host sends (issue 17): one false frame in 258 545
was a genuine CRC-16 collision on line noise with type 0xB8 — a host → device type (0x80–0xFF,
protocol/README.md) that a board never sends."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from host.wire.bulk import decode_bulk
from host.wire.frames import _envelope, encode_frame
from host.wire.stream import StreamDecoder

SAMPLE = dict(t_us=1000, ax=1, ay=-2, az=3, temp=4, gx=-5, gy=6, gz=-7, flags=0)


def test_a_host_type_in_the_device_stream_is_no_frame() -> None:
    false = _envelope(0xB8, 9, bytes(range(11)))  # a valid envelope and CRC, type 0xB8
    data = encode_frame("IMU_SAMPLE", 0, **SAMPLE) + false + encode_frame("IMU_SAMPLE", 1, **SAMPLE)
    got = StreamDecoder().feed(data)
    assert [f.type for f in got] == [1, 1]
    bulk = decode_bulk(data)
    assert bulk.stats.frames == 2 and bulk.others == []
    assert bulk.stats.bytes_discarded == len(false) == StreamDecoder().stats.bytes_discarded + 19
    # a decoder of the host's commands (the board's side) takes it, and drops device types
    assert [f.type for f in StreamDecoder("any").feed(data)] == [1, 0xB8, 1]
    assert [f.type for f in StreamDecoder("host").feed(data)] == [0xB8]
    assert decode_bulk(data, "any").stats.frames == 3


@settings(max_examples=200, deadline=None)
@given(
    st.lists(
        st.tuples(st.integers(0, 255), st.binary(min_size=0, max_size=64)), min_size=1, max_size=8
    ),
    st.integers(1, 40),
)
@pytest.mark.slow
def test_device_stream_never_yields_a_host_type_and_bulk_equals_streaming(
    frames: list[tuple[int, bytes]], chunk: int
) -> None:
    data = b"".join(_envelope(t, k, p) for k, (t, p) in enumerate(frames))
    dec = StreamDecoder()
    got = [f for i in range(0, len(data), chunk) for f in dec.feed(data[i : i + chunk])]
    got += [f for _, f in dec.flush()]
    assert all(f.type < 0x80 for f in got)
    bulk = decode_bulk(data)
    assert bulk.stats.as_dict() == dec.stats.as_dict()
