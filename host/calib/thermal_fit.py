"""Thermal calibration: fit each channel's bias against chip temperature from static records.

Records at several temperatures or along a ramp (the dialogue's warm-up, a chamber, a heat
gun and patience), in any attitudes, are cut into windows of ``window_s`` seconds; each window
gives a mean temperature and a mean reading per channel. Per channel the model is (method.md §8,
"parameters drift with temperature … fits bias(T)")::

    reading = offset[attitude] + Σ_{j=1..k} c_j·(T − T_ref)^j

The offset of each attitude holds gravity's projection and the bias at ``T_ref``. The order k is
chosen, not fixed: by BIC and by held-out prediction (blocks of neighbouring temperatures left
out in turn) — the lower of the two orders, so both criteria agree the extra terms help. The fit
refuses, naming the span needed, when the span cannot determine the order asked
(:data:`SPAN_PER_ORDER_C` per polynomial order), and when the attitudes cannot separate gravity
from temperature (each attitude measured at one temperature only). The residual's slow bias
wander is modelled (:func:`fit_wander`) so that the coefficients' covariance is honest.

The result it returns, :class:`host.calib.thermal.ThermalCalibration`, and its use are
:mod:`host.calib.thermal`.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np

from host.calib.thermal import CHANNELS, UNITS, ChannelThermal, ThermalCalibration
from host.errors import UserError
from host.session.records import Record

#: temperature span each polynomial order needs, °C (a linear bias(T) needs 4 °C, a cubic 12)
SPAN_PER_ORDER_C = 4.0
#: highest order tried by default
MAX_ORDER = 4


# --------------------------------------------------------------------------- data
@dataclass(frozen=True)
class ThermalPoints:
    """Window means: ``temp_c`` (M,) °C, ``values`` (M, 6) ax..gz (m/s², °/s), ``group`` (M,)
    attitude index into ``attitudes`` (labels), ``order`` (M,) time order of the windows,
    ``run`` (M,) the record each window comes from (a record's windows are consecutive, in
    time order)."""

    temp_c: np.ndarray
    values: np.ndarray
    group: np.ndarray
    attitudes: tuple[str, ...]
    order: np.ndarray
    run: np.ndarray | None = None
    #: (M,) s since power-on of each window's middle (from meta ``power_on_s``; without it, time
    #: within the record, and ``timed`` is False: records are then taken as unrelated in time)
    time_s: np.ndarray | None = None
    timed: bool = True
    #: (M, 3) the up direction of each window's attitude in chip axes (NaN: not known)
    up: np.ndarray | None = None


def attitude_key(rec: Record) -> str:
    """The attitude a static record was made in: its up vector rounded (meta ``up`` or the
    name), else the record's name."""
    try:
        up = rec.up
    except UserError:
        return rec.name
    return "[" + ", ".join(f"{v:+.2f}" for v in up) + "]"


def _record_windows(rec: Record, window_s: float) -> np.ndarray:
    """(W, 8) the means of one record's windows of ``window_s`` s that hold two samples and
    at least half a window: accel (3), gyro (3), chip temperature, time in the record, s."""
    t = rec.t_ms / 1000.0
    idx = np.floor((t - t[0]) / window_s).astype(np.int64)
    data = np.column_stack([rec.accel, rec.gyro, rec.temp, t])
    # windows are runs of equal idx (t rises): sums by np.add.reduceat
    first = np.flatnonzero(np.diff(idx, prepend=idx[0] - 1))
    count = np.diff(np.append(first, idx.size))
    last = first + count - 1
    means = np.add.reduceat(data, first, axis=0) / count[:, None]
    keep = (count >= 2) & (t[last] - t[first] >= 0.5 * window_s)
    return means[keep]


def window_means(records: Iterable[Record], window_s: float = 20.0) -> ThermalPoints:
    """Cut each static record into windows of ``window_s`` s (the last partial window is
    dropped if shorter than half) and average temperature and channels in each."""
    temps: list[float] = []
    vals: list[np.ndarray] = []
    groups: list[int] = []
    times: list[float] = []
    runs: list[int] = []
    ups: list[np.ndarray] = []
    keys: list[str] = []
    timed = True
    longest = 0.0  # the longest static record, s (to say why none gave a window)
    for r_i, rec in enumerate(records):
        if rec.kind == "turn" or len(rec) < 2:
            continue
        longest = max(longest, float(rec.t_ms[-1] - rec.t_ms[0]) / 1000.0)
        key = attitude_key(rec)
        try:
            up = np.asarray(rec.up, dtype=np.float64)
        except UserError:
            up = np.full(3, np.nan)
        timed = timed and "power_on_s" in rec.meta
        start = float(rec.meta.get("power_on_s", 0.0) or 0.0)
        means = _record_windows(rec, window_s)
        if not len(means):  # no window: its attitude is no unknown of the fit (was: a zero
            continue  # column, 'each attitude was measured at a single temperature')
        if key not in keys:
            keys.append(key)
        for mean in means:
            temps.append(float(mean[6]))
            vals.append(mean[:6])
            groups.append(keys.index(key))
            times.append(start + float(mean[7]))
            runs.append(r_i)
            ups.append(up)
    if not temps and longest > 0:
        raise UserError(
            f"the static records are at most {longest:.1f} s long, shorter than half of the "
            f"{window_s:g} s averaging window, so none gives a window mean: give "
            f"--window {max(1, int(longest // 2))} (or the warm-up record)"
        )
    if not temps:
        raise UserError(
            "no static records to fit bias(T): give the warm-up, static or thermal records"
        )
    return ThermalPoints(
        np.array(temps),
        np.array(vals),
        np.array(groups, dtype=np.int64),
        tuple(keys),
        np.argsort(np.argsort(np.array(times))),
        np.array(runs, dtype=np.int64),
        np.array(times),
        timed,
        np.array(ups).reshape(-1, 3),
    )


# --------------------------------------------------------------------------- the fit
def design(
    temp_c: np.ndarray, group: np.ndarray, n_groups: int, order: int, t_ref: float, scale: float
) -> np.ndarray:
    """(M, n_groups + order): one column per attitude offset, then ((T − T_ref)/scale)^j."""
    x = np.zeros((temp_c.size, n_groups + order))
    x[np.arange(temp_c.size), group] = 1.0
    d = (temp_c - t_ref) / scale
    for j in range(1, order + 1):
        x[:, n_groups + j - 1] = d**j
    return x


def _lstsq(x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, float]:
    beta, *_ = np.linalg.lstsq(x, y, rcond=None)
    r = y - x @ beta
    return beta, float(r @ r)


def heldout_rmse(
    temp_c: np.ndarray, y: np.ndarray, group: np.ndarray, n_groups: int, order: int,
    t_ref: float, scale: float, folds: int = 5,
) -> float:  # fmt: skip
    """Root-mean-square error predicting blocks of neighbouring temperatures left out in turn:
    the points in temperature order are cut into ``2·folds`` blocks, fold f leaves out blocks
    f and f + folds (long blocks, so slowly correlated noise cannot be interpolated)."""
    m = temp_c.size
    rank = np.argsort(np.argsort(temp_c))
    fold = (rank * 2 * folds // m) % folds
    err: list[float] = []
    x = design(temp_c, group, n_groups, order, t_ref, scale)
    for f in range(folds):
        test = fold == f
        train = ~test
        # an attitude with no training point cannot be predicted: skip its points
        known = np.isin(group, np.unique(group[train]))
        test &= known
        if not np.any(test) or np.count_nonzero(train) <= x.shape[1]:
            continue
        beta, _ = _lstsq(x[train], y[train])
        err.extend(((y[test] - x[test] @ beta) ** 2).tolist())
    return math.sqrt(float(np.mean(err))) if err else math.inf


#: BIC's log m per temperature coefficient is multiplied by this: the wander's variance and
#: correlation time are estimated from the same record, a few correlation times long, and come
#: out too small, so the plain penalty lets wander pass for a higher order (15 simulated
#: chamber ramps with bias instability, 90 channels: 12 wrong orders at 1, 4 at 1.5)
BIC_PENALTY = 1.5
#: the coefficients' covariance is the widest over the wander parameters whose log-likelihood
#: lies within this of the best (χ²₂(0.95)/2: their joint 95 % region)
WANDER_LIKELIHOOD_DROP = 3.0
#: the bias wander's correlation times tried, as multiples of the window (Gauss–Markov)
WANDER_TAUS = (2.0, 5.0, 15.0, 50.0, 150.0, 500.0)
#: the wander's variance tried, per variance of the white part of a window mean
WANDER_RATIOS = (0.0, 0.03, 0.1, 0.3, 1.0, 3.0, 10.0, 30.0, 100.0, 1000.0)


def whiten(
    z: np.ndarray, sequence: np.ndarray, dt: np.ndarray, ratio: np.ndarray, tau_s: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Rows of ``z`` (M, c) whitened for a residual = white noise (variance 1) + a Gauss–Markov
    wander (variance ``ratio``, correlation time ``tau_s``; G of each, one whitening per pair):
    the Kalman filter's innovations over the windows in ``sequence`` order, each divided by
    its standard deviation. ``dt`` (M,) time since the previous window in that order (∞:
    unrelated, the wander starts anew). Returns the whitened rows (G, M, c) in ``sequence``
    order and log det of each covariance (G,)."""
    ratio = np.asarray(ratio, dtype=np.float64).reshape(-1)
    tau = np.asarray(tau_s, dtype=np.float64).reshape(-1)
    out = np.empty((ratio.size, sequence.size, z.shape[1]))
    a = np.zeros((ratio.size, z.shape[1]))
    p = ratio.copy()
    logdet = np.zeros(ratio.size)
    for i, row in enumerate(sequence):
        phi = np.exp(-dt[i] / tau) if math.isfinite(dt[i]) else np.zeros_like(tau)
        a *= phi[:, None]
        p = phi * phi * p + ratio * (1.0 - phi * phi)
        v = z[row][None, :] - a
        s = p + 1.0
        out[:, i] = v / np.sqrt(s)[:, None]
        logdet += np.log(s)
        k = p / s
        a += k[:, None] * v
        p = p * (1.0 - k)
    return out, logdet


@dataclass(frozen=True)
class WanderFit:
    """Generalised least squares of one order with a white + Gauss–Markov residual:
    ``beta``, ``cov`` its covariance, ``loglik`` the log-likelihood maximised over the wander's
    variance ratio and correlation time (``ratio``, ``tau_s``), σ² profiled out."""

    beta: np.ndarray
    cov: np.ndarray
    loglik: float
    ratio: float
    tau_s: float


def fit_wander(
    x: np.ndarray, ys: np.ndarray, pts: ThermalPoints, orders: Sequence[int], n_fixed: int,
    window_s: float,
) -> list[list[WanderFit]]:  # fmt: skip
    """For each column y of ``ys`` (M, C) and order k in ``orders``, the fit of y on the first
    ``n_fixed`` + k columns of ``x`` with a white + Gauss–Markov residual along time (one
    list per column), maximum likelihood over
    :data:`WANDER_RATIOS` × :data:`WANDER_TAUS` (σ² profiled: log L = −(m/2)·log(RSS/m) −
    ½·log det). Slow bias wander (instability) is then noise with its own correlation, not a
    temperature effect of higher order."""
    m, n_y = ys.shape
    if pts.time_s is not None and pts.timed:
        seq = np.argsort(pts.time_s, kind="stable")
        dt = np.diff(pts.time_s[seq], prepend=-math.inf)
    else:  # records without power-on times: each on its own
        seq = np.arange(m)
        run = pts.run if pts.run is not None else np.zeros(m, dtype=np.int64)
        t = pts.time_s if pts.time_s is not None else np.arange(m) * window_s
        dt = np.diff(t, prepend=-math.inf)
        dt[1:][run[1:] != run[:-1]] = math.inf
    nx = x.shape[1]
    z = np.column_stack([x, ys])
    combos = [(0.0, 1.0)] + [(r, f * window_s) for r in WANDER_RATIOS[1:] for f in WANDER_TAUS]
    ratios = np.array([c[0] for c in combos])
    taus = np.array([c[1] for c in combos])
    zws, logdets = whiten(z, seq, dt, ratios, taus)
    lls = np.empty((len(combos), len(orders), n_y))
    for g in range(len(combos)):
        zw = zws[g]
        for i, k in enumerate(orders):
            xw = zw[:, : n_fixed + k]
            beta, *_ = np.linalg.lstsq(xw, zw[:, nx:], rcond=None)
            rss = np.maximum(np.sum((zw[:, nx:] - xw @ beta) ** 2, axis=0), 1e-300)
            lls[g, i] = -0.5 * m * np.log(rss / m) - 0.5 * logdets[g]
    out: list[list[WanderFit]] = []
    for c in range(n_y):
        row = []
        for i, k in enumerate(orders):
            g_best = int(np.argmax(lls[:, i, c]))
            # the wander's parameters are uncertain (a few correlation times in a record):
            # the covariance is the widest among those within the likelihood's 95 % region
            # (log L within χ²₂(0.95)/2 = 3.0 of the best), so the band does not rest on the
            # luckiest guess of them
            cov, beta = None, None
            for g_i in np.flatnonzero(lls[:, i, c] >= lls[g_best, i, c] - WANDER_LIKELIHOOD_DROP):
                g = int(g_i)
                xw, yw = zws[g][:, : n_fixed + k], zws[g][:, nx + c]
                b_g, rss1 = _lstsq(xw, yw)
                cov_g = rss1 / max(m - xw.shape[1], 1) * np.linalg.pinv(xw.T @ xw)
                if g == g_best:
                    beta = b_g
                if cov is None or np.trace(cov_g[n_fixed:, n_fixed:]) > np.trace(
                    cov[n_fixed:, n_fixed:]
                ):
                    cov = cov_g
            assert cov is not None and beta is not None
            ratio, tau = combos[g_best]
            row.append(WanderFit(beta, cov, float(lls[g_best, i, c]), ratio, tau))
        out.append(row)
    return out


def span_needed(order: int) -> float:
    """Temperature span (°C) a polynomial of ``order`` needs (:data:`SPAN_PER_ORDER_C`)."""
    return SPAN_PER_ORDER_C * max(order, 1)


def fit_channel(
    pts: ThermalPoints,
    j: int,
    t_ref: float,
    max_order: int,
    fixed_order: int | None = None,
    window_s: float = 20.0,
    fits: Sequence[WanderFit] | None = None,
) -> ChannelThermal:
    """Fit channel j's bias(T), choosing the order 0..``max_order`` by BIC and held-out
    prediction (the lower of the two), or ``fixed_order``.

    The window means' residual is not independent: bias instability wanders slowly (a
    Gauss–Markov bias with a correlation time of minutes), and along a ramp that wander is
    smooth in temperature too, where a polynomial of higher order would take it for a
    temperature effect. The likelihood behind BIC is therefore that of white noise plus a
    Gauss–Markov wander along time (:func:`fit_wander`, both fitted for each order),
    BIC = −2·log L + (n_attitudes + :data:`BIC_PENALTY`·k)·log m, and the coefficients'
    covariance is that of the same fit."""
    t, y, grp = pts.temp_c, pts.values[:, j], pts.group
    ng = len(pts.attitudes)
    scale = max(float(np.ptp(t)) / 2.0, 1e-6)
    m = t.size
    top = max(max_order, fixed_order or 0)
    x_all = design(t, grp, ng, top, t_ref, scale)
    if fits is None:
        fits = fit_wander(x_all, y[:, None], pts, range(top + 1), ng, window_s)[0]
    cvs = [heldout_rmse(t, y, grp, ng, k, t_ref, scale) for k in range(max_order + 1)]
    bics = tuple(-2.0 * f.loglik + (ng + BIC_PENALTY * k) * math.log(m) for k, f in enumerate(fits))
    if fixed_order is not None:
        order = fixed_order
    else:
        order = min(int(np.argmin(bics[: max_order + 1])), int(np.argmin(cvs)))
    fit = fits[order]
    x = x_all[:, : ng + order]
    rss_k = float(np.sum((y - x @ fit.beta) ** 2))
    sc = np.array([scale**-i for i in range(1, order + 1)])
    coef = fit.beta[ng:] * sc
    cov = fit.cov[ng:, ng:] * np.outer(sc, sc)
    return ChannelThermal(
        CHANNELS[j],
        UNITS[j],
        order,
        tuple(float(c) for c in coef),
        tuple(tuple(float(v) for v in row) for row in cov),
        float(np.sqrt(rss_k / m)),
        bics,
        tuple(cvs),
    )


#: highest order of the accelerometer scale against temperature
MAX_SCALE_ORDER = 2
#: nominal gravity, m/s²: the specific force of a static attitude, up · g (for the scale term)
G_NOMINAL = 9.80665


@dataclass(frozen=True, eq=False)
class _ScaleProblem:
    """Accelerometer channel ``j``'s scale against temperature as it is fitted: its window
    means ``y`` (M,) at ``temp_c`` (M,) °C in the attitudes ``group`` (``n_groups`` of them),
    gravity along the axis at each (``force``, m/s²; NaN where an attitude's direction is not
    known), the temperature about ``t_ref`` in units of half the span (``d``, ``span`` °C)
    and the scale's columns ``force·d^q``, q = 1 … ``q_top``."""

    j: int
    temp_c: np.ndarray
    y: np.ndarray
    group: np.ndarray
    n_groups: int
    t_ref: float
    span: float
    force: np.ndarray
    d: np.ndarray
    q_top: int

    @property
    def scale_cols(self) -> list[np.ndarray]:
        """The scale's columns force·d^q, q = 1 … ``q_top``."""
        return [self.force * self.d**q for q in range(1, self.q_top + 1)]

    def design(self, k: int, q: int) -> np.ndarray:
        """(M, n_groups + k + q): the attitudes' offsets, bias order ``k``, scale order ``q``."""
        x = design(self.temp_c, self.group, self.n_groups, k, self.t_ref, self.span)
        return np.column_stack([x, *self.scale_cols[:q]])


def _scale_problem(pts: ThermalPoints, j: int, t_ref: float, top: int) -> _ScaleProblem:
    """Channel ``j``'s window means set up for :func:`fit_scale` (scale orders up to ``top``,
    at most :data:`MAX_SCALE_ORDER`)."""
    t = pts.temp_c
    span = max(float(np.ptp(t)) / 2.0, 1e-6)
    force = (pts.up[:, j] if pts.up is not None else np.full(t.size, np.nan)) * G_NOMINAL
    q_top = min(MAX_SCALE_ORDER, max(top, 1))
    return _ScaleProblem(j, t, pts.values[:, j], pts.group, len(pts.attitudes), t_ref, span,
                         force, (t - t_ref) / span, q_top)  # fmt: skip


def _scale_determinable(sp: _ScaleProblem, k: int, required: bool) -> bool:
    """Whether gravity along the axis is known at every attitude and the first scale column
    stands apart from the offsets and the bias order ``k``; not determinable and
    ``required``: UserError naming the axis and the records needed."""
    cols = sp.design(k, sp.q_top)[:, : sp.n_groups + k + 1]
    norm = np.linalg.norm(cols, axis=0)
    ok = bool(np.all(np.isfinite(sp.force))) and bool(np.all(norm > 0))
    if ok:
        sv = np.linalg.svd(cols / norm, compute_uv=False)
        ok = bool(sv[-1] > 1e-3 * sv[0])
    if not ok and required:
        name = CHANNELS[sp.j]
        raise UserError(
            f"{name}: the accelerometer's scale against temperature needs attitudes with "
            f"different gravity along {name[1]} (e.g. {name[1]} up and {name[1]} down), "
            "each measured across the temperature span; these records have "
            + ("attitudes of unknown direction" if not np.all(np.isfinite(sp.force)) else
               f"one gravity along {name[1]} over the span")
        )  # fmt: skip
    return ok


def _scale_orders(
    sp: _ScaleProblem, pts: ThermalPoints, orders: Iterable[int], k: int, window_s: float
) -> tuple[tuple[float, int, int, WanderFit] | None, float, tuple[float, ...]]:
    """The bias order and the scale order together (a scale change left out makes the bias
    look like wander): BIC over every pair of a bias order in ``orders`` and a scale order,
    with the scale as the last columns. -> (the best with a scale: (BIC, bias order, scale
    order, its fit), the best BIC without a scale, the BICs of every scale order at the bias
    order ``k``)."""
    best: tuple[float, int, int, WanderFit] | None = None
    no_scale = math.inf  # the best BIC without a scale term
    bics: tuple[float, ...] = ()
    m = sp.temp_c.size
    for kk in orders:
        xk = sp.design(kk, sp.q_top)
        fits = fit_wander(xk, sp.y[:, None], pts, range(sp.q_top + 1), sp.n_groups + kk,
                          window_s)[0]  # fmt: skip
        row = tuple(
            -2.0 * f.loglik + (sp.n_groups + BIC_PENALTY * (kk + q)) * math.log(m)
            for q, f in enumerate(fits)
        )
        if kk == k:
            bics = row
        no_scale = min(no_scale, row[0])
        for q in range(1, sp.q_top + 1):
            if best is None or row[q] < best[0]:
                best = (row[q], kk, q, fits[q])
    return best, no_scale, bics


def _with_scale(
    ch: ChannelThermal, sp: _ScaleProblem, k: int, q: int, fit: WanderFit,
    bics: tuple[float, ...],
) -> ChannelThermal:  # fmt: skip
    """``ch`` with bias order ``k`` and scale order ``q`` of ``fit``, in °C units (the fit's
    in units of half the span)."""
    x = sp.design(k, q)
    sc_b = np.array([sp.span**-i for i in range(1, k + 1)])
    sc_s = np.array([sp.span**-i for i in range(1, q + 1)])
    cols_b = slice(sp.n_groups, sp.n_groups + k)
    cols_s = slice(sp.n_groups + k, sp.n_groups + k + q)
    rss = float(np.sum((sp.y - x @ fit.beta) ** 2))
    return dataclasses.replace(
        ch,
        order=k,
        coef=tuple(float(c) for c in fit.beta[cols_b] * sc_b),
        cov=tuple(
            tuple(float(v) for v in r) for r in fit.cov[cols_b, cols_b] * np.outer(sc_b, sc_b)
        ),
        rms=float(np.sqrt(rss / sp.temp_c.size)),
        scale_order=q,
        scale_coef=tuple(float(c) for c in fit.beta[cols_s] * sc_s),
        scale_cov=tuple(
            tuple(float(v) for v in r) for r in fit.cov[cols_s, cols_s] * np.outer(sc_s, sc_s)
        ),
        scale_bic=bics,
    )


def fit_scale(
    pts: ThermalPoints,
    j: int,
    t_ref: float,
    ch: ChannelThermal,
    top: int,
    window_s: float = 20.0,
    required: bool = False,
    fixed_order: int | None = None,
) -> ChannelThermal:
    """Accelerometer channel j's scale against temperature on top of its bias(T) ``ch``:
    reading = offset(attitude) + Σ c_k·d^k + Σ s_q·d^q·g·up_j, d = T − T_ref. Determined
    only when attitudes with different gravity along the axis each span temperature (axis up
    and axis down along a ramp, say); the order q (0 … :data:`MAX_SCALE_ORDER`) is chosen by
    the same wander-aware BIC as the bias. Not determinable: ``ch`` unchanged, or UserError
    naming the axis and the records needed when ``required``."""
    sp = _scale_problem(pts, j, t_ref, top)
    if not _scale_determinable(sp, ch.order, required):
        return ch
    orders = [fixed_order] if fixed_order is not None else range(top + 1)
    best, no_scale, bics = _scale_orders(sp, pts, orders, ch.order, window_s)
    if best is None or best[0] >= no_scale:
        return dataclasses.replace(ch, scale_bic=bics)
    _, k, q, fit = best
    return _with_scale(ch, sp, k, q, fit, bics)


def fit_thermal(
    records: Sequence[Record],
    serial: str = "",
    order: int | None = None,
    max_order: int = MAX_ORDER,
    window_s: float = 20.0,
    t_ref_c: float | None = None,
    scale: bool | None = None,
) -> tuple[ThermalCalibration, ThermalPoints]:
    """Fit bias(T) of every channel from static ``records`` (any attitudes). ``order`` fixes
    the polynomial order; otherwise it is chosen per channel up to ``max_order`` (and no
    higher than the span supports). Raises UserError when the span or the attitudes cannot
    determine what is asked, naming the span needed.

    The accelerometers' scale against temperature (:func:`fit_scale`) is fitted where the
    attitudes allow (``scale`` None), for every accelerometer axis or refused naming what is
    missing (True), or not at all (False). Static records cannot show a gyro's scale."""
    pts = window_means(records, window_s)
    lo, hi = float(pts.temp_c.min()), float(pts.temp_c.max())
    span = hi - lo
    asked = order if order is not None else 1
    if span < span_needed(asked):
        what = "a linear bias(T)" if asked <= 1 else f"an order-{asked} bias(T)"
        raise UserError(
            f"temperature span {span:.1f} °C ({lo:.1f} to {hi:.1f} °C) cannot determine "
            f"{what}: it needs at least {span_needed(asked):.0f} °C "
            f"({SPAN_PER_ORDER_C:.0f} °C per polynomial order); record the warm-up from a "
            "cold start, or a chamber ramp (sim://?chamber=FROM:TO:MINUTES)"
        )
    top = min(max_order, int(span // SPAN_PER_ORDER_C)) if order is None else order
    # attitudes: each offset must be separable from bias(T) — the design must have full rank
    x = design(pts.temp_c, pts.group, len(pts.attitudes), max(top, 1), lo, max(span, 1e-6))
    if np.linalg.matrix_rank(x) < x.shape[1]:
        raise UserError(
            "the attitudes cannot separate gravity from temperature (each attitude was measured "
            "at a single temperature): measure one attitude across the whole span"
        )
    if t_ref_c is None:
        statics = [r for r in records if r.kind == "static" and r.name.endswith(("_up", "_dn"))]
        t_ref_c = float(np.mean([r.temp.mean() for r in statics])) if statics else (lo + hi) / 2.0
    # the wander's whitening is the same for every channel: one pass for all six
    top_fit = max(top, order or 0)
    t_scale = max(span / 2.0, 1e-6)
    x_all = design(pts.temp_c, pts.group, len(pts.attitudes), top_fit, t_ref_c, t_scale)
    every = fit_wander(
        x_all, pts.values, pts, range(top_fit + 1), len(pts.attitudes), window_s
    )  # fmt: skip
    chans = {
        CHANNELS[j]: fit_channel(pts, j, t_ref_c, top, order, window_s, every[j])
        for j in range(len(CHANNELS))
    }
    if scale is not False:
        for j in range(3):
            chans[CHANNELS[j]] = fit_scale(
                pts, j, t_ref_c, chans[CHANNELS[j]], top, window_s, bool(scale), order
            )
    cal = ThermalCalibration(serial, float(t_ref_c), lo, hi, chans, pts.attitudes)
    return cal, pts
