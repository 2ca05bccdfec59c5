"""A bias step in time placed to the sample, with its ± and its size; two steps on a channel.

The scan (:mod:`host.workbench.scan`) finds a step by trying one at each boundary between rows
and in each gap between records. A row is a block mean (a static's 5 s) or a turn's integral,
and a step inside it moves that row by the part of it after the step: the rows either side fix
the step's size, so the row it falls in fixes where in the row it fell. Here every cut between
two samples of the session is tried on the channel (a gap between records is one cut: any time
in it moves the rows alike), and the drop in χ² each would give, Δχ²(t), is the profile of the
step's time: the best time is its largest, the ± the times whose Δχ² is within
:data:`PROFILE_DROP` of it (scaled by χ²/dof after the step when that exceeds 1), one standard
error for a step whose Δχ²(t) is a parabola near its top, as it is inside a row.

A second step on the same channel is sought with the first in the model: it is named when its
Δχ² is significant over every cut it could have taken (Bonferroni over the scan's cuts at the
scan's α), and then each step is placed again given the other.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import re
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from host.model.dataset import Dataset
from host.model.signals import RecordSignals
from host.model.stats import chi2_sf

#: how the name of every step in time begins
STEP = "a step in time"

#: the fall of Δχ² from its top that bounds a step's time at one standard error (a parabola's
#: unit drop: 68 % for a time read from a row's fraction)
PROFILE_DROP = 3.84


@dataclass(frozen=True, eq=False)
class StepCuts:
    """Every distinct cut of one channel as a whitened step column with the fit's columns
    removed, and each cut's span of time ``lo``/``hi`` (K,) s: the two samples either side of
    it (a gap between records: its last and first sample); ``spans`` (first, last sample time,
    s) of each record with rows on the channel.

    Kept in parts, never as the (n_rows, K) matrix: cut k's column is ``level[:, owner[k]]``
    (the records after the cut, moved whole) plus the cut's record's own rows ``rows`` moved
    by ``moved[:, k - start]`` (one of ``records``: (rows, start, moved)), less ``q @ z[:, k]``
    (the own rows' part along the removed directions ``q``, orthonormal; ``level`` has none).
    """

    lo: np.ndarray
    hi: np.ndarray
    spans: tuple[tuple[float, float], ...]
    level: np.ndarray
    owner: np.ndarray
    records: tuple[tuple[np.ndarray, int, np.ndarray], ...]
    q: np.ndarray
    z: np.ndarray

    @functools.cached_property
    def white(self) -> np.ndarray:
        """(n_rows, K) every cut's column (tests and small sessions: memory n_rows·K)."""
        out = self.level[:, self.owner] - self.q @ self.z
        for rows, start, moved in self.records:
            out[rows, start : start + moved.shape[1]] += moved
        return np.asarray(out)

    def dot(self, v: np.ndarray) -> np.ndarray:
        """(K,) ``v`` (n_rows,) · every cut's column."""
        out = (v @ self.level)[self.owner] - (v @ self.q) @ self.z
        for rows, start, moved in self.records:
            out[start : start + moved.shape[1]] += v[rows] @ moved
        return np.asarray(out)

    def columns(self, ks: Sequence[int] | np.ndarray) -> np.ndarray:
        """(n_rows, len(ks)) the columns of the cuts ``ks``."""
        ks = np.asarray(ks, dtype=np.intp)
        out = self.level[:, self.owner[ks]] - self.q @ self.z[:, ks]
        at = np.searchsorted(self._starts, ks, side="right") - 1  # the record of each cut
        for j in np.unique(at[at >= 0]):
            rows, start, moved = self.records[j]
            inside = (at == j) & (ks < start + moved.shape[1])
            if np.any(inside):
                out[np.ix_(rows, np.flatnonzero(inside))] += moved[:, ks[inside] - start]
        return np.asarray(out)

    @functools.cached_property
    def _starts(self) -> np.ndarray:
        """(records,) the first cut of each record's own."""
        return np.array([start for _, start, _ in self.records], dtype=np.intp)

    def norms2(self) -> np.ndarray:
        """(K,) every column's squared norm: level and removed part are orthogonal, so
        ‖level + own − q·z‖² = ‖level‖² + 2·level·own + ‖own‖² − ‖z‖²."""
        out = np.einsum("ij,ij->j", self.level, self.level)[self.owner]
        out -= np.einsum("ij,ij->j", self.z, self.z)
        for rows, start, moved in self.records:
            lv = self.level[rows][:, self.owner[start : start + moved.shape[1]]]
            out[start : start + moved.shape[1]] += np.einsum("ij,ij->j", moved, moved + 2.0 * lv)
        return np.asarray(out)

    def without(self, u: np.ndarray) -> StepCuts:
        """The cuts with the unit direction ``u`` (n_rows,), orthogonal to ``q``, removed too."""
        z_u = np.zeros(self.z.shape[1])
        for rows, start, moved in self.records:
            z_u[start : start + moved.shape[1]] = u[rows] @ moved
        return dataclasses.replace(
            self,
            level=self.level - np.outer(u, u @ self.level),
            q=np.column_stack([self.q, u]),
            z=np.vstack([self.z, z_u]),
        )


@dataclass(frozen=True)
class Placed:
    """A step placed on a channel: ``at_s`` its best time (s, the records' clock), ``lo_s`` and
    ``hi_s`` the ends of its ± (the times whose Δχ² is within the profile's drop of the best),
    ``size`` the step (sensor units: m/s² or °/s, later less earlier) and its ``size_sd``,
    ``delta_chi2`` what the step removes from χ² (given the other, for two), ``joint`` what the
    channel's steps remove together."""

    at_s: float
    lo_s: float
    hi_s: float
    size: float
    size_sd: float
    delta_chi2: float
    joint: float

    @property
    def sd_s(self) -> float:
        """The step's time's ±, s: the larger side of its interval."""
        return max(self.at_s - self.lo_s, self.hi_s - self.at_s)


#: one record's rows on a channel, in the session's order: (record index, its rows, their
#: aggregator (rows, samples)); no rows: empty
_RecordRows = tuple[int, np.ndarray, np.ndarray]


def channel_cuts(ds: Dataset, basis: np.ndarray, sensor: str, axis: int) -> StepCuts | None:
    """Every cut between two samples of the session as a step column on channel ``axis`` of
    ``sensor`` (aggregated onto its rows like a term's, whitened, the fit's ``basis`` removed);
    None when the channel has no rows.

    W is block-diagonal within each record's rows (one block per record and channel), so the
    whitened column of a cut is the whitened rows of the records after it, which every cut in
    a record shares, and the record's own rows moved by the samples after the cut, whitened by
    that record's blocks alone."""
    blocks, full = _records_in_order(ds, sensor, axis)
    if not np.any(full):
        return None
    return _basis_removed(_cuts_in_parts(ds, blocks, ds.whiten.apply(full)), basis)


def _records_in_order(ds: Dataset, sensor: str, axis: int) -> tuple[list[_RecordRows], np.ndarray]:
    """The records in the session's order with their rows on the channel, and (n_rows,) the
    rows of them all moved by a step before the first sample: each row's weights summed (a
    mean 1, an integral its span)."""
    order = sorted(range(len(ds.signals)), key=lambda i: float(ds.signals[i].t_s[0]))
    full = np.zeros(ds.n_rows)
    blocks: list[_RecordRows] = []
    for ri in order:
        rows = ds.rows_of.get((ri, sensor, axis))
        if rows is None:
            blocks.append((ri, np.zeros(0, dtype=np.intp), np.zeros((0, 0))))
            continue
        agg = ds.aggregator(ri, sensor, axis)
        full[rows] = agg.sum(axis=1)
        blocks.append((ri, rows, agg))
    return blocks, full


def _cuts_in_parts(ds: Dataset, blocks: Sequence[_RecordRows], after: np.ndarray) -> StepCuts:
    """The cuts of the records ``blocks`` (in order) in parts, no basis removed yet (``q``,
    ``z`` empty): a level per record (``after``: the whitened rows of every record moved
    whole, each record's own rows set to 0 past its cuts), and each record's own rows moved
    by the samples after each of its cuts."""
    own_blocks = _record_blocks(ds, [rows for _, rows, _ in blocks if len(rows)])
    levels = [after.copy()]
    lo: list[np.ndarray] = []
    hi: list[np.ndarray] = []
    owner: list[np.ndarray] = []
    records: list[tuple[np.ndarray, int, np.ndarray]] = []
    k_at = 0
    for k, (ri, rows, agg) in enumerate(blocks):
        t = ds.signals[ri].t_s
        if len(rows):
            after[rows] = 0.0
            levels.append(after.copy())
            n = agg.shape[1]
            # a cut before sample i (1 ≤ i < n) moves this record's rows by the weights of
            # samples i… : the reversed running sum
            tail = tail_weights(agg)[:, 1:n]
            records.append((rows, k_at, _whiten_own(own_blocks[int(rows[0])], tail)))
            owner.append(np.full(n - 1, len(levels) - 1, dtype=np.intp))
            k_at += n - 1
            lo.append(np.asarray(t[:-1], dtype=float))
            hi.append(np.asarray(t[1:], dtype=float))
        if k + 1 < len(blocks):  # the gap after this record: every later record moved whole
            nxt = ds.signals[blocks[k + 1][0]].t_s
            owner.append(np.array([len(levels) - 1], dtype=np.intp))
            k_at += 1
            lo.append(np.array([float(t[-1])]))
            hi.append(np.array([float(nxt[0])]))
    spans = tuple((float(ds.signals[ri].t_s[0]), float(ds.signals[ri].t_s[-1]))
                  for ri, rows, _ in blocks if len(rows))  # fmt: skip
    return StepCuts(np.concatenate(lo), np.concatenate(hi), spans, np.column_stack(levels),
                    np.concatenate(owner), tuple(records), np.zeros((len(after), 0)),
                    np.zeros((0, k_at)))  # fmt: skip


def _basis_removed(cuts: StepCuts, basis: np.ndarray) -> StepCuts:
    """``cuts`` (none removed yet) with the fit's orthonormal ``basis`` (n_rows, p) removed:
    from the levels, and ``z`` (p, K) each cut's own rows' part along it."""
    level = cuts.level
    z = np.zeros((basis.shape[1], len(cuts.lo)))
    if basis.shape[1]:
        level = level - basis @ (basis.T @ level)
        for rows, start, moved in cuts.records:
            z[:, start : start + moved.shape[1]] = basis[rows].T @ moved
    return dataclasses.replace(cuts, level=level, q=basis, z=z)


def tail_weights(agg: np.ndarray) -> np.ndarray:
    """(B, N) each row of ``agg`` (B, N)'s weights summed from each sample to the last (the
    reversed running sum): how much a unit step before that sample moves each row."""
    return np.cumsum(agg[:, ::-1], axis=1)[:, ::-1]


def _record_blocks(
    ds: Dataset, record_rows: Sequence[np.ndarray]
) -> dict[int, list[tuple[np.ndarray, np.ndarray]]]:
    """First row of each record's rows -> the whitener's blocks on them: (positions of the
    block's rows among the record's, the block W_b). ValueError if a block reaches past the
    record's rows (W would not be block-diagonal within records)."""
    first = {int(rows[0]): k for k, (rows, _) in enumerate(ds.whiten.blocks) if len(rows)}
    out: dict[int, list[tuple[np.ndarray, np.ndarray]]] = {}
    for rows in record_rows:
        at = {int(r): i for i, r in enumerate(rows)}
        mine: list[tuple[np.ndarray, np.ndarray]] = []
        seen = 0
        for r in rows:
            k = first.get(int(r))
            if k is None:
                continue
            b_rows, w = ds.whiten.blocks[k]
            if any(int(b) not in at for b in b_rows):
                raise ValueError(f"a whitening block reaches past the record's rows {rows}")
            mine.append((np.array([at[int(b)] for b in b_rows], dtype=np.intp), w))
            seen += len(b_rows)
        if seen != len(rows):
            raise ValueError(f"the record's rows {rows} are not whole whitening blocks")
        out[int(rows[0])] = mine
    return out


def _whiten_own(own: Sequence[tuple[np.ndarray, np.ndarray]], a: np.ndarray) -> np.ndarray:
    """W·a on one record's rows (``a`` (rows, k)), block by block (``own``: positions, W_b)."""
    out = np.zeros_like(a)
    for pos, w in own:
        out[pos] = w @ a[pos]
    return out


class _Profiles:
    """Δχ² of a step at every cut of ``cuts`` on the residual ``r`` (whitened), alone or with
    one other step already in the model, each from one product with the cuts."""

    def __init__(self, cuts: StepCuts, r: np.ndarray) -> None:
        self.cuts, self.r = cuts, r
        self.nn = cuts.norms2()
        self.rb = cuts.dot(r)
        self.tiny = 1e-12 * float(np.max(self.nn)) if len(self.nn) else 0.0
        #: :meth:`given` by cut: the climbs from several pairs meet at the same cuts, and each
        #: profile is a product with every cut
        self._given: dict[int, np.ndarray] = {}

    def alone(self) -> np.ndarray:
        """(K,) Δχ² of one step at each cut."""
        ok = self.nn > self.tiny
        return np.where(ok, self.rb**2 / np.where(ok, self.nn, 1.0), 0.0)

    def given(self, k: int) -> np.ndarray:
        """(K,) Δχ² each cut adds to a step at cut ``k``."""
        if k not in self._given:
            self._given[k] = self._given_now(k)
        return self._given[k]

    def _given_now(self, k: int) -> np.ndarray:
        if self.nn[k] <= self.tiny:
            return self.alone()
        norm = math.sqrt(float(self.nn[k]))
        a = self.cuts.dot(self.cuts.columns([k])[:, 0] / norm)
        num = (self.rb - a * float(self.rb[k]) / norm) ** 2
        den = self.nn - a * a
        ok = den > 1e-9 * self.nn
        return np.where(ok, num / np.where(ok, den, 1.0), 0.0)

    def pair(self, i: int, j: int) -> float:
        """Δχ² of steps at cuts ``i`` and ``j`` together."""
        return _joint(self.cuts.columns([i, j]), self.r)

    def climb(self, i: int, j: int) -> tuple[int, int]:
        """From the pair (i, j): each step placed again given the other, to the sample, until
        neither moves."""
        for _ in range(8):
            i2 = int(np.argmax(self.given(j)))
            j2 = int(np.argmax(self.given(i2)))
            if (i2, j2) == (i, j):
                break
            i, j = i2, j2
        return i, j


def _best(cuts: StepCuts, prof: np.ndarray, drop: float) -> tuple[int, float, float, float]:
    """The best cut, its time (the middle of the run of cuts tied with it: a gap and the samples
    no row weighs either side of it) and the ends of its ±: the cuts within ``drop`` of the
    top."""
    k = int(np.argmax(prof))
    top = float(prof[k])
    tie = top - 1e-9 * max(top, 1.0)
    first, last = k, k
    while first > 0 and prof[first - 1] >= tie:
        first -= 1
    while last + 1 < len(prof) and prof[last + 1] >= tie:
        last += 1
    at = 0.5 * (float(cuts.lo[first]) + float(cuts.hi[last]))
    near = np.flatnonzero(prof >= top - drop)
    return k, at, min(at, float(cuts.lo[near].min())), max(at, float(cuts.hi[near].max()))


#: the pairs of the scan's cuts a second step is sought from: those within this much Δχ² of
#: the best pair (each then placed to the sample: a pair of row boundaries may trail a pair
#: inside rows), at most :data:`PAIR_STARTS` of them
PAIR_MARGIN = 100.0
PAIR_STARTS = 20


def place_steps(
    cuts: StepCuts,
    r: np.ndarray,
    dof: int,
    coarse_s: Sequence[float],
    alpha: float,
    drift: np.ndarray | None = None,
) -> tuple[Placed, ...]:
    """One step placed on the channel's residual ``r`` (whitened; the fit's ``dof``), and a
    second when the best pair explains significantly more than the best one step (Bonferroni
    over the scan's ``coarse_s`` cuts, s, at ``alpha``), also with a ``drift`` (the channel's
    whitened time column, fit's columns removed) beside both: a drift is a staircase of many
    small steps, which two steps fit better than one; and never a pair that moves one record
    alone (that record's offset). The two are placed again given each other. Empty when the
    channel moves with no cut."""
    rr = float(r @ r)
    pro = _Profiles(cuts, r)
    prof = pro.alone()
    if not len(prof) or float(np.max(prof)) <= 0.0:
        return ()
    k1 = int(np.argmax(prof))
    one = float(prof[k1])
    single = (_placed(cuts, r, prof, k1, max(1.0, (rr - one) / max(dof - 1, 1)), one),)
    starts = [(k1, int(np.argmax(pro.given(k1)))), *_coarse_pairs(cuts, pro, coarse_s)]
    best, both = (k1, k1), one
    for i, j in starts:
        i, j = pro.climb(i, j)
        d = pro.pair(i, j) if i != j else one
        if d > both:
            best, both = (i, j), d
    n = max(len(coarse_s), 1)
    if best[0] == best[1] or chi2_sf(both - one, 1) * n >= alpha:
        return single
    t1, t2 = sorted(0.5 * (float(cuts.lo[k]) + float(cuts.hi[k])) for k in best)
    moved = [min(t2, b) - max(t1, a) for a, b in cuts.spans]
    if sum(m >= 0.5 * (b - a) for m, (a, b) in zip(moved, cuts.spans, strict=True)) < 2:
        # a pair that moves one record alone (most of it: more than half of no other) is that
        # record's offset (a face's lean, a seat), which a term of one parameter explains
        return single
    if drift is not None and float(drift @ drift) > 0.0:
        # the pair against one step, each with the drift beside it
        u = drift / math.sqrt(float(drift @ drift))
        with_drift = cuts.without(u)
        pro_d = _Profiles(with_drift, r - u * float(u @ r))
        gain = pro_d.pair(*best) - float(np.max(pro_d.alone()))
        if chi2_sf(gain, 1) * n >= alpha:
            return single
    ks = sorted(best, key=lambda k: float(cuts.lo[k]))
    x = cuts.columns(ks)
    beta, *_ = np.linalg.lstsq(x, r, rcond=None)
    scale = max(1.0, (rr - both) / max(dof - 2, 1))
    cov = np.linalg.inv(x.T @ x)
    out = []
    for j, k in enumerate(ks):
        p = _placed(cuts, r, pro.given(ks[1 - j]), k, scale, both)
        out.append(Placed(p.at_s, p.lo_s, p.hi_s, float(beta[j]),
                          math.sqrt(float(cov[j, j]) * scale), p.delta_chi2, both))  # fmt: skip
    return tuple(out)


def two_against_one(
    cuts: StepCuts, r: np.ndarray, t1_s: float, t2_s: float, drift: np.ndarray | None = None
) -> float:
    """Δχ² that two steps at the times ``t1_s`` and ``t2_s`` (s, the records' clock) explain
    on the residual ``r`` beyond the best one step anywhere on the channel, and beyond the best
    one step with a ``drift`` beside it (the channel's whitened time column, as
    :func:`place_steps` takes it): how well the records tell those two steps from one (a check
    on data whose steps are known)."""
    pro = _Profiles(cuts, r)
    last = len(cuts.hi) - 1
    k1, k2 = (min(int(np.searchsorted(cuts.hi, t)), last) for t in (t1_s, t2_s))
    one = float(np.max(pro.alone()))
    if drift is not None and float(drift @ drift) > 0.0:
        u = drift / math.sqrt(float(drift @ drift))
        with_drift = cuts.without(u)
        pro_d = _Profiles(with_drift, r - u * float(u @ r))
        one = max(one, float(u @ r) ** 2 + float(np.max(pro_d.alone())))
    return pro.pair(k1, k2) - one


def _joint(x: np.ndarray, r: np.ndarray) -> float:
    """Δχ² of the columns ``x`` (n, k) together on ``r``: r's part in their span."""
    beta, *_ = np.linalg.lstsq(x, r, rcond=None)
    fitted = x @ beta
    return float(fitted @ fitted)


def _coarse_pairs(
    cuts: StepCuts, pro: _Profiles, coarse_s: Sequence[float]
) -> list[tuple[int, int]]:
    """The pairs of the scan's cuts (``coarse_s``, s) whose two steps together explain the most
    of the residual, best first (:data:`PAIR_MARGIN`, :data:`PAIR_STARTS`)."""
    at = np.searchsorted(cuts.hi, np.asarray(coarse_s, dtype=float))
    idx = np.unique(at[at < len(cuts.hi)])
    if len(idx) < 2:
        return []
    x = cuts.columns(idx)
    g = x.T @ x
    b = pro.rb[idx]
    d = np.diag(g)
    det = np.outer(d, d) - g * g
    bb = np.outer(b * b, d)
    num = bb + bb.T - 2.0 * g * np.outer(b, b)
    ok = np.triu(det > 1e-9 * np.outer(d, d), 1)
    delta = np.where(ok, num / np.where(ok, det, 1.0), -np.inf)
    flat = np.argsort(delta, axis=None)[::-1][:PAIR_STARTS]
    top = float(delta.flat[flat[0]])
    return [
        (int(idx[i]), int(idx[j]))
        for i, j in zip(*np.unravel_index(flat, delta.shape), strict=True)
        if np.isfinite(delta[i, j]) and delta[i, j] >= top - PAIR_MARGIN
    ]


def _placed(
    cuts: StepCuts, r: np.ndarray, prof: np.ndarray, k: int, scale: float, joint: float
) -> Placed:
    """The step at cut ``k`` from its profile ``prof`` (given the channel's other step, if
    any): its time, ±, its own size and the size's σ (χ²/dof ``scale`` above 1 widens both)."""
    _, at, lo, hi = _best(cuts, prof, PROFILE_DROP * scale)
    col = cuts.columns([k])[:, 0]
    nn = float(col @ col)
    return Placed(at, lo, hi, float(col @ r) / nn, math.sqrt(scale / nn), float(prof[k]), joint)


# ---- names -----------------------------------------------------------------------------------
def _when(records: list[RecordSignals], t: float, end: bool) -> str:
    """A time in the records' words: 'x s into R', or (in a gap, where any time moves the rows
    alike) the end of the record before it, or (``end``: the interval's end) the start of the
    record after it."""
    for s in records:
        t0, t1 = float(s.t_s[0]), float(s.t_s[-1])
        if t0 <= t <= t1:
            return f"{t - t0:.2f} s into {s.name}"
    if end:
        nxt = next((s for s in records if float(s.t_s[0]) >= t), None)
        return f"the start of {nxt.name}" if nxt else f"the end of {records[-1].name}"
    before = [s for s in records if float(s.t_s[-1]) <= t]
    return f"the end of {before[-1].name}" if before else f"the start of {records[0].name}"


def step_name(signals: tuple[RecordSignals, ...], p: Placed, unit: str) -> str:
    """A placed step in words: inside one record 'a step in time during x_cw, 7.52 s in
    (± 0.15 s), by +0.0498 m/s²'; when its ± reaches past a record (a gap between records,
    where any time moves the rows alike) 'a step in time between the end of z_up and the
    start of z_dn, by …'."""
    records = sorted(signals, key=lambda s: float(s.t_s[0]))
    by = f"by {p.size:+.3g} {unit}"
    for s in records:
        t0, t1 = float(s.t_s[0]), float(s.t_s[-1])
        if t0 <= p.lo_s and p.hi_s <= t1:
            return f"{STEP} during {s.name}, {p.at_s - t0:.2f} s in (± {p.sd_s:.2f} s, 95 %), {by}"
    return (
        f"{STEP} between {_when(records, p.lo_s, False)} and {_when(records, p.hi_s, True)}, {by}"
    )


_IN = re.compile(r"during (?P<rec>.+?), (?P<x>[0-9.]+) s in")
_AFTER = re.compile(r"after (?P<rec>[^,/()]+?)\s*$")
_BETWEEN = re.compile(r"between (?P<a>.+?) and (?P<b>.+?)$")
_INTO = re.compile(r"(?P<x>[0-9.]+) s into (?P<rec>.+)")
_EDGE = re.compile(r"the (?P<edge>start|end) of (?P<rec>.+)")
_BY = re.compile(r", by (?P<size>[-+][0-9.eE+-]+) ")


def step_times(signals: tuple[RecordSignals, ...], name: str) -> list[tuple[float, float]] | None:
    """The steps a step's name states, [(time s, size)]: the names :func:`step_name` writes
    (one, or two joined by ', and ') and the scan's cuts ('a step in time after x_cw', '…
    during x_cw, 4.3 s in'; size 1); None when ``name`` is no step."""
    if not name.startswith(STEP):
        return None
    recs = {s.name: s for s in signals}
    order = sorted(signals, key=lambda s: float(s.t_s[0]))

    def at(text: str) -> float | None:
        text = text.strip()
        if (m := _INTO.fullmatch(text)) and m["rec"] in recs:
            return float(recs[m["rec"]].t_s[0]) + float(m["x"])
        if m := _EDGE.fullmatch(text):
            if m["rec"] in recs:
                s = recs[m["rec"]]
                return float(s.t_s[0] if m["edge"] == "start" else s.t_s[-1])
        return None

    out = []
    for part in name.split(", and "):
        part = part.removeprefix(STEP).strip()
        size_m = _BY.search(part + " ")
        size = float(size_m["size"]) if size_m else 1.0
        head = part[: size_m.start()] if size_m else part
        head = re.sub(r"\s*\(± [^)]*\)", "", head).strip()
        t: float | None = None
        if (m := _IN.fullmatch(head)) and m["rec"] in recs:
            t = float(recs[m["rec"]].t_s[0]) + float(m["x"])
        elif (m := _AFTER.fullmatch(head)) and m["rec"] in recs:
            s = recs[m["rec"]]
            later = [o for o in order if float(o.t_s[0]) > float(s.t_s[-1])]
            t = float(s.t_s[-1]) if not later else 0.5 * (float(s.t_s[-1]) + float(later[0].t_s[0]))
        elif m := _BETWEEN.fullmatch(head):
            a, b = at(m["a"]), at(m["b"])
            if a is not None and b is not None:
                t = 0.5 * (a + b)
        if t is None:
            return None
        out.append((t, size))
    return out


def short_step_name(signals: tuple[RecordSignals, ...], name: str) -> str:
    """A step's name as short as a command line needs it: the same steps read back by
    :func:`step_times` (every sample on the same side of each), its time given as 'during R,
    x s in' or, in a gap, 'after R'; the size only when there are two (their ratio matters,
    one step's size is fitted). ``name`` unchanged when it is no step or a step before the
    first sample."""
    times = step_times(signals, name)
    if not times:
        return name
    records = sorted(signals, key=lambda s: float(s.t_s[0]))
    parts = []
    for t, size in times:
        where = _short_when(records, t)
        if where is None:
            return name
        parts.append(f"{STEP} {where}" + (f", by {size:+.3g}" if len(times) > 1 else ""))
    return ", and ".join(parts)


def _short_when(records: list[RecordSignals], t: float) -> str | None:
    """'during R, x s in' (x between the two samples around ``t``, to as many decimals as that
    needs) or 'after R' (``t`` in the gap after R); None before the first sample."""
    for s in records:
        ts = np.asarray(s.t_s, dtype=float)
        t0 = float(ts[0])
        if t0 <= t < float(ts[-1]):
            k = int(np.searchsorted(ts, t, side="right"))  # the first sample after t
            lo, hi = float(ts[k - 1]), float(ts[k])
            for digits in range(2, 7):
                x = round(0.5 * (lo + hi) - t0, digits)
                if lo <= t0 + x < hi:
                    return f"during {s.name}, {x:.{digits}f} s in"
            return None
    before = [s for s in records if float(s.t_s[-1]) <= t]
    return f"after {before[-1].name}" if before else None
