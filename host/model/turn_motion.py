"""The plate's tilt read from the turns' motion (issue 40): every sample of every turn, not
only its rests.

A hand turn on the method's bench has no rests inside it: the cube is turned once or n times
in one motion, resting only at its start and end, at the same heading. The rests then show
one heading and draw no circle (:func:`host.model.plate.turn_circle`), but the tilt is there
all the same: turning about the plate's normal by ψ(t) (the angle the gyro integrates,
:attr:`host.model.signals.RecordSignals.heading`), the horizontal accelerometers read gravity's
lean g·(t_e·e(ψ) + t_n·n(ψ)), a circle in the turn's own angle, beside what the motion itself
puts there:

    a_k(t) = c_k + g·s_k·(t_e·e_k(ψ) + t_n·n_k(ψ)) + [A·M(t)·r]_k + hand + noise

with c_k the body-fixed part of the turn and channel (bias, misalignment, a face's lean:
gravity along the turn axis), s_k the channel's scale, M(t) the lever arm's matrix of ω² and
ω̇ (:func:`host.model.turning.sensed_lever_matrix`, ONE offset r for every turn) and the
hand's wobble, which is zero at the rests and scatters the moving blocks.

:func:`motion_tilts` fits that for every turn record at once, on the rows the dataset reads
(the rests' means and the 0.5 s moving blocks, :func:`host.model.noise.still_runs`,
:func:`host.model.turning.moving_blocks`): per turn and horizontal channel a constant, per
turn the tilt as it sees it (2 angles in its own frame at heading 0), one lever arm; each row
weighted by its white noise plus a named variance component of its kind — the seating at the
rests, the hand while the cube turns — estimated from the residuals (σ² = Σ(r² −
v·(1 − h))/Σ(1 − h), refitted until it settles). Rests inside a turn are a special case: more
rows of the rest kind. The per-turn tilts then place the turns against each other as the rests'
circles do (:func:`host.model.plate.plate_from_rests`).

Units: rad for tilts, m/s² for specific force, m for the lever arm.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from host.model import turning
from host.model.geometry import plate_axes
from host.model.noise import still_runs
from host.model.signals import RecordSignals

#: the fewest rows a turn's horizontal channel needs for its tilt to be read from its motion
MIN_ROWS = 6
#: refits of the two variance components (they settle in 2-3)
ITERATIONS = 5
#: the least variance a row is given, (m/s²)²: noise-free records (a simulator's) are not
#: divided by zero
VAR_FLOOR = 1e-14


@dataclass(frozen=True)
class MotionTilt:
    """One turn record's tilt read from its motion: ``tilt`` (2,) rad in the record's frame at
    heading 0, ``cov`` (2, 2) rad², ``centre`` (2,) m/s² the body-fixed part of its two
    horizontal channels with ``centre_var`` (2,), ``rms`` m/s² the rows' residual,
    ``n_rests`` and ``n_blocks`` the rows of each kind per channel."""

    record: str
    tilt: np.ndarray
    cov: np.ndarray
    centre: np.ndarray
    centre_var: np.ndarray
    rms: float
    n_rests: int
    n_blocks: int


@dataclass(frozen=True)
class MotionFit:
    """Every turn's :class:`MotionTilt`, the lever arm fitted with them (3,) m and its
    covariance, and the two variance components (σ m/s² of a row beyond its white noise):
    ``seating`` at the rests, ``hand`` on the moving blocks."""

    tilts: tuple[MotionTilt, ...]
    lever: np.ndarray
    lever_cov: np.ndarray
    seating: float
    hand: float


@dataclass
class _Rows:
    """The design being gathered: rows' values, white variances, kinds (True: a rest), and
    columns by name (constants and tilts per record, the shared lever arm)."""

    y: list[float]
    white: list[float]
    rest: list[bool]
    cols: dict[tuple[str, ...], dict[int, float]]


def _turn_rows(rows: _Rows, sig: RecordSignals, gyro_sd: float, white: np.ndarray) -> int:
    """One turn record's horizontal rows into ``rows``; -> rests per channel (-1: too few
    rows, nothing added)."""
    t_rel = sig.t_s - sig.t_s[0]
    rate_up = sig.rate @ sig.up
    runs = still_runs(rate_up, t_rel, gyro_sd)
    blocks = turning.moving_blocks(rate_up, t_rel, gyro_sd)
    ranges = np.array([*runs, *blocks], dtype=np.intp).reshape(-1, 2)
    if len(ranges) < MIN_ROWS:
        return -1
    up_k = int(np.argmax(np.abs(sig.up)))
    east, north = plate_axes(sig.up, sig.heading)
    # the scales alone: before the plate is known the statics' misalignments hold its tilt
    scale = np.ones(3) if sig.accel_matrix is None else np.diag(np.asarray(sig.accel_matrix))
    lever = turning.sensed_lever_matrix(sig.t_s, sig.rate, np.diag(scale))
    rest = [b < len(runs) for b in range(len(ranges))]
    for k in (i for i in range(3) if i != up_k):
        tilt = sig.g * scale[k] * np.column_stack([east[:, k], north[:, k]])
        means = range_means(np.column_stack([sig.accel[:, k], tilt]), ranges)
        first = len(rows.y)
        rows.y.extend(means[:, 0].tolist())
        rows.white.extend((float(white[k]) / (ranges[:, 1] - ranges[:, 0])).tolist())
        rows.rest.extend(rest)
        at = range(first, first + len(ranges))
        rows.cols.setdefault(("c", sig.name, str(k)), {}).update(dict.fromkeys(at, 1.0))
        for j, side in ((1, "e"), (2, "n")):
            col = rows.cols.setdefault(("t", sig.name, side), {})
            col.update(zip(at, means[:, j].tolist(), strict=True))
        _lever_columns(rows, range_means(lever[:, k, :], ranges, centred=False), first)
    return len(runs)


def range_means(columns: np.ndarray, ranges: np.ndarray, centred: bool = True) -> np.ndarray:
    """(R, m) the mean of each of ``columns`` (N, m) over each [start, stop) of ``ranges``
    (R, 2), in one pass: a running sum, not a mean per range. ``centred``: summed from each
    column's first value, so that the sums stay small; else from zero, so that a range of
    zeros has a mean of exactly zero."""
    x = np.asarray(columns, dtype=np.float64)
    x0 = x[0] if centred else np.zeros(x.shape[1])
    run = np.zeros((len(x) + 1, x.shape[1]))
    np.cumsum(x - x0, axis=0, out=run[1:])
    n = (ranges[:, 1] - ranges[:, 0])[:, None]
    return (run[ranges[:, 1]] - run[ranges[:, 0]]) / n + x0


def _lever_columns(rows: _Rows, means: np.ndarray, first: int) -> None:
    """The lever arm's three columns of the rows from ``first`` (``means`` (R, 3)), each
    value that is not zero; a column new to ``rows`` is added where its first value falls
    (in the order of the rows, then x, y, z)."""
    nonzero = means != 0.0
    order = sorted(
        (int(np.argmax(nonzero[:, j])), j) for j in range(3) if bool(nonzero[:, j].any())
    )
    for _, j in order:
        at = np.flatnonzero(nonzero[:, j])
        col = rows.cols.setdefault(("r", "xyz"[j]), {})
        col.update(zip((at + first).tolist(), means[at, j].tolist(), strict=True))


def _weighted_fit(
    x: np.ndarray, y: np.ndarray, var: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Weighted least squares of ``y`` on ``x`` with row variances ``var``: -> (coefficients,
    their covariance, residuals, leverages)."""
    sw = 1.0 / np.sqrt(np.maximum(var, VAR_FLOOR))
    xw = x * sw[:, None]
    cov = np.linalg.pinv(xw.T @ xw)
    beta = cov @ (xw.T @ (y * sw))
    resid = y - x @ beta
    lev = np.sum((xw @ cov) * xw, axis=1)
    return beta, cov, resid, np.clip(lev, 0.0, 1.0)


def _components(
    x: np.ndarray, y: np.ndarray, white: np.ndarray, rest: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, float, float]:
    """The fit with the seating (rest rows) and the hand (moving rows) as variance components
    refitted from its residuals: -> (coefficients, covariance, residuals, σ_seat, σ_hand)."""
    comp = {True: 0.0, False: 0.0}
    for _ in range(ITERATIONS):
        var = white + np.where(rest, comp[True], comp[False])
        beta, cov, resid, lev = _weighted_fit(x, y, var)
        for kind in (True, False):
            m = rest == kind
            free = float(np.sum(1.0 - lev[m]))
            if free > 1.0:
                excess = float(np.sum(resid[m] ** 2 - white[m] * (1.0 - lev[m]))) / free
                comp[kind] = max(excess, 0.0)
    var = white + np.where(rest, comp[True], comp[False])
    beta, cov, resid, lev = _weighted_fit(x, y, var)
    dof = len(y) - float(np.sum(lev))
    chi2 = float(np.sum(resid**2 / np.maximum(var, VAR_FLOOR)))
    cov = cov * max(1.0, chi2 / dof) if dof > 0 else cov
    return beta, cov, resid, math.sqrt(comp[True]), math.sqrt(comp[False])


def motion_tilts(
    signals: Sequence[RecordSignals], gyro_sd: np.ndarray, accel_var: np.ndarray
) -> MotionFit | None:
    """Every turn record's tilt from its motion (module docstring), jointly with one lever arm;
    ``gyro_sd`` (3,) °/s the gyro's per-sample noise (finds the rests and the moving blocks),
    ``accel_var`` (3,) (m/s²)² the accelerometer's per-sample white variance (the static
    records'). None without a turn record that has rows enough."""
    rows = _Rows([], [], [], {})
    n_rests: dict[str, int] = {}
    for s in signals:
        if s.kind == "turn" and s.heading_deg is not None:
            up_k = int(np.argmax(np.abs(s.up)))
            got = _turn_rows(rows, s, float(gyro_sd[up_k]), accel_var)
            if got >= 0:
                n_rests[s.name] = got
    if not n_rests:
        return None
    names = list(rows.cols)
    x = np.zeros((len(rows.y), len(names)))
    for j, key in enumerate(names):
        for i, v in rows.cols[key].items():
            x[i, j] = v
    y, white, rest = np.array(rows.y), np.array(rows.white), np.array(rows.rest)
    beta, cov, resid, seat, hand = _components(x, y, white, rest)
    return _result(names, beta, cov, resid, rows, n_rests, seat, hand)


def _result(
    names: list[tuple[str, ...]],
    beta: np.ndarray,
    cov: np.ndarray,
    resid: np.ndarray,
    rows: _Rows,
    n_rests: dict[str, int],
    seat: float,
    hand: float,
) -> MotionFit:
    """The fit's coefficients by record (:class:`MotionTilt`) and the lever arm."""
    at = {key: j for j, key in enumerate(names)}
    tilts = []
    for rec, n in n_rests.items():
        t = [at[("t", rec, "e")], at[("t", rec, "n")]]
        c = [j for key, j in at.items() if key[0] == "c" and key[1] == rec]
        mine = np.array([i for j in c for i in rows.cols[names[j]]])
        tilts.append(MotionTilt(
            rec, beta[t], cov[np.ix_(t, t)], beta[c], np.diag(cov)[c],
            math.sqrt(float(np.mean(resid[mine] ** 2))), n, len(mine) // len(c) - n,
        ))  # fmt: skip
    lever, lever_cov = np.zeros(3), np.zeros((3, 3))
    idx = [(j, at[("r", a)]) for j, a in enumerate("xyz") if ("r", a) in at]
    for j, p in idx:
        lever[j] = beta[p]
        for q, pq in idx:
            lever_cov[j, q] = cov[p, pq]
    return MotionFit(tuple(tilts), lever, lever_cov, seat, hand)
