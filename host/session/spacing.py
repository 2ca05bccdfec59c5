"""Sample spacing of a stream or record: timing quality and integrals over the true times.

A logger's time stamps are the truth about when each sample was taken; a record with gaps
(bursty host time stamps, lost samples) is integrated over those times (trapezoid rule,
method.md §4), never over a nominal rate, and the gaps are reported: every command that reads
records (``import``, ``calibrate --from-dir``, ``model``, ``thermal``, ``noise``) prints the
same table (:func:`timing_report`) when a record has gaps.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from host.session.records import Record

GAP_MIN_MS = 50.0  #: a spacing above max(GAP_MIN_MS, GAP_FACTOR × median) is a gap
GAP_FACTOR = 3.0
WARN_GAP_SHARE = 0.02  #: warn when more than this share of a record's time is inside gaps
WARN_WORST_FACTOR = 10.0  #: … or when the worst gap exceeds this × the median spacing


@dataclass(frozen=True)
class TimingQuality:
    """Sample spacing of one record: ``median_ms``, ``worst_gap_ms`` (largest spacing),
    ``gap_share`` (fraction of the duration inside spacings above ``gap_limit_ms``) and
    ``warning`` (share above ``WARN_GAP_SHARE`` or worst gap above ``WARN_WORST_FACTOR`` ×
    median)."""

    n: int
    median_ms: float
    worst_gap_ms: float
    gap_share: float
    gap_limit_ms: float
    warning: bool

    def describe(self) -> str:
        """One line: 'median 2.1 ms, worst gap 252 ms, 23 % of the time in gaps > 50 ms'."""
        return (
            f"median spacing {self.median_ms:.3g} ms, worst gap {self.worst_gap_ms:.3g} ms, "
            f"{100 * self.gap_share:.1f} % of the time in gaps > {self.gap_limit_ms:.3g} ms"
        )

    def meta(self) -> dict[str, str]:
        """Record metadata lines."""
        return {
            "timing_median_ms": f"{self.median_ms:.4g}",
            "timing_worst_gap_ms": f"{self.worst_gap_ms:.4g}",
            "timing_gap_share": f"{self.gap_share:.4f}",
            "timing_gap_limit_ms": f"{self.gap_limit_ms:.4g}",
            "timing_warning": "yes" if self.warning else "no",
        }


def timing_quality(t_s: np.ndarray) -> TimingQuality:
    """Spacing statistics of sample times ``t_s`` (s), see :class:`TimingQuality`."""
    t = np.asarray(t_s, dtype=np.float64)
    if t.size < 2:
        return TimingQuality(int(t.size), math.nan, math.nan, 0.0, GAP_MIN_MS, False)
    counts = ValueCounts()
    counts.add(np.diff(t) * 1000.0)
    return spacing_quality(counts)


def spacing_quality(spacings_ms: ValueCounts) -> TimingQuality:
    """:class:`TimingQuality` of the sample spacings (ms) counted in ``spacings_ms`` (a
    recording read in blocks counts them block by block)."""
    v, c = spacings_ms.values, spacings_ms.counts
    if spacings_ms.n == 0:
        return TimingQuality(1, math.nan, math.nan, 0.0, GAP_MIN_MS, False)
    median = spacings_ms.median()
    worst = float(v[-1])
    limit = max(GAP_MIN_MS, GAP_FACTOR * median)
    total = float(np.sum(v * c))
    share = float(np.sum((v * c)[v > limit]) / total) if total > 0 else 0.0
    warn = share > WARN_GAP_SHARE or (median > 0 and worst > WARN_WORST_FACTOR * median)
    return TimingQuality(spacings_ms.n + 1, median, worst, share, limit, bool(warn))


class ValueCounts:
    """The exact distribution of values met piece by piece (sample spacings, temperatures: a
    few distinct values each), for medians and percentiles without holding every value."""

    def __init__(self) -> None:
        self.values = np.zeros(0)
        self.counts = np.zeros(0, np.int64)

    def add(self, v: np.ndarray) -> None:
        """Count the values ``v``."""
        u, c = np.unique(np.asarray(v, dtype=np.float64), return_counts=True)
        u2, inv = np.unique(np.concatenate([self.values, u]), return_inverse=True)
        self.values = u2
        weights = np.concatenate([self.counts, c]).astype(np.float64)
        self.counts = np.rint(np.bincount(inv, weights=weights)).astype(np.int64)

    @property
    def n(self) -> int:
        """How many values were counted."""
        return int(self.counts.sum())

    def _at(self, k: int) -> float:
        """The k-th smallest value (from 0)."""
        return float(self.values[int(np.searchsorted(np.cumsum(self.counts), k, side="right"))])

    def median(self) -> float:
        """As numpy's median: the middle value, or the mean of the two."""
        n = self.n
        if n % 2:
            return self._at(n // 2)
        return (self._at(n // 2 - 1) + self._at(n // 2)) / 2.0

    def percentile(self, q: float) -> float:
        """As numpy's percentile ``q`` (%; linear between the two nearest values)."""
        h = (self.n - 1) * q / 100.0
        lo = int(np.floor(h))
        a, b, w = self._at(lo), self._at(min(lo + 1, self.n - 1)), h - lo
        return b - (b - a) * (1.0 - w) if w >= 0.5 else a + (b - a) * w


def trapezoid(t_s: np.ndarray, values: np.ndarray) -> np.ndarray:
    """∫ values dt over the true times ``t_s`` (s) by the trapezoid rule (method.md §4);
    ``values`` (N,) or (N,k) -> (unit)·s."""
    t = np.asarray(t_s, dtype=np.float64)
    v = np.asarray(values, dtype=np.float64)
    if t.size < 2:
        return np.zeros(v.shape[1:])
    return np.asarray(np.tensordot(np.diff(t), 0.5 * (v[1:] + v[:-1]), axes=(0, 0)))


def cumulative_trapezoid(t_s: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Running ∫ values dt from the first sample (trapezoid rule over ``t_s``, s): (N,) for
    ``values`` (N,), starting at 0."""
    t = np.asarray(t_s, dtype=np.float64)
    v = np.asarray(values, dtype=np.float64)
    out = np.zeros(t.size)
    if t.size > 1:
        out[1:] = np.cumsum(np.diff(t) * 0.5 * (v[1:] + v[:-1]))
    return out


def uniform_rate_error_deg(t_s: np.ndarray, gyro_dps: np.ndarray) -> float:
    """How far the gyro integral (°, largest channel) moves if the samples are assumed evenly
    spaced over the same span instead of at their true times ``t_s`` (s)."""
    t = np.asarray(t_s, dtype=np.float64)
    if t.size < 2:
        return 0.0
    uniform = np.linspace(t[0], t[-1], t.size)
    diff = trapezoid(uniform, gyro_dps) - trapezoid(t, gyro_dps)
    return float(np.max(np.abs(diff)))


def timing_table(records: Mapping[str, Record]) -> str:
    """Per-record timing table: samples, median spacing, worst gap, share of time in gaps."""
    return _table({name: timing_quality(rec.t_ms / 1000.0) for name, rec in records.items()})


def _table(qualities: Mapping[str, TimingQuality]) -> str:
    lines = [f"{'record':<9} {'samples':>7} {'median ms':>9} {'worst gap ms':>12} {'in gaps':>8}"]
    for name, q in qualities.items():
        flag = "  irregular" if q.warning else ""
        lines.append(
            f"{name:<9} {q.n:>7} {q.median_ms:>9.3g} {q.worst_gap_ms:>12.4g} "
            f"{100 * q.gap_share:>7.1f}%{flag}"
        )
    return "\n".join(lines) + "\n"


def quality_report(name: str, q: TimingQuality) -> str:
    """:func:`timing_report` of one static recording from its :class:`TimingQuality` (a
    recording read in blocks, never held whole)."""
    if not q.warning:
        return ""
    return _table({name: q}) + f"warning: {name}: irregular sample times ({q.describe()})\n"


def timing_warnings(records: Mapping[str, Record]) -> list[str]:
    """One line per record with irregular sample times; for a turn also how far assuming a
    uniform rate would move its integral (it is integrated over the true times)."""
    out = []
    for name, rec in records.items():
        tq = timing_quality(rec.t_ms / 1000.0)
        if not tq.warning:
            continue
        msg = f"warning: {name}: irregular sample times ({tq.describe()})"
        if rec.kind == "turn":
            err = uniform_rate_error_deg(rec.t_ms / 1000.0, rec.gyro)
            msg += (
                f"; the turn integral uses the true times (assuming a uniform rate would move "
                f"it by {err:.2f}°)"
            )
        out.append(msg)
    return out


def timing_report(records: Mapping[str, Record]) -> str:
    """The timing table and its warnings when any record has irregular sample times, else ''
    (what ``calibrate --from-dir``, ``model``, ``thermal`` and ``noise`` print to stderr)."""
    warnings = timing_warnings(records)
    if not warnings:
        return ""
    return timing_table(records) + "\n".join(warnings) + "\n"
