"""The accelerometer while the cube turns: the sensor's lever arm, the moving blocks, the hand.

Physics (rigid body; method.md §2 for the accelerometer model, §4 for the hand turns). The
accelerometer measures specific force at the point where the sensor sits. With the cube turning
about a fixed point O at angular rate ω (body frame, rad/s), the sensor at r (body frame, m,
from O) accelerates by

    a = ω̇ × r + ω × (ω × r)                                   (tangential + centripetal)

so that, beside gravity, each accelerometer channel i reads Σ_j M_ij(t)·r_j with

    M(t) = [ω̇]ₓ + [ω]ₓ[ω]ₓ = [ω̇]ₓ + ω·ωᵀ − |ω|²·I          ([v]ₓ: the cross-product matrix)

linear in r, read through the accelerometer's scale and misalignment A as gravity is
(:func:`sensed_lever_matrix`: A·M(t)·r). For a hand turn about the body axis k that points up
(ω = ω·e_k) only the two components of r perpendicular to k matter: the centripetal term is
−ω²·r⊥ (toward the axis), the tangential one ω̇·(e_k × r); the up channel reads neither.

Geometry assumption: every turn pivots about the vertical through the centre of the cube (the
operator turns the cube in place against the ruler), so ONE vector r — the sensor's offset from
the cube's centre, in body axes — explains every turn: each component of r is seen by the two
turns about the other axes, which is also the test of the assumption. Rate-table records turn
about the table's axis (another point): their rows are not read here.

Size of the signal: ω²·r = 0.12 m/s² at 90 °/s and r = 5 cm (3 mm at 1 cm and 30 °/s); the
hand's block means scatter by a few 0.01 m/s² (wobble tilts gravity by g·θ), so a turn at ≥ 60 °/s
resolves r to millimetres.

Rows (:func:`moving_blocks`): the turning parts of a turn record (the rate about up beyond its
noise) cut into blocks of :data:`BLOCK_S`; the accelerometer's block means are rows of the fit.
A block mean of ω² keeps the centripetal term (ω² > 0 on every sample); ω̇ averages to
(ω_end − ω_start)/T, so blocks shorter than one push also see the tangential term. Accelerometer
and gyro are sampled at the same instant by the MPU-6000 (its DLPF delays differ by < 1 ms,
which moves a 0.5 s block mean of ω² by < 0.3 %): no time alignment is needed.

Their noise (:func:`hand_scatter`): the white noise of the accelerometer plus the hand — the
cube wobbles and is pushed while it turns. That scatter is measured from the moving blocks
themselves: the scatter beyond a constant per turn and channel (bias, face error,
misalignment: fixed in the body), the lever arm and the plate tilt (the effects the rows are read
for), and beyond each block's white noise; and, apart, how far a turn's level while moving
departs from its level at rest (the still moments): a wobble has no net tilt, so a turn's
blocks scatter about a level that is nearly the resting one (σ_block·(I − 11ᵀ/n) +
σ_turn²·11ᵀ, :func:`hand_covariance`), not like independent blocks. The lever arm is in that
regression on purpose: the scatter it explains is signal, not noise (as the plate tilt for the
still moments' seating).
"""

from __future__ import annotations

import math
from collections.abc import Hashable, Mapping, Sequence

import numpy as np

from host.model.signals import true_runs
from host.model.stats import beyond_white

#: length of a moving block, s: shorter than a push (≈ 1 s) so the tangential term survives
BLOCK_S = 0.5
#: a turn whose moving samples' RMS rate is below this, °/s, shows no lever arm: ω²·r at
#: 30 °/s and 5 cm is 0.014 m/s², the hand's scatter of one block mean
MIN_RATE_DPS = 30.0
#: the fewest samples of a moving block
MIN_BLOCK_SAMPLES = 4
#: below this rate, °/s, the cube is at rest: the gyro's noise is not a rate (ω²·r at 1 °/s
#: and 10 cm is 3·10⁻⁵ m/s²), so M(t) is exactly 0 there
REST_DPS = 1.0


def angular_acceleration(t_s: np.ndarray, rate_dps: np.ndarray) -> np.ndarray:
    """(N, 3) ω̇ in rad/s² from the rate ``rate_dps`` (N, 3) °/s at times ``t_s`` (N,) s
    (central differences; one-sided at the ends; zeros for fewer than two distinct times).
    Samples sharing one time stamp (a logger stamping in 0.1 s steps) are averaged and the
    difference is taken over the distinct times: a zero step would divide by zero."""
    rate = np.radians(np.asarray(rate_dps, dtype=np.float64))
    t = np.asarray(t_s, dtype=np.float64)
    times, where = np.unique(t, return_inverse=True)
    if len(times) < 2:
        return np.zeros_like(rate)
    if len(times) == len(t) and np.all(np.diff(t) > 0):
        return derivative(t, rate)
    mean = np.zeros((len(times), rate.shape[1]))
    np.add.at(mean, where, rate)
    mean /= np.bincount(where, minlength=len(times))[:, None]
    return derivative(times, mean)[where]


def derivative(t: np.ndarray, y: np.ndarray) -> np.ndarray:
    """(N, k) dy/dt of ``y`` (N, k) at the increasing times ``t`` (N,): the derivative of the
    quartic through each sample and its two neighbours either side (error O(h⁴); np.gradient's
    differences at the two samples at either end). Central differences alone shrink a push's ω̇ by
    (ω·h)²/6 and misplace ω at a block's edge by h²·ω̈/8: at 50 Hz and 1 s pushes 0.3 % of the
    tangential term, a bias of the lever arm of several σ."""
    n = len(t)
    out = np.asarray(np.gradient(y, t, axis=0), dtype=np.float64)
    if n < 5:
        return out
    i = np.arange(2, n - 2)
    w = _centre_weights(np.stack([t[i + k] - t[i] for k in range(-2, 3)]))
    out[2 : n - 2] = sum(w[k][:, None] * y[i + k - 2] for k in range(5))
    return out


def _centre_weights(d: np.ndarray) -> np.ndarray:
    """(5, n) L_k'(0) of the Lagrange basis on the offsets ``d`` (5, n), d[2] = 0: over m ≠ k,
    den_k = Π (d_k − d_m) and num_k = Σ Π_{q ≠ k, m} (−d_q), the left-out factors set to 1.
    Every term of num_k (k ≠ 2) but m = 2 holds the factor −d_2 = 0, so that num_k =
    Π_{q ≠ k, 2} (−d_q), and num_2 is the sum of those over k ≠ 2: (5, 5, n) products, not
    (5, 5, 5, n), with every product and sum in the same order (the same numbers)."""
    same = np.eye(5, dtype=bool)
    diff = d[:, None, :] - d[None, :, :]
    diff[same] = 1.0
    neg = np.broadcast_to(-d, (5, 5, d.shape[1])).copy()  # [k, q]
    neg[same] = 1.0
    neg[:, 2] = 1.0
    num = np.prod(neg, axis=1)
    num[2] = ((num[0] + num[1]) + num[3]) + num[4]
    return np.asarray(num / np.prod(diff, axis=1))


def lever_arm_matrix(t_s: np.ndarray, rate_dps: np.ndarray) -> np.ndarray:
    """(N, 3, 3) M(t) = [ω̇]ₓ + [ω]ₓ[ω]ₓ (module docstring): the specific force the sensor
    reads, m/s², is M·r for a lever arm r in metres (body axes); rate ``rate_dps`` (N, 3) °/s
    at times ``t_s`` (N,) s. Exactly 0 at rest (|ω| < :data:`REST_DPS`)."""
    w = np.radians(np.asarray(rate_dps, dtype=np.float64))
    wd = angular_acceleration(t_s, rate_dps)
    m = np.zeros((len(w), 3, 3))
    # [ω̇]ₓ
    m[:, 0, 1], m[:, 0, 2] = -wd[:, 2], wd[:, 1]
    m[:, 1, 0], m[:, 1, 2] = wd[:, 2], -wd[:, 0]
    m[:, 2, 0], m[:, 2, 1] = -wd[:, 1], wd[:, 0]
    # [ω]ₓ[ω]ₓ = ω·ωᵀ − |ω|²·I
    m += w[:, :, None] * w[:, None, :]
    m -= np.sum(w * w, axis=1)[:, None, None] * np.eye(3)[None]
    m[at_rest(rate_dps)] = 0.0
    return m


def sensed_lever_matrix(
    t_s: np.ndarray, rate_dps: np.ndarray, accel_matrix: np.ndarray | None
) -> np.ndarray:
    """(N, 3, 3) A·M(t): what the accelerometer reads of the lever arm, m/s² per m — the
    turning force M(t)·r (:func:`lever_arm_matrix`) through the accelerometer's matrix
    ``accel_matrix`` A (3, 3; scale and misalignment as measured on the static records;
    None: the identity). A channel reads its own component of M·r times its scale and the
    others' times its misalignments: with ±1.5 % scales and ±10 mrad misalignments left out
    the lever arm came out up to 2 % off (several σ), the hand's scatter absorbing the rest."""
    m = lever_arm_matrix(t_s, rate_dps)
    if accel_matrix is None:
        return m
    return np.asarray(np.einsum("ij,njk->nik", np.asarray(accel_matrix, dtype=np.float64), m))


def at_rest(rate_dps: np.ndarray) -> np.ndarray:
    """(N,) bool: the cube is at rest at a sample of the rate ``rate_dps`` (N, 3) °/s — below
    :data:`REST_DPS` there AND at both neighbours, the samples its ω̇ is differenced from. A
    push starts from rest with ω ∝ τ² but ω̇ ∝ τ: its first sample turns at a fraction of
    1 °/s while the tangential term ω̇×r is already a tenth of its peak (2.5 rad/s² · 2.5 cm
    = 0.06 m/s²); zeroing M there by the rate alone left it out of every moving block that
    starts or ends a push, and the lever arm came out 0.3–2 % long (10σ)."""
    slow = np.linalg.norm(np.asarray(rate_dps, dtype=np.float64), axis=1) < REST_DPS
    rest = slow.copy()
    rest[1:] &= slow[:-1]
    rest[:-1] &= slow[1:]
    return rest


def moving_blocks(
    rate_up_dps: np.ndarray, t_s: np.ndarray, sigma_dps: float, block_s: float = BLOCK_S
) -> list[tuple[int, int]]:
    """[start, stop) index ranges of the turning parts of a turn record, cut into blocks of about
    ``block_s`` s: where the rate about the up axis ``rate_up_dps`` (N,) °/s (bias removed) is
    beyond 4·``sigma_dps`` (the gyro's per-sample noise, °/s), at times ``t_s`` (N,) s. A run
    of fewer than :data:`MIN_BLOCK_SAMPLES` samples is left out."""
    t = np.asarray(t_s, dtype=np.float64)
    moving = np.abs(np.asarray(rate_up_dps, dtype=np.float64)) >= 4.0 * max(sigma_dps, 1e-6)
    out: list[tuple[int, int]] = []
    for i, j in true_runs(moving):
        if j - i >= MIN_BLOCK_SAMPLES:
            length = float(t[j - 1] - t[i])
            k = max(1, min(round(length / block_s), (j - i) // MIN_BLOCK_SAMPLES))
            # from the run's own start: a tie (x.5) rounds the same wherever the record's
            # window begins (rounding i + x.5 to even flips with the parity of i)
            edges = i + np.linspace(0, j - i, k + 1).round().astype(int)
            out.extend((int(edges[b]), int(edges[b + 1])) for b in range(k))
    return out


def rms_rate_dps(rate_up_dps: np.ndarray, blocks: Sequence[tuple[int, int]]) -> float:
    """RMS of the rate ``rate_up_dps`` (N,) °/s over the samples of ``blocks`` (0 without)."""
    if not blocks:
        return 0.0
    r = np.concatenate([np.asarray(rate_up_dps)[a:b] for a, b in blocks])
    return float(np.sqrt(np.mean(r * r)))


def _constants_fit(
    y: np.ndarray, keys: Sequence[Hashable], columns: np.ndarray
) -> tuple[list[Hashable], np.ndarray, np.ndarray, np.ndarray, int]:
    """Least squares of ``y`` (K,) on a constant per key of ``keys`` (K,) plus the shared
    ``columns`` (K, m): -> (the keys in first-seen order, each value's position among them
    (K,), the coefficients (constants first), the residuals (K,), the degrees of freedom left;
    0 without values). The shared part is fitted to the values less their key's mean (the
    constants' fit, exactly), so memory and time grow with K, not with K times the keys."""
    yv = np.asarray(y, dtype=np.float64)
    pos: dict[Hashable, int] = {}
    idx = np.array([pos.setdefault(k, len(pos)) for k in keys], dtype=np.intp)
    uniq = list(pos)
    if len(yv) == 0:
        return uniq, idx, np.zeros(0), yv, 0
    cols = np.asarray(columns, dtype=np.float64).reshape(len(yv), -1)
    n = np.bincount(idx, minlength=len(uniq)).astype(float)
    y_mean = np.bincount(idx, weights=yv, minlength=len(uniq)) / n
    c_mean = np.stack(
        [np.bincount(idx, weights=c, minlength=len(uniq)) / n for c in cols.T], axis=1
    ) if cols.shape[1] else np.zeros((len(uniq), 0))  # fmt: skip
    yc = yv - y_mean[idx]
    xc = cols - c_mean[idx]
    shared, rank = np.zeros(cols.shape[1]), 0
    if cols.shape[1]:
        shared, _, rank, _ = np.linalg.lstsq(xc, yc, rcond=None)
    beta = np.concatenate([y_mean - c_mean @ shared, shared])
    return uniq, idx, beta, yc - xc @ shared, len(yv) - len(uniq) - int(rank)


def hand_scatter(
    y: np.ndarray,
    keys: Sequence[Hashable],
    columns: np.ndarray,
    white_var: np.ndarray,
    rest: Mapping[Hashable, tuple[float, float, np.ndarray]],
) -> tuple[float, float, int]:
    """The hand's scatter of the moving blocks: ``y`` (K,) block means, ``keys`` (K,) their
    turn and channel, ``columns`` (K, m) the shared regressors (lever arm, plate tilt),
    ``white_var`` (K,) each mean's white-noise variance; ``rest`` key -> (the mean of that
    turn's still moments, its variance, the shared regressors there (m,)). Least squares with
    a constant per key, then -> (σ_block, σ_turn, dof): σ_block² = Σ(r² − w)/dof, the scatter
    of a block about its turn's level; σ_turn² the scatter of a turn's level while moving about
    its level at rest (the constants against ``rest``, beyond their white noise; without
    ``rest`` σ_block). A fast wobble has no net tilt (σ_turn far below σ_block/√n), a slow
    one leaves some over a turn (σ_turn up to σ_block/√n). Each is 0 unless its scatter is
    beyond the white noise (:func:`resolved`)."""
    w = np.asarray(white_var, dtype=np.float64)
    uniq, idx, beta, r, dof = _constants_fit(y, keys, columns)
    if dof <= 0:
        return 0.0, 0.0, 0
    block2 = resolved(float(np.sum(r * r - w)) / dof, w, dof)
    shared = beta[len(uniq) :]
    d: list[float] = []
    v: list[float] = []
    n_of = np.bincount(idx, minlength=len(uniq))
    w_of = np.bincount(idx, weights=w, minlength=len(uniq)) / n_of
    for j, k in enumerate(uniq):
        if k not in rest:
            continue
        level, var0, cols0 = rest[k]
        d.append(float(beta[j]) - (level - float(np.asarray(cols0) @ shared)))
        # white noise only: σ_turn² is all the level's variance beyond it, so that the
        # covariance σ_block²·(I − 11ᵀ/n) + σ_turn²·11ᵀ holds the level's whole scatter
        # (a slow wobble's blocks do not average to no net tilt over one turn)
        v.append(var0 + float(w_of[j]) / float(n_of[j]))
    if not d:
        return math.sqrt(block2), math.sqrt(block2), dof
    dd, vv = np.array(d), np.array(v)
    turn2 = resolved(float(np.sum(dd * dd - vv)) / len(dd), vv, len(dd))
    return math.sqrt(block2), math.sqrt(turn2), dof


def resolved(var: float, white_var: np.ndarray, dof: int) -> float:
    """``var`` (an excess variance Σ(r² − w)/dof over values of white-noise variances
    ``white_var``) if that scatter is beyond the white noise
    (:func:`host.model.stats.beyond_white`: Σr² against Σw ± √(2·Σw²)), else 0: a clipped
    estimate max(0, ·) would be positive in half of all sessions without any excess and widen
    the yardstick there (χ² under the null runs low)."""
    if dof <= 0:
        return 0.0
    w = np.asarray(white_var, dtype=np.float64)
    white = float(np.sum(w))
    return var if beyond_white(var * dof + white, white, 2.0 * float(np.sum(w * w))) else 0.0


def hand_covariance(sigma_block: float, sigma_turn: float, n: int) -> np.ndarray:
    """(n, n) covariance of a turn's ``n`` moving blocks from :func:`hand_scatter`: each block
    scatters by ``sigma_block`` about the turn's level, the level by ``sigma_turn``:
    σ_block²·(I − 11ᵀ/n) + σ_turn²·11ᵀ, in y's unit²."""
    ones = np.ones((n, n))
    return np.asarray(sigma_block**2 * (np.eye(n) - ones / n) + sigma_turn**2 * ones)


def excess_scatter(
    y: np.ndarray,
    keys: Sequence[Hashable],
    columns: np.ndarray,
    white_var: np.ndarray,
) -> tuple[float, int]:
    """Scatter of values beyond their white noise and what explains them: ``y`` (K,) values,
    ``keys`` (K,) a constant per key (e.g. per turn and channel), ``columns`` (K, m) shared
    regressors (e.g. the lever arm, the plate tilt), ``white_var`` (K,) each value's white-noise
    variance. Least squares, then σ² = Σ(r² − w)/dof, 0 unless resolved (:func:`resolved`):
    -> (σ in y's unit, dof); (0, 0) when nothing is left over (dof ≤ 0)."""
    w = np.asarray(white_var, dtype=np.float64)
    _, _, _, r, dof = _constants_fit(y, keys, columns)
    if dof <= 0:
        return 0.0, 0
    return math.sqrt(resolved(float(np.sum(r * r - w)) / dof, w, dof)), dof
