"""Statistics in pure numpy: the χ² tail and its inverse, the project's one uncertainty policy
(:func:`stderr_scale`), the degrees of freedom of a σ that is itself estimated
(:func:`satterthwaite_dof`), the row echelon form the fit reads combinations from and the right
singular vectors it reads null spaces from (:func:`right_singular`)."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np


# ---- statistics (pure numpy) ----------------------------------------------------------------
def chi2_sf(x: float, dof: float) -> float:
    """P(χ²_dof > x): the regularised upper incomplete gamma Q(dof/2, x/2)."""
    if dof <= 0 or not math.isfinite(x):
        return float("nan") if not math.isfinite(x) else 1.0
    if x <= 0:
        return 1.0
    a, z = 0.5 * dof, 0.5 * x
    gln = math.lgamma(a)
    if z < a + 1.0:  # series for P
        term_, total, ap = 1.0 / a, 1.0 / a, a
        for _ in range(1000):
            ap += 1.0
            term_ *= z / ap
            total += term_
            if abs(term_) < abs(total) * 1e-15:
                break
        return float(max(0.0, 1.0 - total * math.exp(-z + a * math.log(z) - gln)))
    # continued fraction for Q (Lentz)
    tiny = 1e-300
    b = z + 1.0 - a
    c = 1.0 / tiny
    d = 1.0 / b
    h = d
    for i in range(1, 1000):
        an = -i * (i - a)
        b += 2.0
        d = an * d + b
        d = tiny if abs(d) < tiny else d
        c = b + an / c
        c = tiny if abs(c) < tiny else c
        d = 1.0 / d
        delta = d * c
        h *= delta
        if abs(delta - 1.0) < 1e-15:
            break
    return float(min(1.0, math.exp(-z + a * math.log(z) - gln) * h))


def chi2_isf(p: float, dof: float) -> float:
    """x with P(χ²_dof > x) = p (bisection on :func:`chi2_sf`)."""
    lo, hi = 0.0, max(10.0, dof * 10.0)
    while chi2_sf(hi, dof) > p:
        hi *= 2.0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if mid in (lo, hi):  # lo and hi adjacent doubles: every further step returns mid
            return mid
        if chi2_sf(mid, dof) > p:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


#: the χ² test of a channel rejects the model at this level: its standard errors are scaled
ALPHA_FIT = 0.01


def stderr_scale(chi2: float, dof: int) -> float:
    """The project's one uncertainty policy: standard errors come from the noise model; when a
    channel's fit is poor (χ² p < :data:`ALPHA_FIT` and χ² > dof) they are multiplied by
    √(χ²/dof) (the Birge ratio) and the report says so. 1.0 otherwise (and with no dof)."""
    if dof <= 0 or not math.isfinite(chi2) or chi2 <= dof:
        return 1.0
    return math.sqrt(chi2 / dof) if chi2_sf(chi2, dof) < ALPHA_FIT else 1.0


#: a variance component (a scatter beyond the sensor's white noise: the floor's wander, the hand,
#: the seating, the turn angle and wobble) enters the yardstick only when the rows it is read
#: from show it at this level (:func:`beyond_white`). Those rows are also counted by the χ² test
#: of the model: a component resolved by chance under the null widens the yardstick there and
#: that session's χ² runs low. At "two standard errors" (2.5–5 % a component on skewed χ² of
#: few dof, five components) 400 controls of the independent simulator read median p 0.55, KS
#: p 0.025 (the same with the components off: 0.49, 0.96); at 0.001: 0.49, 0.98. The price: a
#: real scatter between about 2 and 3 standard errors goes unresolved (and shows as misfit).
ALPHA_COMPONENT = 0.001


def beyond_white(ss: float, null_mean: float, null_var: float) -> bool:
    """True when a sum of squares ``ss`` is beyond what white noise alone gives, at
    p < :data:`ALPHA_COMPONENT`: under white noise ``ss`` has mean ``null_mean`` and variance
    ``null_var`` (same unit², squared), its tail taken as that of c·χ²_ν with those two moments
    (c = var/(2·mean), ν = 2·mean²/var; exact for equal variances). Without white noise
    (noise-free samples) any scatter is beyond it."""
    if not math.isfinite(ss):
        return False
    if not (null_mean > 0.0 and null_var > 0.0):
        return ss > max(null_mean, 0.0)
    c = null_var / (2.0 * null_mean)
    nu = 2.0 * null_mean**2 / null_var
    return chi2_sf(ss / c, nu) < ALPHA_COMPONENT


def least_beyond_white(null_mean: float, null_var: float) -> float:
    """The smallest sum of squares :func:`beyond_white` calls beyond the white noise (its
    ``null_mean`` and ``null_var``); inf without white noise to compare with."""
    if not (null_mean > 0.0 and null_var > 0.0):
        return math.inf
    c = null_var / (2.0 * null_mean)
    return c * chi2_isf(ALPHA_COMPONENT, 2.0 * null_mean**2 / null_var)


#: a σ on this many degrees of freedom or more is read as exact (its coverage factor that of the
#: normal distribution; a result file writes no dof for it)
NORMAL_DOF = 1000.0


def satterthwaite_dof(
    variance: float, shares: Sequence[float], share_dofs: Sequence[float]
) -> float:
    """Welch–Satterthwaite: the effective degrees of freedom of a ``variance`` (unit²) that is
    a sum of parts, the estimated ones ``shares`` (unit², each read on ``share_dofs`` degrees
    of freedom) and the rest known exactly: ν = V² / Σ s²/ν_s. inf when no part is estimated
    (a share of 0, or one on infinite dof, adds nothing)."""
    denom = sum(
        s * s / d
        for s, d in zip(shares, share_dofs, strict=True)
        if s > 0.0 and d > 0.0 and math.isfinite(d)
    )
    if not (denom > 0.0) or not (variance > 0.0):
        return math.inf
    return variance * variance / denom


def rref(m: np.ndarray, tol: float = 1e-9) -> np.ndarray:
    """Reduced row echelon form of ``m`` (rows independent), leading coefficients 1."""
    a = np.array(m, dtype=np.float64)
    r = 0
    for col in range(a.shape[1]):
        if r >= a.shape[0]:
            break
        piv = r + int(np.argmax(np.abs(a[r:, col])))
        if abs(a[piv, col]) < tol:
            continue
        a[[r, piv]] = a[[piv, r]]
        a[r] /= a[r, col]
        for i in range(a.shape[0]):
            if i != r:
                a[i] -= a[i, col] * a[r]
        r += 1
    return a[:r]


def right_singular(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(singular values (min(m, P),), all P right singular vectors as rows (P, P)) of ``a``
    (m, P), the null space's among them; the left ones only as far as they are needed (never
    m × m: memory linear in the rows)."""
    _, sv, vt = np.linalg.svd(a, full_matrices=a.shape[0] < a.shape[1])
    return sv, vt
