"""The timeline of a capture (every sample mapped, segments between resets, losses), against
a simulated link with known true sample times."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from host.bench.linksim import LinkCapture, LinkParams, simulate_link
from host.timing import timeline
from host.wire import bulk, capture, frames


def decode(lc: LinkCapture) -> tuple[bulk.BulkResult, np.ndarray, timeline.Timeline]:
    cap = capture.parse(lc.to_imucap())
    r = bulk.decode_bulk(cap.data)
    arrivals = cap.arrival_ns_at(r.samples["offset"] + 26)
    return r, arrivals, timeline.build_timeline(r.samples, arrivals)


def rms_after_offset(err: np.ndarray) -> float:
    e = err[~np.isnan(err)]
    return float(np.sqrt(np.mean((e - e.mean()) ** 2)))


def test_offline_mapping_beats_arrival_stamping_by_far() -> None:
    lc = simulate_link(LinkParams(seconds=180, skew_ppm=-95, seed=11))
    r, arrivals, tl = decode(lc)
    mapped = rms_after_offset(tl.host_ns - lc.true_host_ns)
    naive = rms_after_offset(arrivals - lc.true_host_ns)
    assert mapped < 50_000, mapped  # ns: the acceptance figure (10-min run: benchmark)
    assert naive > 1_000_000  # arrival stamping is off by milliseconds
    (seg,) = tl.segments
    assert seg.clock is not None
    assert seg.clock.overall.skew_ppm == pytest.approx(95, abs=4)


def test_device_time_wrap_and_seq_wrap() -> None:
    lc = simulate_link(LinkParams(seconds=40, device_t0_us=2**32 - 10_000_000, seq0=65_000, seed=2))
    r, _, tl = decode(lc)
    assert r.stats.resets == 0 and r.stats.lost_frames == 0
    assert np.all(r.samples["t_us"][-10:] < 40_000_000)  # it did wrap on the wire
    assert np.all(np.diff(tl.device_us) > 0)  # and is monotonic once unwrapped
    assert tl.device_us[-1] - tl.device_us[0] == pytest.approx(lc.device_us[-1] - lc.device_us[0])
    assert rms_after_offset(tl.host_ns - lc.true_host_ns) < 60_000
    assert tl.lost_frames == 0


def test_reset_mid_stream_starts_a_new_segment_with_its_own_map() -> None:
    a = simulate_link(LinkParams(seconds=20, seed=3, device_t0_us=50_000_000))
    b = simulate_link(LinkParams(seconds=20, seed=4, host_t0_ns=a.chunks[-1][0] + 2 * 10**9))
    joined = LinkCapture(a.chunks + b.chunks, np.concatenate((a.true_host_ns, b.true_host_ns)),
                         np.concatenate((a.device_us, b.device_us)), a.params)  # fmt: skip
    r, _, tl = decode(joined)
    assert r.stats.resets == 1 and len(tl.segments) == 2
    s1, s2 = tl.segments
    assert s1.stop == s2.start == a.true_host_ns.size
    assert np.all(np.diff(tl.host_ns[: s1.stop]) > 0) and np.all(
        np.diff(tl.host_ns[s2.start :]) > 0
    )
    assert tl.host_ns[s2.start] > tl.host_ns[s1.stop - 1]  # never mis-ordered across the reset
    err = tl.host_ns - joined.true_host_ns
    for s in (s1, s2):  # 20 s segments: a shorter span pins the skew down less well
        assert rms_after_offset(err[s.start : s.stop]) < 100_000


def test_lost_frames_and_missed_samples_are_counted_apart() -> None:
    lc = simulate_link(LinkParams(seconds=20, seed=6, status_every_s=100))
    data = bytearray(capture.parse(lc.to_imucap()).data)
    del data[27 * 100 : 27 * 103]  # three frames lost on the link
    r = bulk.decode_bulk(bytes(data))
    tl = timeline.build_timeline(r.samples, None)
    assert tl.lost_frames == 3 and tl.missed_samples == 0
    # the firmware skipped one sample: consecutive seq, t_us jumps by two periods
    s = r.samples.copy()
    s["t_us"][500:] += 20_000
    s["flags"][500] |= 1
    tl = timeline.build_timeline(s, None)
    assert tl.missed_samples == 1 and tl.lost_frames == 3


def test_the_timeline_counts_losses_by_the_decoders_rules() -> None:
    """Frames lost on the link are counted once, by host.wire.segments (through the decoder's
    per-sample ``lost``): STATUS frames between samples are not losses, a lost STATUS frame is."""
    lc = simulate_link(LinkParams(seconds=20, seed=12, status_every_s=1))
    data = bytearray(capture.parse(lc.to_imucap()).data)
    r = bulk.decode_bulk(bytes(data))
    assert len(r.others) >= 15  # STATUS frames between the samples
    assert timeline.build_timeline(r.samples, None).lost_frames == 0
    off = r.samples["offset"]
    k = 700 + int(np.flatnonzero(off[702:] - off[700:-2] == 2 * 27)[0])  # nothing between them
    a, b = int(off[k]), int(off[k + 2])
    del data[a:b]  # two samples lost
    status_at = r.others[5][0]
    assert status_at < a
    del data[status_at : status_at + 8 + frames.BY_NAME["STATUS"].length]  # and one STATUS
    r = bulk.decode_bulk(bytes(data))
    tl = timeline.build_timeline(r.samples, None)
    assert tl.lost_frames == r.stats.lost_frames == 3
    assert int(r.samples["lost"].sum()) == 3


@settings(max_examples=100, deadline=None)
@given(values=st.lists(st.floats(-1e12, 1e12), min_size=1, max_size=200))
def test_the_sample_periods_median_is_numpys(values: list[float]) -> None:
    """The median the timeline takes its sample period from is np.median's, to the bit."""
    a = np.asarray(values)
    assert timeline._median(a) == float(np.median(a))
