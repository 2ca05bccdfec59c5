"""Per-channel statistics of a fit (:func:`channel_fits`): each output channel's χ², degrees
of freedom, record-level dof, the standard-error scale (:func:`host.model.stats.stderr_scale`)
and what its records determine of the parameters they leave undetermined
(:class:`Combination`); the moves' rows (:mod:`host.model.moves`) are a channel of their own
(:data:`MOVES`), since each reads every gyro channel's terms and two poses' attitudes; and the
factor each parameter's standard error is widened by (:func:`parameter_scales`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from host.model.dataset import Dataset
from host.model.signals import AXES, SENSORS
from host.model.stats import right_singular, rref, stderr_scale
from host.model.whitening import Group

#: who owns each design column: (name, unit, (sensor, axis or -1), term label, key)
Owners = Sequence[tuple[str, str, tuple[str, int], str, str]]

#: the channel of the moves' rows (:mod:`host.model.moves`): each reads every gyro channel's
#: terms and two poses' attitudes, so it is a channel of its own, not gyro x or y
MOVES = "moves"
#: a move's two rows: the miss along the two directions across the next rest's gravity
MOVE_ROWS = ("move a", "move b")


@dataclass(frozen=True, eq=False)
class Combination:
    """A combination of undetermined parameters that the records DO determine:
    Σ coefficient·parameter = value ± stderr (unit of the first parameter)."""

    terms: tuple[tuple[float, str], ...]  # (coefficient, parameter name)
    value: float
    stderr: float
    unit: str

    def describe(self) -> str:
        """'A0x + 9.815·Axx = 0.6021 ± 0.0003 m/s²'."""
        parts: list[str] = []
        for i, (c, n) in enumerate(self.terms):
            sign = "−" if c < 0 else "+"
            mag = abs(c)
            coef = "" if abs(mag - 1.0) < 1e-9 else f"{mag:.4g}·"
            parts.append((("−" if c < 0 else "") if i == 0 else f" {sign} ") + coef + n)
        return f"{''.join(parts)} = {self.value:.6g} ± {self.stderr:.2g} {self.unit}".strip()


@dataclass(frozen=True, eq=False)
class ChannelFit:
    """Fit statistics of one output channel (the channels are independent problems).

    ``dof`` = rows − determined parameters; ``dof_records`` = record/channel values −
    parameters (the between-record test: 0 means the model is not tested at all, verdict
    ``untestable``); ``se_scale``: :func:`stderr_scale`; ``combinations``: what the records
    determine of the undetermined parameters. ``axis`` is 'x', 'y', 'z', or :data:`MOVES`
    for the moves' rows (gyro moves). In a session with poses, where a pose's attitude is
    read by three channels and a move by all the gyro's, ``dof`` is what the fit leaves each
    channel's rows, Σ(1 − h) of their leverages h (rows − rank otherwise: the same when no
    column reads two channels)."""

    sensor: str
    axis: str
    chi2: float
    dof: int
    dof_records: int
    se_scale: float
    combinations: tuple[Combination, ...] = ()

    @property
    def channel(self) -> str:
        return f"{self.sensor} {self.axis}"

    @property
    def testable(self) -> bool:
        return self.dof_records > 0


def parameter_scales(
    ds: Dataset,
    channels: Sequence[ChannelFit],
    owners: Owners,
    x: np.ndarray,
) -> np.ndarray:
    """(P,) the factor each parameter's standard error is widened by: its channel's, a shared
    parameter the largest of its sensor's channels', and a parameter the moves' rows read
    (``x`` the design) at least the moves' channel's."""
    scale_of = {(c.sensor, AXES.index(c.axis)): c.se_scale for c in channels if c.axis in AXES}
    for chf in channels:  # a shared parameter: the largest scale of its sensor's channels
        scale_of[(chf.sensor, -1)] = max(scale_of.get((chf.sensor, -1), 1.0), chf.se_scale)
    moves = max((c.se_scale for c in channels if c.axis == MOVES), default=1.0)
    moving = move_rows(ds)
    reads = np.any(x[moving] != 0.0, axis=0) if moving.any() else np.zeros(len(owners), bool)
    return np.array([
        max(scale_of.get(o[2], 1.0), moves if reads[c] else 1.0) for c, o in enumerate(owners)
    ])  # fmt: skip


def move_rows(ds: Dataset) -> np.ndarray:
    """(n_rows,) which rows of ``ds`` are the moves' (:data:`MOVES`)."""
    kinds = np.array([sig.kind == "move" for sig in ds.signals] + [False])
    return np.asarray(kinds[ds.row_record]) if ds.n_rows else np.zeros(0, dtype=bool)


def channel_fits(
    ds: Dataset,
    x: np.ndarray,
    xw: np.ndarray,
    wres: np.ndarray,
    theta: np.ndarray,
    cov: np.ndarray,
    owners: Owners,
    basis: np.ndarray,
) -> tuple[list[ChannelFit], np.ndarray]:
    """Per output channel: χ², dof, record-level dof, the standard-error scale, which columns
    the records determine individually (a parameter is determined when its unit vector lies in
    the row space of the channel's design) and the combinations they do determine; the moves'
    rows a channel of their own (:data:`MOVES`)."""
    estimable = np.zeros(len(owners), dtype=bool)
    out: list[ChannelFit] = []
    solved = _Solved(x, xw, wres, theta, cov, owners)
    joint = _pose_record_dof(ds, x, owners)  # with poses: over a sensor's channels together
    moving = move_rows(ds)
    # with poses a column reads several channels: each channel's dof is its rows' Σ(1 − h)
    free = 1.0 - np.sum(basis**2, axis=1) if joint and basis.shape[1] else None
    for s_i, sensor in enumerate(SENSORS):
        for ax in range(3):
            rows = np.flatnonzero((ds.row_sensor == s_i) & (ds.row_axis == ax) & ~moving)
            if not len(rows):
                continue
            grs = [g for g in ds.groups if g.sensor == sensor and g.axis == ax
                   and ds.signals[g.record].kind != "move"]  # fmt: skip
            chf = _channel(solved, (sensor, ax), rows, grs, estimable, joint, free)
            out.append(chf)
    if moving.any():
        out.append(_moves_channel(wres, moving, free, joint))
    if any(o[2][1] < 0 for o in owners) or moving.any():
        # shared parameters (or the moves' rows) couple the channels: what all rows determine
        estimable = estimable_columns(xw)
    return out, estimable


def _moves_channel(
    wres: np.ndarray, moving: np.ndarray, free: np.ndarray | None, joint: Mapping[str, int]
) -> ChannelFit:
    """The moves' rows as one channel: χ² on Σ(1 − h) of their rows."""
    rows = np.flatnonzero(moving)
    chi2 = float(wres[rows] @ wres[rows])
    dof = int(round(float(np.sum(free[rows])))) if free is not None else len(rows)
    return ChannelFit("gyro", MOVES, chi2, dof, joint.get("gyro", dof), stderr_scale(chi2, dof))


@dataclass(frozen=True)
class _Solved:
    """What a channel's statistics read of the solved fit: the design ``x`` and the whitened
    design ``xw``, the whitened residuals, the parameters ``theta`` with their covariance
    ``cov``, and each column's owner."""

    x: np.ndarray
    xw: np.ndarray
    wres: np.ndarray
    theta: np.ndarray
    cov: np.ndarray
    owners: Owners


def _channel(
    solved: _Solved,
    channel: tuple[str, int],
    rows: np.ndarray,
    grs: Sequence[Group],
    estimable: np.ndarray,
    joint: Mapping[str, int],
    free: np.ndarray | None,
) -> ChannelFit:
    """One channel's :class:`ChannelFit` from its ``rows`` and groups ``grs`` (``estimable``
    marked for the columns its rows determine; ``free`` each row's 1 − h, None: rows − rank)."""
    x, xw, wres, owners = solved.x, solved.xw, solved.wres, solved.owners
    sensor, ax = channel
    cols = np.array(
        [c for c, o in enumerate(owners) if o[2] in ((sensor, ax), (sensor, -1))], dtype=int
    )
    xc = xw[np.ix_(rows, cols)] if len(cols) else np.zeros((len(rows), 0))
    norms = np.linalg.norm(xc, axis=0)
    live = norms > 0
    rank, null = 0, np.zeros((len(cols), 0))
    if live.any():
        xn = xc[:, live] / norms[live]
        sv, vt = right_singular(xn)
        rank = int(np.sum(sv > 1e-9 * sv[0])) if len(sv) else 0
        null = np.zeros((len(cols), vt.shape[0] - rank))
        null[live] = vt[rank:].T / norms[live, None]  # back to parameter units
    for j, c in enumerate(cols):
        estimable[c] = (
            estimable[c]
            or bool(live[j])
            and (null.shape[1] == 0 or float(np.linalg.norm(null[j] * norms[j])) < 1e-6)
        )
    # record-level design: one row per record/channel value (mean of its rows; not a free
    # level's, which is a value of its own)
    tested = [g for g in grs if not g.free_level]
    rank_g = _record_rank(x, tested, cols)
    chi2 = float(wres[rows] @ wres[rows])
    if free is None:
        dof = len(rows) - rank - free_levels(grs)
    else:
        dof = int(round(float(np.sum(free[rows])))) - free_levels(grs)
    scale = stderr_scale(chi2, dof)
    combos = (
        _combinations(cols, estimable, null, norms, solved.theta, solved.cov * scale**2, owners)
        if null.shape[1]
        else ()
    )
    dof_g = joint.get(sensor, len(tested) - rank_g)
    return ChannelFit(sensor, AXES[ax], chi2, dof, dof_g, scale, combos)


def _pose_record_dof(ds: Dataset, x: np.ndarray, owners: Owners) -> dict[str, int]:
    """sensor -> its record-level dof counted over its three channels together, in a session
    with poses: a pose's attitude (two unknowns shared by the accelerometer's channels) is
    tested by the three values it explains, which no channel alone shows. {} without poses."""
    if not any(sig.kind == "pose" for sig in ds.signals):
        return {}
    out: dict[str, int] = {}
    for sensor in SENSORS:
        tested = [g for g in ds.groups if g.sensor == sensor and not g.free_level]
        cols = np.array([c for c, o in enumerate(owners) if o[2][0] == sensor], dtype=int)
        if tested and len(cols):
            out[sensor] = len(tested) - _record_rank(x, tested, cols)
    return out


def _record_rank(x: np.ndarray, tested: Sequence[Group], cols: np.ndarray) -> int:
    """The rank of the record-level design: one row per record/channel value of ``tested``
    (the mean of its rows of the design ``x``), on the columns ``cols``."""
    if not len(cols) or not tested:
        return 0
    xg = np.array([x[np.ix_(g.rows, cols)].mean(axis=0) for g in tested])
    gn = np.linalg.norm(xg, axis=0)
    return int(np.linalg.matrix_rank(xg[:, gn > 0] / gn[gn > 0], tol=1e-9))


def free_levels(groups: Sequence[Group]) -> int:
    """How many of ``groups`` have a level of their own (each takes one degree of freedom as
    a parameter would: its rows' mean is weighed out,
    :data:`host.model.whitening.FREE_LEVEL_RAD`)."""
    return sum(gr.free_level for gr in groups)


def estimable_columns(xw: np.ndarray) -> np.ndarray:
    """(P,) which columns of the whitened design ``xw`` (n, P) the rows determine: the
    parameter's unit vector lies in the row space (it has no part in the null space)."""
    norms = np.linalg.norm(xw, axis=0)
    live = norms > 0
    out = np.zeros(xw.shape[1], dtype=bool)
    if not live.any():
        return out
    sv, vt = right_singular(xw[:, live] / norms[live])
    rank = int(np.sum(sv > 1e-9 * sv[0])) if len(sv) else 0
    null = vt[rank:].T
    idx = np.flatnonzero(live)
    for j, c in enumerate(idx):
        out[c] = null.shape[1] == 0 or float(np.linalg.norm(null[j])) < 1e-6
    return out


def _combinations(
    cols: np.ndarray,
    estimable: np.ndarray,
    null: np.ndarray,
    norms: np.ndarray,
    theta: np.ndarray,
    cov: np.ndarray,
    owners: Owners,
) -> tuple[Combination, ...]:
    """Combinations c·θ of the undetermined parameters of one channel that the records
    determine: c supported on them with cᵀ·N = 0 (N the null space of the design)."""
    und = [j for j, c in enumerate(cols) if not estimable[c] and norms[j] > 0]
    if not und:
        return ()
    # in normalised coordinates (columns of unit norm) for a well-scaled null space
    ns = null[und] * norms[und, None]
    _, sv, vt = np.linalg.svd(ns.T, full_matrices=True)
    r = int(np.sum(sv > 1e-9 * max(float(sv[0]), 1e-300))) if len(sv) else 0
    basis = vt[r:]
    if not len(basis):
        return ()
    out: list[Combination] = []
    for row in rref(basis * norms[und][None, :]):
        coef = row / row[np.flatnonzero(np.abs(row) > 1e-12)[0]]
        idx = [cols[und[k]] for k in range(len(und))]
        terms = tuple((float(coef[k]), owners[idx[k]][0]) for k in range(len(und))
                      if abs(coef[k]) > 1e-9)  # fmt: skip
        full = np.zeros(len(theta))
        for k in range(len(und)):
            full[idx[k]] = coef[k]
        value = float(full @ theta)
        se = math.sqrt(max(float(full @ cov @ full), 0.0))
        unit = owners[idx[next(k for k in range(len(und)) if abs(coef[k]) > 1e-9)]][1]
        out.append(Combination(terms, value, se, unit))
    return tuple(out)
