"""Unexplained structure: the residuals scanned against every signal.

The residuals of a fit are correlated, channel by channel, with every signal of the records
(temperature, its rate of change dT/dt, time since power-on, a step in time between two rows,
each input, its square, its magnitude, rate², …); the drop in
χ² each signal would give is tested, Holm-corrected over the family. A signal that explains a
channel better than any candidate term (:mod:`host.workbench.candidates`) is what the verdict
calls unexplained. A step found is named placed to the sample, with its 95 % ± and its size,
and a second step on its channel when the records tell two from one
(:mod:`host.workbench.steps`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from host.model.dataset import Dataset
from host.model.design import aggregate
from host.model.fit import Fit
from host.model.signals import AXES, SENSORS, RecordSignals
from host.model.stats import chi2_isf, chi2_sf
from host.workbench.candidates import ALPHA, IDENTIFIABLE_TOL, holm, json_number
from host.workbench.steps import (
    STEP,
    Placed,
    channel_cuts,
    place_steps,
    step_name,
    step_times,
    tail_weights,
)

#: |correlation| with session time from which a scanned signal is reported as confounded with
#: it (the plan's fixed order: the Z faces last makes "(specific force z)²" r ≈ 0.8 with time)
TIME_CONFOUNDED_R = 0.75


@dataclass(frozen=True)
class ScanHit:
    """Residual structure along a signal: ``r`` correlation of the (whitened) residual with
    the signal (after removing the model's columns), Δχ² if the signal were added."""

    sensor: str
    axis: str
    signal: str
    r: float
    delta_chi2: float
    p_value: float
    significant: bool
    #: correlation of the signal with time since power-on over these records (after the
    #: model's columns); |·| near 1: the plan measured them in an order that makes the two
    #: indistinguishable
    time_r: float = math.nan
    #: a step in time: each step placed to the sample (its time, ±, size; two when a second on
    #: the channel is significant given the first; :mod:`host.workbench.steps`)
    steps: tuple[Placed, ...] = ()

    @property
    def time_confounded(self) -> bool:
        """The signal moves with time since power-on in this plan, though it is not itself a
        function of time (a step in time or a drift is time: whether the two are told apart
        is the groups of equals' question, :mod:`host.workbench.equals`)."""
        of_time = self.signal.startswith(STEP) or "time since power-on" in self.signal
        return math.isfinite(self.time_r) and abs(self.time_r) >= TIME_CONFOUNDED_R and not of_time

    def describe(self) -> str:
        text = (
            f"{self.sensor}-{self.axis} residual correlates with {self.signal} "
            f"(r = {self.r:+.2f}, Δχ² = {self.delta_chi2:.1f})"
        )
        if self.time_confounded:
            text += (
                f"; CONFOUNDED with session time in this plan (r = {self.time_r:+.2f} with time "
                "since power-on: the records were measured in this order) — a drift or a bias "
                "step looks the same; measuring the attitudes in another order (or the closing "
                "re-measurement of the first one) separates them"
            )
        return text

    def to_dict(self) -> dict[str, Any]:
        return {
            "sensor": self.sensor, "axis": self.axis, "signal": self.signal,
            "r": json_number(self.r), "delta_chi2": json_number(self.delta_chi2),
            "p_value": json_number(self.p_value), "text": self.describe(),
            "time_r": json_number(self.time_r), "time_confounded": self.time_confounded,
            "steps": [{"at_s": p.at_s, "lo_s": p.lo_s, "hi_s": p.hi_s, "size": p.size,
                       "size_sd": p.size_sd, "delta_chi2": json_number(p.delta_chi2)}
                      for p in self.steps],
        }  # fmt: skip


SignalFn = Callable[[RecordSignals, str, int], np.ndarray]


def _signals(sensor: str) -> dict[str, SignalFn]:
    inp = "specific force" if sensor == "accel" else "rate"
    out: dict[str, SignalFn] = {
        "temperature": lambda s, sen, a: s.d_temp,
        "temperature²": lambda s, sen, a: s.d_temp**2,
        "time since power-on": lambda s, sen, a: s.hours,
        "(time since power-on)²": lambda s, sen, a: s.hours**2,
        f"|{inp}|²": lambda s, sen, a: np.sum(s.reference(sen) ** 2, axis=1),
        f"temperature × {inp} on the axis": lambda s, sen, a: s.d_temp * s.reference(sen)[:, a],
    }
    for k, ax in enumerate(AXES):
        out[f"{inp} {ax}"] = _component(k, 1)
        out[f"({inp} {ax})²"] = _component(k, 2)
        out[f"|{inp} {ax}|"] = _component(k, 0)
    if sensor == "gyro":
        for k, ax in enumerate(AXES):
            out[f"(specific force {ax})²"] = _force_squared(k)
            out[f"|specific force {ax}|"] = _force_squared(k, power=1)
    return out


def _plain_signals(
    ds: Dataset, sensor: str, warming: Mapping[str, np.ndarray]
) -> dict[str, SignalFn]:
    """The signals the scan tries on a channel of ``sensor`` that are not a step in time (the
    time signals only when the records carry their time since power-on), the chip's
    ``warming`` rates (:func:`warming_rates`) given."""
    out = {**_signals(sensor), WARMING: lambda s, sen, a: warming[s.name]}
    if not ds.time_known:
        out = {k: v for k, v in out.items() if not k.startswith("(time")}
    return out


def signal_function(ds: Dataset, sensor: str, name: str) -> SignalFn | None:
    """The scan's signal ``name`` on a channel of ``sensor`` (the first of a finding's names
    joined by ' / '), a step named to the sample as the scan writes it (one or two steps, their
    sizes) included; None when the scan has no such signal."""
    first = name.split(" / ")[0]
    if not first.startswith(STEP):  # the chip's warming is read only for its own signal
        plain = _plain_signals(ds, sensor, warming_rates(ds) if first == WARMING else {})
        return plain.get(first)
    fn = _steps(ds).get(first) if ds.time_known else None
    if fn is not None or not ds.time_known:
        return fn
    steps = step_times(ds.signals, first)
    if not steps:
        return None
    scale = steps[0][1] if steps[0][1] else 1.0

    def placed(s: RecordSignals, sen: str, a: int) -> np.ndarray:
        out = np.zeros(len(s.t_s))
        for t, size in steps:
            out += (size / scale) * (s.t_s > t)
        return out

    return placed


#: the scan's name of the chip's rate of change of temperature
WARMING = "dT/dt (the chip warming or cooling)"
#: half the span of the session's temperature samples a record's dT/dt is read from, s: a
#: record or two either side of it (10–15 s long, 15–25 s apart), so that the curve's bend is
#: read from two minutes of samples instead of one record's
WARMING_HALF_S = 60.0


def warming_rates(ds: Dataset) -> dict[str, np.ndarray]:
    """Record name -> (N,) the chip's rate of change of temperature at each of its samples,
    °C/s: the derivative of a quadratic in time fitted to every temperature sample of the
    session within :data:`WARMING_HALF_S` of the record's middle (the records before and
    after it too: the chip's temperature is a smooth curve, and one record's 10 s read its
    slope but not how it bends, which a bias following dT/dt shows between a static's
    blocks). On 10 independent sessions with such a bias (seeds 4000–4009) the signal
    explained 64–100 % of its channel's misfit (χ² − dof) with one slope per record, 100 %
    with this (half-spans of 45, 70, 100 s: 71–100, 99–100, 98–100 %). A straight line through
    the record's own samples where the window holds no more (records without their time since
    power-on, whose times are each their own)."""
    t_all = np.concatenate([s.t_s for s in ds.signals]) if ds.signals else np.zeros(0)
    temp_all = np.concatenate([s.temp_c for s in ds.signals]) if ds.signals else np.zeros(0)
    out: dict[str, np.ndarray] = {}
    for s in ds.signals:
        mid = float(np.mean(s.t_s)) if len(s.t_s) else 0.0
        own = float(np.ptp(s.t_s)) if len(s.t_s) else 0.0
        near = np.abs(t_all - mid) <= WARMING_HALF_S
        t, temp = (t_all[near], temp_all[near]) if ds.time_known else (s.t_s, s.temp_c)
        if not ds.time_known or not len(t) or float(np.ptp(t)) < 2.0 * max(own, 1e-9):
            t, temp = s.t_s, s.temp_c
            power = 1
        else:
            power = 2
        x = t - mid
        if len(x) <= power or float(np.ptp(x)) == 0.0:
            out[s.name] = np.zeros(len(s.t_s))
            continue
        coef = np.polynomial.polynomial.polyfit(x, temp, power)
        slope = coef[1] + (2.0 * coef[2] * (s.t_s - mid) if power == 2 else 0.0)
        out[s.name] = np.asarray(np.broadcast_to(slope, s.t_s.shape), dtype=float)
    return out


def step_cuts(ds: Dataset) -> list[tuple[float, str]]:
    """Every time a bias step is tried at, s (the records' own clock), with its name: the
    middle of each gap between two records taken one after the other ("a step in time after
    x_cw"), and each boundary between the rows of one record ("a step in time during x_cw,
    4.3 s in": between a static's blocks, a turn's still moments and moving blocks): the
    family the scan tests. Inside a record a step moves only the rows after it (a turn's
    integral by the part of the turn after it), which no step in a gap can fit; the step found
    is then placed to the sample (:mod:`host.workbench.steps`)."""
    order = sorted(range(len(ds.signals)), key=lambda i: float(ds.signals[i].t_s[0]))
    out: list[tuple[float, str]] = []
    for k, ri in enumerate(order):
        s = ds.signals[ri]
        seen = set()
        for e in _row_edges(ds, ri):
            cut = 0.5 * (float(s.t_s[e - 1]) + float(s.t_s[e]))
            name = f"{STEP} during {s.name}, {cut - float(s.t_s[0]):.1f} s in"
            if name not in seen:  # edges a sample apart: one step
                seen.add(name)
                out.append((cut, name))
        if k + 1 < len(order):
            after = ds.signals[order[k + 1]]
            cut = 0.5 * (float(s.t_s[-1]) + float(after.t_s[0]))
            out.append((cut, f"{STEP} after {s.name}"))
    return out


def _row_edges(ds: Dataset, record: int) -> list[int]:
    """The sample indices (0 < i < N) between two rows of ``record``: where one of its rows,
    on any channel, begins or ends, with some row ending at or before it and some beginning at
    or after it (a cut before its first row or after its last is its gap's step)."""
    n = len(ds.signals[record].t_s)
    starts: set[int] = set()
    ends: set[int] = set()
    for r, sensor, a in ds.rows_of:
        if r != record:
            continue
        on = ds.aggregator(record, sensor, a) != 0
        starts.update(int(i) for i in on.argmax(axis=1))
        ends.update(int(n - i) for i in on[:, ::-1].argmax(axis=1))
    if not starts:
        return []
    first_end, last_start = min(ends), max(starts)
    return sorted(e for e in starts | ends if 0 < e < n and first_end <= e <= last_start)


def _steps(ds: Dataset) -> dict[str, SignalFn]:
    """A bias step at each of :func:`step_cuts` (0 before, 1 after). Each is one more test of
    the Holm family, so scanning every cut costs the other signals nothing under the null
    beyond that correction. A drift or a warm-up looks partly like a step: the strongest
    signal wins, and the candidates (time_drift) are tested beside it."""
    out: dict[str, SignalFn] = {}
    for cut, name in step_cuts(ds):

        def fn(s: RecordSignals, sen: str, a: int, cut: float = cut) -> np.ndarray:
            return (s.t_s > cut).astype(float)

        out[name] = fn
    return out


def _joined(names: Sequence[str]) -> str:
    """One finding's name from the signals that move the records identically, the strongest
    form first: a run of steps (a step anywhere between two rows that carry this channel) is
    written by its first and last place."""
    steps = [n for n in names if n.startswith(STEP)]
    others = [n for n in names if not n.startswith(STEP)]
    if len(steps) > 2:
        steps = [steps[0], "…", steps[-1]]
    return " / ".join(steps + others if names[0].startswith(STEP) else others + steps)


def _component(k: int, power: int) -> SignalFn:
    """Signal: component ``k`` of the sensor's input; power 1, 2, or 0 for |·|."""

    def fn(s: RecordSignals, sen: str, a: int) -> np.ndarray:
        x = s.reference(sen)[:, k]
        return np.abs(x) if power == 0 else x**power

    return fn


def _force_squared(k: int, power: int = 2) -> SignalFn:
    """Signal: (f_k/g)², or |f_k|/g for ``power`` 1 (a gyro reading the specific force)."""

    def fn(s: RecordSignals, sen: str, a: int) -> np.ndarray:
        return np.asarray(np.abs(s.force[:, k] / s.g) ** power)

    return fn


def _columns(
    ds: Dataset, sensor: str, a: int, fns: Sequence[SignalFn], cuts: Sequence[float]
) -> np.ndarray | None:
    """(n_rows, len(fns) + len(cuts)) the signals ``fns`` and then a step at each of ``cuts``
    (s), aggregated onto the rows of channel ``a`` of ``sensor`` like a term's columns (a
    turn's accelerometer at its still moments and moving blocks: the rows' own weights, not
    the record's trapezoid); None when the channel has no rows."""
    out = np.zeros((ds.n_rows, len(fns) + len(cuts)))
    any_rows = False
    at = np.asarray(cuts, dtype=float)
    for ri, rs in enumerate(ds.signals):
        rows = ds.rows_of.get((ri, sensor, a))
        if rows is None:
            continue
        any_rows = True
        agg = ds.aggregator(ri, sensor, a)
        if fns:
            per_sample = np.empty((len(rs.t_s), len(fns)))
            for k, fn in enumerate(fns):
                per_sample[:, k] = fn(rs, sensor, a)
            # each signal's round-off set to 0 against its own largest value
            scale = np.abs(per_sample).max(axis=0) if len(per_sample) else 0.0
            out[rows, : len(fns)] = aggregate(agg, per_sample, scale)
        if len(at):
            out[np.ix_(rows, np.arange(len(fns), out.shape[1]))] = _steps_aggregated(
                agg, rs.t_s, at
            )
    return out if any_rows else None


def _steps_aggregated(agg: np.ndarray, t_s: np.ndarray, cuts: np.ndarray) -> np.ndarray:
    """(B, len(cuts)) the rows of one record (``agg`` (B, N) over its sample times ``t_s``
    (N,) s) moved by a unit step at each of ``cuts`` (s): each row's weights summed over the
    samples after the cut (the reversed running sum, as :func:`host.workbench.steps.channel_cuts`
    builds every cut's), round-off below 1e-9 set to exactly 0
    (:func:`host.model.design.aggregate`)."""
    n = agg.shape[1]
    tail = np.zeros((agg.shape[0], n + 1))
    tail[:, :n] = tail_weights(agg)
    first_after = np.searchsorted(t_s, cuts, side="right")
    out = tail[:, first_after]
    if np.any(first_after < n):  # a sample after some cut: the step's largest value is 1
        out[np.abs(out) < 1e-9] = 0.0
    return out


class ScanColumns:
    """The scan's signals on the rows of ``ds``, whitened: the same for every fit the scan
    weighs them against on those rows (each fit removes its own columns), so built once per
    dataset by whoever scans it more than once, and dropped with the call."""

    def __init__(self, ds: Dataset) -> None:
        self.ds = ds
        #: every step the scan tries (:func:`step_cuts`) and the chip's warming rates
        self.cuts = step_cuts(ds) if ds.time_known else []
        self.warming = warming_rates(ds)
        self._white: dict[tuple[str, int], np.ndarray | None] = {}

    def named(self, sensor: str) -> list[tuple[str, SignalFn]]:
        """The signals other than the steps, by name, in the scan's order."""
        return list(_plain_signals(self.ds, sensor, self.warming).items())

    def white(self, sensor: str, a: int) -> np.ndarray | None:
        """(n_rows, signals [+ time since power-on] + cuts) whitened; None: no rows."""
        if (sensor, a) not in self._white:

            def hours(s: RecordSignals, sen: str, a: int) -> np.ndarray:
                return s.hours

            fns = [fn for _, fn in self.named(sensor)] + ([hours] if self.ds.time_known else [])
            x = _columns(self.ds, sensor, a, fns, [c for c, _ in self.cuts])
            self._white[(sensor, a)] = None if x is None else self.ds.whiten.apply(x)
        return self._white[(sensor, a)]


#: one signal tried on one channel: (sensor, axis index, signal name, r, Δχ²)
_Tried = tuple[str, int, str, float, float]
#: a channel's signals: whitened, their part the model does not fit, and time since power-on
#: (its part the model does not fit; None: the records carry none, or it is all the model's)
_Channel = tuple[np.ndarray, np.ndarray, np.ndarray | None]
#: per signal of a channel: its norm, its norm orthogonal to the model, the residual's
#: projection on that part and its correlation with time
_ChannelStats = tuple[list[float], list[float], list[float], list[float]]


def scan_signals(
    ds: Dataset, fit: Fit, alpha: float = ALPHA, columns: ScanColumns | None = None
) -> list[ScanHit]:
    """Residuals of ``fit`` against every signal on every channel, Holm-corrected; -> the
    significant hits, strongest first (``columns``: the signals already built on these rows,
    :class:`ScanColumns`)."""
    if columns is None or columns.ds is not ds:
        columns = ScanColumns(ds)
    r = fit.white_residual
    tried: list[_Tried] = []
    time_r: list[float] = []
    for sensor in SENSORS:
        named = columns.named(sensor)
        names = [k for k, _ in named] + [name for _, name in columns.cuts]
        chans = _sensor_channels(ds, columns, fit.basis, sensor, len(named))
        stats = {a: _channel_stats(chan, r) for a, chan in chans.items()}
        got, got_r = _try_signals(sensor, names, stats, float(r @ r))
        tried += got
        time_r += got_r
    pvals, is_sig = _holm_tested(tried, alpha)
    found = _findings(tried, pvals, is_sig, time_r)
    return _one_step_per_channel(ds, fit, found, [c for c, _ in columns.cuts], alpha)


def _sensor_channels(
    ds: Dataset, columns: ScanColumns, q: np.ndarray, sensor: str, n_named: int
) -> dict[int, _Channel]:
    """Per channel of ``sensor`` with rows: every signal's whitened column and its part the
    model's orthonormal basis ``q`` does not fit, the time column (after the ``n_named``
    signals, when the records carry time since power-on) taken out beside them."""
    chans: dict[int, _Channel] = {}
    for a in range(3):
        cw = columns.white(sensor, a)
        if cw is None:
            continue
        cp = cw - q @ (q.T @ cw) if q.shape[1] else cw
        if ds.time_known:
            tcol = cp[:, n_named]
            keep = np.r_[0:n_named, n_named + 1 : cw.shape[1]]
            cw, cp = cw[:, keep], cp[:, keep]
            chans[a] = (cw, cp, tcol if float(np.linalg.norm(tcol)) > 0 else None)
        else:
            chans[a] = (cw, cp, None)
    return chans


def _channel_stats(chan: _Channel, r: np.ndarray) -> _ChannelStats:
    """Every signal of one channel at once, against the whitened residual ``r``: the column's
    norm, its norm orthogonal to the model, the residual's projection on that part and its
    correlation with time (NaN without a time column)."""
    cw_all, cp_all, tcol = chan
    n0 = np.linalg.norm(cw_all, axis=0)
    n1 = np.linalg.norm(cp_all, axis=0)
    ok = n1 > 0
    proj = np.where(ok, (r @ cp_all) / np.where(ok, n1, 1.0), 0.0)
    tr = np.full(len(n1), math.nan)
    if tcol is not None:
        tr = np.where(ok, (tcol @ cp_all) / np.where(ok, n1, 1.0), 0.0)
        tr /= float(np.linalg.norm(tcol))
    return n0.tolist(), n1.tolist(), proj.tolist(), tr.tolist()


def _try_signals(
    sensor: str,
    names: Sequence[str],
    stats: Mapping[int, _ChannelStats],
    rr: float,
) -> tuple[list[_Tried], list[float]]:
    """Each signal ``names`` on each channel of ``sensor`` that the model leaves a part of,
    signal by signal, and its correlation with time (``rr``: the whitened residual's squared
    norm; none when it is 0)."""
    tried: list[_Tried] = []
    time_r: list[float] = []
    for j, name in enumerate(names):
        for a in range(3):
            if a not in stats:
                continue
            n0s, n1s, projs, trs = stats[a]
            if n0s[j] == 0 or n1s[j] < IDENTIFIABLE_TOL * n0s[j] or rr == 0:
                continue
            tried.append((sensor, a, name, projs[j] / math.sqrt(rr), projs[j] * projs[j]))
            time_r.append(trs[j])
    return tried, time_r


def _holm_tested(tried: Sequence[_Tried], alpha: float) -> tuple[list[float], list[bool]]:
    """Each tried signal's p and whether it is significant, Holm-corrected over them all. A
    Δχ² below the α-quantile of χ²₁ is never significant, whatever Holm's rank: its p (beyond
    α) is not needed, only that it sorts after every p ≤ α."""
    floor = 0.99 * chi2_isf(alpha, 1) if 0.0 < alpha < 1.0 else 0.0
    pvals = [chi2_sf(h[4], 1) if h[4] >= floor else 1.0 for h in tried]
    return pvals, holm(pvals, alpha)


def _findings(
    tried: Sequence[_Tried], pvals: Sequence[float], is_sig: Sequence[bool],
    time_r: Sequence[float],
) -> list[ScanHit]:  # fmt: skip
    """The significant signals as findings: those that move the records identically on one
    channel (|f|, f², … on ±1 g faces: the same Δχ²) are one finding, named by them all."""
    merged: dict[tuple[str, int, float], list[int]] = {}
    for i, h in enumerate(tried):
        if is_sig[i]:
            merged.setdefault((h[0], h[1], round(h[4], 6)), []).append(i)
    return [
        ScanHit(tried[ix[0]][0], AXES[tried[ix[0]][1]], _joined([tried[i][2] for i in ix]),
                tried[ix[0]][3], tried[ix[0]][4], pvals[ix[0]], True, time_r[ix[0]])
        for ix in merged.values()
    ]  # fmt: skip


def _one_step_per_channel(
    ds: Dataset, fit: Fit, found: Sequence[ScanHit], coarse_s: list[float], alpha: float
) -> list[ScanHit]:
    """The findings strongest first, one step per channel: a step at the times either side of
    the strongest one is the same finding, less well placed; the one kept is placed to the
    sample (the scan's cuts ``coarse_s``, s)."""
    kept: list[ScanHit] = []
    stepped: set[tuple[str, str]] = set()
    for hit in sorted(found, key=lambda x: -x.delta_chi2):
        if hit.signal.startswith(STEP):
            if (hit.sensor, hit.axis) in stepped:
                continue
            stepped.add((hit.sensor, hit.axis))
            hit = _placed(ds, fit, hit, coarse_s, alpha)
        kept.append(hit)
    return sorted(kept, key=lambda x: -x.delta_chi2)


def time_column(ds: Dataset, fit: Fit, sensor: str, axis: str) -> np.ndarray | None:
    """(n_rows,) time since power-on on the channel's rows, whitened, the fit's columns removed:
    the drift a second step must beat (:func:`host.workbench.steps.place_steps`); None when
    the records carry no power-on time or the channel no rows."""
    if not ds.time_known:
        return None
    x = _columns(ds, sensor, AXES.index(axis), [lambda s, sen, a: s.hours], [])
    if x is None:
        return None
    w = ds.whiten.apply(x)[:, 0]
    return np.asarray(w - fit.basis @ (fit.basis.T @ w) if fit.basis.shape[1] else w)


def _placed(ds: Dataset, fit: Fit, hit: ScanHit, coarse_s: list[float], alpha: float) -> ScanHit:
    """A step the scan found at a cut, placed to the sample (one or two steps on its channel,
    :func:`host.workbench.steps.place_steps`) and named so, with their joint Δχ²."""
    cuts = channel_cuts(ds, fit.basis, hit.sensor, AXES.index(hit.axis))
    if cuts is None:
        return hit
    r = fit.white_residual
    steps = place_steps(
        cuts, r, fit.dof, coarse_s, alpha, time_column(ds, fit, hit.sensor, hit.axis)
    )
    if not steps:
        return hit
    unit = "m/s²" if hit.sensor == "accel" else "°/s"
    name = ", and ".join(step_name(ds.signals, p, unit) for p in steps)
    others = [n for n in hit.signal.split(" / ") if n != "…" and not n.startswith(STEP)]
    d2 = max(steps[0].joint, hit.delta_chi2)
    rr = float(r @ r)
    return ScanHit(
        hit.sensor, hit.axis, " / ".join([name, *others]),
        math.copysign(math.sqrt(min(d2 / rr, 1.0)), steps[0].size), d2,
        chi2_sf(d2, len(steps)), True, hit.time_r, steps,
    )  # fmt: skip
