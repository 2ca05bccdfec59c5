"""The whitening of a dataset's rows: per record and channel a :class:`Group` and its block of
W with W·Cov·Wᵀ = I (:func:`whiten_rows`), so that χ² is honest under the null. W is
block-diagonal, one block per group, and kept as its blocks (:class:`Whitener`): its memory and
every product with it grow with the rows, not with their square.

The rows of one record and channel share one covariance ``v·I + f²·11ᵀ`` (:mod:`host.model.noise`)
and are whitened exactly as their mean and orthonormal (Helmert) contrasts; a turn's gyro
integral is one row; the accelerometer rows of a turn whose still moments and moving blocks
differ in variance and are correlated (the hand) are whitened through their Cholesky factor.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Callable, Collection, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from host.errors import UserError
from host.model import turning
from host.model.rows import ChannelRows
from host.model.signals import RecordSignals
from host.model.stats import ALPHA_COMPONENT, chi2_sf


@dataclass(frozen=True, eq=False)
class Group:
    """The rows of one record and channel: ``rows`` indices; ``sigma`` = std of their mean
    (static: block-mean average; turn: the integral); ``contrast_sigma`` = std of a block's
    deviation from the record's mean (NaN for one row); ``free_level``: their common level is
    an unknown of its own (:data:`FREE_LEVEL_RAD`), only their differences are measured, and
    ``sigma`` is their mean's noise without it."""

    record: int
    sensor: str
    axis: int
    rows: np.ndarray
    sigma: float
    contrast_var: float
    free_level: bool = False


#: a turn made about an axis off its face's seat (:func:`host.model.turn_axis.resolve_turn_axes`)
#: has its lean measured from its own accelerometer rows against the statics of that face, so
#: its horizontal accelerometer rows' level is that lean, not a second reading of the sensor:
#: weighed as a reading, it would count those statics' noise twice (the accelerometer's bias
#: and misalignment pulls had sd 1.27 and 1.73 over 50 independent sessions). Their level is
#: left free as a common-mode variance (g·this)² over the rows: a lean of 0.1 rad (6°) is past
#: any seat a hand makes, and leaves the level a weight below 1e-6 of its noise's
FREE_LEVEL_RAD = 0.1


#: groups gathered by their number of rows: (group indices (m,), their rows (m, b)) per size
GroupsBySize = list[tuple[np.ndarray, np.ndarray]]


def groups_by_size(groups: Sequence[Group]) -> GroupsBySize:
    """``groups`` gathered by their number of rows, for :func:`group_means`."""
    sizes: dict[int, list[int]] = {}
    for k, gr in enumerate(groups):
        sizes.setdefault(len(gr.rows), []).append(k)
    return [
        (np.array(ks, dtype=np.intp),
         np.array([groups[k].rows for k in ks], dtype=np.intp).reshape(len(ks), b))
        for b, ks in sorted(sizes.items())
    ]  # fmt: skip


def group_means(values: np.ndarray, by_size: GroupsBySize) -> np.ndarray:
    """(n_groups,) the mean of ``values`` (n_rows,) over each group's rows, the groups of one
    size in one call (each row of the gathered (m, b) array summed as ``np.mean`` sums one
    group's: the same value to the bit); NaN for a group without rows."""
    n = sum(len(ks) for ks, _ in by_size)
    out = np.zeros(n)
    for ks, rows in by_size:
        if rows.shape[1]:
            out[ks] = np.mean(values[rows], axis=1)
        else:
            out[ks] = math.nan
    return out


@dataclass(frozen=True, eq=False)
class Whitener:
    """W (n, n) with W·Cov·Wᵀ = I, block-diagonal: ``blocks`` one (row indices (b,), the
    block W_b (b, b)) per :class:`Group`, the row sets disjoint and covering the n rows. Every
    product works block by block (blocks of one size together), in memory and time linear in
    n; :meth:`dense` builds the whole matrix (tests and tiny sessions only)."""

    n: int
    blocks: tuple[tuple[np.ndarray, np.ndarray], ...]

    @functools.cached_property
    def _by_size(self) -> list[tuple[np.ndarray, np.ndarray]]:
        """Per block size b: (rows (m, b), blocks (m, b, b)) of the m blocks of that size."""
        sizes: dict[int, list[int]] = {}
        for k, (rows, _) in enumerate(self.blocks):
            sizes.setdefault(len(rows), []).append(k)
        return [
            (
                np.array([self.blocks[k][0] for k in ks], dtype=np.intp).reshape(len(ks), b),
                np.array([self.blocks[k][1] for k in ks], dtype=np.float64).reshape(len(ks), b, b),
            )
            for b, ks in sorted(sizes.items())
        ]

    @functools.cached_property
    def _index(self) -> dict[int, int]:
        """First row of a block -> its position in ``blocks``."""
        return {int(rows[0]): k for k, (rows, _) in enumerate(self.blocks)}

    def _per_block(self, a: np.ndarray, op: str) -> np.ndarray:
        a = np.asarray(a, dtype=np.float64)
        if a.shape[0] != self.n:
            raise ValueError(f"whitener of {self.n} rows applied to {a.shape[0]} rows")
        flat = a.ndim == 1
        a2 = a[:, None] if flat else a.reshape(self.n, -1)
        out = np.zeros_like(a2)
        for rows, w in self._by_size:
            part = a2[rows]  # (m, b, k)
            if op == "apply":
                out[rows] = w @ part
            elif op == "solve_t":
                out[rows] = np.linalg.solve(np.swapaxes(w, 1, 2), part)
            else:
                out[rows] = np.linalg.solve(w, part)
        return out[:, 0] if flat else out.reshape(a.shape)

    def apply(self, a: np.ndarray) -> np.ndarray:
        """W·a for ``a`` (n,) or (n, k)."""
        return self._per_block(a, "apply")

    def solve_t(self, a: np.ndarray) -> np.ndarray:
        """W⁻ᵀ·a for ``a`` (n,) or (n, k)."""
        return self._per_block(a, "solve_t")

    def inv_apply(self, a: np.ndarray) -> np.ndarray:
        """W⁻¹·a for ``a`` (n,) or (n, k): whitened values back to the rows."""
        return self._per_block(a, "inv_apply")

    def block(self, rows: np.ndarray) -> np.ndarray:
        """The block (b, b) of W of the rows ``rows`` (one group's, in its order)."""
        rows = np.asarray(rows, dtype=np.intp)
        k = self._index.get(int(rows[0]), -1) if len(rows) else -1
        if k < 0 or not np.array_equal(self.blocks[k][0], rows):
            raise ValueError(f"rows {rows.tolist()} are not one block of this whitener")
        return self.blocks[k][1]

    def with_block(self, rows: np.ndarray, w_block: np.ndarray) -> Whitener:
        """A copy with the block of the rows ``rows`` (one group's, in its order) replaced by
        ``w_block`` (b, b)."""
        rows = np.asarray(rows, dtype=np.intp)
        k = self._index.get(int(rows[0]), -1) if len(rows) else -1
        if k < 0 or not np.array_equal(self.blocks[k][0], rows):
            raise ValueError(f"rows {rows.tolist()} are not one block of this whitener")
        w_block = np.asarray(w_block, dtype=np.float64).reshape(len(rows), len(rows))
        blocks = list(self.blocks)
        blocks[k] = (rows, w_block.copy())
        return Whitener(self.n, tuple(blocks))

    def dense(self) -> np.ndarray:
        """The whole W (n, n): for tests and tiny sessions only (memory n²)."""
        out = np.zeros((self.n, self.n))
        for rows, w in self.blocks:
            out[np.ix_(rows, rows)] = w
        return out


def _whiten_exact(
    record: int,
    sensor: str,
    axis: int,
    idx: Sequence[int],
    cov: np.ndarray,
) -> tuple[Group, np.ndarray]:
    """Whiten the rows ``idx`` of one record and channel exactly when their variances differ
    or they are correlated (still moments and moving blocks of a turn): ``cov`` their
    covariance, W = L⁻¹ with L its Cholesky factor; -> (the :class:`Group`, its block of W)."""
    b = len(idx)
    if not np.all(np.diag(cov) > 0.0):
        raise UserError(
            f"record {record}: accel {'xyz'[axis]} reads the same value in every sample while "
            "turning (noise-free data): give a floor, e.g. --floor accel=1e-4,gyro=1e-3"
        )
    w = np.linalg.inv(np.linalg.cholesky(cov))
    v_mean = float(np.sum(cov)) / b**2
    group = Group(
        record, sensor, axis, np.array(idx), math.sqrt(v_mean), float(np.mean(np.diag(cov)))
    )
    return group, w


def _within_record_inflation(
    channels: Sequence[ChannelRows],
    signals: Sequence[RecordSignals],
    y: np.ndarray,
    counts_of: Callable[[np.ndarray], np.ndarray],
) -> dict[tuple[str, int], float]:
    """Within-record wander per (sensor, axis): the pooled excess scatter of the static
    records' block means over their white noise (1 unless resolved); ``counts_of``: the
    samples in each row of an aggregator."""
    excess: dict[tuple[str, int], list[float]] = {}
    for ch in channels:
        idx = ch.rows
        if len(idx) >= 2 and signals[ch.record].kind != "turn":
            agg = ch.aggregator
            m = agg.sum(axis=1)  # ones
            counts = counts_of(agg)
            v_b = ch.white / counts * m
            yb = y[idx]
            chi = float(np.sum((yb - yb.mean()) ** 2 / v_b))
            excess.setdefault((ch.sensor, ch.axis), []).extend([chi, len(idx) - 1])
    out: dict[tuple[str, int], float] = {}
    for k, v in excess.items():
        chi2, dof = sum(v[0::2]), sum(v[1::2])
        # only a scatter the white noise cannot explain (ALPHA_COMPONENT) widens the
        # contrasts: max(1, χ²/dof) would widen them under the null in half of all sessions
        out[k] = chi2 / dof if dof > 0 and chi2_sf(chi2, dof) < ALPHA_COMPONENT else 1.0
    return out


def _integral_group(
    ch: ChannelRows,
    floor: float,
    static_noise: Mapping[tuple[str, int], Sequence[tuple[float, float]]],
    turn_sigma: float,
) -> tuple[Group, np.ndarray]:
    """A turn's gyro integral, one row: the static records' white noise integrated, the floor
    over the turn's duration T and the hand's error ``turn_sigma`` (°: its angle error on the
    up channel, its wobble on the others); -> (the :class:`Group`, its block of W (1, 1))."""
    idx, w = ch.rows, ch.aggregator[0]
    levels = static_noise.get((ch.sensor, ch.axis), [(0.0, 1.0)])
    v_white = float(np.mean([v * t for v, t in levels]))
    T = float(w.sum())
    var = v_white * float(w @ w) + (floor * T) ** 2 + turn_sigma**2
    group = Group(ch.record, ch.sensor, ch.axis, np.array(idx), math.sqrt(var), math.nan)
    return group, np.array([[1.0 / math.sqrt(var)]])


def helmert_contrasts(b: int) -> np.ndarray:
    """(b − 1, b) the orthonormal Helmert contrasts of ``b`` values: row k − 1 is
    (1, …, 1, −k, 0, …, 0)/√(k + k²), k ones (each orthogonal to the mean and to the others)."""
    k = np.arange(1, b)
    h = np.tri(b - 1, b)  # ones left of and on the diagonal: k ones in row k − 1
    h[k - 1, k] = -k
    return h / np.sqrt(k + k * k)[:, None]


def _block_group(
    ch: ChannelRows,
    sig: RecordSignals,
    v_blocks: np.ndarray,
    floor: float,
    inflate: float,
    contrasts: np.ndarray,
) -> tuple[Group, np.ndarray]:
    """Block means of a static record, or a turn's still moments (variances ``v_blocks`` of
    each block mean): their mean and orthonormal Helmert contrasts (``contrasts``,
    :func:`helmert_contrasts` of their number); -> (the :class:`Group`, its block of W)."""
    idx, s, ax = ch.rows, ch.sensor, ch.axis
    b = len(idx)
    v_mean = float(np.sum(v_blocks)) / b**2 + floor**2
    if not v_mean > 0.0:
        raise UserError(
            f"{sig.name}: {s} {'xyz'[ax]} reads the same value in every sample "
            "(noise-free data, or a stuck sensor): the fit weighs each record by its "
            "noise; give a floor, e.g. --floor accel=1e-4,gyro=1e-3 (m/s², °/s), or check "
            "the sensor"
        )
    w = np.zeros((b, b))
    w[0] = (1.0 / b) / math.sqrt(v_mean)
    turn = sig.kind == "turn"  # still moments: their spread is the signal
    v_c = float(np.mean(v_blocks)) * (1.0 if turn else inflate)
    if not v_c > 0.0:  # noise-free samples (with a given floor): the only scale there is
        v_c = v_mean
    if b >= 2:
        w[1:] = contrasts / math.sqrt(v_c)
    return Group(ch.record, s, ax, np.array(idx), math.sqrt(v_mean), v_c), w


@dataclass(frozen=True, eq=False)
class RowNoise:
    """What the rows' covariance is made of beyond each channel's own white noise: ``floors``
    the bias-instability floor per sensor (m/s², °/s), ``white_level`` (sensor, axis) ->
    variance·τ of one sample from the static records (``static_noise`` their levels per
    record), ``n_still`` turn record -> how many of its accelerometer rows are still moments,
    ``seat`` and ``hand`` the seating and the hand's scatter (m/s², :mod:`host.model.rows`),
    ``turn_sigma`` the hand's turn-angle error and its wobble on the cross axes (°,
    :mod:`host.model.variance`); ``free_levels`` (record, axis) of the accelerometer channels
    whose rows' common level is an unknown of its own (:data:`FREE_LEVEL_RAD`, ``g`` m/s²)."""

    floors: Mapping[str, float]
    static_noise: Mapping[tuple[str, int], Sequence[tuple[float, float]]]
    white_level: Mapping[tuple[str, int], float]
    n_still: Mapping[int, int]
    seat: float
    hand: tuple[float, float]
    turn_sigma: tuple[float, float]
    free_levels: Collection[tuple[int, int]] = ()
    g: float = 9.80665


class _Shared:
    """What one whitening reads more than once: the samples in each row of an aggregator
    (shared by a record's channels) and the Helmert contrasts of b blocks."""

    def __init__(self) -> None:
        self._samples: dict[int, np.ndarray] = {}
        self._contrasts: dict[int, np.ndarray] = {}

    def counts_of(self, agg: np.ndarray) -> np.ndarray:
        """(B,) the samples in each row of ``agg`` (B, N)."""
        if id(agg) not in self._samples:
            self._samples[id(agg)] = np.count_nonzero(agg, axis=1)
        return self._samples[id(agg)]

    def contrasts(self, b: int) -> np.ndarray:
        """:func:`helmert_contrasts` of ``b`` blocks ((0, b) for fewer than two)."""
        if b not in self._contrasts:
            self._contrasts[b] = helmert_contrasts(b) if b >= 2 else np.zeros((0, b))
        return self._contrasts[b]


def _moving_group(
    ch: ChannelRows, v_blocks: np.ndarray, ns: int, level: float, counts: np.ndarray,
    floor: float, noise: RowNoise,
) -> tuple[Group, np.ndarray]:  # fmt: skip
    """A turn's accelerometer rows with moving blocks after its ``ns`` still moments, or a
    level left free (:data:`FREE_LEVEL_RAD`): each moving block the sensor's white noise (the
    static records' ``level``) and the hand, correlated, whitened exactly."""
    idx, ax = ch.rows, ch.axis
    free = ch.sensor == "accel" and (ch.record, ax) in noise.free_levels
    v_blocks[ns:] = level / counts[ns:]
    cov = np.diag(v_blocks) + floor**2
    cov[ns:, ns:] += turning.hand_covariance(noise.hand[0], noise.hand[1], len(idx) - ns)
    if not free:
        return _whiten_exact(ch.record, ch.sensor, ax, idx, cov)
    own, _ = _whiten_exact(ch.record, ch.sensor, ax, idx, cov)
    _, w = _whiten_exact(ch.record, ch.sensor, ax, idx, cov + (noise.g * FREE_LEVEL_RAD) ** 2)
    return dataclasses.replace(own, free_level=True), w


def _channel_group(
    ch: ChannelRows, sig: RecordSignals, noise: RowNoise, inflate: float, shared: _Shared
) -> tuple[Group, np.ndarray]:
    """The :class:`Group` of one record and channel and its block of W: a turn's gyro
    integral, a turn's accelerometer rows, or block means (``inflate``: the within-record
    wander of the channel, :func:`_within_record_inflation`)."""
    s, ax, idx = ch.sensor, ch.axis, ch.rows
    floor = noise.floors[s]
    if sig.kind == "turn" and s == "gyro":
        on_up = abs(float(sig.up[ax])) > 0.5
        by_hand = noise.turn_sigma[0] if on_up else noise.turn_sigma[1]
        return _integral_group(ch, floor, noise.static_noise, by_hand)
    counts = shared.counts_of(ch.aggregator).astype(float)
    level = noise.white_level.get((s, ax), 0.0)
    # each block mean: the channel's own white noise, else the static records' level
    v_blocks = (ch.white if math.isfinite(ch.white) else level) / counts
    horizontal = abs(float(sig.up[ax])) < 0.5
    ns = noise.n_still.get(ch.record, len(idx)) if sig.kind == "turn" else len(idx)
    if sig.kind == "turn" and horizontal:
        v_blocks[:ns] = v_blocks[:ns] + noise.seat**2  # a horizontal channel at a still moment
    free = s == "accel" and (ch.record, ax) in noise.free_levels
    if ns < len(idx) or free:
        return _moving_group(ch, v_blocks, ns, level, counts, floor, noise)
    return _block_group(ch, sig, v_blocks, floor, inflate, shared.contrasts(len(idx)))


def whiten_rows(
    channels: Sequence[ChannelRows],
    signals: Sequence[RecordSignals],
    y: np.ndarray,
    noise: RowNoise,
) -> tuple[Whitener, list[Group]]:
    """(W (n, n) as its blocks, the groups) for the rows ``y`` (n,) built as ``channels``, with
    the noise beyond each channel's own white noise ``noise``."""
    shared = _Shared()
    inflate = _within_record_inflation(channels, signals, y, shared.counts_of)
    groups: list[Group] = []
    blocks: list[tuple[np.ndarray, np.ndarray]] = []
    for ch in channels:
        group, w = _channel_group(
            ch, signals[ch.record], noise, inflate.get((ch.sensor, ch.axis), 1.0), shared
        )
        groups.append(group)
        blocks.append((group.rows, w))
    return Whitener(len(y), tuple(blocks)), groups
