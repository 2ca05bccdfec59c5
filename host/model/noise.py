"""How uncertain each row is: the noise model (:class:`NoiseModel`, method.md §8 "residual mean
near 0") and the noise levels a session measures of itself.

The rows of one record and channel share one covariance ``v·I + f²·11ᵀ``: ``v`` = variance of a
block mean from the record's own samples (pooled within-block variance × integrated
autocorrelation time, at least the quantisation step²/12), ``f`` = the bias-instability floor:
the slow wander of a MEMS bias, from the unit's noise file (``--noise``) or ``--floor``, else
from the records' own samples (:func:`wander_floor`, :func:`session_floor`) — never from the
misfit, so that a drift or a step between records shows as misfit. Turn integrals: white noise
integrated + (floor·T)² + the hand's angle error (``turn_angle_sigma_deg``: given by the user,
else measured from the closure of the turns made both ways, :mod:`host.model.variance`).
The still moments of a turn add the cube's seating, its moving blocks the hand
(:mod:`host.model.rows`, :mod:`host.model.turning`). A step inside a static record is neither
noise nor wander: where its samples show one (:func:`inner_step`), the record's blocks are cut
there and its white noise read about the two levels (:func:`host.model.rows.block_means`), and
the floor leaves that record's channel out.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from host.model.signals import SENSORS, UNIT, true_runs
from host.model.stats import beyond_white, chi2_sf, least_beyond_white


# ---- noise model ----------------------------------------------------------------------------
@dataclass(frozen=True)
class NoiseModel:
    """How uncertain each row is (see the module docstring).

    ``block_s``: length of the blocks static records are cut into, s (at most ``max_blocks``);
    ``floor``: bias-instability floor per sensor (m/s², °/s): the std of a record's mean bias
    wander of a record mean. Not given: from the records' own samples (:func:`wander_floor`);
    ``turn_angle_sigma_deg``: the hand's angle error per turn (method.md §4), °, as the user
    knows it; None (default): measured from the closure of the repeated turns
    (:func:`host.model.variance.turn_angle_sigma`), never assumed.
    """

    block_s: float = 5.0
    max_blocks: int = 6
    #: per sensor; a sensor not given is measured from the records (:func:`wander_floor`)
    floor: Mapping[str, float] = field(default_factory=dict)
    turn_angle_sigma_deg: float | None = None
    max_lag: int = 30


#: a still moment inside a turn record lasts at least this long, s, after :data:`STILL_TRIM_S`
#: is cut at each end (the hand letting go / taking hold)
STILL_MIN_S = 0.1
STILL_TRIM_S = 0.05


def still_runs(
    rate_up_dps: np.ndarray,
    t_s: np.ndarray,
    sigma_dps: float,
    *,
    trim_s: float | None = None,
    min_s: float | None = None,
) -> list[tuple[int, int]]:
    """[start, stop) index ranges where the cube rests inside a turn record: the rate about the
    up axis ``rate_up_dps`` (N,) °/s (static bias removed) stays within 4·``sigma_dps`` (the
    gyro's per-sample noise, °/s) of zero; ``trim_s`` (default :data:`STILL_TRIM_S`) s cut at
    each end, at least ``min_s`` (:data:`STILL_MIN_S`) s left (times ``t_s`` (N,) s)."""
    trim = STILL_TRIM_S if trim_s is None else trim_s
    least = STILL_MIN_S if min_s is None else min_s
    still = np.abs(rate_up_dps) < 4.0 * max(sigma_dps, 1e-6)
    out: list[tuple[int, int]] = []
    for i, j in true_runs(still):
        a = int(np.searchsorted(t_s, t_s[i] + trim))
        b = int(np.searchsorted(t_s, t_s[j - 1] - trim, side="right"))
        if b - a >= 4 and t_s[b - 1] - t_s[a] >= least:
            out.append((a, b))
    return out


def resolution(x: np.ndarray) -> float:
    """Smallest step between distinct values of ``x`` (its quantisation), 0 if constant."""
    u = np.unique(x)
    if len(u) < 2:
        return 0.0
    d = np.diff(u)
    return float(np.min(d[d > 1e-12])) if np.any(d > 1e-12) else 0.0


def integrated_autocorrelation(dev: np.ndarray | Sequence[np.ndarray], max_lag: int) -> float:
    """1 + 2·Σρ_k of the deviations ``dev`` (one array (N,), or several runs of one channel
    pooled: the lag products are summed within each run), summed while ρ_k stays beyond two
    standard errors of a white sequence's (2/√N): the variance of a mean of m samples is
    σ²·τ/m (clipped to 1 … 50). A white sequence gives τ = 1 in 98 % of cases; summing until
    ρ_k first drops to ≤ 0 would add the noise of ρ_1 … (≈ 0.8/√N on average) and widen every
    record mean's σ, so that χ² under the null runs low."""
    runs = (
        [np.asarray(dev, dtype=np.float64)]
        if isinstance(dev, np.ndarray)
        else [np.asarray(d, dtype=np.float64) for d in dev]
    )
    runs = [d for d in runs if len(d) >= 2]
    n = sum(len(d) for d in runs)
    ss = sum(float(d @ d) for d in runs)
    if n < 4 or ss <= 0:
        return 1.0
    longest = max(len(d) for d in runs)
    tau = 1.0
    for k in range(1, min(max_lag, longest // 4) + 1):
        rho = sum(float(d[k:] @ d[:-k]) for d in runs if len(d) > k) / ss
        if rho <= 2.0 / math.sqrt(n):
            break
        tau += 2.0 * rho
    return float(min(max(tau, 1.0), 50.0))


#: a step inside a static record is looked for with at least this many samples a side
INNER_STEP_MIN = 8
#: the level a step inside one static record's channel is taken at, over every cut of it: a
#: session has some 40 static channels, so white noise shows one in about one session of
#: 25 000; a step of the plan's least size (0.02 m/s², 0.05 °/s: twice a sample's noise) at
#: 15 % of a 10 s record is p ≈ 1e-25 there
INNER_STEP_ALPHA = 1e-6


def inner_step(x: np.ndarray, max_lag: int) -> int | None:
    """The sample a bias step inside one static record's channel ``x`` (N,) starts at, when
    the records' own samples show one: the best cut of ``x`` into two levels, its between-level
    sum of squares over the variance of a mean of the pieces' deviations (their own serial
    correlation taken in), beyond chance over every cut (Bonferroni at
    :data:`INNER_STEP_ALPHA`); else None. A step there is an effect for the
    model to show, not noise: read as noise it widens the record's σ, the channel's τ and the
    session's floor until the step's own misfit is within them (a step inside the first record,
    whose level the pair's scale and the misalignments take, then shows nowhere else)."""
    n = len(x)
    if n < 4 * INNER_STEP_MIN:
        return None
    k = np.arange(INNER_STEP_MIN, n - INNER_STEP_MIN + 1, dtype=float)
    csum = np.cumsum(x - x.mean())
    between = csum[INNER_STEP_MIN - 1 : n - INNER_STEP_MIN] ** 2 * n / (k * (n - k))
    cut = int(np.argmax(between)) + INNER_STEP_MIN
    pieces = [x[:cut] - x[:cut].mean(), x[cut:] - x[cut:].mean()]
    dev = np.concatenate(pieces)
    var = float(dev @ dev) / (n - 2)
    if var <= 0.0:
        return None
    tau = integrated_autocorrelation(pieces, max_lag)
    p = chi2_sf(float(between[cut - INNER_STEP_MIN]) / (var * tau), 1) * len(k)
    return cut if p < INNER_STEP_ALPHA else None


#: what the static records' block means may follow inside a record that is an effect, not
#: wander: the chip's temperature and the time (a temperature bias, a drift)
SHAPES = ("temperature", "time")


def wander_floor(
    blocks: Sequence[tuple[np.ndarray, np.ndarray]],
    shapes: Sequence[tuple[int, np.ndarray]] | None = None,
) -> tuple[float, int, float]:
    """The bias wander a record's own samples show, from the block means of the static records:
    ``blocks`` per record and channel (means (B,), their white-noise variances (B,)). A block
    mean that wanders by f about its record's level scatters by v_b + f², so
    E[Σ(y_b − ȳ)²] = (1 − 1/B)·Σ(v_b + f²) and f² = Σ[SS − (1 − 1/B)·Σv_b] / Σ(1 − 1/B)·B
    (the Allan variance at the block length less its white part, pooled over the records).
    ``shapes``, one per entry of ``blocks``: its channel and what its blocks were read at
    ((B, k): their mean temperature and time, :data:`SHAPES`). A bias that follows them across
    the blocks of every record of a channel alike (a temperature bias, a drift) is an effect,
    and the larger it is the more it would raise a floor read from the raw scatter (and lower
    the misfit it should show): per channel the blocks' departures are first fitted by those
    shapes, and f is read from what is left, their k dof taken off.
    -> (f ≥ 0 in the channel's unit, 0 unless the scatter is beyond the white noise at
    p < :data:`~host.model.stats.ALPHA_COMPONENT`; dof; the smallest f it would resolve, in
    the channel's unit). A drift or a step between records does not enter either."""
    ss, white, dof, var_se, taken = 0.0, 0.0, 0, 0.0, 0
    by_channel: dict[int, list[tuple[np.ndarray, np.ndarray]]] = {}
    for i, (y, v) in enumerate(blocks):
        b = len(y)
        if b < 2:
            continue
        white += (1.0 - 1.0 / b) * float(np.sum(v))
        dof += b - 1
        var_se += 2.0 * (b - 1) * float(np.mean(v)) ** 2
        if shapes is None:
            ss += float(np.sum((y - y.mean()) ** 2))
            continue
        channel, x = shapes[i]
        by_channel.setdefault(channel, []).append((y - y.mean(), x - x.mean(axis=0)))
    for parts in by_channel.values():
        resid, k = _without_shapes(parts)
        ss += resid
        taken += k
    if dof - taken <= 0:
        return 0.0, 0, math.nan
    keep = (dof - taken) / dof  # the white part the shapes' fit leaves, in expectation
    white, var_se, dof = white * keep, var_se * keep, dof - taken
    f2 = (ss - white) / dof
    least = math.sqrt(max(least_beyond_white(white, var_se) - white, 0.0) / dof)
    # a wander the blocks do not resolve (:func:`host.model.stats.beyond_white`) is taken as
    # none: a clipped estimate of 0 ± se would always widen the yardstick a little, and one
    # resolved by chance widens it in that session
    return (math.sqrt(f2) if beyond_white(ss, white, var_se) else 0.0), dof, least


def _without_shapes(parts: Sequence[tuple[np.ndarray, np.ndarray]]) -> tuple[float, int]:
    """Σ of squares of one channel's block departures (each record's, about its mean) left
    after fitting them by the shapes' departures (one coefficient each for every record of the
    channel), and how many coefficients that took (the shapes' rank)."""
    y = np.concatenate([p[0] for p in parts])
    x = np.concatenate([p[1] for p in parts])
    scale = np.linalg.norm(x, axis=0)
    x = x[:, scale > 0] / scale[scale > 0]
    if not x.shape[1]:
        return float(y @ y), 0
    beta, _, rank, _ = np.linalg.lstsq(x, y, rcond=1e-9)
    r = y - x @ beta
    return float(r @ r), int(rank)


def session_floor(
    blocks: Mapping[str, Sequence[tuple[np.ndarray, np.ndarray, int, np.ndarray]]],
    nm: NoiseModel,
) -> tuple[dict[str, float], str]:
    """The floor per sensor (m/s², °/s) and a note saying where it came from: ``nm.floor`` where
    given (``--floor``, ``--noise``: the unit's Allan variance), else from the records' own
    samples (:func:`wander_floor` over ``blocks``: sensor -> the static records' block means,
    their white variances, the channel and the blocks' :data:`SHAPES`). Never from repeated
    attitudes: a slow effect between two measurements of one attitude (a drift, a step, a
    temperature bias) is misfit for the model and the workbench to see, not noise to widen the
    yardstick with."""
    out: dict[str, float] = {}
    said: list[str] = []
    for s in SENSORS:
        if s in nm.floor:
            out[s] = float(nm.floor[s])
            said.append(f"{s} {out[s]:.2g} {UNIT[s]} (given)")
            continue
        entries = blocks.get(s, ())
        f, dof, least = wander_floor([e[:2] for e in entries],
                                     [(e[2], e[3]) for e in entries])  # fmt: skip
        out[s] = f
        if dof == 0:
            said.append(f"{s} 0 (no record long enough for two blocks: white noise only)")
            continue
        said.append(
            f"{s} {f:.2g} {UNIT[s]} (wander of the static records' block means beyond their "
            f"white noise and what follows the temperature or the time inside every record, "
            f"{dof} dof; none resolved below {least:.2g})"
        )
    return out, (
        "noise floor of a record mean, from each record's own samples (white noise with its "
        "serial correlation, plus " + "; ".join(said) + ")"
    )
