"""The whitening of a dataset's rows: per record and channel a :class:`Group` and its block of
W with W·Cov·Wᵀ = I (:func:`whiten_rows`), so that χ² is honest under the null.

The rows of one record and channel share one covariance ``v·I + f²·11ᵀ`` (:mod:`host.model.noise`)
and are whitened exactly as their mean and orthonormal (Helmert) contrasts; a turn's gyro
integral is one row; the accelerometer rows of a turn whose still moments and moving blocks
differ in variance and are correlated (the hand) are whitened through their Cholesky factor.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from host.errors import UserError
from host.model import turning
from host.model.rows import ChannelRows
from host.model.signals import RecordSignals
from host.model.stats import chi2_sf


@dataclass(frozen=True, eq=False)
class Group:
    """The rows of one record and channel: ``rows`` indices; ``sigma`` = std of their mean
    (static: block-mean average; turn: the integral); ``contrast_sigma`` = std of a block's
    deviation from the record's mean (NaN for one row)."""

    record: int
    sensor: str
    axis: int
    rows: np.ndarray
    sigma: float
    contrast_var: float


def _whiten_exact(
    whiten: np.ndarray,
    record: int,
    sensor: str,
    axis: int,
    idx: Sequence[int],
    cov: np.ndarray,
) -> Group:
    """Whiten the rows ``idx`` of one record and channel exactly when their variances differ
    or they are correlated (still moments and moving blocks of a turn): ``cov`` their
    covariance, W = L⁻¹ with L its Cholesky factor, written into ``whiten``; -> the
    :class:`Group`."""
    b = len(idx)
    if not np.all(np.diag(cov) > 0.0):
        raise UserError(
            f"record {record}: accel {'xyz'[axis]} reads the same value in every sample while "
            "turning (noise-free data): give a floor, e.g. --floor accel=1e-4,gyro=1e-3"
        )
    w = np.linalg.inv(np.linalg.cholesky(cov))
    whiten[np.ix_(list(idx), list(idx))] = w
    v_mean = float(np.sum(cov)) / b**2
    return Group(
        record, sensor, axis, np.array(idx), math.sqrt(v_mean), float(np.mean(np.diag(cov)))
    )


def _within_record_inflation(
    channels: Sequence[ChannelRows], signals: Sequence[RecordSignals], y: np.ndarray
) -> dict[tuple[str, int], float]:
    """Within-record wander per (sensor, axis): the pooled excess scatter of the static
    records' block means over their white noise (1 unless resolved)."""
    excess: dict[tuple[str, int], list[float]] = {}
    for ch in channels:
        idx = ch.rows
        if len(idx) >= 2 and signals[ch.record].kind != "turn":
            agg = ch.aggregator
            m = agg.sum(axis=1)  # ones
            counts = np.count_nonzero(agg, axis=1)
            v_b = ch.white / counts * m
            yb = y[idx]
            chi = float(np.sum((yb - yb.mean()) ** 2 / v_b))
            excess.setdefault((ch.sensor, ch.axis), []).extend([chi, len(idx) - 1])
    out: dict[tuple[str, int], float] = {}
    for k, v in excess.items():
        chi2, dof = sum(v[0::2]), sum(v[1::2])
        # only a scatter the white noise cannot explain (p < 2.5 %) widens the contrasts:
        # max(1, χ²/dof) would widen them under the null in half of all sessions
        out[k] = chi2 / dof if dof > 0 and chi2_sf(chi2, dof) < 0.025 else 1.0
    return out


def _integral_group(
    whiten: np.ndarray,
    ch: ChannelRows,
    floor: float,
    static_noise: Mapping[tuple[str, int], Sequence[tuple[float, float]]],
    turn_sigma: float,
) -> Group:
    """A turn's gyro integral, one row: the static records' white noise integrated, the floor
    over the turn's duration T and the hand's error ``turn_sigma`` (°: its angle error on the
    up channel, its wobble on the others)."""
    idx, w = ch.rows, ch.aggregator[0]
    levels = static_noise.get((ch.sensor, ch.axis), [(0.0, 1.0)])
    v_white = float(np.mean([v * t for v, t in levels]))
    T = float(w.sum())
    var = v_white * float(w @ w) + (floor * T) ** 2 + turn_sigma**2
    whiten[idx[0], idx[0]] = 1.0 / math.sqrt(var)
    return Group(ch.record, ch.sensor, ch.axis, np.array(idx), math.sqrt(var), math.nan)


def _block_group(
    whiten: np.ndarray,
    ch: ChannelRows,
    sig: RecordSignals,
    v_blocks: np.ndarray,
    floor: float,
    inflate: float,
) -> Group:
    """Block means of a static record, or a turn's still moments (variances ``v_blocks`` of
    each block mean): their mean and orthonormal Helmert contrasts."""
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
    whiten[idx[0], idx] = (1.0 / b) / math.sqrt(v_mean)
    turn = sig.kind == "turn"  # still moments: their spread is the signal
    v_c = float(np.mean(v_blocks)) * (1.0 if turn else inflate)
    if not v_c > 0.0:  # noise-free samples (with a given floor): the only scale there is
        v_c = v_mean
    if b >= 2:
        # orthonormal Helmert contrasts of the b blocks
        for k in range(1, b):
            h = np.zeros(b)
            h[:k] = 1.0
            h[k] = -float(k)
            h /= np.linalg.norm(h)
            whiten[idx[k], idx] = h / math.sqrt(v_c)
    return Group(ch.record, s, ax, np.array(idx), math.sqrt(v_mean), v_c)


def whiten_rows(
    channels: Sequence[ChannelRows],
    signals: Sequence[RecordSignals],
    y: np.ndarray,
    *,
    floors: Mapping[str, float],
    static_noise: Mapping[tuple[str, int], Sequence[tuple[float, float]]],
    white_level: Mapping[tuple[str, int], float],
    n_still: Mapping[int, int],
    seat: float,
    hand: tuple[float, float],
    turn_sigma: tuple[float, float],
) -> tuple[np.ndarray, list[Group]]:
    """(W (n, n), the groups) for the rows ``y`` (n,) built as ``channels``: ``floors`` the
    bias-instability floor per sensor, ``white_level`` (sensor, axis) -> variance·τ of one
    sample from the static records (``static_noise`` their levels per record), ``n_still``
    turn record -> how many of its accelerometer rows are still moments, ``seat`` and ``hand``
    the seating and the hand's scatter (m/s², :mod:`host.model.rows`), ``turn_sigma`` the
    hand's turn-angle error and its wobble on the cross axes (°, :mod:`host.model.variance`)."""
    n_rows = len(y)
    whiten = np.zeros((n_rows, n_rows))
    groups: list[Group] = []
    inflate = _within_record_inflation(channels, signals, y)
    for ch in channels:
        sig = signals[ch.record]
        s, ax, idx = ch.sensor, ch.axis, ch.rows
        floor = floors[s]
        if sig.kind == "turn" and s == "gyro":
            on_up = abs(float(sig.up[ax])) > 0.5
            by_hand = turn_sigma[0] if on_up else turn_sigma[1]
            groups.append(_integral_group(whiten, ch, floor, static_noise, by_hand))
            continue
        counts = np.count_nonzero(ch.aggregator, axis=1).astype(float)
        level = white_level.get((s, ax), 0.0)
        # each block mean: the channel's own white noise, else the static records' level
        v_blocks = (ch.white if math.isfinite(ch.white) else level) / counts
        horizontal = abs(float(sig.up[ax])) < 0.5
        ns = n_still.get(ch.record, len(idx)) if sig.kind == "turn" else len(idx)
        if sig.kind == "turn" and horizontal:
            v_blocks[:ns] = v_blocks[:ns] + seat**2  # a horizontal channel at a still moment
        if ns < len(idx):
            # moving blocks: the sensor's white noise (the static records' level) + the hand
            v_blocks[ns:] = level / counts[ns:]
            cov = np.diag(v_blocks) + floor**2
            cov[ns:, ns:] += turning.hand_covariance(hand[0], hand[1], len(idx) - ns)
            groups.append(_whiten_exact(whiten, ch.record, s, ax, idx, cov))
            continue
        groups.append(_block_group(whiten, ch, sig, v_blocks, floor, inflate.get((s, ax), 1.0)))
    return whiten, groups
