"""The timeline of a capture: every sample's device time unwrapped and mapped to host time.

Samples decoded with their segments and losses (:data:`host.wire.bulk.SAMPLE_DTYPE`) and the
arrival time of each frame go in; out come per-sample device µs (unwrapped within each segment)
and host ns, and the segments between board resets, each with its own clock map fitted by the
minimum-delay estimator of :mod:`host.timing.clock` (method.md eq. 1) in half-overlapping
windows. :class:`TimelineBuilder` does it in bounded memory, chunk by chunk;
:func:`build_timeline` is the same builder fed one chunk, so the two give the same map.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from host.timing.clock import (
    ClockMap,
    PiecewiseClockMap,
    fit_min_delay,
    fit_min_delay_spans,
    serialisation_ns,
    unwrap,
)
from host.wire.protocol_gen import ENUMS
from host.wire.segments import seq_step

#: the sample flag of a sample the firmware skipped (from the spec)
MISSED = ENUMS["sample_flags"]["MISSED"]


@dataclass(frozen=True)
class Segment:
    """Samples between two device resets, with their own clock map."""

    start: int  # index of the first sample (in the samples array)
    stop: int  # one past the last
    clock: PiecewiseClockMap | None  # None without arrival times
    lost_frames: int  # seq gaps: frames lost on the link
    missed_samples: int  # samples the firmware could not send (t_us steps, MISSED flag)


@dataclass(frozen=True)
class Timeline:
    """Per-sample device time (unwrapped, µs), mapped host time (ns) and the segments."""

    device_us: np.ndarray  # float64, unwrapped within each segment
    host_ns: np.ndarray  # float64 mapped host time of each sample (nan without arrivals)
    segments: tuple[Segment, ...]

    @property
    def lost_frames(self) -> int:
        return sum(s.lost_frames for s in self.segments)

    @property
    def missed_samples(self) -> int:
        return sum(s.missed_samples for s in self.segments)


def missed_samples(device_us: np.ndarray, seq: np.ndarray, period_us: float) -> int:
    """Samples the device skipped: t_us steps of ≥ 1.5 periods between consecutive seq."""
    if device_us.size < 2:
        return 0
    q = np.asarray(seq, dtype=np.int64)
    consecutive = seq_step(q[:-1], q[1:]) == 1
    steps = np.diff(device_us) / period_us
    return int(np.sum(np.where(consecutive & (steps >= 1.5), np.rint(steps) - 1, 0)))


def _median(a: np.ndarray) -> float:
    """np.median of ``a`` (not empty), the same value without the 20-30 ms that numpy's median
    and percentile spend importing numpy.ma on their first call."""
    h = a.size // 2
    if a.size % 2:
        return float(np.partition(a, h)[h])
    part = np.partition(a, [h - 1, h])
    return float((part[h - 1] + part[h]) / 2)


#: a segment whose clock would need more samples than this held at once (a board at 50 Hz
#: needs ≈ 4 500: 1.5 windows) has device times no board makes (far too dense or too sparse):
#: its clock is given up and t_host_ns falls back to arrival times (≈ 87 min at 50 Hz)
MAX_HELD_SAMPLES = 1 << 18
#: window maps kept per segment for reporting; beyond, every other is dropped (34 h at 60 s)
MAX_KEPT_MAPS = 4096
#: the sample period (for missed samples) is the median step of a segment's first samples
PERIOD_SAMPLES = 1001


class _WindowFitter:
    """The windows of one segment's clock fit, fitted as the points stream in.

    Window k covers device times [x0 + k·w/2, x0 + k·w/2 + w] (half-overlapping, ``w`` =
    ``window_s``); it is fitted (:func:`fit_min_delay`) once a point beyond its end arrives,
    and at the end if more than half of it is covered; a window holding fewer than two points
    with different device times has no map. With no window fitted at all, one line goes
    through all the points (``finish``). Memory: the points of the open window only.
    """

    def __init__(self, window_s: float, x0: float | None) -> None:
        self.w = window_s * 1e6
        self.h = self.w / 2
        self.x0 = x0
        self.k = 0
        self.px = np.zeros(0)
        self.py = np.zeros(0)
        self.maps: list[ClockMap] = []
        self.centres: list[float] = []
        self.stride = 1
        self.windows = 0
        self.last_x = float("-inf")

    @property
    def held(self) -> int:
        return int(self.px.size)

    def _fit(
        self, x: np.ndarray, y: np.ndarray, windows: list[tuple[int, int, float]]
    ) -> list[tuple[float, ClockMap]]:
        """Fit the completed windows (x[i:j], y[i:j], centre) together; keep every
        ``stride``-th map."""
        fittable = [(i, j, c) for i, j, c in windows if j - i >= 2 and x[j - 1] > x[i]]
        maps = fit_min_delay_spans(x, y, [(i, j) for i, j, _ in fittable])
        out = []
        for (_, _, centre), m in zip(fittable, maps, strict=True):
            if self.windows % self.stride == 0:
                self.maps.append(m)
                self.centres.append(centre)
                if len(self.maps) > MAX_KEPT_MAPS:
                    self.maps, self.centres = self.maps[::2], self.centres[::2]
                    self.stride *= 2
            self.windows += 1
            out.append((centre, m))
        return out

    def add(self, x: np.ndarray, y: np.ndarray) -> list[tuple[float, ClockMap]]:
        """Points in device-time order (µs, floor ns); returns the windows they completed."""
        if x.size == 0:
            return []
        if self.x0 is None:
            self.x0 = float(x[0])
        self.px = np.concatenate((self.px, x))
        self.py = np.concatenate((self.py, y))
        self.last_x = float(self.px[-1])
        return self._advance(final=False)

    def _advance(self, final: bool) -> list[tuple[float, ClockMap]]:
        done: list[tuple[int, int, float]] = []
        assert self.x0 is not None or self.px.size == 0
        px, py = self.px, self.py
        at = 0  # the open window's first point in px
        while at < px.size:
            x0 = float(self.x0)  # type: ignore[arg-type]
            start = x0 + self.k * self.h
            end = start + self.w
            if final:
                if not start + self.h < self.last_x:
                    break
            elif not px[-1] > end:
                break
            # the points are in device-time order: a window is a slice
            done.append((at, int(px.searchsorted(end, side="right")), start + self.h))
            self.k += 1
            at = int(px.searchsorted(x0 + self.k * self.h, side="left"))
            if at < px.size and px[at] > x0 + self.k * self.h + self.w:
                # skip the empty windows of a gap: to the first window holding the next point
                self.k = int(np.ceil((px[at] - x0 - self.w) / self.h))
        self.px, self.py = px[at:], py[at:]
        return self._fit(px, py, done)

    def finish(self, x: np.ndarray, y: np.ndarray) -> list[tuple[float, ClockMap]]:
        """End of the segment: fit the windows left; ``x``, ``y`` all the segment's points
        when no window was fitted yet (for one line through them), else ignored."""
        out = self._advance(final=True)
        if not self.maps and x.size >= 2 and x[-1] > x[0]:
            m = fit_min_delay(x, y)
            self.maps.append(m)
            self.centres.append(float(x.mean()))
            self.windows = 1
            out.append((self.centres[-1], m))
        self.px = self.py = np.zeros(0)
        return out

    @property
    def clock(self) -> PiecewiseClockMap | None:
        if not self.maps:
            return None
        return PiecewiseClockMap(np.asarray(self.centres), tuple(self.maps), self.windows)


@dataclass
class TimelineBlock:
    """Samples whose host time is known, in stream order."""

    samples: np.ndarray  # SAMPLE_DTYPE
    device_us: np.ndarray  # float64, unwrapped within the segment
    host_ns: np.ndarray  # float64 mapped host time (nan: no map, or no arrival times)
    arrival_ns: np.ndarray | None  # the arrival (ns) of each sample, as given


class _OpenSegment:
    """The running state of the segment being read."""

    def __init__(self, number: int, start: int, period_us: float | None, window_s: float):
        self.number = number
        self.start = start
        self.n = 0
        self.period = period_us
        self.fitter = _WindowFitter(window_s, None)
        self.gave_up = False
        self.last_raw_t = 0
        self.last_dev = 0
        self.last_arr = 0.0
        self.lost = 0  # frames lost between the first and the last sample
        self.flagged = 0
        self.missed_steps = 0
        self.head_dev: list[np.ndarray] = []  # until the period is known
        self.head_seq: list[np.ndarray] = []
        self.head_n = 0
        self.tail_dev: float | None = None  # last sample counted for missed samples
        self.tail_seq = 0
        # samples waiting for their host time (in order), with their points
        self.pending: list[tuple[np.ndarray, np.ndarray, np.ndarray | None, np.ndarray]] = []
        self.pending_n = 0
        self.prev_map: tuple[float, ClockMap] | None = None


class TimelineBuilder:
    """Unwrap, split at resets and map every sample to host time, streaming: :meth:`add` the
    decoded samples chunk by chunk (with each one's arrival and the other frames' offsets),
    get back the :class:`TimelineBlock` s whose host time is known; :meth:`finish` at the
    end. The blocks concatenated are the same whatever the chunking (the clock is eq. (1) per
    window, blended between window centres). Holds one window and a half of samples
    (≈ 90 s, bounded by :data:`MAX_HELD_SAMPLES`); ``keep_segments`` bounds the closed
    segments kept (None: all; :attr:`segments_dropped` counts the others). With
    ``map_samples`` False the segments and their clock maps are the same, and no block is
    handed back (no sample's host time computed: for counters and maps alone).
    """

    def __init__(
        self,
        baud: int = 115200,
        frame_bytes: int = 27,
        period_us: float | None = None,
        window_s: float = 60.0,
        keep_segments: int | None = None,
        map_samples: bool = True,
    ) -> None:
        self.floor_shift_ns = float(serialisation_ns(frame_bytes, baud))
        self.map_samples = map_samples
        self.period_us = period_us
        self.window_s = window_s
        self.keep_segments = keep_segments
        self.segments: list[Segment] = []
        self.segments_dropped = 0
        self.lost_frames = 0
        self.missed_samples = 0
        #: segments whose device times no board makes (their clock given up)
        self.implausible: list[int] = []
        self._seg: _OpenSegment | None = None
        self._n = 0  # samples added so far

    # ---- feeding
    def add(self, samples: np.ndarray, arrival_ns: np.ndarray | None) -> list[TimelineBlock]:
        """Samples in stream order (SAMPLE_DTYPE with ``segment`` and ``lost`` from the
        decoder) and their arrivals (ns, or None for a raw capture)."""
        out: list[TimelineBlock] = []
        n = samples.size
        if n == 0:
            return out
        seg_ids = samples["segment"]
        bounds = np.flatnonzero(np.diff(seg_ids)) + 1
        starts = np.concatenate(([0], bounds))
        stops = np.concatenate((bounds, [n]))
        for a, b in zip(starts, stops, strict=True):
            part = samples[a:b]
            arr = None if arrival_ns is None else np.asarray(arrival_ns[a:b], np.float64)
            if self._seg is not None and self._seg.number != int(part["segment"][0]):
                out += self._close()
            if self._seg is None:
                self._seg = _OpenSegment(
                    int(part["segment"][0]), self._n, self.period_us, self.window_s
                )
            out += self._extend(self._seg, part, arr)
            self._n += part.size
        return out

    def finish(self) -> list[TimelineBlock]:
        """End of input: map and hand back everything held."""
        return self._close() if self._seg is not None else []

    # ---- one segment
    def _extend(
        self, g: _OpenSegment, s: np.ndarray, arr: np.ndarray | None
    ) -> list[TimelineBlock]:
        raw_t = s["t_us"].astype(np.int64)
        seq = s["seq"].astype(np.int64)
        if g.n == 0:
            d = unwrap(raw_t, 32, arr, 1e-3)
            g.lost += int(np.sum(s["lost"][1:]))  # (a segment's first sample: lost across it)
        else:
            prev_arr = None if arr is None else np.concatenate(([g.last_arr], arr))
            d = unwrap(np.concatenate(([g.last_raw_t], raw_t)), 32, prev_arr, 1e-3)
            d = d[1:] - g.last_raw_t + g.last_dev
            g.lost += int(np.sum(s["lost"]))
        g.flagged += int(np.count_nonzero(s["flags"] & MISSED))
        g.last_raw_t, g.last_dev = int(raw_t[-1]), int(d[-1])
        if arr is not None:
            g.last_arr = float(arr[-1])
        g.n += s.size
        dev = d.astype(np.float64)
        self._count_missed(g, dev, seq, final=False)
        if arr is None:
            return (
                [TimelineBlock(s, dev, np.full(s.size, np.nan), None)] if self.map_samples else []
            )
        g.pending.append((s, dev, arr, arr - self.floor_shift_ns))
        g.pending_n += s.size
        if g.gave_up:
            return self._release(g, None)
        fitted = g.fitter.add(dev, arr - self.floor_shift_ns)
        out = self._map_pending(g, fitted)
        if g.fitter.held > MAX_HELD_SAMPLES or g.pending_n > MAX_HELD_SAMPLES:
            g.gave_up = True
            g.fitter = _WindowFitter(self.window_s, None)  # drop its points
            self.implausible.append(g.number)
            out += self._release(g, None)
        return out

    def _count_missed(self, g: _OpenSegment, dev: np.ndarray, seq: np.ndarray, final: bool):
        if g.period is None:
            g.head_dev.append(dev)
            g.head_seq.append(seq)
            g.head_n += dev.size
            if g.head_n < PERIOD_SAMPLES and not final:
                return
            hd, hq = np.concatenate(g.head_dev), np.concatenate(g.head_seq)
            g.head_dev, g.head_seq = [], []
            steps = np.diff(hd[:PERIOD_SAMPLES])
            g.period = _median(steps) if steps.size else 20000.0
            dev, seq = hd, hq
        if g.tail_dev is not None:
            dev = np.concatenate(([g.tail_dev], dev))
            seq = np.concatenate(([g.tail_seq], seq))
        if dev.size:
            g.missed_steps += missed_samples(dev, seq, g.period)
            g.tail_dev, g.tail_seq = float(dev[-1]), int(seq[-1])

    def _map_pending(
        self, g: _OpenSegment, fitted: list[tuple[float, ClockMap]]
    ) -> list[TimelineBlock]:
        """Map the held samples that lie before the newest fitted window's centre."""
        out: list[TimelineBlock] = []
        for centre, m in fitted:
            out += self._release(g, (centre, m))
            g.prev_map = (centre, m)
        return out

    def _release(
        self, g: _OpenSegment, upto: tuple[float, ClockMap] | None, everything: bool = False
    ) -> list[TimelineBlock]:
        """Hand back held samples: with ``upto`` those up to its centre, blended from the
        previous fitted window; with ``everything`` all of them with the last map; with
        neither all of them unmapped."""
        out: list[TimelineBlock] = []
        while g.pending:
            s, dev, arr, _ = g.pending[0]
            if upto is None and not everything:
                host = np.full(s.size, np.nan) if self.map_samples else None
                k = s.size
            else:
                if upto is not None:
                    centre, m = upto
                    k = int(np.searchsorted(dev, centre, side="right"))
                else:
                    k = s.size
                    centre, m = g.prev_map  # type: ignore[misc]
                if k == 0:
                    break
                host = None
                if self.map_samples:
                    x = dev[:k]
                    host = m.to_host_ns(x)
                    if upto is not None and g.prev_map is not None:
                        c0, m0 = g.prev_map
                        wgt = np.clip((x - c0) / (centre - c0), 0.0, 1.0)
                        host = (1 - wgt) * m0.to_host_ns(x) + wgt * host
            if host is not None:
                a = arr[:k] if arr is not None else None
                out.append(TimelineBlock(s[:k], dev[:k], host, a))
            if k == s.size:
                g.pending.pop(0)
            else:
                rest = (s[k:], dev[k:], arr[k:] if arr is not None else None, g.pending[0][3][k:])
                g.pending[0] = rest
            g.pending_n -= k
        return out

    def _close(self) -> list[TimelineBlock]:
        g = self._seg
        assert g is not None
        self._seg = None
        self._count_missed(g, np.zeros(0), np.zeros(0, np.int64), final=True)
        out: list[TimelineBlock] = []
        clock = None
        if g.pending and not g.gave_up:
            if g.fitter.maps:
                out += self._map_pending(g, g.fitter.finish(np.zeros(0), np.zeros(0)))
            else:
                xs = np.concatenate([p[1] for p in g.pending])
                ys = np.concatenate([p[3] for p in g.pending])
                out += self._map_pending(g, g.fitter.finish(xs, ys))
            clock = g.fitter.clock
            out += self._release(g, None, everything=clock is not None)
        elif not g.gave_up:
            clock = g.fitter.clock
        out += self._release(g, None)
        lost = g.lost
        missed = max(g.missed_steps, g.flagged)
        self.lost_frames += lost
        self.missed_samples += missed
        seg = Segment(g.start, g.start + g.n, clock, lost, missed)
        if self.keep_segments is None or len(self.segments) < self.keep_segments:
            self.segments.append(seg)
        else:
            self.segments_dropped += 1
        return out


def build_timeline(
    samples: np.ndarray,
    arrival_ns: np.ndarray | None,
    baud: int = 115200,
    frame_bytes: int = 27,
    period_us: float | None = None,
    window_s: float = 60.0,
) -> Timeline:
    """Unwrap, split at resets and map every sample of a decoded capture (all at once: a
    :class:`TimelineBuilder` fed one chunk).

    ``samples`` is :data:`host.wire.bulk.SAMPLE_DTYPE` (with ``segment`` and ``lost`` from
    the decoder, which applies the counters' rules of :mod:`host.wire.segments`),
    ``arrival_ns`` the host time of the read that completed each sample's frame.
    """
    b = TimelineBuilder(baud, frame_bytes, period_us, window_s)
    blocks = b.add(samples, arrival_ns) + b.finish()
    n = samples.size
    dev = np.concatenate([k.device_us for k in blocks]) if blocks else np.zeros(n)
    host = np.concatenate([k.host_ns for k in blocks]) if blocks else np.full(n, np.nan)
    return Timeline(dev, host, tuple(b.segments))
