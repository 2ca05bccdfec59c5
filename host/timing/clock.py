"""Time: map the device's microsecond clock to the host's monotonic clock.

Every IMU sample carries ``t_us``, the device time latched in the data-ready interrupt. Every
read from the port carries the host monotonic time taken right after ``read()`` returned. The
arrival of a frame is late by a variable, non-negative latency (UART serialisation, the USB
bridge's ≈4 ms flush timer, 1 ms USB frames, OS jitter, rare spikes of tens of ms), so a least
squares line through (device time, arrival) is biased and noisy. Instead we estimate

    host_ns = a + b · device_us                                           (1)

as the line *under* all points that is closest to them on average (a minimum-delay estimator:
the supporting line of the lower convex hull at the points' mean device time; it minimises
Σ(yᵢ − a − b·xᵢ) subject to yᵢ ≥ a + b·xᵢ). Points are arrivals minus the frame's known
serialisation time at the link's baud rate.

- Offline (a whole capture; :class:`host.timing.timeline.TimelineBuilder`): lines fitted in
  overlapping windows and blended linearly between window centres, so a clock whose skew
  drifts slowly with temperature is still followed.
- Live (:class:`LiveClock`): the same estimator over a sliding window of recent points.

Counters wrap (t_us at 2³², seq at 2¹⁶); :func:`unwrap` resolves wraps, using host time when a
gap is too long for the counter alone. A device reset (time or seq going back) starts a new
segment with its own map: :mod:`host.timing.timeline` applies this estimator to every segment
of a capture, whole or streaming.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

UART_BITS_PER_BYTE = 10  # 8N1


def serialisation_ns(n_bytes: int | np.ndarray, baud: int) -> np.ndarray:
    """Time (ns) the UART needs to send ``n_bytes`` at ``baud`` (8N1)."""
    return np.asarray(n_bytes, dtype=np.float64) * UART_BITS_PER_BYTE * 1e9 / baud


def unwrap(
    values: np.ndarray,
    bits: int,
    host_ns: np.ndarray | None = None,
    ticks_per_ns: float | None = None,
) -> np.ndarray:
    """Unwrap a ``bits``-wide counter into int64, assuming it only moves forward.

    Consecutive differences are taken modulo 2^bits. Where host times are given with the
    counter's nominal rate (``ticks_per_ns``), a gap longer than the counter's period is
    resolved from the host time elapsed: the number of whole wraps that best explains it.
    """
    v = np.asarray(values, dtype=np.int64)
    if v.size == 0:
        return v
    mod = 1 << bits
    d = np.diff(v) & (mod - 1)  # modulo 2^bits (two's complement: a bitwise and)
    if host_ns is not None and ticks_per_ns is not None:
        dh = np.diff(np.asarray(host_ns, dtype=np.float64)) * ticks_per_ns
        # under half a period of host time between every two (the usual case) rounds to no
        # whole wrap anywhere, the counter's step being >= 0
        if not (dh.size == 0 or float(dh.max()) < mod / 2):
            wraps = np.maximum(np.rint((dh - d) / mod), 0).astype(np.int64)
            d = d + wraps * mod
    return v[0] + np.concatenate(([0], np.cumsum(d)))


#: below this many candidates a run's last hull points are walked one by one
_HULL_WALK = 64


def lower_hull(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Indices of the lower convex hull of points sorted by x (among equal x, by y), from the
    first point to the last, collinear points left out: Andrew's monotone chain
    (:func:`lower_hulls` of one run)."""
    return lower_hulls(x, y, [0, np.size(x)])[0]


def lower_hulls(
    x: np.ndarray, y: np.ndarray, bounds: Sequence[int] | np.ndarray
) -> list[np.ndarray]:
    """:func:`lower_hull` of each run of points ``x[bounds[k] : bounds[k + 1]]`` (bounds
    increasing), as indices into ``x``; all runs at once.

    Vectorised: a point on or above the segment between its two neighbours is no vertex, so
    all such points are dropped at once (a run's first and last point stay), and again among
    what is left, until a pass drops few (a few passes: each about halves random points, and
    the samples of one read, which share its arrival time, go in one); a run whose candidates
    left still turn somewhere the wrong way is walked by the monotone chain (the same cross
    products, so the same hull as walking them all). A point equal to a neighbour stays for
    the walk: of two equal points each is on the segment through the other, and dropping both
    would lose a vertex.
    """
    xs, ys = np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64)
    b = np.asarray(bounds, dtype=np.int64)
    ends = np.zeros(xs.size + 1, dtype=bool)  # a run's first or last point: never dropped
    ends[b[:-1]] = ends[b[1:] - 1] = True
    idx = np.arange(b[0], b[-1])
    while idx.size > _HULL_WALK:
        cross, repeat = _turns(xs[idx], ys[idx])
        keep = np.ones(idx.size, dtype=bool)
        keep[1:-1] = ~((cross < 0) | ((cross == 0) & ~repeat)) | ends[idx[1:-1]]  # nan: kept
        left = int(np.count_nonzero(keep))
        idx = idx[keep]
        if 8 * left > 7 * keep.size:  # under 1/8 dropped: the walk is cheaper now
            break
    at = np.searchsorted(idx, b)
    # a run whose candidates all turn left is its hull (the walk would keep every one)
    cross, _ = _turns(xs[idx], ys[idx])
    bent = (idx[1:-1])[~(cross > 0) & ~ends[idx[1:-1]]]  # a nan is walked too
    walk = np.zeros(b.size, dtype=bool)
    walk[np.searchsorted(b, bent, side="right") - 1] = True
    out = []
    for k in range(b.size - 1):
        c = idx[at[k] : at[k + 1]]
        out.append(c[_monotone_chain(xs[c].tolist(), ys[c].tolist())] if walk[k] else c)
    return out


def _turns(x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """At each inner point of a chain: the cross product of (it − the one before) and (the
    one after − the one before) (> 0: the chain turns left there), and whether it equals a
    neighbour."""
    ox, oy, px, py, qx, qy = x[:-2], y[:-2], x[1:-1], y[1:-1], x[2:], y[2:]
    cross = (px - ox) * (qy - oy) - (py - oy) * (qx - ox)
    repeat = ((px == ox) & (py == oy)) | ((px == qx) & (py == qy))
    return cross, repeat


def _monotone_chain(xs: list[float], ys: list[float]) -> list[int]:
    """Andrew's monotone chain over points sorted by x: the lower hull's indices."""
    hull: list[int] = []
    for i, (xi, yi) in enumerate(zip(xs, ys, strict=True)):  # Python floats: 10x numpy scalars
        while len(hull) >= 2:
            o, a = hull[-2], hull[-1]
            # drop a if it lies on or above the segment o -> i
            if (xs[a] - xs[o]) * (yi - ys[o]) - (ys[a] - ys[o]) * (xi - xs[o]) <= 0:
                hull.pop()
            else:
                break
        hull.append(i)
    return hull


@dataclass(frozen=True)
class ClockMap:
    """host_ns = host0_ns + offset_ns + b · (device_us − device0_us)   — eq. (1), centred.

    ``b`` is host ns per device µs (1000 for a perfect clock); the reference values keep the
    arithmetic exact in float64 over days.
    """

    device0_us: float
    host0_ns: float
    offset_ns: float
    b: float
    points: int = 0
    latency_median_us: float = float("nan")  # how late arrivals are above the floor, typical
    floor_spread_us: float = float("nan")  # 5th percentile of the gaps: how sharp the floor is

    @property
    def skew_ppm(self) -> float:
        """Device clock rate error: positive when the device clock runs slow."""
        return (self.b / 1000.0 - 1.0) * 1e6

    def to_host_ns(self, device_us: np.ndarray | float) -> np.ndarray:
        """Map device µs (unwrapped) to host monotonic ns."""
        dx = np.asarray(device_us, dtype=np.float64) - self.device0_us
        return self.host0_ns + self.offset_ns + self.b * dx

    def describe(self) -> str:
        return (
            f"skew {self.skew_ppm:+.1f} ppm, {self.points} points, "
            f"typical latency {self.latency_median_us / 1000:.2f} ms, "
            f"floor spread {self.floor_spread_us:.0f} µs"
        )


def fit_min_delay(device_us: np.ndarray, floor_ns: np.ndarray) -> ClockMap:
    """Minimum-delay line under the points (device µs, host ns) — see the module docstring.

    Needs at least two points with distinct device times.
    """
    return fit_min_delay_many([(device_us, floor_ns)])[0]


def fit_min_delay_many(windows: Sequence[tuple[np.ndarray, np.ndarray]]) -> list[ClockMap]:
    """:func:`fit_min_delay` of each window (device µs, floor ns), the windows' hulls and line
    refinements done together (one set of array operations for all windows: at 50 Hz a
    window's own refinement is mostly numpy's per-call overhead)."""
    rel = []
    for device_us, floor_ns in windows:
        x0 = float(device_us[0])
        y0 = float(floor_ns[0])
        x = np.asarray(device_us, dtype=np.float64) - x0
        y = np.asarray(floor_ns, dtype=np.float64) - y0
        if np.all(x[1:] > x[:-1]):  # in order already (a capture's samples): no sort
            xs, ys = x, y
        else:
            order = np.lexsort((y, x))  # by device time, the lowest first among equal times
            xs, ys = x[order], y[order]
        rel.append((x0, y0, x, y, xs, ys))
    at = np.cumsum([0] + [w[4].size for w in rel])
    cx = np.concatenate([w[4] for w in rel]) if rel else np.zeros(0)
    cy = np.concatenate([w[5] for w in rel]) if rel else np.zeros(0)
    hulls = [h - at[k] for k, h in enumerate(lower_hulls(cx, cy, at))]
    return _fit_lines([(*w, w[4][h], w[5][h]) for w, h in zip(rel, hulls, strict=True)])


def fit_min_delay_spans(
    device_us: np.ndarray, floor_ns: np.ndarray, spans: Sequence[tuple[int, int]]
) -> list[ClockMap]:
    """:func:`fit_min_delay` of each window ``device_us[i:j]``, ``floor_ns[i:j]`` for
    (i, j) in ``spans``: the windows of one run of points, overlapping (a capture's
    half-overlapping clock windows).

    Points in device-time order: the stretches between the windows' ends are hulled once
    each (:func:`lower_hulls`), and a window's hull is the hull of its stretches' hulls (a
    point under no stretch's hull is under the window's; the cross products are the same in
    any origin, the coordinates being differences of exact values), so each point is hulled
    once, not once per window it is in. Out of order: each window alone."""
    x = np.asarray(device_us, dtype=np.float64)
    y = np.asarray(floor_ns, dtype=np.float64)
    if not spans:
        return []
    lo, hi = min(i for i, _ in spans), max(j for _, j in spans)
    if not np.all(x[lo + 1 : hi] > x[lo : hi - 1]):
        return fit_min_delay_many([(x[i:j], y[i:j]) for i, j in spans])
    cuts = np.asarray(sorted({k for span in spans for k in span}), dtype=np.int64)
    stretch = lower_hulls(x, y, cuts)
    cand, bounds = [], [0]
    for i, j in spans:
        c = np.concatenate(stretch[cuts.searchsorted(i) : cuts.searchsorted(j)])
        cand.append(c)
        bounds.append(bounds[-1] + c.size)
    c_all = np.concatenate(cand)
    hulls = [c_all[h] for h in lower_hulls(x[c_all], y[c_all], bounds)]
    pre = []
    for (i, j), h in zip(spans, hulls, strict=True):
        x0, y0 = float(x[i]), float(y[i])
        xw, yw = x[i:j] - x0, y[i:j] - y0
        pre.append((x0, y0, xw, yw, xw, yw, x[h] - x0, y[h] - y0))
    return _fit_lines(pre)


def _fit_lines(
    windows: Sequence[tuple[float, float, np.ndarray, np.ndarray, np.ndarray, np.ndarray,
                            np.ndarray, np.ndarray]],
) -> list[ClockMap]:  # fmt: skip
    """Each window's map from its hull: (x0, y0, x, y, the same sorted, the hull's x and y;
    all but x0, y0 relative to them): the hull edge at the mean device time, refined
    together (:func:`_refine_many`), and its gaps' median and 5th percentile."""
    pre = []
    for _, _, x, _, xs, ys, hx, hy in windows:
        if hx.size < 2:
            raise ValueError("need two points with different device times")
        xm = float(np.add.reduce(x) / x.size)  # x.mean(): its sum and division, not its wrapper
        k = int(hx.searchsorted(xm, side="right")) - 1
        k = min(max(k, 0), hx.size - 2)
        b = (hy[k + 1] - hy[k]) / (hx[k + 1] - hx[k])
        pre.append((xs, ys, hy[k] - b * hx[k], b))
    lines = _refine_many(pre)
    out = []
    for (x0, y0, x, y, _, _, _, _), (a, b) in zip(windows, lines, strict=True):
        gaps_us = (y - (a + b * x)) / 1000.0
        median, p5 = _percentiles(gaps_us, (50.0, 5.0))
        out.append(ClockMap(x0, y0, a, b, int(x.size), median, p5))
    return out


def _percentiles(a: np.ndarray, qs: tuple[float, ...]) -> list[float]:
    """numpy's (linear) percentiles ``qs`` of ``a`` from one partial sort (np.percentile and
    np.median sort once each, and cost more than the sort itself on a clock window)."""
    if not np.isfinite(a).all():
        return [float(np.percentile(a, q)) for q in qs]
    pos = [(a.size - 1) * q / 100.0 for q in qs]
    lo = [int(p) for p in pos]
    hi = [min(k + 1, a.size - 1) for k in lo]
    part = np.partition(a, sorted(set(lo + hi)))
    return [
        float(part[k] + (part[m] - part[k]) * (p - k)) for p, k, m in zip(pos, lo, hi, strict=True)
    ]


#: a window as :func:`_refine_many` takes it: (x sorted, y, its hull line's a, b)
_Window = tuple[np.ndarray, np.ndarray, float, float]


@dataclass(frozen=True, eq=False)
class _Bins:
    """The windows' points joined end to end (window ``k`` of ``ids`` at ``at[k]:at[k + 1]``):
    ``r`` their residuals from their hull lines, and the non-empty bins: ``first`` point of
    each, its ``counts`` and its window (``window``, the index in ``ids``)."""

    at: np.ndarray
    r: np.ndarray
    first: np.ndarray
    counts: np.ndarray
    window: np.ndarray


def _join_bins(windows: Sequence[_Window], ids: list[int], bin_us: float) -> _Bins:
    """The residuals of windows ``ids`` from their hull lines, end to end, and their
    ``bin_us`` bins of device time (bin j of a window: its points with
    j·bin_us <= x − x[0] < (j + 1)·bin_us)."""
    at = np.cumsum([0] + [windows[w][0].size for w in ids])
    r = np.empty(at[-1])  # the windows' residuals end to end
    firsts = []
    edges: np.ndarray = np.zeros(0)
    for k, w in enumerate(ids):
        x, y, a, b = windows[w]
        seg = r[at[k] : at[k + 1]]
        np.subtract(y, np.add(np.multiply(x, b, out=seg), a, out=seg), out=seg)
        # bin j found by bisection (the same as ``(x − x[0]) // bin_us``: a float floor
        # division costs 30 times more)
        nb = int((x[-1] - x[0]) // bin_us) + 1
        if edges.size < nb:
            edges = bin_us * np.arange(2 * nb)
        firsts.append((x - x[0] if x[0] else x).searchsorted(edges[:nb], side="left"))
    first = np.concatenate(firsts) + np.repeat(at[:-1], [f.size for f in firsts])
    nonempty = np.flatnonzero(np.diff(first, append=r.size))
    first = first[nonempty]
    counts = np.diff(first, append=r.size)
    window = np.repeat(np.arange(len(ids)), [f.size for f in firsts])[nonempty]
    return _Bins(at, r, first, counts, window)


def _bin_floors(bins: _Bins) -> tuple[np.ndarray, np.ndarray]:
    """(the point, its window) of the floor of each bin of at least 5 points: its first
    lowest point (nan counts as the highest: a bin's floor is not finite only when none of its
    points is, and then its window keeps the hull line)."""
    r, first, counts = bins.r, bins.first, bins.counts
    low = np.minimum.reduceat(r, first)
    r_low = r if np.all(np.isfinite(low)) else np.where(np.isnan(r), np.inf, r)
    if r_low is not r:
        low = np.minimum.reduceat(r_low, first)
    lowest = np.flatnonzero(r_low == np.repeat(low, counts))
    lowest_bin = np.searchsorted(first, lowest, side="right") - 1
    pick = lowest[np.flatnonzero(np.diff(lowest_bin, prepend=-1))][counts >= 5]
    return pick, bins.window[counts >= 5]


def _floor_table(
    windows: Sequence[_Window], ids: list[int], bins: _Bins, pick: np.ndarray, fw: np.ndarray,
    m: np.ndarray, rows: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:  # fmt: skip
    """(x, residual, valid) (window × floor) of the floors ``pick`` of the windows ``rows``
    (of ``ids``) that have ``m`` >= 4 floors each (``fw``: each floor's window)."""
    row_of = np.full(len(ids), -1)
    row_of[rows] = np.arange(rows.size)
    starts = np.concatenate(([0], np.cumsum(m[rows])[:-1]))
    fr_row = row_of[fw]
    col = np.arange(pick.size) - starts[fr_row]
    width = int(m[rows].max())
    fx = np.zeros((rows.size, width))
    fr = np.zeros((rows.size, width))
    valid = np.zeros((rows.size, width), dtype=bool)
    at = bins.at
    cut = np.searchsorted(pick, at[1:-1])  # each window's floors: its own points' x
    px = [windows[ids[k]][0][p - at[k]] for k, p in enumerate(np.split(pick, cut))]
    fx[fr_row, col], fr[fr_row, col], valid[fr_row, col] = np.concatenate(px), bins.r[pick], True
    return fx, fr, valid


def _robust_lines(
    fx: np.ndarray, fr: np.ndarray, valid: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(c0, c1, the floors kept) per row: a least-squares line through the valid floors,
    refitted up to three times without those beyond 4 MADs, each row stopping when its kept
    floors do not change or fewer than four would be left."""
    keep = valid.copy()
    active = np.ones(fx.shape[0], dtype=bool)
    c0 = np.zeros(fx.shape[0])
    c1 = np.zeros(fx.shape[0])
    for _ in range(3):
        k1, k0 = _lines(fx, fr, keep)
        c1 = np.where(active, k1, c1)
        c0 = np.where(active, k0, c0)
        res = fr - (c0[:, None] + c1[:, None] * fx)
        med = _row_percentiles(res, keep, 50.0)
        mad = _row_percentiles(np.abs(res - med[:, None]), keep, 50.0)
        mad = np.where(mad == 0, 1.0, mad)
        new_keep = valid & (np.abs(res) <= 4 * 1.4826 * mad[:, None])
        stop = np.all(new_keep == keep, axis=1) | (np.count_nonzero(new_keep, axis=1) < 4)
        go = active & ~stop
        keep[go] = new_keep[go]
        active = go
        if not active.any():
            break
    return c0, c1, keep


def _refine_many(windows: Sequence[_Window], bin_us: float = 1e6) -> list[tuple[float, float]]:
    """Refine each window's hull line (x sorted, y, a, b), all windows together: the floor
    (first lowest point) of each ``bin_us`` bin of the detrended points that holds at least
    5, then a robust least-squares line through the floors, lowered to pass under all floors
    but the lowest 2 %, so its offset stays a minimum-delay offset.

    The hull edge at the mean is exact for the points it touches but can be short, so its
    slope is noisy; the floors of many bins pin the slope down. A window shorter than four
    bins, with fewer than four floors, or whose floors are not all finite keeps its hull
    line. The windows' points are joined end to end, the floors found by segment reductions,
    and the robust line iterated on (window × floor) arrays, each window stopping when it
    would alone."""
    out = [(float(a), float(b)) for _, _, a, b in windows]
    ids = [w for w, (x, _, _, _) in enumerate(windows) if x[-1] - x[0] >= 4 * bin_us]
    if not ids:
        return out
    bins = _join_bins(windows, ids, bin_us)
    pick, fw = _bin_floors(bins)
    m = np.bincount(fw, minlength=len(ids))
    rows = np.flatnonzero(m >= 4)
    if rows.size == 0:
        return out
    sel = m[fw] >= 4
    fx, fr, valid = _floor_table(windows, ids, bins, pick[sel], fw[sel], m, rows)
    c0, c1, keep = _robust_lines(fx, fr, valid)
    floor = _row_percentiles(fr - (c0[:, None] + c1[:, None] * fx), keep, 2.0)
    for row, w in enumerate(np.asarray(ids)[rows]):
        if np.isfinite(c0[row]) and np.isfinite(c1[row]):
            a, b = out[w]
            out[w] = (a + float(c0[row] + floor[row]), b + float(c1[row]))
    return out


def _lines(x: np.ndarray, y: np.ndarray, mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares line y = c0 + c1·x through each row's masked points, from the centred
    sums (a general polynomial fit costs ten times that): (c1, c0) per row."""
    n = np.count_nonzero(mask, axis=1)
    xm = np.where(mask, x, 0.0).sum(axis=1) / n
    ym = np.where(mask, y, 0.0).sum(axis=1) / n
    dx = np.where(mask, x - xm[:, None], 0.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        c1 = (dx * (y - ym[:, None])).sum(axis=1) / (dx * dx).sum(axis=1)
    return c1, ym - c1 * xm


def _row_percentiles(a: np.ndarray, mask: np.ndarray, q: float) -> np.ndarray:
    """numpy's (linear) percentile ``q`` of each row's masked values (at least one a row)."""
    s = np.sort(np.where(mask, a, np.inf), axis=1)
    pos = (np.count_nonzero(mask, axis=1) - 1) * q / 100.0
    lo = pos.astype(np.int64)
    hi = np.minimum(lo + 1, np.count_nonzero(mask, axis=1) - 1)
    vlo = np.take_along_axis(s, lo[:, None], axis=1)[:, 0]
    vhi = np.take_along_axis(s, hi[:, None], axis=1)[:, 0]
    return vlo + (vhi - vlo) * (pos - lo)


@dataclass(frozen=True)
class PiecewiseClockMap:
    """Window maps blended linearly between their centres (offline fit of a whole capture)."""

    centres_us: np.ndarray
    maps: tuple[ClockMap, ...]
    #: windows fitted (``maps`` keeps at most :data:`MAX_KEPT_MAPS` of them, evenly spread)
    windows: int = 0

    def to_host_ns(self, device_us: np.ndarray | float) -> np.ndarray:
        x = np.asarray(device_us, dtype=np.float64)
        if len(self.maps) == 1:
            return self.maps[0].to_host_ns(x)
        preds = np.stack([m.to_host_ns(x) for m in self.maps])  # (K, N)
        c = self.centres_us
        k = np.clip(np.searchsorted(c, x, side="right") - 1, 0, len(c) - 2)
        w = np.clip((x - c[k]) / (c[k + 1] - c[k]), 0.0, 1.0)
        cols = np.arange(x.size) if x.ndim else 0
        return (1 - w) * preds[k, cols] + w * preds[k + 1, cols]

    @property
    def overall(self) -> ClockMap:
        """The map of the middle window (for reporting skew and quality)."""
        return self.maps[len(self.maps) // 2]


@dataclass
class LiveClock:
    """Streaming minimum-delay estimate over the last ``window_s`` seconds of points.

    ``add()`` each sample's (device µs, floor ns); ``map`` is refreshed every ``refit_every``
    points (it is ``None`` until two seconds of data have arrived).
    """

    window_s: float = 30.0
    refit_every: int = 25
    min_span_s: float = 2.0
    map: ClockMap | None = None
    _x: deque = field(default_factory=deque)
    _y: deque = field(default_factory=deque)
    _since_fit: int = 0

    def add(self, device_us: float, floor_ns: float) -> None:
        self._x.append(float(device_us))
        self._y.append(float(floor_ns))
        while self._x and self._x[-1] - self._x[0] > self.window_s * 1e6:
            self._x.popleft()
            self._y.popleft()
        self._since_fit += 1
        span_ok = self._x[-1] - self._x[0] >= self.min_span_s * 1e6
        if span_ok and (self.map is None or self._since_fit >= self.refit_every):
            self.map = fit_min_delay(np.fromiter(self._x, float), np.fromiter(self._y, float))
            self._since_fit = 0

    def to_host_ns(self, device_us: np.ndarray | float) -> np.ndarray | None:
        return None if self.map is None else self.map.to_host_ns(device_us)
