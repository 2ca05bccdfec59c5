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
    dt_ms = np.diff(t) * 1000.0
    median = float(np.median(dt_ms))
    worst = float(dt_ms.max())
    limit = max(GAP_MIN_MS, GAP_FACTOR * median)
    total = float(dt_ms.sum())
    share = float(dt_ms[dt_ms > limit].sum() / total) if total > 0 else 0.0
    warn = share > WARN_GAP_SHARE or (median > 0 and worst > WARN_WORST_FACTOR * median)
    return TimingQuality(int(t.size), median, worst, share, limit, bool(warn))


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
    lines = [f"{'record':<9} {'samples':>7} {'median ms':>9} {'worst gap ms':>12} {'in gaps':>8}"]
    for name, rec in records.items():
        q = timing_quality(rec.t_ms / 1000.0)
        flag = "  irregular" if q.warning else ""
        lines.append(
            f"{name:<9} {q.n:>7} {q.median_ms:>9.3g} {q.worst_gap_ms:>12.4g} "
            f"{100 * q.gap_share:>7.1f}%{flag}"
        )
    return "\n".join(lines) + "\n"


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
