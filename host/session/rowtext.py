"""A record's data rows as text, all rows at once (:mod:`host.session.records` holds the
format): printed with one ``%`` over every value, read with one ``np.loadtxt``, where the
line of underscores after them is, and the time stamps' spacing a record may have.

Reading a session's records cost as much as writing them, a ``float`` per field and a format
per value: ``benchmarks/records_bench.py`` times both against that reference.
"""

from __future__ import annotations

import re
from collections.abc import Sequence

import numpy as np

#: the line after the data rows: underscores alone
UNDERSCORES_RE = re.compile(r"^_{3,}\s*$")
#: what a block of data rows holds when :func:`read_rows` reads it: digits, signs, points,
#: exponents and blanks (no ``#`` line, no ``nan``, no other script's digits)
_PLAIN_ROWS_RE = re.compile(r"[0-9eE+\-. \t\n]*")
#: how many lines at a record's end :func:`underscores_at_end` looks through
_TAIL_LINES = 8
#: the sample spacing a record's times may have on average, ms: the MPU-6000 samples at most
#: at 8 kHz; one sample a minute is no recording of a sensor either
SPACING_RANGE_MS = (0.1, 60_000.0)


def format_rows(data: np.ndarray, decimals: Sequence[int]) -> str:
    """The rows of ``data`` (n, m) as text, one line each and no final newline, column j with
    ``decimals[j]`` decimals and tabs between; a value printed as minus zero without its
    sign."""
    if not len(data):
        return ""
    row = "\t".join(f"%.{d}f" for d in decimals)
    return "\n".join([row] * len(data)) % tuple(_no_minus_zero(data, decimals).ravel().tolist())


def _no_minus_zero(data: np.ndarray, decimals: Sequence[int]) -> np.ndarray:
    """``data`` with each value its column's decimals would print as minus zero ("-0.000")
    made +0. Only values in (−10⁻ᵈ, −0] can round to zero; each of those few is printed to
    tell."""
    out = data
    for j, d in enumerate(decimals):
        col = data[:, j]
        for i in np.flatnonzero(np.signbit(col) & (col > -(10.0**-d))).tolist():
            if float(f"{col[i]:.{d}f}") == 0.0:
                out = out if out is not data else data.copy()
                out[i, j] = 0.0
    return out


def read_rows(block: list[str], columns: int) -> np.ndarray | None:
    """The data rows ``block`` (one line each) as an (n, ``columns``) array, in one pass; None
    unless every line is ``columns`` plain finite numbers and the first column never goes
    back (the line-by-line reader then names what is wrong). A blank line is no row."""
    if not block or _PLAIN_ROWS_RE.fullmatch("\n".join(block)) is None:
        return None
    try:
        data = np.loadtxt(block, dtype=np.float64, comments=None, ndmin=2)
    except ValueError:
        return None
    if data.shape[0] == 0 or data.shape[1] != columns or not np.all(np.isfinite(data)):
        return None
    return None if np.any(np.diff(data[:, 0]) < 0) else data


def underscores_at_end(lines: list[str], head: int) -> int | None:
    """The index of the line of underscores among the last lines (not before ``head``)."""
    for i in range(len(lines) - 1, max(head, len(lines) - _TAIL_LINES) - 1, -1):
        if UNDERSCORES_RE.match(lines[i].strip()):
            return i
    return None


def spacing_problem(t_ms: np.ndarray) -> str | None:
    """What is wrong with time stamps ``t_ms`` (n,) ms no record has — all equal, or spaced on
    average outside :data:`SPACING_RANGE_MS` (seconds, or µs, where the format has ms) — or
    None."""
    if t_ms.size < 2:
        return None
    mean = (t_ms[-1] - t_ms[0]) / (t_ms.size - 1)
    if mean == 0:
        return (f"every time stamp is {t_ms[0]:g} ms: the times do not run; the first column "
                "is the time since the start in ms")  # fmt: skip
    lo, hi = SPACING_RANGE_MS
    if lo <= mean <= hi:
        return None
    unit = "seconds" if mean < lo else "µs or another unit"
    return (
        f"the time stamps are {mean:.3g} ms apart on average (a sensor samples every {lo:g} "
        f"to {hi:g} ms): they look like {unit}; the first column is the time since the start "
        "in ms (import --units t=s converts)"
    )
