"""The decoder: streaming and bulk paths, resync, counters, chunking, garbage."""

from __future__ import annotations

import io
import random

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from host.wire.bulk import decode_bulk
from host.wire.frames import IMU_FIELDS, encode_frame, encode_imu_samples
from host.wire.stream import DecoderStats, FrameReader, StreamDecoder


def make_stream(n: int, seed: int = 0, seq0: int = 0, t0: int = 0, status_every: int = 50) -> bytes:
    """n IMU samples with a different value on every axis, a STATUS frame now and then."""
    rng = np.random.default_rng(seed)
    counts = rng.integers(-32768, 32768, size=(n, 7))
    out = bytearray()
    seq = seq0
    for i in range(n):
        out += encode_imu_samples(seq, np.array([t0 + 20000 * i]), counts[i : i + 1])
        seq += 1
        if status_every and i % status_every == status_every - 1:
            out += encode_frame(
                "STATUS", seq, uptime_ms=i * 20, samples=i, missed=0, dropped=0,
                crc_errors=0, spi_faults=0, fifo_overflows=0, tx_queue_max=1, bad_bursts=0, flags=0,
            )  # fmt: skip
            seq += 1
    return bytes(out)


def stream_decode(data: bytes, chunks: list[int] | None = None):
    d = StreamDecoder()
    frames = []
    pos = 0
    for c in chunks or [len(data)]:
        frames += d.feed_raw(data[pos : pos + c])
        pos += c
    frames += d.feed_raw(data[pos:])
    frames += d.flush()
    return frames, d.stats


def summary(frames) -> list[tuple[int, int, bytes]]:
    return [(f.type, f.seq, f.payload) for _, f in frames]


def bulk_summary(data: bytes) -> tuple[list[tuple[int, int, bytes]], DecoderStats]:
    """Bulk result in stream order, as (type, seq, payload) for comparison."""
    r = decode_bulk(data)
    items = [(off, f.type, f.seq, f.payload) for off, f in r.others]
    for s in r.samples:
        payload = int(s["t_us"]).to_bytes(4, "little")
        payload += b"".join(int(s[k]).to_bytes(2, "big", signed=True) for k in IMU_FIELDS)
        payload += bytes([int(s["flags"])])
        items.append((int(s["offset"]), 1, int(s["seq"]), payload))
    items.sort()
    return [(t, q, p) for _, t, q, p in items], r.stats


def test_clean_stream_every_field_on_its_axis() -> None:
    rng = np.random.default_rng(3)
    counts = rng.integers(-32768, 32768, size=(500, 7))
    data = encode_imu_samples(100, np.arange(500) * 20000 + 5, counts, flags=2)
    r = decode_bulk(data)
    assert r.stats == DecoderStats(frames=500)
    for i, name in enumerate(IMU_FIELDS):
        assert np.array_equal(r.samples[name], counts[:, i]), name
    assert np.array_equal(r.samples["seq"], 100 + np.arange(500))
    assert np.all(r.samples["flags"] == 2)
    frames, stats = stream_decode(data, [7] * 100)
    assert stats == r.stats
    assert [f.fields["gy"] for _, f in frames] == counts[:, 5].tolist()


def test_crc_failure_resyncs_at_the_next_byte_not_after_the_frame() -> None:
    """A corrupted frame followed immediately by a good one: the good one must survive, and a
    good frame hidden right after a false sync inside garbage must be found."""
    good = make_stream(3, status_every=0)
    bad = bytearray(good[:27])
    bad[10] ^= 0x40  # corrupt the first frame's payload
    data = bytes(bad) + good[27:]
    frames, stats = stream_decode(data)
    assert [f.seq for _, f in frames] == [1, 2]
    assert stats.crc_errors == 1 and stats.bytes_discarded == 27
    # a false sync whose claimed frame would swallow the real one
    trap = b"\xa5\x5a\x01\x13" + b"\x00" * 2 + good
    frames, stats = stream_decode(trap)
    assert [f.seq for _, f in frames] == [0, 1, 2]
    assert stats.crc_errors == 1 and stats.bytes_discarded == 6
    assert bulk_summary(trap)[1] == stats


def test_impossible_length_is_not_a_crc_error() -> None:
    data = b"\xa5\x5a\x01\x05" + make_stream(2, status_every=0)  # IMU_SAMPLE must be 19 long
    frames, stats = stream_decode(data)
    assert len(frames) == 2 and stats.crc_errors == 0 and stats.bytes_discarded == 4


def test_unknown_type_is_counted_and_skipped_whole() -> None:
    unknown = bytearray(b"\xa5\x5a\x70\x03\x01\x00abc")
    import binascii

    crc = binascii.crc_hqx(bytes(unknown[2:]), 0xFFFF)
    unknown += crc.to_bytes(2, "little")
    data = encode_imu_samples(0, np.array([0]), np.ones((1, 7))) + bytes(unknown)
    data += encode_imu_samples(2, np.array([20000]), np.ones((1, 7)))
    frames, stats = stream_decode(data)
    assert stats.unknown_types == 1 and stats.frames == 3 and stats.lost_frames == 0
    assert frames[1][1].name == "UNKNOWN_0x70" and not frames[1][1].known
    assert bulk_summary(data)[1] == stats


def test_lost_frames_and_resets() -> None:
    first = make_stream(100, status_every=0, t0=10_000_000)
    second = make_stream(50, seed=1, status_every=0)  # board reset: seq and time restart
    data = first[: 27 * 40] + first[27 * 43 :] + second
    frames, stats = stream_decode(data)
    assert stats.lost_frames == 3
    assert stats.resets == 1
    assert bulk_summary(data)[1] == stats


def test_reset_detected_by_time_even_when_seq_goes_forward() -> None:
    a = encode_imu_samples(10, np.arange(5) * 20000 + 5_000_000, np.ones((5, 7)))
    b = encode_imu_samples(20, np.arange(5) * 20000, np.ones((5, 7)))
    _, stats = stream_decode(a + b)
    assert stats.resets == 1 and stats.lost_frames == 0
    assert bulk_summary(a + b)[1] == stats


def test_time_and_seq_wrap_are_not_resets() -> None:
    n = 30
    t = (2**32 - 10 * 20000 + np.arange(n) * 20000) % 2**32
    data = encode_imu_samples(0xFFF0, t, np.zeros((n, 7)))
    frames, stats = stream_decode(data, [5] * 200)
    assert stats.resets == 0 and stats.lost_frames == 0 and stats.frames == n
    assert frames[-1][1].seq == (0xFFF0 + n - 1) & 0xFFFF
    assert bulk_summary(data)[1] == stats


def test_frame_reader_over_a_file_like_object() -> None:
    data = b"junk" + make_stream(120)
    reader = FrameReader(io.BytesIO(data), chunk=13)
    got = list(reader)
    assert len(got) == 122 and reader.stats.bytes_discarded == 4
    assert all(raw[:2] == b"\xa5\x5a" and raw == f.to_bytes() for raw, f in got)


# --------------------------------------------------------------------------- properties

BASE = make_stream(300, seed=11)


@settings(max_examples=60, deadline=None)
@given(st.lists(st.integers(min_value=1, max_value=200), max_size=80))
def test_chunking_never_changes_the_output(chunks: list[int]) -> None:
    whole, s_whole = stream_decode(BASE)
    split, s_split = stream_decode(BASE, chunks)
    assert summary(split) == summary(whole)
    assert s_split == s_whole


def corrupt(data: bytes, rng: random.Random, n_ops: int) -> bytes:
    b = bytearray(data)
    for _ in range(n_ops):
        op = rng.choice(["drop", "insert", "flip", "sync"])
        i = rng.randrange(len(b))
        if op == "drop":
            del b[i : i + rng.randint(1, 30)]
        elif op == "insert":
            b[i:i] = bytes(rng.randrange(256) for _ in range(rng.randint(1, 30)))
        elif op == "flip":
            b[i] ^= 1 << rng.randrange(8)
        else:
            b[i:i] = b"\xa5\x5a" + bytes(rng.randrange(256) for _ in range(rng.randint(0, 70)))
    return bytes(b)


@settings(max_examples=80, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(0, 40), st.lists(st.integers(1, 97), max_size=30))
@pytest.mark.slow
def test_bulk_equals_streaming_on_corrupted_streams(seed: int, n_ops: int, chunks) -> None:
    data = corrupt(BASE, random.Random(seed), n_ops)
    frames, stats = stream_decode(data, chunks)
    bulk, bstats = bulk_summary(data)
    assert bulk == summary(frames)
    assert bstats == stats
    # every byte is accounted for: in a frame or discarded
    assert sum(len(raw) for raw, _ in frames) + stats.bytes_discarded == len(data)


@settings(max_examples=200, deadline=None)
@given(st.binary(max_size=600))
def test_fuzz_arbitrary_bytes_never_raise(data: bytes) -> None:
    from host.wire.capture import MAGIC

    assume(not data.startswith(MAGIC))  # that is a capture file: test_imucap01_* below
    frames, stats = stream_decode(data, [3, 50, 1])
    bulk, bstats = bulk_summary(data)
    assert bulk == summary(frames) and bstats == stats
    assert stats.bytes_discarded + sum(len(r) for r, _ in frames) == len(data)


@pytest.mark.parametrize("seed", range(5))
def test_one_percent_corrupted_recovers_the_rest(seed: int) -> None:
    rng = np.random.default_rng(seed)
    n = 5000
    data = bytearray(encode_imu_samples(0, np.arange(n) * 20000, rng.integers(-999, 999, (n, 7))))
    hit = rng.choice(n, size=n // 100, replace=False)
    for k in hit:
        data[27 * k + rng.integers(2, 27)] ^= 1 << int(rng.integers(8))
    r = decode_bulk(bytes(data))
    assert r.stats.frames == n - hit.size
    assert r.stats.crc_errors + 0 >= hit.size - 5  # a flipped length/type byte is no CRC error
    assert r.stats.lost_frames == hit.size
    assert not set(r.samples["seq"].tolist()) & set(hit.tolist())


# --------------------------------------------------------------------------- IMUCAP01 files


def imucap(data: bytes, reads: list[int]) -> bytes:
    """``data`` as ``python3 -m host capture`` writes it: magic, then (host ns, n, bytes) per
    read, the reads ``reads`` bytes long (the rest in one last read)."""
    import struct

    from host.wire.capture import MAGIC

    out = bytearray(MAGIC)
    pos = 0
    for k, n in enumerate([*reads, len(data)]):
        part = data[pos : pos + n]
        pos += len(part)
        if part:
            out += struct.pack("<QI", 10**9 + 1000 * k, len(part)) + part
    return bytes(out)


@settings(max_examples=40, deadline=None)
@given(
    st.lists(st.integers(1, 300), max_size=30),
    st.integers(1, 97),
    st.integers(0, 2**32 - 1),
    st.integers(0, 10),
)
@pytest.mark.slow
def test_imucap01_files_decode_like_the_bytes_they_hold(
    reads: list[int], chunk: int, seed: int, n_ops: int
) -> None:
    """decode_bulk and FrameReader take a capture file as written by ``capture`` (IMUCAP01,
    however its reads were split) and find exactly the frames of the bytes it recorded."""
    data = corrupt(BASE, random.Random(seed), n_ops)
    cap = imucap(data, reads)
    want, want_stats = bulk_summary(data)
    got, got_stats = bulk_summary(cap)
    assert got == want and got_stats == want_stats
    reader = FrameReader(io.BytesIO(cap), chunk=chunk)
    frames = list(reader)
    assert summary(frames) == want and reader.stats == want_stats


def test_imucap01_cut_short_keeps_every_complete_read() -> None:
    data = make_stream(100, status_every=0)
    cap = imucap(data, [27 * 10] * 9)  # ten reads of ten frames
    r = decode_bulk(cap[:-5])  # the last read cut off (a killed recording)
    assert len(r.samples) == 90 and r.stats.bytes_discarded == 12 + 270 - 5
    assert np.array_equal(r.samples["t_us"], np.arange(90) * 20000)
    assert sum(1 for _ in FrameReader(io.BytesIO(cap[:-5]))) == 90


@settings(max_examples=200, deadline=None)
@given(st.binary(min_size=19, max_size=19))
def test_the_sample_accessors_read_the_spec_fields(payload: bytes) -> None:
    """The board driver's per-sample reads (t_us, counts, flags) are the spec codec's fields."""
    from host.wire.frames import (
        IMU_FIELDS,
        IMU_SAMPLE,
        MESSAGES,
        sample_counts,
        sample_flags,
        sample_t_us,
    )

    fields = MESSAGES[IMU_SAMPLE].unpack(payload)
    assert sample_t_us(payload) == fields["t_us"]
    assert sample_counts(payload) == tuple(fields[n] for n in IMU_FIELDS)
    assert sample_flags(payload) == fields["flags"]
