"""Where a stream is not to be read across: gaps in its time, values out of any sensor's range.

- A **gap** is a sample spacing longer than ``max(GAP_MIN_S, GAP_FACTOR × the median)``: the
  logger stopped (or its clock jumped), and what the unit did meanwhile is unknown. A rest, a
  turn or a move never spans a gap (:func:`gap_starts` gives the first sample after each one);
  shorter irregular spacings (a bursty logger) are integrated over the true times as usual.
- A value **out of range** is an accelerometer reading beyond ``MAX_ACCEL_MS2`` or a rate
  beyond ``MAX_GYRO_DPS`` (after the unit conversion): no IMU reads that, so the row is a
  logger's or a converter's fault. :func:`out_of_range` finds those rows; the importer leaves
  them out, names each with its line, and the turn around it keeps its other samples.
"""

from __future__ import annotations

import numpy as np

GAP_MIN_S = 1.0  #: a spacing longer than this, s, …
GAP_FACTOR = 20.0  #: … and this many times the median spacing is a gap in the time column
MAX_ACCEL_MS2 = 2000.0  #: m/s² (≈ 200 g): beyond every IMU's accelerometer range
MAX_GYRO_DPS = 20000.0  #: °/s: beyond every IMU's gyro range
#: how many of a file's out-of-range rows are named one by one (the rest are counted)
NAMED_ROWS = 3


def gap_limit_s(t_s: np.ndarray) -> float:
    """The spacing above which two samples are a gap apart, s (module docstring)."""
    t = np.asarray(t_s, dtype=np.float64)
    dt = float(np.median(np.diff(t))) if t.size > 1 else 0.0
    return max(GAP_MIN_S, GAP_FACTOR * dt)


def gap_starts(t_s: np.ndarray) -> np.ndarray:
    """Indices i (ascending) where ``t_s[i] − t_s[i − 1]`` is a gap: the first sample after it."""
    t = np.asarray(t_s, dtype=np.float64)
    if t.size < 2:
        return np.zeros(0, dtype=int)
    return np.flatnonzero(np.diff(t) > gap_limit_s(t)) + 1


def gap_between(gaps: np.ndarray, a: int, b: int) -> bool:
    """True when a gap lies between samples a and b (a < b): some gap start g with a < g ≤ b."""
    k = int(np.searchsorted(gaps, a, side="right"))
    return k < gaps.size and int(gaps[k]) <= b


def out_of_range(accel: np.ndarray, gyro: np.ndarray) -> np.ndarray:
    """Rows (bool (N,)) where an accelerometer channel (m/s²) or a rate (°/s) is beyond
    ``MAX_ACCEL_MS2`` / ``MAX_GYRO_DPS``."""
    a = np.abs(np.asarray(accel, dtype=np.float64))
    g = np.abs(np.asarray(gyro, dtype=np.float64))
    return np.asarray(np.any(a > MAX_ACCEL_MS2, axis=1) | np.any(g > MAX_GYRO_DPS, axis=1))


def out_of_range_text(
    source: str, lines: np.ndarray, accel: np.ndarray, gyro: np.ndarray, bad: np.ndarray
) -> str:
    """One line naming the rows left out: the first ``NAMED_ROWS`` with their line and
    value, then how many more (``lines`` the file's line number of every row)."""
    idx = np.flatnonzero(bad)
    named = []
    for i in idx[:NAMED_ROWS].tolist():
        a, g = np.abs(accel[i]), np.abs(gyro[i])
        if np.any(a > MAX_ACCEL_MS2):
            k = int(np.argmax(a))
            what = f"a{'xyz'[k]} {accel[i, k]:.3g} m/s² (beyond ±{MAX_ACCEL_MS2:g})"
        else:
            k = int(np.argmax(g))
            what = f"g{'xyz'[k]} {gyro[i, k]:.3g} °/s (beyond ±{MAX_GYRO_DPS:g})"
        named.append(f"{source}:{int(lines[i])}: {what}")
    more = f"; and {idx.size - NAMED_ROWS} more rows" if idx.size > NAMED_ROWS else ""
    rows = "the row is" if idx.size == 1 else "these rows are"
    return (
        f"{'; '.join(named)}{more}: out of any IMU's range, {rows} left out (the samples "
        "around are kept; fix the logger or the --units)"
    )
