"""Statistics in pure numpy: the χ² tail and its inverse, the project's one uncertainty policy
(:func:`stderr_scale`), the row echelon form the fit reads combinations from and the right
singular vectors it reads null spaces from (:func:`right_singular`)."""

from __future__ import annotations

import math

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
