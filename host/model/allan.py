"""Noise of a static recording: overlapping Allan deviation, its three slopes, and a planner.

Pure functions over numpy arrays (the command is :mod:`host.cli.noise`). The estimator is the
overlapping Allan deviation of rate samples (:func:`oadev`: second differences of their
cumulative sum, IEEE Std 1139 / NIST SP 1065 eq. 11); its confidence intervals are chi-squared
intervals with Greenhall's equivalent degrees of freedom (:func:`edf`: C. A. Greenhall and
W. J. Riley, "Uncertainty of stability variances based on finite differences", 2003), the noise
type at each τ taken from the fitted model. The ``allantools`` library is the oracle the tests
compare both with; it is not needed at run time.

The noise model of one channel (IEEE Std 952-1997, Annex C), as Allan variance::

    σ²(τ) = N²/τ + (2·ln 2/π)·B² + K²·τ/3

- ``N`` white noise density (slope −½ in a log–log plot of σ), unit/√Hz (for a gyro °/s/√Hz,
  i.e. the angle random walk; ×60 gives °/√h);
- ``B`` bias instability (slope 0, the flat floor σ = 0.664·B), in the channel's unit;
- ``K`` rate random walk (slope +½), unit/s/√Hz (°/s²/√Hz; ×3600·60 gives °/h/√h).

The three coefficients (N², B², K²) are fitted jointly by weighted least squares (they enter
σ² linearly), non-negative. Each figure is then *read where its slope holds*: at the τ where
that term dominates σ² and the measured local slope agrees with the model, its value and
confidence interval are those of σ²(τ) there, minus the other two terms. A term that dominates
nowhere is not resolved: it gets an upper bound and a warning (a recording too short for rate
random walk, or a bias-instability floor hidden under the other two).

:func:`plan_duration` answers the planner's question under a fitted model: how long must a
recording be for a figure, read by the same rules, to have a given relative precision.
:mod:`host.model.recording` applies all this to a recording (and keeps temperature drift out).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

CHANNELS = ("ax", "ay", "az", "gx", "gy", "gz")
#: the three quantities, in the order of the model's terms (white, flat, +½)
QUANTITIES = ("white_noise_density", "bias_instability", "rate_random_walk")
#: Allan variance of bias instability (flicker) per B²: 2·ln 2/π (IEEE 952 C.3), σ = 0.664·B
FLICKER_AVAR = 2.0 * math.log(2.0) / math.pi
#: slope of σ(τ) in a log–log plot, per term
SLOPES = (-0.5, 0.0, 0.5)
#: Greenhall's noise exponent α of fractional frequency per term (white FM, flicker FM, RW FM)
_ALPHA = (0, -1, -2)
#: a term holds at τ where it makes at least this share of σ²(τ)
DOMINANT_SHARE = 0.6
#: default confidence level of every interval
CI_LEVEL = 0.95
#: (white, bias instability, rate random walk) units per sensor, as the --json keys fix them
UNITS = {
    "accel": ("m/s^2/sqrt(Hz)", "m/s^2", "m/s^3/sqrt(Hz)"),
    "gyro": ("deg/s/sqrt(Hz)", "deg/s", "deg/s^2/sqrt(Hz)"),
}


def sensor_of(channel: str) -> str:
    """'ax' -> 'accel', 'gz' -> 'gyro'."""
    return "accel" if channel.startswith("a") else "gyro"


# --------------------------------------------------------------------------- the curve
@dataclass(frozen=True)
class AllanCurve:
    """Overlapping Allan deviation of one channel: ``tau_s`` (M,) s, ``adev`` (M,) in the
    channel's unit, ``n`` samples at ``rate_hz`` Hz. ``edf``, ``lo``, ``hi`` (M,) are filled by
    :func:`fit_noise` once the noise type at each τ is known (confidence level ``ci``)."""

    tau_s: np.ndarray
    adev: np.ndarray
    n: int
    rate_hz: float
    edf: np.ndarray | None = None
    lo: np.ndarray | None = None
    hi: np.ndarray | None = None
    ci: float = CI_LEVEL

    @property
    def m(self) -> np.ndarray:
        """Averaging factors τ·rate (integers)."""
        return np.rint(self.tau_s * self.rate_hz).astype(np.int64)


def tau_grid(n: int, points_per_decade: int = 8, max_fraction: float = 1 / 3) -> np.ndarray:
    """Averaging factors m (integers, log-spaced) from 1 to ``max_fraction``·n."""
    top = max(1, int(n * max_fraction))
    k = max(2, int(math.ceil(math.log10(top) * points_per_decade)) + 1)
    return np.unique(np.rint(np.logspace(0.0, math.log10(top), k)).astype(np.int64))


#: phase points worked on at once by :func:`oadev_of_phase` (8 MiB of float64)
PHASE_BLOCK = 1 << 20


def phase_of(x: np.ndarray, rate_hz: float) -> np.ndarray:
    """(N + 1,) the phase of the rate samples ``x`` (N,) at ``rate_hz`` Hz: the cumulative sum
    of x less its mean, divided by the rate, from 0 (x's unit × s)."""
    x = np.asarray(x, dtype=np.float64)
    return np.concatenate([[0.0], np.cumsum(x - np.mean(x)) / rate_hz])


def oadev(x: np.ndarray, rate_hz: float, m: np.ndarray) -> np.ndarray:
    """(len(m),) overlapping Allan deviation of the rate samples ``x`` (N,) at ``rate_hz`` Hz
    for the averaging factors ``m`` (integers; τ = m/rate), in x's unit; NaN where fewer than
    two second differences fit. The phase φ is :func:`phase_of` (N + 1 points);
    σ²(τ) = Σ (φ[i+2m] − 2φ[i+m] + φ[i])² / (2·(N + 1 − 2m)·τ²)."""
    phase = phase_of(x, rate_hz)
    return oadev_of_phase(lambda a, b: phase[a:b], phase.size, rate_hz, m, block=phase.size)


def oadev_of_phase(
    window: Callable[[int, int], np.ndarray],
    size: int,
    rate_hz: float,
    m: np.ndarray,
    block: int = PHASE_BLOCK,
) -> np.ndarray:
    """:func:`oadev` from a phase of ``size`` points that ``window(a, b)`` gives piece by piece
    (φ[a:b], float64), ``block`` points of second differences at a time: one pass over the
    phase serves every m up to block/2, each larger m takes its own. Memory: about three
    blocks, whatever the length."""
    m = np.asarray(m, dtype=np.int64)
    count = size - 2 * m
    valid = (m >= 1) & (count >= 2)
    acc = np.zeros(m.size)
    # two working buffers, reused: d = φ[i+2m] − 2φ[i+m] + φ[i] (no temporaries per m)
    width = min(block, int(count.max(initial=0)))
    d_buf, twice = np.empty(max(width, 0)), np.empty(max(width, 0))

    def second_difference(far: np.ndarray, mid: np.ndarray, near: np.ndarray) -> float:
        n = far.size
        d, t = d_buf[:n], twice[:n]
        np.multiply(mid, 2.0, out=t)
        np.subtract(far, t, out=d)
        d += near
        return float(d @ d)

    small = np.flatnonzero(valid & (2 * m <= block))
    if small.size:
        reach = 2 * int(m[small].max())
        for i0 in range(0, int(count[small].max()), block):
            w = window(i0, min(size, i0 + block + reach))
            for k in small:
                mk, n = int(m[k]), min(block, int(count[k]) - i0)
                if n > 0:
                    acc[k] += second_difference(w[2 * mk : 2 * mk + n], w[mk : mk + n], w[:n])
    for k in np.flatnonzero(valid & (2 * m > block)):
        mk = int(m[k])
        for i0 in range(0, int(count[k]), block):
            n = min(block, int(count[k]) - i0)
            far, mid = window(i0 + 2 * mk, i0 + 2 * mk + n), window(i0 + mk, i0 + mk + n)
            acc[k] += second_difference(far, mid, window(i0, i0 + n))
    out = np.full(m.size, np.nan)
    for k in np.flatnonzero(valid):
        out[k] = math.sqrt(acc[k] / (2.0 * int(count[k]))) * rate_hz / float(m[k])
    return out


def allan_curve(x: np.ndarray, rate_hz: float, points_per_decade: int = 8) -> AllanCurve:
    """Overlapping Allan deviation (:func:`oadev`) of the rate samples ``x`` (N,) taken at
    ``rate_hz`` Hz, on a log-spaced τ grid up to a third of the length."""
    x = np.asarray(x, dtype=np.float64)
    phase = phase_of(x, rate_hz)
    window = lambda a, b: phase[a:b]  # noqa: E731
    return allan_curve_of_phase(window, x.size, rate_hz, points_per_decade, block=phase.size)


def allan_curve_of_phase(
    window: Callable[[int, int], np.ndarray],
    n: int,
    rate_hz: float,
    points_per_decade: int = 8,
    block: int = PHASE_BLOCK,
) -> AllanCurve:
    """:func:`allan_curve` of ``n`` samples from their phase (``n`` + 1 points, read through
    ``window`` as :func:`oadev_of_phase` does): a recording too long to hold."""
    if n < 16:
        raise ValueError(f"{n} samples: at least 16 are needed for an Allan deviation")
    m = tau_grid(n, points_per_decade)
    adev = oadev_of_phase(window, n + 1, rate_hz, m, block)
    ok = np.isfinite(adev) & (adev > 0)
    return AllanCurve(m[ok] / float(rate_hz), adev[ok], int(n), float(rate_hz))


def basis(tau_s: np.ndarray) -> np.ndarray:
    """(M, 3): σ² per unit of (N², B², K²) at each τ — 1/τ, 2·ln2/π, τ/3."""
    t = np.asarray(tau_s, dtype=np.float64)
    return np.column_stack([1.0 / t, np.full_like(t, FLICKER_AVAR), t / 3.0])


#: Greenhall's J_max: above it his EDF takes a closed form or a shortened sum
_J_MAX = 100
#: Greenhall & Riley's Table 2, d = 2: (a0, a1) of 1/edf = (a0 − a1/r)/r for the unmodified
#: overlapping Allan variance when J > J_max and r = M/m > 3, per noise exponent α
_TABLE2 = {0: (2.0 / 3.0, 1.0 / 3.0), -1: (0.852, 0.375), -2: (1.079, 0.368)}


def _sw(t: np.ndarray, alpha: int) -> np.ndarray:
    """Greenhall's s_w(t) for the noise exponent ``alpha`` (2 … −2)."""
    a = np.abs(t)
    if alpha in (1, -1):
        with np.errstate(divide="ignore", invalid="ignore"):
            out = a ** (3 - alpha) * np.log(a)
        return np.where(a == 0.0, 0.0, out)
    return {2: -a, 0: a**3, -2: a**5}[alpha]


def _sx(t: np.ndarray, f: float, alpha: int) -> np.ndarray:
    """Greenhall's s_x(t): the filter of F = ``f`` samples (inf: its limit)."""
    if math.isinf(f):
        return _sw(t, alpha + 2)
    return f * f * (2.0 * _sw(t, alpha) - _sw(t - 1.0 / f, alpha) - _sw(t + 1.0 / f, alpha))


def _sz(t: np.ndarray, f: float, alpha: int) -> np.ndarray:
    """Greenhall's s_z(t) for second differences (d = 2)."""
    t = np.asarray(t, dtype=np.float64)
    return (6.0 * _sx(t, f, alpha) - 4.0 * (_sx(t - 1.0, f, alpha) + _sx(t + 1.0, f, alpha))
            + _sx(t - 2.0, f, alpha) + _sx(t + 2.0, f, alpha))  # fmt: skip


def _basic_sum(j_big: int, big_m: float, s: float, f: float, alpha: int) -> float:
    """Greenhall's BasicSum: s_z(0)² + (1 − J/M)·s_z(J/S)² + 2·Σ_{j<J} (1 − j/M)·s_z(j/S)²."""
    j = np.arange(1, j_big, dtype=np.float64)
    z = _sz(np.concatenate([[0.0, j_big / s], j / s]), f, alpha) ** 2
    return float(z[0] + (1.0 - j_big / big_m) * z[1] + 2.0 * np.sum((1.0 - j / big_m) * z[2:]))


def edf(alpha: int, m: int, n: int) -> float:
    """Greenhall's equivalent degrees of freedom of the overlapping Allan variance at averaging
    factor ``m`` over ``n`` rate samples for noise exponent ``alpha`` (0 white FM, −1 flicker
    FM, −2 random-walk FM).

    Where Greenhall sums J = 3m terms (case 2.1: 3m ≤ J_max, M = n − 2m + 1 ≥ 3m estimator
    terms), his eq. (10) is 1/edf = (A − B/M)/M with A, B depending on (α, m) only: they are
    summed once per (α, m) (:func:`_greenhall_ab`), so the planner's many lengths cost nothing
    more. Elsewhere: his sum over J = M terms (M ≤ J_max), the table's closed form (r = M/m >
    3) or the sum shortened to J_max terms."""
    if 2 * m + 1 > n:
        return 1.0
    alpha, m = int(alpha), int(m)
    big_m = n - 2 * m + 1  # Greenhall's M for N = n + 1 phase points, d = 2, F = S = m
    if 3 * m <= _J_MAX and big_m >= 3 * m:
        a, b = _greenhall_ab(alpha, m)
        return 1.0 / ((a - b / big_m) / big_m)
    j_big = min(big_m, 3 * m)
    if j_big <= _J_MAX:
        f = float(m) if 3 * m <= _J_MAX else math.inf
        return (
            big_m
            * float(_sz(np.zeros(1), f, alpha)[0]) ** 2
            / _basic_sum(j_big, big_m, m, f, alpha)
        )
    r = big_m / m
    if r > 3.0:
        a0, a1 = _TABLE2[alpha]
        return 1.0 / ((a0 - a1 / r) / r)
    z0 = float(_sz(np.zeros(1), math.inf, alpha)[0]) ** 2
    return _J_MAX * z0 / _basic_sum(_J_MAX, _J_MAX, _J_MAX / r, math.inf, alpha)


@functools.lru_cache(maxsize=4096)
def _greenhall_ab(alpha: int, m: int) -> tuple[float, float]:
    """A, B of 1/edf = (A − B/M)/M for Greenhall's case 2.1 with J = 3m (overlapping Allan
    variance, d = 2, F = S = m): his BasicSum (eq. 10) split into the part independent of M
    (A) and the part proportional to 1/M (B), both over s_z(0)²."""
    j_big = 3 * m
    j = np.arange(j_big + 1, dtype=np.float64)
    z = _sz(j / m, float(m), alpha) ** 2
    a = z[0] + z[j_big] + 2.0 * float(np.sum(z[1:j_big]))
    b = j_big * z[j_big] + 2.0 * float(np.sum(j[1:j_big] * z[1:j_big]))
    return float(a / z[0]), float(b / z[0])


def chi2_interval(var: np.ndarray, dof: np.ndarray, ci: float = CI_LEVEL) -> tuple:
    """Chi-squared confidence interval of a variance estimate ``var`` with ``dof`` degrees of
    freedom: (lo, hi) of the variance."""
    from scipy.stats import chi2  # noqa: PLC0415

    var = np.asarray(var, dtype=np.float64)
    dof = np.maximum(np.asarray(dof, dtype=np.float64), 1e-3)
    lo = var * dof / chi2.ppf(0.5 + ci / 2.0, dof)
    hi = var * dof / chi2.ppf(0.5 - ci / 2.0, dof)
    return lo, hi


# --------------------------------------------------------------------------- the fit
@dataclass(frozen=True)
class Figure:
    """One fitted quantity of one channel, in the channel's SI-like unit (see :data:`UNITS`).

    ``value`` None when not resolved (then ``ci`` is (0, upper bound)); ``tau_s`` where it was
    read; ``warning`` one line for the user when not resolved."""

    value: float | None
    ci: tuple[float, float]
    unit: str
    tau_s: float | None
    warning: str | None = None

    def as_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "value": self.value,
            "ci": [self.ci[0], self.ci[1]],
            "unit": self.unit,
            "tau_s": self.tau_s,
            "resolved": self.value is not None,
        }
        if self.warning:
            out["warning"] = self.warning
        return out


@dataclass(frozen=True)
class ChannelNoise:
    """The noise of one channel: its curve, the joint fit ``coef`` (N², B², K²) and the three
    figures (``white``, ``bias_instability``, ``rate_random_walk``)."""

    channel: str
    curve: AllanCurve
    coef: np.ndarray
    figures: dict[str, Figure]


def _wls_nonneg(y: np.ndarray, a: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Weighted least squares ``a @ c ≈ y`` with c ≥ 0 (every subset of the 3 columns)."""
    best: tuple[float, np.ndarray] = (math.inf, np.zeros(a.shape[1]))
    sw = np.sqrt(w)
    for mask in range(1, 1 << a.shape[1]):
        cols = [j for j in range(a.shape[1]) if mask >> j & 1]
        sol, *_ = np.linalg.lstsq(a[:, cols] * sw[:, None], y * sw, rcond=None)
        if np.any(sol < 0):
            continue
        c = np.zeros(a.shape[1])
        c[cols] = sol
        chi = float(np.sum(w * (a @ c - y) ** 2))
        if chi < best[0]:
            best = (chi, c)
    return best[1]


def fit_coefficients(curve: AllanCurve, edfs: np.ndarray | None = None) -> np.ndarray:
    """(N², B², K²) ≥ 0 by iteratively reweighted least squares on σ²(τ): the weight of each
    τ is edf/(2·model²), the variance of a chi-squared variance estimate."""
    a = basis(curve.tau_s)
    y = curve.adev**2
    dof = np.full(y.shape, 10.0) if edfs is None else np.asarray(edfs)
    model = y.copy()
    coef = np.zeros(3)
    for _ in range(6):
        coef = _wls_nonneg(y, a, dof / (2.0 * model**2))
        model = np.maximum(a @ coef, 1e-300)
    return coef


def _dominant_alpha(coef: np.ndarray, tau_s: np.ndarray) -> np.ndarray:
    parts = basis(tau_s) * coef
    return np.array(_ALPHA)[np.argmax(parts, axis=1)]


def curve_edf(curve: AllanCurve, coef: np.ndarray) -> np.ndarray:
    """Equivalent degrees of freedom at each τ of ``curve`` for the noise type that dominates
    there under the model ``coef``."""
    alphas = _dominant_alpha(coef, curve.tau_s)
    return np.array([edf(int(al), int(m), curve.n) for al, m in zip(alphas, curve.m, strict=True)])


def local_slopes(tau: np.ndarray, dev: np.ndarray, half: float = 0.3) -> np.ndarray:
    """At each point i: the least-squares slope of log σ against log τ over the points within
    ±``half`` decades of it (NaN where fewer than 3)."""
    lt = np.log10(np.asarray(tau, dtype=np.float64))
    ld = np.log10(np.asarray(dev, dtype=np.float64))
    sel = (np.abs(lt[:, None] - lt[None, :]) <= half).astype(np.float64)
    n = sel.sum(axis=1)
    xm = (sel @ lt) / n
    ym = (sel @ ld) / n
    dx = lt[None, :] - xm[:, None]
    dy = ld[None, :] - ym[:, None]
    sxx = np.sum(sel * dx * dx, axis=1)
    sxy = np.sum(sel * dx * dy, axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        out = sxy / sxx
    out[n < 3] = np.nan
    return out


def _slopes(curve: AllanCurve, coef: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Local slopes (:func:`local_slopes`) of the measured curve and of the model ``coef``."""
    model = np.sqrt(np.maximum((basis(curve.tau_s) * coef).sum(axis=1), 1e-300))
    return local_slopes(curve.tau_s, curve.adev), local_slopes(curve.tau_s, model)


def _read_term(
    k: int,
    curve: AllanCurve,
    coef: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
    unit: str,
    others_band: tuple[np.ndarray, np.ndarray] | None = None,
    slopes: tuple[np.ndarray, np.ndarray] | None = None,
) -> Figure:
    """Figure of term k, read at the τ where it holds with the narrowest interval.

    At each τ the term is σ² minus the other two terms: the value with their fitted values,
    the interval with the interval of σ² and the others' own intervals (``others_band``: their
    lowest and highest contribution at each τ; the fitted values when None). ``slopes``: the
    local slopes of the curve and of the model (:func:`_slopes`), when already known."""
    a = basis(curve.tau_s)
    parts = a * coef
    total = np.maximum(parts.sum(axis=1), 1e-300)
    share = parts[:, k] / total
    others = total - parts[:, k]
    o_lo, o_hi = (others, others) if others_band is None else others_band
    var = curve.adev**2
    best: tuple[float, int] | None = None
    slopes_data, slopes_model = slopes if slopes is not None else _slopes(curve, coef)
    for i in range(curve.tau_s.size):
        if share[i] < DOMINANT_SHARE or lo[i] - o_hi[i] <= 0:
            continue
        s_data, s_model = float(slopes_data[i]), float(slopes_model[i])
        if math.isnan(s_data) or math.isnan(s_model):
            continue
        # the slope agrees within its noise: the relative half-width of σ over the window
        spread = 0.5 * math.log10(hi[i] / lo[i]) / 0.6
        if abs(s_data - s_model) > 0.12 + spread:
            continue
        width = math.log((hi[i] - o_lo[i]) / (lo[i] - o_hi[i]))
        if best is None or width < best[0]:
            best = (width, i)
    if best is None:
        # not resolved: the whole σ² bounds the term from above at every τ
        upper = float(np.min(np.maximum(hi - o_lo, 0.0) / a[:, k]))
        return Figure(None, (0.0, math.sqrt(upper)), unit, None, _not_resolved(k, curve, coef))
    i = best[1]
    value = math.sqrt(max(var[i] - others[i], 0.0) / a[i, k])
    lo_v = math.sqrt((lo[i] - o_hi[i]) / a[i, k])
    hi_v = math.sqrt((hi[i] - o_lo[i]) / a[i, k])
    return Figure(value, (min(lo_v, value), max(hi_v, value)), unit, float(curve.tau_s[i]))


def _bands(
    k: int, tau_s: np.ndarray, figures: Sequence[Figure], coef: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Lowest and highest σ² contribution of the terms other than k at each τ, from their
    figures' intervals (a term not yet read counts at its fitted value)."""
    a = basis(tau_s)
    lo = np.zeros(tau_s.size)
    hi = np.zeros(tau_s.size)
    for j in range(3):
        if j == k:
            continue
        if j < len(figures):
            lo += a[:, j] * figures[j].ci[0] ** 2
            hi += a[:, j] * figures[j].ci[1] ** 2
        else:
            lo += a[:, j] * coef[j]
            hi += a[:, j] * coef[j]
    return lo, hi


def _not_resolved(k: int, curve: AllanCurve, coef: np.ndarray) -> str:
    dur = curve.n / curve.rate_hz
    if k == 2:
        return (
            f"rate random walk not reached: the {_fmt_duration(dur)} recording ends before the "
            "+1/2 slope dominates; only an upper bound is given — record longer "
            "(--plan says how long)"
        )
    if k == 1:
        return (
            "bias instability not resolved: no flat part of the curve dominates (white noise "
            f"and rate random walk hide it in this {_fmt_duration(dur)} recording); only an "
            "upper bound is given"
        )
    return "white noise not resolved: no -1/2 slope at the shortest tau (filtered data?)"


def _fmt_duration(s: float) -> str:
    if s >= 3600:
        return f"{s / 3600:.1f} h"
    if s >= 120:
        return f"{s / 60:.0f} min"
    return f"{s:.0f} s"


def fit_noise(channel: str, curve: AllanCurve, ci: float = CI_LEVEL) -> ChannelNoise:
    """Fit the three-term model to ``curve`` and read each figure where its slope holds."""
    coef = fit_coefficients(curve)
    edfs = curve_edf(curve, coef)
    coef = fit_coefficients(curve, edfs)
    edfs = curve_edf(curve, coef)
    lo, hi = chi2_interval(curve.adev**2, edfs, ci)
    full = AllanCurve(curve.tau_s, curve.adev, curve.n, curve.rate_hz, edfs, lo, hi, ci)
    units = UNITS[sensor_of(channel)]
    # first with the others at their fitted values, then twice with their intervals
    sl = _slopes(full, coef)
    figs = [_read_term(k, full, coef, lo, hi, units[k], slopes=sl) for k in range(3)]
    for _ in range(2):
        figs = [
            _read_term(k, full, coef, lo, hi, units[k], _bands(k, full.tau_s, figs, coef), sl)
            for k in range(3)
        ]
    return ChannelNoise(channel, full, coef, dict(zip(QUANTITIES, figs, strict=True)))


# --------------------------------------------------------------------------- the planner
def expected_figures(
    coef: np.ndarray, n: int, rate_hz: float, ci: float = CI_LEVEL, channel: str = "gx"
) -> dict[str, Figure]:
    return _expected_figures(tuple(float(c) for c in coef), n, rate_hz, ci, channel)


@functools.lru_cache(maxsize=512)
def _expected_figures(
    coef_t: tuple[float, ...], n: int, rate_hz: float, ci: float, channel: str
) -> dict[str, Figure]:
    """The figures :func:`fit_noise` would give from ``n`` samples at ``rate_hz`` of a
    recording that follows the model ``coef`` (N², B², K²) exactly: the same reading rules, on
    the model's curve with the intervals of that length."""
    coef = np.array(coef_t)
    m = tau_grid(n)
    tau = m / rate_hz
    curve = AllanCurve(tau, np.sqrt(basis(tau) @ coef), n, rate_hz)
    edfs = curve_edf(curve, coef)
    lo, hi = chi2_interval(curve.adev**2, edfs, ci)
    full = AllanCurve(tau, curve.adev, n, rate_hz, edfs, lo, hi, ci)
    units = UNITS[sensor_of(channel)]
    sl = _slopes(full, coef)
    figs = [_read_term(k, full, coef, lo, hi, units[k], slopes=sl) for k in range(3)]
    for _ in range(2):
        figs = [
            _read_term(k, full, coef, lo, hi, units[k], _bands(k, tau, figs, coef), sl)
            for k in range(3)
        ]
    return dict(zip(QUANTITIES, figs, strict=True))


def relative_precision(interval: tuple[float, float]) -> float:
    """The larger relative distance of an interval's ends from the value (1 = the value)."""
    return max(interval[1] - 1.0, 1.0 - interval[0])


def plan_duration(
    coef: np.ndarray,
    k: int,
    precision: float,
    rate_hz: float,
    ci: float = CI_LEVEL,
    max_s: float = 30 * 86400.0,
) -> float | None:
    """Shortest recording (s) whose figure k, read as :func:`analyse` reads it, has a
    confidence interval within ±``precision`` (relative) under the model ``coef``; None when
    not reachable within ``max_s``."""

    if coef[k] <= 0:
        return None

    def ok(seconds: float) -> bool:
        n = int(seconds * rate_hz)
        if n < 64:
            return False
        f = expected_figures(coef, n, rate_hz, ci)[QUANTITIES[k]]
        if f.value is None or f.value <= 0:
            return False
        return relative_precision((f.ci[0] / f.value, f.ci[1] / f.value)) <= precision

    hi = 10.0
    while not ok(hi):
        hi *= 2.0
        if hi > max_s:
            return None
    lo = hi / 2.0
    for _ in range(20):
        mid = math.sqrt(lo * hi)
        if ok(mid):
            hi = mid
        else:
            lo = mid
        if hi / lo < 1.05:
            break
    return hi
