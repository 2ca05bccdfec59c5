"""Decoding in bounded memory (issue 17, item 4): the chunked decoder, the streaming capture
unwrapper and the streaming clock give exactly what the whole-file paths give, at every chunk
size; ``decode`` on a file, a FIFO or a device streams. (Memory figures: the benchmark
``benchmarks/decode_memory.py``; a FIFO and ``/dev/zero``: tests/host/test_bad_input.py.)"""

from __future__ import annotations

import json
import random
import struct
from functools import partial
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from host.bench.linksim import LinkCapture, LinkParams, simulate_link
from host.timing import timeline
from host.wire import bulk, capture
from host.wire.bulk import ChunkedDecoder, decode_bulk
from tests.host.wire.test_frames import BASE, corrupt, imucap


def chunked(data: bytes, sizes: list[int], min_batch: int) -> bulk.BulkResult:
    d = ChunkedDecoder(min_batch=min_batch)
    parts, pos, i = [], 0, 0
    while pos < len(data):
        k = sizes[i % len(sizes)] if sizes else len(data)
        parts.append(d.feed(data[pos : pos + k]))
        pos, i = pos + k, i + 1
    parts.append(d.flush())
    return bulk.BulkResult(
        np.concatenate([p.samples for p in parts]), [x for p in parts for x in p.others], d.stats
    )


@pytest.mark.slow
@settings(max_examples=80, deadline=None)
@given(
    st.integers(0, 2**32 - 1),
    st.integers(0, 60),
    st.lists(st.integers(1, 2000), max_size=8),
    st.sampled_from([1, 700, 5000]),
)
def test_chunked_bulk_decoder_equals_the_whole_file(
    seed: int, n_ops: int, sizes: list[int], min_batch: int
) -> None:
    """Corrupted streams (resyncs, resets, lost frames) cut anywhere: same samples (with
    offsets and segment numbers), same other frames, same counters."""
    rng = random.Random(seed)
    data = corrupt(BASE + BASE[: rng.randrange(len(BASE))], rng, n_ops)  # a reset mid-way
    whole = decode_bulk(data)
    got = chunked(data, sizes, min_batch)
    assert np.array_equal(got.samples, whole.samples)
    assert got.others == whole.others
    assert got.stats == whole.stats


@settings(max_examples=60, deadline=None)
@given(
    st.lists(st.integers(0, 400), max_size=40),
    st.lists(st.integers(1, 500), min_size=1, max_size=6),
    st.integers(0, 40),
)
@pytest.mark.slow
def test_capture_unwrapper_with_times_equals_parse(
    reads: list[int], pieces: list[int], cut: int
) -> None:
    """Port bytes, each byte's read time and a cut-off last read: as :func:`capture.parse`."""
    data = corrupt(BASE, random.Random(len(reads)), 3)
    raw = imucap(data, reads)
    raw = raw[: len(raw) - cut]
    want = capture.parse(raw)
    u = capture.CaptureUnwrapper(times=True)
    got, pos, i = bytearray(), 0, 0
    while pos < len(raw):
        k = pieces[i % len(pieces)]
        got += u.feed(raw[pos : pos + k])
        pos, i = pos + k, i + 1
    got += u.finish()
    assert bytes(got) == want.data
    assert u.truncated_bytes == want.truncated_bytes
    offsets = np.arange(len(got))
    if len(got):
        assert np.array_equal(u.arrival_ns_at(offsets), want.arrival_ns_at(offsets))


@pytest.mark.slow
def test_a_read_longer_than_any_port_read_is_damage_and_memory_stays_bounded() -> None:
    """A made-up header claiming a 5 MiB read (no port read is above MAX_READ) in front of
    5 MiB of zeros and then two real reads: the zeros are skipped as one damaged place, the
    reads after them come through, and what is held at a time stays a few MAX_READ."""
    body = bytes(5 << 20)
    tail = struct.pack("<QI", 200, 3) + b"abc" + struct.pack("<QI", 300, 2) + b"de"
    raw = capture.MAGIC + struct.pack("<QI", 123, len(body)) + body + tail
    u = capture.CaptureUnwrapper(times=True)
    passed, held = [], []
    for i in range(0, len(raw), 1 << 19):
        passed.append(u.feed(raw[i : i + (1 << 19)]))
        held.append(len(u._buf))
    passed.append(u.finish())
    assert b"".join(passed) == b"abcde" and u.truncated_bytes == 0
    assert u.skipped == [(8, 12 + len(body))]
    assert max(held) <= (capture.RESYNC_CHAIN + 2) * (capture.MAX_READ + 12) + (1 << 19)
    assert list(u.arrival_ns_at(np.arange(5))) == [200, 200, 200, 300, 300]


def link_capture() -> LinkCapture:
    """Two board runs (a reset), 150 s and 100 s: several clock windows each."""
    a = simulate_link(LinkParams(seconds=150, seed=3, skew_ppm=40, device_t0_us=50_000_000))
    b = simulate_link(LinkParams(seconds=100, seed=4, host_t0_ns=a.chunks[-1][0] + 2 * 10**9))
    true = np.concatenate((a.true_host_ns, b.true_host_ns))
    return LinkCapture(a.chunks + b.chunks, true, np.concatenate((a.device_us, b.device_us)),
                       a.params)  # fmt: skip


@pytest.fixture(scope="module")
def two_runs() -> tuple[LinkCapture, bytes]:
    lc = link_capture()
    return lc, lc.to_imucap()


@pytest.mark.slow
@settings(max_examples=8, deadline=None)
@given(st.lists(st.integers(1, 30_000), min_size=1, max_size=5))
def test_streaming_timeline_equals_the_whole_capture(
    two_runs: tuple[LinkCapture, bytes], sizes: list[int]
) -> None:
    """Host time of every sample, segments, losses and window maps: as build_timeline."""
    lc, raw = two_runs
    cap = capture.parse(raw)
    r = decode_bulk(cap.data)
    arr = cap.arrival_ns_at(r.samples["offset"] + 26)
    whole = timeline.build_timeline(r.samples, arr)
    assert len(whole.segments) == 2 and all(s.clock and s.clock.windows > 2 for s in whole.segments)
    b = timeline.TimelineBuilder()
    blocks, i, n, k = [], 0, r.samples.size, 0
    while i < n:
        j = min(n, i + sizes[k % len(sizes)])
        blocks += b.add(r.samples[i:j], arr[i:j])
        i, k = j, k + 1
    blocks += b.finish()
    assert np.array_equal(np.concatenate([x.samples for x in blocks]), r.samples)
    assert np.array_equal(np.concatenate([x.host_ns for x in blocks]), whole.host_ns)
    assert [(s.start, s.stop, s.lost_frames, s.missed_samples, s.clock and s.clock.windows)
            for s in b.segments] == [
        (s.start, s.stop, s.lost_frames, s.missed_samples, s.clock and s.clock.windows)
        for s in whole.segments]  # fmt: skip


def test_a_timeline_that_maps_no_sample_has_the_same_segments_and_maps(
    two_runs: tuple[LinkCapture, bytes],
) -> None:
    """decode --stats's timeline (map_samples False): every segment, loss count and window
    map as the timeline that maps each sample, and no block handed back."""
    _, raw = two_runs
    cap = capture.parse(raw)
    r = decode_bulk(cap.data)
    arr = cap.arrival_ns_at(r.samples["offset"] + 26)
    full, bare = timeline.TimelineBuilder(), timeline.TimelineBuilder(map_samples=False)
    blocks = []
    for i in range(0, r.samples.size, 7000):
        full.add(r.samples[i : i + 7000], arr[i : i + 7000])
        blocks += bare.add(r.samples[i : i + 7000], arr[i : i + 7000])
    full.finish()
    blocks += bare.finish()
    assert blocks == []
    assert len(full.segments) == 2
    for a, b in zip(full.segments, bare.segments, strict=True):
        assert (a.start, a.stop, a.lost_frames, a.missed_samples) == (
            b.start, b.stop, b.lost_frames, b.missed_samples)  # fmt: skip
        assert a.clock is not None and b.clock is not None and a.clock.windows > 2
        assert a.clock.maps == b.clock.maps
        assert np.array_equal(a.clock.centres_us, b.clock.centres_us)


def test_streaming_timeline_is_accurate(two_runs: tuple[LinkCapture, bytes]) -> None:
    lc, raw = two_runs
    cap = capture.parse(raw)
    r = decode_bulk(cap.data)
    tl = timeline.build_timeline(r.samples, cap.arrival_ns_at(r.samples["offset"] + 26))
    for s in tl.segments:
        err = (tl.host_ns - lc.true_host_ns)[s.start : s.stop]
        assert np.sqrt(np.mean((err - err.mean()) ** 2)) < 60_000  # ns
    assert tl.segments[0].clock.overall.skew_ppm == pytest.approx(-40, abs=4)


def test_a_clock_no_board_has_is_given_up_in_bounded_memory(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Samples 1 µs apart (far denser than any board): the clock of that segment is given
    up once the window holds too many (t_host_ns then falls back to the arrivals)."""
    monkeypatch.setattr(timeline, "MAX_HELD_SAMPLES", 5000)
    n = 20_000
    s = np.zeros(n, bulk.SAMPLE_DTYPE)
    s["seq"] = np.arange(n) % 65536
    s["t_us"] = np.arange(n)
    s["offset"] = np.arange(n) * 27
    b = timeline.TimelineBuilder()
    out = []
    for i in range(0, n, 1000):
        out += b.add(s[i : i + 1000], np.arange(i, i + 1000, dtype=np.float64) * 1000)
        assert sum(x.samples.size for x in out) >= i - 6000  # nothing piles up
    out += b.finish()
    assert b.implausible == [0] and b.segments[0].clock is None
    assert sum(x.samples.size for x in out) == n
    assert np.isnan(np.concatenate([x.host_ns for x in out])).all()


def run_decode(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    from host.__main__ import main

    rc = main(argv)
    out, err = capsys.readouterr()
    return rc, out, err


@pytest.mark.parametrize("fmt", ["--csv", "--jsonl", "--stats"])
@pytest.mark.slow
def test_decode_output_does_not_depend_on_the_read_size(
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
    two_runs: tuple[LinkCapture, bytes],
    fmt: str,
) -> None:
    """The command on a 250 s capture with a reset, read whole vs in 1000-byte reads (the
    rows stream out as the clock windows complete); the mapped times are build_timeline's."""
    lc, raw = two_runs
    path = tmp_path / "two.cap"
    path.write_bytes(raw)
    rc, whole, err = run_decode(["decode", fmt, str(path)], capsys)
    assert rc == 0 and "warning" not in err
    import host.cli.decode as cli_decode

    monkeypatch.setattr(cli_decode, "BulkReader", partial(bulk.BulkReader, chunk=1000))
    rc, pieces, _ = run_decode(["decode", fmt, str(path)], capsys)
    assert rc == 0 and pieces == whole
    if fmt == "--stats":
        st_ = json.loads(whole)
        assert st_["resets"] == 1 and [c["samples"] for c in st_["clock"]] == [7530, 5020]
        return
    cap = capture.parse(raw)
    r = decode_bulk(cap.data)
    tl = timeline.build_timeline(r.samples, cap.arrival_ns_at(r.samples["offset"] + 26))
    if fmt == "--csv":
        rows = whole.splitlines()[1:]
        t_host = [int(x.rsplit(",", 1)[1]) for x in rows]
    else:
        t_host = [json.loads(x)["t_host_ns"] for x in whole.splitlines()]
    assert t_host == np.rint(tl.host_ns).astype(np.int64).tolist()
    assert len(t_host) == lc.true_host_ns.size


@settings(max_examples=100, deadline=None)
@given(data=st.binary(min_size=1, max_size=300), picks=st.lists(st.integers(0, 10**6), min_size=1))
def test_the_frame_rows_are_the_bytes_at_each_start_zero_padded(
    data: bytes, picks: list[int]
) -> None:
    """The bulk decoder's rows of frame bytes: row i is the ``width`` bytes from starts[i],
    zeros past the end of the buffer."""
    from host.wire.bulk import _frames_at

    buf = np.frombuffer(data, np.uint8)
    width = 28
    starts = np.unique(np.asarray(picks) % buf.size)
    rows = _frames_at(buf, starts, width)
    padded = data + bytes(width)
    assert [bytes(r) for r in rows] == [padded[k : k + width] for k in starts.tolist()]


@settings(max_examples=200, deadline=None)
@given(
    ends=st.lists(st.integers(1, 500), max_size=30, unique=True),
    offsets=st.lists(st.integers(0, 520), max_size=120),
    in_order=st.booleans(),
)
@pytest.mark.slow
def test_each_bytes_read_is_the_count_of_reads_ended_before_it(
    ends: list[int], offsets: list[int], in_order: bool
) -> None:
    """The read holding each byte (the arrival-time lookup): how many reads end at or before
    its offset, counted one by one; offsets in order or not."""
    from host.wire.capture import _read_of

    e = np.asarray(sorted(ends), dtype=np.int64)
    at = sorted(offsets) if in_order else offsets
    got = _read_of(e, np.asarray(at, dtype=np.int64)).tolist()
    assert got == [sum(1 for x in sorted(ends) if x <= o) for o in at]


@settings(max_examples=100, deadline=None)
@given(
    frames=st.lists(
        st.tuples(
            st.binary(min_size=19, max_size=19), st.integers(-1, 8 * 23 - 1), st.integers(0, 255)
        ),
        min_size=1,
        max_size=40,
    )
)
def test_the_imu_crc_check_from_words_is_the_crc_of_each_frame(
    frames: list[tuple[bytes, int, int]],
) -> None:
    """The bulk decoder's CRC check of IMU_SAMPLE frames (table lookups by 16-bit words, the
    type and length folded in, the stored CRC among the words) says what CRC-16 of each
    frame's bytes says, with a bit flipped anywhere after the header's length (or none) and
    any byte after the frame."""
    from host.wire.bulk import _IMU_CRC
    from host.wire.frames import IMU_FRAME_LEN, IMU_SAMPLE, SYNC, crc16

    rows, want = [], []
    for payload, flip, after in frames:
        body = bytearray(bytes([IMU_SAMPLE, len(payload)]) + bytes(2) + payload)
        frame = bytearray(SYNC + body + crc16(body).to_bytes(2, "little") + bytes([after]))
        if flip >= 0:
            frame[4 + flip // 8] ^= 1 << (flip % 8)  # seq, payload or the stored CRC
        rows.append(bytes(frame))
        stored = int.from_bytes(frame[IMU_FRAME_LEN - 2 : IMU_FRAME_LEN], "little")
        want.append(crc16(bytes(frame[2 : IMU_FRAME_LEN - 2])) == stored)
    got = _IMU_CRC.check(np.frombuffer(b"".join(rows), np.uint8).reshape(len(rows), -1), 2)
    assert got.tolist() == want
