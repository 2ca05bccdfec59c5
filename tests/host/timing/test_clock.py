"""Device-to-host time mapping: the minimum-delay estimator, live and on its own, and the
counters' unwrap, against a simulated link with known true sample times."""

from __future__ import annotations

import math
from unittest import mock

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from host.bench.linksim import LinkParams, simulate_link
from host.timing import clock
from host.wire import stream
from tests.host.timing.test_timeline import rms_after_offset


def test_unwrap_uses_host_time_for_gaps_longer_than_the_counter() -> None:
    period = 2**32  # µs: one wrap is 71.6 min
    dev = np.array([100, 200, 300 + 2 * period + 50], dtype=np.int64)  # two wraps in the gap
    host = np.array([0, 100_000, (300 + 2 * period + 50 - 100) * 1000], dtype=np.float64)
    assert unwrap_wire(dev, host).tolist() == dev.tolist()
    # without host time the gap is read as less than one wrap
    assert clock.unwrap(dev % 2**32, 32)[-1] == 300 + 50


def unwrap_wire(dev: np.ndarray, host: np.ndarray) -> np.ndarray:
    return clock.unwrap(dev % 2**32, 32, host, 1e-3)


def test_live_estimate_is_usable_early_and_accurate_after_ten_seconds() -> None:
    lc = simulate_link(LinkParams(seconds=40, seed=8))
    dec = stream.StreamDecoder()
    live = clock.LiveClock()
    serial_ns = float(clock.serialisation_ns(27, lc.params.baud))
    mapped = np.full(lc.true_host_ns.size, np.nan)
    k = 0
    first_estimate_at = None
    for t_ns, chunk in lc.chunks:
        for f in dec.feed(chunk):
            if f.type != 1:
                continue
            live.add(lc.device_us[k], t_ns - serial_ns)
            m = live.to_host_ns(lc.device_us[k])
            if m is not None:
                mapped[k] = float(m)
                first_estimate_at = first_estimate_at or k
            k += 1
    t_s = (lc.true_host_ns - lc.true_host_ns[0]) / 1e9
    assert first_estimate_at is not None and t_s[first_estimate_at] < 3.0
    after = t_s > 10
    assert rms_after_offset((mapped - lc.true_host_ns)[after]) < 200_000


def test_min_delay_fit_is_exact_on_noise_free_points_and_ignores_late_ones() -> None:
    x = np.arange(0, 10_000_000, 20_000, dtype=float)  # µs
    y = 7e9 + 999.95 * x  # ns: a clock 50 ppm fast
    late = y + np.where(np.arange(x.size) % 3 == 0, 0.0, 3e6)  # most points 3 ms late
    m = clock.fit_min_delay(x, late)
    assert m.skew_ppm == pytest.approx(-50, abs=1e-6)
    assert np.max(np.abs(m.to_host_ns(x) - y)) < 1.0


def _walked_hull(x: list[float], y: list[float]) -> list[int]:
    """The lower hull walked point by point (Andrew's monotone chain, the textbook loop): the
    reference the vectorised hull must reproduce."""
    hull: list[int] = []
    for i in range(len(x)):
        while len(hull) >= 2:
            o, a = hull[-2], hull[-1]
            if (x[a] - x[o]) * (y[i] - y[o]) - (y[a] - y[o]) * (x[i] - x[o]) <= 0:
                hull.pop()
            else:
                break
        hull.append(i)
    return hull


_small_points = st.lists(
    st.tuples(st.integers(0, 40), st.integers(0, 25)), min_size=65, max_size=200
)  # integer coordinates: exact cross products, many ties and repeats; over 64 points, so
# the vectorised passes run before the walk


@settings(max_examples=50, deadline=None)
@given(points=_small_points)
@pytest.mark.slow
def test_lower_hull_is_the_walked_hull_and_lies_under_every_point(
    points: list[tuple[int, int]],
) -> None:
    pts = sorted(points)  # by x, then y
    x = np.asarray([p[0] for p in pts], dtype=float)
    y = np.asarray([p[1] for p in pts], dtype=float)
    h = clock.lower_hull(x, y)
    assert h.tolist() == _walked_hull(x.tolist(), y.tolist())
    if len(pts) >= 2:
        assert h[0] == 0 and h[-1] == len(pts) - 1
    for i, j in zip(h[:-1], h[1:], strict=True):  # no point strictly under an edge's line
        if x[j] > x[i]:
            below = (x[j] - x[i]) * (y - y[i]) - (y[j] - y[i]) * (x - x[i])
            between = (x >= x[i]) & (x <= x[j])
            assert np.all(below[between] >= 0)


@settings(max_examples=60, deadline=None)
@given(
    n=st.integers(2, 4000),
    skew_ppm=st.floats(-200, 200),
    latency_ms=st.floats(0.01, 30),
    per_read=st.integers(1, 200),
    seed=st.integers(0, 2**32 - 1),
)
def test_min_delay_fit_with_the_vectorised_hull_is_the_walked_hulls_fit(
    n: int, skew_ppm: float, latency_ms: float, per_read: int, seed: int
) -> None:
    rng = np.random.default_rng(seed)
    x = np.cumsum(rng.integers(1, 40_000, n)).astype(float)  # µs, increasing
    y = 5e11 + (1000 + skew_ppm / 1000) * x + rng.exponential(latency_ms * 1e6, n)
    last = np.minimum((np.arange(n) // per_read + 1) * per_read, n) - 1
    y = np.maximum.accumulate(y)[last]  # the samples of one read share its arrival
    fast = clock.fit_min_delay(x, y)
    walk = lambda a, b: np.asarray(_walked_hull(a.tolist(), b.tolist()), dtype=np.int64)  # noqa: E731
    with mock.patch.object(clock, "lower_hull", walk):
        walked = clock.fit_min_delay(x, y)
    assert fast.b == pytest.approx(walked.b, rel=1e-12, abs=1e-12)
    assert fast.offset_ns == pytest.approx(walked.offset_ns, rel=1e-12, abs=1e-3)
    assert fast.latency_median_us == pytest.approx(walked.latency_median_us, abs=1e-6)


@settings(max_examples=100, deadline=None)
@given(
    values=st.lists(st.floats(-1e9, 1e9), min_size=1, max_size=300),
    q=st.floats(0, 100),
)
def test_the_clocks_percentiles_and_line_are_numpys(values: list[float], q: float) -> None:
    """The window fit's own percentiles (one partial sort) and least-squares line (centred
    sums) give numpy's percentile, median and polyfit to rounding."""
    a = np.asarray(values)
    got = clock._percentiles(a, (q, 50.0))
    scale = 1 + float(np.max(np.abs(a)))
    assert got[0] == pytest.approx(np.percentile(a, q), abs=1e-12 * scale)
    assert got[1] == pytest.approx(np.median(a), abs=1e-12 * scale)
    x = np.arange(a.size, dtype=float) * 1e6
    if a.size >= 2:
        mask = np.ones((1, a.size), dtype=bool)
        (c1,), (c0,) = clock._lines(x[None, :], a[None, :], mask)
        p1, p0 = np.polyfit(x, a, 1)
        assert c1 == pytest.approx(p1, rel=1e-9, abs=1e-9 * scale / 1e6 / a.size)
        assert c0 == pytest.approx(p0, rel=1e-9, abs=1e-6 * scale)


def _refined_alone(
    x: np.ndarray, y: np.ndarray, a: float, b: float, bin_us: float = 1e6
) -> tuple[float, float]:
    """The refinement of one window's hull line, written out plainly as method.md says it:
    the first lowest point of each 1 s bin holding at least 5 points (nan never lowest), a
    line fitted (np.polyfit) and refitted up to 3 times to the floors within 4 scaled MADs,
    lowered to the floors' 2nd percentile; the hull line where that is undefined."""
    if x[-1] - x[0] < 4 * bin_us:
        return a, b
    r = y - (a + b * x)
    by_bin: dict[int, list[int]] = {}
    for i, xi in enumerate(x.tolist()):
        by_bin.setdefault(math.floor((xi - x[0]) / bin_us), []).append(i)
    floors = []
    for members in by_bin.values():
        if len(members) >= 5:
            vals = [math.inf if math.isnan(r[i]) else r[i] for i in members]
            floors.append(members[vals.index(min(vals))])
    if len(floors) < 4 or not np.all(np.isfinite(r[floors])):
        return a, b
    fx, fr = x[floors], r[floors]
    keep = np.ones(fx.size, dtype=bool)
    for _ in range(3):
        c1, c0 = np.polyfit(fx[keep], fr[keep], 1)
        res = fr - (c0 + c1 * fx)
        mad = np.median(np.abs(res[keep] - np.median(res[keep]))) or 1.0
        new_keep = np.abs(res) <= 4 * 1.4826 * mad
        if np.array_equal(new_keep, keep) or np.count_nonzero(new_keep) < 4:
            break
        keep = new_keep
    c0 += np.percentile(fr[keep] - (c0 + c1 * fx[keep]), 2.0)
    return a + c0, b + c1


@settings(max_examples=40, deadline=None)
@given(
    sizes=st.lists(st.integers(2, 3000), min_size=1, max_size=6),
    skew_ppm=st.floats(-200, 200),
    latency_ms=st.floats(0.01, 30),
    per_read=st.integers(1, 200),
    gap_us=st.integers(1, 40_000),
    holes=st.integers(0, 3),
    seed=st.integers(0, 2**32 - 1),
)
def test_windows_refined_together_get_each_windows_own_line(
    sizes: list[int],
    skew_ppm: float,
    latency_ms: float,
    per_read: int,
    gap_us: int,
    holes: int,
    seed: int,
) -> None:
    """Several clock windows' lines refined in one batch are the lines each window's own
    refinement gives (bin floors, robust iterations stopping per window, 2 % lowering),
    written out plainly (_refined_alone), also with sparse bins and points with no arrival
    time (nan)."""
    rng = np.random.default_rng(seed)
    windows = []
    for n in sizes:
        x = np.cumsum(rng.integers(1, gap_us + 1, n)).astype(float)
        y = 5e11 + (1000 + skew_ppm / 1000) * x + rng.exponential(latency_ms * 1e6, n)
        last = np.minimum((np.arange(n) // per_read + 1) * per_read, n) - 1
        y = np.maximum.accumulate(y)[last]
        x, y = x - x[0], y - y[0]
        y[rng.integers(1, n, holes)] = np.nan  # (the first has one: a is finite)
        b = 1000 + float(rng.normal(0, 0.1))
        windows.append((x, y, float(np.nanmin(y - b * x)), b))
    together = clock._refine_many(windows)
    for (x, y, a, b), (a2, b2) in zip(windows, together, strict=True):
        a1, b1 = _refined_alone(x, y, a, b)
        assert b2 == pytest.approx(b1, rel=1e-9, abs=1e-9, nan_ok=True)
        assert a2 == pytest.approx(a1, abs=1e-2, nan_ok=True)  # ns


def test_a_capture_fitted_window_by_window_and_in_batches_has_the_same_maps() -> None:
    """fit_min_delay_many over a capture's windows gives fit_min_delay of each."""
    rng = np.random.default_rng(7)
    x = np.arange(20_000) * 20_000.0 + rng.integers(0, 50, 20_000)
    y = 3e12 + 1000.01 * x + rng.exponential(2e6, x.size)
    windows = [(x[k : k + 3000], y[k : k + 3000]) for k in range(0, 17_000, 1500)]
    for (wx, wy), m in zip(windows, clock.fit_min_delay_many(windows), strict=True):
        one = clock.fit_min_delay(wx, wy)
        assert m.b == pytest.approx(one.b, rel=1e-12)
        assert m.offset_ns == pytest.approx(one.offset_ns, abs=1e-3)
        assert m.latency_median_us == pytest.approx(one.latency_median_us, abs=1e-6)


@settings(max_examples=50, deadline=None)
@given(runs=st.lists(_small_points, min_size=1, max_size=5))
@pytest.mark.slow
def test_the_hulls_of_several_runs_at_once_are_each_runs_walked_hull(
    runs: list[list[tuple[int, int]]],
) -> None:
    """lower_hulls over runs of points laid end to end (each sorted by x, then y; the runs'
    coordinates unrelated, so a run's neighbours must not matter) gives each run's walked
    hull."""
    pts = [sorted(r) for r in runs]
    x = np.asarray([p[0] for r in pts for p in r], dtype=float)
    y = np.asarray([p[1] for r in pts for p in r], dtype=float)
    bounds = np.cumsum([0] + [len(r) for r in pts])
    for k, h in enumerate(clock.lower_hulls(x, y, bounds)):
        a, b = bounds[k], bounds[k + 1]
        assert (h - a).tolist() == _walked_hull(x[a:b].tolist(), y[a:b].tolist())


def _min_delay_line(x: np.ndarray, y: np.ndarray) -> tuple[float, float]:
    """The minimum-delay line by brute force: of the lines through two points that no point
    lies under, the highest at the points' mean x (offset at the mean, slope)."""
    x0, y0 = x[0], y[0]
    x, y = x - x0, y - y0
    xm = float(x.mean())
    i, j = np.triu_indices(x.size, 1)
    i, j = i[x[j] > x[i]], j[x[j] > x[i]]
    b = (y[j] - y[i]) / (x[j] - x[i])
    under = y[None, :] - (y[i][:, None] + b[:, None] * (x[None, :] - x[i][:, None]))
    ok = np.all(under >= -1e-3, axis=1)  # ns
    at_mean = y[i] + b * (xm - x[i])
    best = np.flatnonzero(ok)[np.argmax(at_mean[ok])]
    return float(y0 + at_mean[best]), float(b[best])


@settings(max_examples=40, deadline=None)
@given(
    n=st.integers(6, 90),
    per_read=st.integers(1, 5),
    seed=st.integers(0, 2**32 - 1),
)
def test_overlapping_windows_of_one_run_get_each_windows_min_delay_line(
    n: int, per_read: int, seed: int
) -> None:
    """fit_min_delay_spans over half-overlapping windows of a run of points (their hulls
    merged from the stretches between window ends) gives each window the line under its
    points that is highest at their mean, found by brute force (windows under 4 s: the
    line of the hull alone), and the gaps' numpy median and 5th percentile."""
    rng = np.random.default_rng(seed)
    x = 7e9 + np.cumsum(rng.integers(1, 40_000, n)).astype(float)  # µs
    y = 3e12 + 1000.05 * x + rng.exponential(2e6, n)  # ns
    last = np.minimum((np.arange(n) // per_read + 1) * per_read, n) - 1
    y = np.rint(np.maximum.accumulate(y)[last])
    half = max(n // 4, 1)
    spans = [(i, min(i + 2 * half + 1, n)) for i in range(0, n - 1, half)]
    for (i, j), m in zip(spans, clock.fit_min_delay_spans(x, y, spans), strict=True):
        wx, wy = x[i:j], y[i:j]
        at_mean, b = _min_delay_line(wx, wy)
        assert m.b == pytest.approx(b, rel=1e-9)
        assert float(m.to_host_ns(wx.mean())) == pytest.approx(at_mean, abs=0.01)  # ns
        gaps = (wy - m.to_host_ns(wx)) / 1000.0
        assert m.latency_median_us == pytest.approx(np.median(gaps), abs=1e-4)
        assert m.floor_spread_us == pytest.approx(np.percentile(gaps, 5), abs=1e-4)


@settings(max_examples=200, deadline=None)
@given(
    steps=st.lists(
        st.tuples(
            st.one_of(st.integers(0, 3000), st.integers(0, 2**16 - 1)),
            st.one_of(st.integers(0, 3000), st.integers(0, 2**18)),
        ),
        max_size=40,
    ),
    v0=st.integers(0, 2**16 - 1),
)
@pytest.mark.slow
def test_unwrap_with_host_time_is_the_step_by_step_rule(
    steps: list[tuple[int, int]], v0: int
) -> None:
    """A 16-bit counter at 1 tick/µs unwrapped with host times: each step is the counter's
    step modulo 2^16 plus the whole wraps that best explain the host time elapsed (none when
    that is under half a period), step by step."""
    ticks = [v0]
    host = [0.0]
    for dv, dh_us in steps:
        ticks.append((ticks[-1] + dv) % 2**16)
        host.append(host[-1] + dh_us * 1000.0)
    got = clock.unwrap(np.asarray(ticks), 16, np.asarray(host), 1e-3).tolist()
    want = [v0]
    for k in range(1, len(ticks)):
        d = (ticks[k] - ticks[k - 1]) % 2**16
        dh = (host[k] - host[k - 1]) * 1e-3
        want.append(want[-1] + d + max(round((dh - d) / 2**16), 0) * 2**16)
    assert got == want
