"""The statistics of many calibrations: pure functions over numpy arrays (no archive, no I/O).

Every test here states its false-alarm rate, and the rate is a family-wise one: ``alpha`` is
the probability that one run of the command over a lot in which nothing is wrong flags
anything (Bonferroni over the ``m`` tests of the run: units × parameters, benches ×
parameters). The tests in ``tests/host/archive/test_stats.py`` simulate many null lots and
count the flagged fraction.

- Repeatability (:func:`repeatability`): the sessions of a unit on one bench scatter by the σ
  each fit reports, so Σ ((xᵢ − x̄_w)/σᵢ)² ~ χ²(n − 1) (x̄_w: the inverse-variance weighted
  mean); p below alpha/m flags the parameter. The coefficient of variation (scatter / |mean|)
  is given only where the parameter is far from zero (|x̄| ≥ :data:`CV_FAR_FROM_ZERO` × the
  predicted σ): near zero a CV means nothing (Gzz ≈ −0.0018 would need σ = 1.8e-5 for 1 %).
- Drift (:func:`drift_z`): between a unit's last two calibrations, z = Δ / √(σ₁² + σ₂²);
  |z| beyond the family-wise k, or |Δ| beyond a tolerance the user gives, flags it.
- Lot (:func:`lot_summary`, :func:`grubbs_outliers`): mean, spread (sample standard deviation)
  and mean ± 3·spread against the datasheet limit; outlier units by the two-sided Grubbs test
  (the exact critical value for normal data), repeated after removing each one found.
- Control charts (:func:`individuals_limits`, :func:`run_rules`): an individuals chart with
  σ from the mean moving range (MR̄/1.128) of a baseline, and the four Western Electric rules.
  In control, with known limits, a point fires rule 1 with probability 0.0027 (ARL 370) and
  any of the four rules after 91.75 points on average (Champ & Woodall 1987).
- Bench comparison (:func:`compare_benches`): the reference unit's weighted mean per bench
  against the weighted mean of the other benches, z = Δ/√(u_b² + u_ref²) and
  Eₙ = Δ / √(U_b² + U_ref²) with U = 2u (ISO 13528); the worst bench beyond the family-wise
  k is flagged and left out of the others' reference, then the rest are tested again.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: the family-wise false-alarm rate of one command run, unless the user says otherwise
DEFAULT_ALPHA = 0.01
#: a parameter is 'far from zero' (its CV means something) when |mean| ≥ this × predicted σ
CV_FAR_FROM_ZERO = 10.0
#: the seed's repeatability criterion for parameters far from zero: CV ≤ 1 %
CV_LIMIT = 0.01
#: moving-range constant d₂ for ranges of two
D2 = 1.128
#: in-control average run length of an individuals chart with known limits
ARL_RULE1 = 1.0 / math.erfc(3.0 / math.sqrt(2.0))  # 1 / (2 · P(z > 3))
ARL_WESTERN_ELECTRIC = 91.75


def family_z(alpha: float, m: int) -> float:
    """The two-sided z beyond which one of ``m`` tests fires, so that any of them fires with
    probability ≤ ``alpha`` when nothing is wrong (Bonferroni)."""
    from scipy import stats as sps  # scipy's import is a second: only where a figure needs it

    return float(sps.norm.isf(alpha / (2.0 * max(m, 1))))


# ---- repeatability ---------------------------------------------------------------------------
@dataclass(frozen=True)
class Repeatability:
    """Per group (e.g. unit × parameter; arrays of the leading shape): ``n`` sessions,
    weighted ``mean``, ``scatter`` (sample standard deviation between sessions), ``predicted``
    σ (RMS of the sessions' σ), ``chi2`` on ``dof`` = n − 1, its ``p`` (NaN for n < 2), and
    ``cv`` = scatter/|mean| where the mean is far from zero (else NaN). ``nu``: the second
    degrees of freedom of Welch's test where a session's σ is itself estimated (inf: every σ
    from the noise model alone, ``p`` the χ² tail), :func:`welch_p`."""

    n: np.ndarray
    mean: np.ndarray
    scatter: np.ndarray
    predicted: np.ndarray
    chi2: np.ndarray
    dof: np.ndarray
    p: np.ndarray
    cv: np.ndarray
    nu: np.ndarray


def welch_p(
    chi2: np.ndarray, w: np.ndarray, dofs: np.ndarray, n: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """(p, ν₂) of Welch's heteroscedastic test that ``n`` sessions share one value, from the
    weighted ``chi2`` = Σ w_i (x_i − x̄)² with weights ``w`` = 1/σ_i² (0: no session) whose σ_i
    are read on ``dofs`` degrees of freedom (along the last axis): with λ = Σ (1 − w_i/W)²/ν_i,
    F = χ²/(n − 1) / (1 + 2(n − 2)λ/(n² − 1)) on (n − 1, (n² − 1)/(3λ)) degrees of freedom.
    Where every σ is exact (λ = 0) this is the χ² test on n − 1 (ν₂ inf): a σ read on few
    dof scatters, and the χ² tail would reject a true repeat far more often than it says."""
    from scipy import stats as sps

    dof = np.maximum(n - 1, 1)
    with np.errstate(invalid="ignore", divide="ignore"):
        share = w / w.sum(axis=-1, keepdims=True)
        lam = np.where(w > 0, (1.0 - share) ** 2 / dofs, 0.0).sum(axis=-1)
        nu = np.where(lam > 0, (n * n - 1.0) / (3.0 * lam), np.inf)
        f = chi2 / dof / (1.0 + 2.0 * (n - 2.0) * lam / (n * n - 1.0))
        p = np.where(lam > 0, sps.f.sf(f, dof, np.where(lam > 0, nu, 1.0)),
                     sps.chi2.sf(chi2, dof))  # fmt: skip
    return np.where(n >= 2, p, np.nan), nu


def repeatability(
    values: np.ndarray, sigmas: np.ndarray, dofs: np.ndarray | None = None
) -> Repeatability:
    """The sessions along the last axis of ``values``/``sigmas`` (NaN: no session there),
    each σ read on ``dofs`` degrees of freedom (inf, and None for all: exact)."""
    x = np.asarray(values, dtype=np.float64)
    s = np.asarray(sigmas, dtype=np.float64)
    d = np.full(x.shape, np.inf) if dofs is None else np.asarray(dofs, dtype=np.float64)
    ok = np.isfinite(x) & np.isfinite(s) & (s > 0)
    w = np.where(ok, 1.0 / np.where(ok, s, 1.0) ** 2, 0.0)
    xz = np.where(ok, x, 0.0)
    n = ok.sum(axis=-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = (w * xz).sum(axis=-1) / w.sum(axis=-1)
        chi2 = (w * (xz - mean[..., None]) ** 2).sum(axis=-1)
        plain = xz.sum(axis=-1) / n
        scatter = np.sqrt(((xz - plain[..., None]) ** 2 * ok).sum(axis=-1) / (n - 1))
        predicted = np.sqrt((np.where(ok, s, 0.0) ** 2).sum(axis=-1) / n)
        cv = np.where(np.abs(mean) >= CV_FAR_FROM_ZERO * predicted, scatter / np.abs(mean), np.nan)
    p, nu = welch_p(chi2, w, np.where(ok & (d > 0), d, np.inf), n)
    bad = n < 2
    scatter = np.where(bad, np.nan, scatter)
    return Repeatability(n, mean, scatter, predicted, np.where(bad, np.nan, chi2), n - 1, p, cv,
                         np.where(bad, np.nan, nu))  # fmt: skip


# ---- drift -----------------------------------------------------------------------------------
def drift_z(
    before: np.ndarray, sigma_before: np.ndarray, after: np.ndarray, sigma_after: np.ndarray
) -> np.ndarray:
    """z of the change from one calibration to the next: Δ / √(σ₁² + σ₂²)."""
    d = np.asarray(after, dtype=np.float64) - np.asarray(before, dtype=np.float64)
    u = np.hypot(np.asarray(sigma_before, float), np.asarray(sigma_after, float))
    with np.errstate(invalid="ignore", divide="ignore"):
        return d / u


def drifted(
    z: np.ndarray, delta: np.ndarray, k: float, tolerance: np.ndarray | float = math.inf
) -> np.ndarray:
    """Where a parameter moved beyond ``k``·σ or beyond ``tolerance`` (same unit as
    ``delta``; inf: none)."""
    return (np.abs(z) > k) | (np.abs(delta) > tolerance)


# ---- lot -------------------------------------------------------------------------------------
@dataclass(frozen=True)
class LotSummary:
    """One parameter over a lot: ``n`` units, ``mean``, ``spread`` (sample standard deviation),
    ``low``/``high`` = mean ∓ 3·spread, and ``within`` the datasheet limit ±``limit``
    (None when there is no limit)."""

    n: int
    mean: float
    spread: float
    low: float
    high: float
    limit: float | None
    within: bool | None


def lot_summary(x: np.ndarray, limit: float | None = None) -> LotSummary:
    """Mean, spread and the 3σ band of the finite values of ``x`` against ±``limit``."""
    v = np.asarray(x, dtype=np.float64)
    v = v[np.isfinite(v)]
    n = int(v.size)
    mean = float(v.mean()) if n else math.nan
    spread = float(v.std(ddof=1)) if n > 1 else math.nan
    low, high = mean - 3 * spread, mean + 3 * spread
    within = None if limit is None or n < 2 else bool(max(abs(low), abs(high)) <= limit)
    return LotSummary(n, mean, spread, low, high, limit, within)


def grubbs_critical(n: int | np.ndarray, alpha: float) -> np.ndarray:
    """Two-sided Grubbs critical value G for ``n`` values at level ``alpha``:
    (n−1)/√n · √(t²/(n−2+t²)), t the upper alpha/(2n) point of Student's t on n−2 dof."""
    from scipy import stats as sps

    nn = np.asarray(n, dtype=np.float64)
    t = sps.t.isf(alpha / (2.0 * nn), np.maximum(nn - 2.0, 1.0))
    return (nn - 1.0) / np.sqrt(nn) * np.sqrt(t * t / (nn - 2.0 + t * t))


def grubbs_statistic(x: np.ndarray) -> np.ndarray:
    """max |x − mean| / s along the last axis (s: sample standard deviation)."""
    v = np.asarray(x, dtype=np.float64)
    m = v.mean(axis=-1, keepdims=True)
    s = v.std(axis=-1, ddof=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.abs(v - m).max(axis=-1) / s


def grubbs_outliers(x: np.ndarray, alpha: float, max_fraction: float = 0.1) -> list[int]:
    """Indices of the outliers of ``x`` (finite values only): the Grubbs test at ``alpha``,
    repeated after removing each outlier found, at most ``max_fraction`` of the values."""
    v = np.asarray(x, dtype=np.float64)
    idx = np.flatnonzero(np.isfinite(v))
    out: list[int] = []
    while idx.size >= 3 and len(out) < max(1, int(max_fraction * v.size)):
        w = v[idx]
        s = w.std(ddof=1)
        if not s > 0:
            break
        dev = np.abs(w - w.mean()) / s
        j = int(np.argmax(dev))
        if dev[j] <= grubbs_critical(idx.size, alpha):
            break
        out.append(int(idx[j]))
        idx = np.delete(idx, j)
    return out


# ---- control charts --------------------------------------------------------------------------
RULES = (
    "1: one point beyond 3σ",
    "2: two of three beyond 2σ on one side",
    "3: four of five beyond 1σ on one side",
    "4: eight in a row on one side",
)


def individuals_limits(x: np.ndarray, baseline: int = 20) -> tuple[float, float]:
    """Centre line and σ of an individuals chart from the first ``baseline`` finite points:
    their mean and the mean moving range / d₂."""
    v = np.asarray(x, dtype=np.float64)
    v = v[np.isfinite(v)][:baseline]
    if v.size < 2:
        return (float(v.mean()) if v.size else math.nan), math.nan
    return float(v.mean()), float(np.abs(np.diff(v)).mean() / D2)


def _window_count(flags: np.ndarray, width: int) -> np.ndarray:
    """How many of the last ``width`` points (this one included) are flagged, per point."""
    c = np.cumsum(np.concatenate([np.zeros(flags.shape[:-1] + (1,)), flags], axis=-1), axis=-1)
    n = flags.shape[-1]
    lo = np.maximum(np.arange(1, n + 1) - width, 0)
    return c[..., 1:] - c[..., lo]


def run_rules(x: np.ndarray, centre: float, sigma: float) -> np.ndarray:
    """Which Western Electric rule fires at each point, shape (..., n, 4) (points along the
    last axis of ``x``); a rule fires at the point that completes its pattern."""
    z = (np.asarray(x, dtype=np.float64) - centre) / sigma
    out = np.zeros(z.shape + (4,), dtype=bool)
    out[..., 0] = np.abs(z) > 3
    for sign in (1.0, -1.0):
        s = sign * z
        out[..., 1] |= (_window_count(s > 2, 3) >= 2) & (s > 2)
        out[..., 2] |= (_window_count(s > 1, 5) >= 4) & (s > 1)
        out[..., 3] |= _window_count(s > 0, 8) >= 8
    return out


# ---- bench comparison ------------------------------------------------------------------------
@dataclass(frozen=True)
class BenchComparison:
    """Per bench (last axis): the reference unit's weighted ``mean`` and its standard
    uncertainty ``u`` (scaled up by the Birge ratio when the sessions scatter more than their
    σ), the reference value ``ref`` (weighted mean of the benches not flagged, this one left
    out) and ``u_ref``, ``z`` = (mean − ref)/√(u² + u_ref²), ``en`` = z/2 (Eₙ with U = 2u),
    ``flagged`` beyond the family-wise k."""

    mean: np.ndarray
    u: np.ndarray
    ref: np.ndarray
    u_ref: np.ndarray
    z: np.ndarray
    en: np.ndarray
    flagged: np.ndarray


def bench_means(values: np.ndarray, sigmas: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Weighted mean and its uncertainty over the sessions (last axis), the uncertainty
    scaled by √(χ²/dof) when that exceeds 1."""
    r = repeatability(values, sigmas)
    ok = np.isfinite(values) & np.isfinite(sigmas) & (sigmas > 0)
    u = 1.0 / np.sqrt(np.where(ok, 1.0 / np.where(ok, sigmas, 1.0) ** 2, 0.0).sum(axis=-1))
    with np.errstate(invalid="ignore", divide="ignore"):
        birge = np.sqrt(np.where(r.dof > 0, r.chi2 / np.maximum(r.dof, 1), 1.0))
    return r.mean, u * np.maximum(np.nan_to_num(birge, nan=1.0), 1.0)


def compare_benches(mean: np.ndarray, u: np.ndarray, k: float) -> BenchComparison:
    """Compare each bench (last axis of ``mean``/``u``) with the others; iterate: flag the
    worst |z| > ``k``, leave it out of the others' reference, test again."""
    x = np.asarray(mean, dtype=np.float64)
    uu = np.asarray(u, dtype=np.float64)
    active = np.isfinite(x) & np.isfinite(uu) & (uu > 0)
    flagged = np.zeros(x.shape, dtype=bool)
    w = np.where(active, 1.0 / np.where(active, uu, 1.0) ** 2, 0.0)
    for _ in range(x.shape[-1]):
        ref, u_ref, z = _leave_one_out(x, uu, w * (active & ~flagged))
        worst = np.where(active & ~flagged, np.abs(np.nan_to_num(z)), -1.0)
        j = np.argmax(worst, axis=-1)
        hit = np.take_along_axis(worst, j[..., None], axis=-1)[..., 0] > k
        if not hit.any():
            break
        np.put_along_axis(flagged, j[..., None], hit[..., None], axis=-1)
    ref, u_ref, z = _leave_one_out(x, uu, w * (active & ~flagged))
    return BenchComparison(x, uu, ref, u_ref, z, z / 2.0, flagged)


def _leave_one_out(
    x: np.ndarray, u: np.ndarray, w: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    sw = w.sum(axis=-1, keepdims=True) - w
    sx = (w * np.nan_to_num(x)).sum(axis=-1, keepdims=True) - w * np.nan_to_num(x)
    with np.errstate(invalid="ignore", divide="ignore"):
        ref = sx / sw
        u_ref = 1.0 / np.sqrt(sw)
        z = (x - ref) / np.sqrt(u * u + u_ref * u_ref)
    return ref, u_ref, z
