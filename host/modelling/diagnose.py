"""Compare the model with the measurements, locate the misfit, name what is missing.

method.md §8: "large or trending residuals mean the model misses an effect (cross-coupling,
temperature …)"; §3: "the three bias estimates disagreeing is itself a sign the linear model is
missing something". :func:`diagnose` turns that into a test:

1. compare — per record and channel measured vs model, residual and z (:class:`~host.model.Fit`);
2. where it fails — |z| > 3, worst first, and within-record time spans that depart;
3. what is missing — every catalogue term not in the model, per sensor and axis, is added to
   the same data (Frisch-Waugh-Lovell: its columns orthogonalised to the model's). With the
   noise model's known variances the drop in χ² is χ²(k) under the null: p-values are
   Holm-corrected over all candidates (family α = 0.01). Each candidate reports ΔBIC, RMS z
   after, its coefficient ± std error, and whether the records can identify it at all (and what
   data would). Significant candidates are tested against each other: when neither adds
   significantly to the other they are CONFOUNDED (reported together); when one adds nothing
   to a better one it is "explained by" it;
4. unexplained structure — the residuals of the model plus the best candidate per channel are
   scanned against every signal (temperature, time, each input, its square, its magnitude,
   rate², …), Holm-corrected;
5. verdict — ``adequate`` / ``missing_effect`` / ``unexplained``, or ``untestable`` when
   nothing is found but some channel's record values leave no degrees of freedom (the model
   passes through them exactly: it is not tested at all, so it is never called adequate).

Length (over 600 lines): the diagnosis and its text rendering (the ``format_*`` functions, about a
quarter); the rendering could move beside the report — left while the diagnosis issue (#12)
is still changing both.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from host.errors import UserError
from host.modelling.model import (
    AXES,
    BASE,
    CATALOGUE,
    SENSORS,
    UNIT,
    Dataset,
    Fit,
    GroupResidual,
    ModelTerm,
    Prediction,
    RecordSignals,
    SpanResidual,
    Term,
    aggregate,
    chi2_sf,
    fit_model,
    leave_one_out,
    merge_model,
    model_spec,
    parse_model,
    residual_sigmas,
    term_columns,
)

#: family-wise error rate of each family of tests (candidates; signal scan; overall χ²)
ALPHA = 0.01
#: a candidate whose columns keep less than this fraction of their norm after removing the
#: model's columns cannot be identified from the records
IDENTIFIABLE_TOL = 1e-3
VERDICTS = ("adequate", "missing_effect", "unexplained", "untestable")
#: a candidate with p up to this many times the Bonferroni threshold is "just below
#: significance": it is still compared with the significant ones for confounding
NEAR_FACTOR = 100.0
#: the verdict advises adding terms only when together they remove at least this fraction of
#: the misfit (χ² − dof) of the model
MOST = 0.5
#: a signal of the residual scan "explains the channel better" than its best candidate when its
#: Δχ² exceeds the candidate's by this factor (equal: the candidate IS that signal)
DOMINANT = 1.05
#: |correlation| with session time from which a scanned signal is reported as confounded with
#: it (the plan's fixed order: the Z faces last makes "(specific force z)²" r ≈ 0.8 with time)
TIME_CONFOUNDED_R = 0.75


@dataclass(frozen=True)
class Candidate:
    """One term tried on top of the model (per sensor and axis).

    ``delta_chi2``: drop of χ²; ``p_value`` of the LR test (χ² with ``n_params`` dof);
    ``significant`` after Holm's correction; ``delta_bic`` = −Δχ² + k·ln n (negative: better);
    ``coefficient``/``stderr``/``unit`` of its (largest, in σ) parameter, ``coefficients`` all
    of them (name -> (value, stderr, unit)). ``identifiable`` False: ``reason`` says why and
    ``needs`` what data would help. ``confounded_with``: candidates the data cannot tell apart
    from this one; ``explained_by``: a better candidate that makes this one redundant.
    """

    term: str
    sensor: str
    axes: str
    n_params: int
    physics: str
    identifiable: bool
    reason: str = ""
    needs: str = ""
    delta_chi2: float = math.nan
    p_value: float = math.nan
    significant: bool = False
    delta_bic: float = math.nan
    rms_z_after: float = math.nan
    coefficient: float = math.nan
    stderr: float = math.nan
    unit: str = ""
    coefficients: Mapping[str, tuple[float, float, str]] = field(default_factory=dict)
    confounded_with: tuple[str, ...] = ()
    explained_by: str = ""
    implausible: str = ""

    @property
    def label(self) -> str:
        return f"{self.term}:{self.sensor}:{self.axes}"

    @property
    def channel(self) -> tuple[str, str]:
        return (self.sensor, self.axes)

    def to_dict(self) -> dict[str, Any]:
        return {
            "term": self.term, "sensor": self.sensor, "axes": self.axes, "label": self.label,
            "significant": self.significant, "identifiable": self.identifiable,
            "delta_chi2": _num(self.delta_chi2), "p_value": _num(self.p_value),
            "delta_bic": _num(self.delta_bic), "rms_z_after": _num(self.rms_z_after),
            "coefficient": _num(self.coefficient), "stderr": _num(self.stderr),
            "unit": self.unit,
            "coefficients": {k: {"value": _num(v), "stderr": _num(s), "unit": u}
                             for k, (v, s, u) in self.coefficients.items()},
            "confounded_with": list(self.confounded_with), "explained_by": self.explained_by,
            "reason": self.reason, "needs": self.needs, "physics": self.physics,
            "implausible": self.implausible,
        }  # fmt: skip


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

    @property
    def time_confounded(self) -> bool:
        return math.isfinite(self.time_r) and abs(self.time_r) >= TIME_CONFOUNDED_R

    def describe(self) -> str:
        text = (
            f"{self.sensor}-{self.axis} residual correlates with {self.signal} "
            f"(r = {self.r:+.2f}, Δχ² = {self.delta_chi2:.1f})"
        )
        if self.time_confounded and "time" not in self.signal:
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
            "r": _num(self.r), "delta_chi2": _num(self.delta_chi2),
            "p_value": _num(self.p_value), "text": self.describe(),
            "time_r": _num(self.time_r), "time_confounded": self.time_confounded,
        }  # fmt: skip


@dataclass(frozen=True, eq=False)
class Diagnosis:
    """Everything :func:`diagnose` found (see the module docstring)."""

    fit: Fit
    candidates: tuple[Candidate, ...]
    unexplained: tuple[ScanHit, ...]
    verdict: str
    notes: tuple[str, ...] = ()
    #: labels of the candidates the verdict advises adding (empty: none)
    recommended: tuple[str, ...] = ()
    #: per channel, the signal that explains the model's residual better than any candidate
    dominant: tuple[ScanHit, ...] = ()
    #: the model spec of the recommended terms (``diagnose --json`` key ``recommended``)
    recommended_spec: str | None = None
    #: local gravity of the dataset, m/s²
    g: float = 9.80665

    @property
    def worst(self) -> tuple[GroupResidual, ...]:
        """Record/channel residuals with |z| > 3, worst first."""
        bad = [g for g in self.fit.groups if abs(g.z) > 3.0]
        return tuple(sorted(bad, key=lambda g: -abs(g.z)))

    @property
    def worst_spans(self) -> tuple[SpanResidual, ...]:
        """Blocks departing from their record's own mean by |z| > 3, worst first."""
        bad = [s for s in self.fit.spans if abs(s.z) > 3.0]
        return tuple(sorted(bad, key=lambda s: -abs(s.z)))

    @property
    def significant(self) -> tuple[Candidate, ...]:
        return tuple(c for c in self.candidates if c.significant)

    def to_dict(self) -> dict[str, Any]:
        """The ``--json`` object."""
        f = self.fit
        return {
            "model": [mt.label for mt in f.model],
            "fit": {"rms_z": _num(f.rms_z), "chi2": _num(f.chi2), "chi2_p": _num(f.chi2_p),
                    "dof": f.dof, "n_rows": len(f.residual), "n_params": f.n_params},
            "parameters": [{"name": p.name, "term": p.term, "value": _num(p.value),
                            "stderr": _num(p.stderr), "unit": p.unit} for p in f.parameters],
            "compare": [_group_dict(g) for g in f.groups],
            "worst": [_group_dict(g) for g in self.worst],
            "worst_spans": [{"record": s.record, "channel": f"{s.sensor} {s.axis}",
                             "t0_s": s.t0_s, "t1_s": s.t1_s, "residual": _num(s.residual),
                             "z": _num(s.z), "unit": s.unit} for s in self.worst_spans],
            "candidates": [c.to_dict() for c in self.candidates],
            "unexplained": [h.to_dict() for h in self.unexplained],
            "verdict": self.verdict,
            "recommended": self.recommended_spec,
            "unexplained_signals": [h.to_dict() for h in self.dominant],
            "notes": list(self.notes),
        }  # fmt: skip


def _group_dict(g: GroupResidual) -> dict[str, Any]:
    return {
        "record": g.record, "channel": g.channel, "sensor": g.sensor, "axis": g.axis,
        "measured": _num(g.measured), "model": _num(g.model), "residual": _num(g.residual),
        "sigma": _num(g.sigma), "z": _num(g.z), "unit": g.unit,
    }  # fmt: skip


def _num(v: float) -> float | None:
    return float(v) if v is not None and math.isfinite(float(v)) else None


# ---- multiple testing -----------------------------------------------------------------------
def holm(p_values: Sequence[float], alpha: float = ALPHA) -> list[bool]:
    """Holm's step-down procedure: which of ``p_values`` are significant at family ``alpha``."""
    order = sorted(range(len(p_values)), key=lambda i: p_values[i])
    out = [False] * len(p_values)
    m = len(p_values)
    for rank, i in enumerate(order):
        if not p_values[i] <= alpha / (m - rank):
            break
        out[i] = True
    return out


# ---- one candidate --------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class _Tried:
    mt: ModelTerm
    cw_perp: np.ndarray  # whitened columns, orthogonalised to the model
    r: np.ndarray  # whitened residual to explain (offset of a nonlinear term removed)
    beta: np.ndarray
    cov: np.ndarray
    delta: float
    reason: str


def _try(ds: Dataset, fit: Fit, mt: ModelTerm) -> _Tried:
    """Add ``mt`` to the fitted model by orthogonal projection (exact for linear terms)."""
    x, off = term_columns(ds, mt)
    cw = ds.whiten @ x
    q = fit.basis

    def perp(v: np.ndarray) -> np.ndarray:
        return v - q @ (q.T @ v) if q.shape[1] else v

    cp = perp(cw)
    r = fit.white_residual - perp(ds.whiten @ off) if np.any(off) else fit.white_residual
    norms = np.linalg.norm(cw, axis=0)
    kept = np.linalg.norm(cp, axis=0)
    reason = ""
    if mt.term.check is not None:
        reason = mt.term.check(ds.signals) or ""
    if not reason and (np.any(norms == 0) or np.any(kept < IDENTIFIABLE_TOL * norms)):
        reason = (
            "no variation of its input in these records"
            if np.any(norms == 0)
            else "on these records it acts exactly like terms already in the model"
        )
    if not reason and cp.shape[1] > 1:
        s = np.linalg.svd(cp / kept, compute_uv=False)
        if s[-1] < IDENTIFIABLE_TOL * s[0]:
            reason = "its parameters cannot be told apart on these records"
    if reason:
        k = cp.shape[1]
        return _Tried(mt, cp, r, np.full(k, np.nan), np.full((k, k), np.nan), math.nan, reason)
    beta, *_ = np.linalg.lstsq(cp, r, rcond=None)
    cov = np.linalg.inv(cp.T @ cp)
    after = r - cp @ beta
    delta = float(fit.white_residual @ fit.white_residual - after @ after)
    return _Tried(mt, cp, r, beta, cov, delta, "")


def _conditional_delta(a: _Tried, b: _Tried) -> float:
    """Δχ² of adding ``b`` to the model that already holds ``a`` (both orthogonal to it)."""
    qa, _ = np.linalg.qr(a.cw_perp)
    cb = b.cw_perp - qa @ (qa.T @ b.cw_perp)
    ra = a.r - a.cw_perp @ a.beta
    if np.any(np.linalg.norm(cb, axis=0) < IDENTIFIABLE_TOL * np.linalg.norm(b.cw_perp, axis=0)):
        return 0.0
    beta, *_ = np.linalg.lstsq(cb, ra, rcond=None)
    after = ra - cb @ beta
    return float(ra @ ra - after @ after)


def candidate_terms(
    model: Sequence[ModelTerm], catalogue: Mapping[str, Term] | None = None
) -> list[ModelTerm]:
    """Every (term, sensor, axis) of the catalogue that the model does not hold."""
    cat = catalogue if catalogue is not None else CATALOGUE
    have = {(mt.term.name, mt.sensor, a) for mt in model for a in mt.axes}
    out = []
    for t in cat.values():
        for s in t.sensors:
            if t.shared:  # one set of parameters for all the channels: tried once
                if not any((t.name, s, a) in have for a in range(3)):
                    out.append(ModelTerm(t, s, (0, 1, 2)))
                continue
            for a in range(3):
                if (t.name, s, a) not in have:
                    out.append(ModelTerm(t, s, (a,)))
    return out


def evaluate_candidates(
    ds: Dataset,
    fit: Fit,
    catalogue: Mapping[str, Term] | None = None,
    alpha: float = ALPHA,
) -> tuple[list[Candidate], list[_Tried]]:
    """Try every candidate on ``fit``; Holm-correct; find confounded groups; sort best first."""
    tried = [_try(ds, fit, mt) for mt in candidate_terms(fit.model, catalogue)]
    n_rows = len(fit.residual)
    ident = [t for t in tried if not t.reason]
    pvals = [chi2_sf(t.delta, t.mt.n_params) for t in ident]
    sig = dict(zip([id(t) for t in ident], holm(pvals, alpha), strict=True))
    pv = dict(zip([id(t) for t in ident], pvals, strict=True))
    # significant candidates of the same channel against each other
    significant = [t for t in ident if sig[id(t)]]
    m = max(len(ident), 1)
    # members just below significance (p within NEAR_FACTOR of the threshold) join the
    # comparison: a group the data cannot resolve is reported whole
    near = [t for t in ident if not sig[id(t)] and pv[id(t)] <= NEAR_FACTOR * alpha / m]
    confounded: dict[int, list[str]] = {id(t): [] for t in tried}
    explained_by: dict[int, str] = {}
    pool = significant + near
    for i, a in enumerate(pool):
        for b in pool[i + 1 :]:
            if (a.mt.sensor, a.mt.axes) != (b.mt.sensor, b.mt.axes):
                continue
            if not (sig[id(a)] or sig[id(b)]):
                continue
            b_given_a = chi2_sf(_conditional_delta(a, b), b.mt.n_params) <= alpha / m
            a_given_b = chi2_sf(_conditional_delta(b, a), a.mt.n_params) <= alpha / m
            if not b_given_a and not a_given_b:
                confounded[id(a)].append(b.mt.label)
                confounded[id(b)].append(a.mt.label)
            elif a_given_b and not b_given_a:
                explained_by.setdefault(id(b), a.mt.label)
            elif b_given_a and not a_given_b:
                explained_by.setdefault(id(a), b.mt.label)
    out: list[tuple[Candidate, _Tried]] = []
    winv = np.linalg.inv(ds.whiten)
    for t in tried:
        mt = t.mt
        labels = mt.term.param_labels(mt.sensor, mt.axes[0])
        units = mt.term.param_units(mt.sensor)
        coefs: dict[str, tuple[float, float, str]] = {}
        best = 0
        if not t.reason:
            se = np.sqrt(np.diag(t.cov))
            coefs = {
                labels[j]: (float(t.beta[j]), float(se[j]), units[j]) for j in range(len(labels))
            }
            best = int(np.argmax(np.abs(t.beta) / se))
        name0 = labels[best]
        c0 = coefs.get(name0, (math.nan, math.nan, units[best]))
        after_rms = math.nan
        if not t.reason:
            after_rms = _rms_z_after(ds, fit, t, winv)
        out.append(
            (
                Candidate(
                    term=mt.term.name, sensor=mt.sensor,
                    axes="".join(AXES[a] for a in mt.axes),
                    n_params=mt.n_params, physics=mt.term.physics,
                    identifiable=not t.reason, reason=t.reason, needs=mt.term.needs,
                    delta_chi2=t.delta, p_value=pv.get(id(t), math.nan),
                    significant=bool(sig.get(id(t), False)),
                    delta_bic=(-t.delta + mt.n_params * math.log(max(n_rows, 2)))
                    if not t.reason else math.nan,
                    rms_z_after=after_rms, coefficient=c0[0], stderr=c0[1], unit=c0[2],
                    coefficients=coefs, confounded_with=tuple(confounded[id(t)]),
                    explained_by=explained_by.get(id(t), ""),
                    implausible=_implausible(mt, coefs, fit) if sig.get(id(t)) else "",
                ),
                t,
            )
        )  # fmt: skip

    def key(item: tuple[Candidate, _Tried]) -> tuple[int, int, float]:
        c = item[0]
        usable = c.significant and not c.explained_by and not c.implausible
        rank = 0 if usable else 1 if c.significant else 2
        if not c.identifiable:
            rank = 3
        return (rank, 0, c.delta_bic if math.isfinite(c.delta_bic) else math.inf)

    out.sort(key=key)
    # confounded partners right after the first of their group
    ordered: list[tuple[Candidate, _Tried]] = []
    placed: set[str] = set()
    by_label = {c.label: (c, t) for c, t in out}
    for c, t in out:
        if c.label in placed:
            continue
        ordered.append((c, t))
        placed.add(c.label)
        for other in c.confounded_with:
            if other not in placed and other in by_label:
                ordered.append(by_label[other])
                placed.add(other)
    return [c for c, _ in ordered], [t for _, t in ordered]


def _implausible(mt: ModelTerm, coefs: Mapping[str, tuple[float, float, str]], fit: Fit) -> str:
    """Why the fitted coefficients are not a physical reading of the term ("" if they are):
    beyond the term's documented plausible range, and — when the model lacks a base term on
    that channel — probably standing in for it (an alias)."""
    bound = mt.term.plausible.get(mt.sensor)
    if bound is None:
        return ""
    worst = max(coefs.items(), key=lambda kv: abs(kv[1][0]), default=None)
    if worst is None or abs(worst[1][0]) <= bound:
        return ""
    name, (v, _, unit) = worst
    why = f"{name} = {v:.3g} {unit} is beyond the plausible ±{bound:g} ({mt.term.plausible_source})"
    have = {(m.term.name, m.sensor, a) for m in fit.model for a in m.axes}
    missing = [b for b in BASE if (b, mt.sensor, mt.axes[0]) not in have
               and mt.sensor in CATALOGUE[b].sensors]  # fmt: skip
    if missing:
        why += "; probably an alias of the omitted base term(s) " + ", ".join(
            f"{b}:{mt.sensor}:{AXES[mt.axes[0]]}" for b in missing
        )
    return why


def _rms_z_after(ds: Dataset, fit: Fit, t: _Tried, winv: np.ndarray) -> float:
    """RMS of the record/channel z after adding the candidate: the refit's whitened residual
    is r − C⊥·β; ``winv`` = W⁻¹ brings it back to the rows."""
    resid_after = winv @ (t.r - t.cw_perp @ t.beta)
    q, _ = np.linalg.qr(t.cw_perp)
    basis = np.column_stack([fit.basis, q]) if fit.basis.shape[1] else q
    sd = residual_sigmas(ds, basis)
    zs = [
        float(np.mean(resid_after[gr.rows])) / sd[k]
        for k, gr in enumerate(ds.groups)
        if sd[k] > 1e-3 * gr.sigma
    ]
    return float(np.sqrt(np.mean(np.square(zs)))) if zs else math.nan


# ---- signal scan ----------------------------------------------------------------------------
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
    return out


def _component(k: int, power: int) -> SignalFn:
    """Signal: component ``k`` of the sensor's input; power 1, 2, or 0 for |·|."""

    def fn(s: RecordSignals, sen: str, a: int) -> np.ndarray:
        x = s.reference(sen)[:, k]
        return np.abs(x) if power == 0 else x**power

    return fn


def _force_squared(k: int) -> SignalFn:
    def fn(s: RecordSignals, sen: str, a: int) -> np.ndarray:
        return np.asarray((s.force[:, k] / s.g) ** 2)

    return fn


def scan_signals(ds: Dataset, fit: Fit, alpha: float = ALPHA) -> list[ScanHit]:
    """Residuals of ``fit`` against every signal on every channel, Holm-corrected; -> the
    significant hits, strongest first."""
    hits: list[tuple[str, int, str, float, float]] = []
    time_r: list[float] = []
    q = fit.basis
    r = fit.white_residual
    rr = float(r @ r)

    def column(fn: SignalFn, sensor: str, a: int) -> tuple[np.ndarray, np.ndarray] | None:
        col = np.zeros(ds.n_rows)
        any_rows = False
        for ri, rs in enumerate(ds.signals):
            rows = ds.rows_of.get((ri, sensor, a))
            if rows is None:
                continue
            any_rows = True
            # NOTE: the record's aggregator, also for the accelerometer rows of a turn (still
            # moments, moving blocks: ds.aggregator(ri, sensor, a) would be their own); kept
            # as it was, the hidden-effect verdicts are tuned to it (issue 12 report)
            col[rows] = aggregate(ds.aggregators[ri], np.asarray(fn(rs, sensor, a), float))
        if not any_rows:
            return None
        cw = ds.whiten @ col
        return cw, (cw - q @ (q.T @ cw) if q.shape[1] else cw)

    def hours(s: RecordSignals, sen: str, a: int) -> np.ndarray:
        return s.hours

    for sensor in SENSORS:
        for name, fn in _signals(sensor).items():
            if not ds.time_known and name.startswith("(time"):
                continue
            for a in range(3):
                cols = column(fn, sensor, a)
                if cols is None:
                    continue
                cw, cp = cols
                n0 = float(np.linalg.norm(cw))
                n1 = float(np.linalg.norm(cp))
                if n0 == 0 or n1 < IDENTIFIABLE_TOL * n0 or rr == 0:
                    continue
                proj = float(cp @ r) / n1
                hits.append((sensor, a, name, proj / math.sqrt(rr), proj * proj))
                tr = math.nan
                tcols = column(hours, sensor, a) if ds.time_known else None
                if tcols is not None and float(np.linalg.norm(tcols[1])) > 0:
                    tr = float(cp @ tcols[1]) / (n1 * float(np.linalg.norm(tcols[1])))
                time_r.append(tr)
    pvals = [chi2_sf(h[4], 1) for h in hits]
    is_sig = holm(pvals, alpha)
    # signals that move the records identically (|f|, f², … on ±1 g faces) are one finding
    merged: dict[tuple[str, int, float], list[int]] = {}
    for i, h in enumerate(hits):
        if is_sig[i]:
            merged.setdefault((h[0], h[1], round(h[4], 6)), []).append(i)
    out = [
        ScanHit(hits[ix[0]][0], AXES[hits[ix[0]][1]], " / ".join(hits[i][2] for i in ix),
                hits[ix[0]][3], hits[ix[0]][4], pvals[ix[0]], True, time_r[ix[0]])
        for ix in merged.values()
    ]  # fmt: skip
    return sorted(out, key=lambda h: -h.delta_chi2)


# ---- the diagnosis --------------------------------------------------------------------------
def diagnose(
    ds: Dataset,
    model: Sequence[ModelTerm],
    catalogue: Mapping[str, Term] | None = None,
    alpha: float = ALPHA,
) -> Diagnosis:
    """Fit ``model`` to ``ds`` and run the whole diagnosis (module docstring). UserError when
    the records leave the fit no degrees of freedom: then nothing tests the model, and any
    verdict (one record gave ``adequate``) would be a claim without evidence."""
    fit = fit_model(ds, model)
    if fit.dof <= 0:
        n = len(ds.signals)
        raise UserError(
            f"{n} record{' leaves' if n == 1 else 's leave'} the model no "
            f"degrees of freedom ({fit.n_params} parameters determined by as many values): "
            "nothing tests it; diagnose needs more records (at least the six static faces)"
        )
    cands, _ = evaluate_candidates(ds, fit, catalogue, alpha)
    cat = catalogue if catalogue is not None else CATALOGUE
    usable_all = [c for c in cands if c.significant and not c.explained_by and not c.implausible]
    top = max(usable_all, key=lambda c: c.delta_chi2, default=None)
    if top is not None and cat[top.term].shared:
        # a property of the bench (one set of parameters for every channel) explains more than
        # any single channel's term: take it first and diagnose what is left after it
        return _after_shared(ds, fit, cands, top, model, cat, alpha)
    # the best usable candidate of each channel (significant, plausible, not made redundant)
    best: dict[tuple[str, str], Candidate] = {}
    for c in cands:
        if c.significant and not c.explained_by and not c.implausible:
            best.setdefault(c.channel, c)
    # structure in the model's residual that a plain signal explains better than any candidate
    dominant: dict[tuple[str, str], ScanHit] = {}
    for h in scan_signals(ds, fit, alpha):
        ch = (h.sensor, h.axis)
        cb = best.get(ch)
        if ch not in dominant and (cb is None or h.delta_chi2 > DOMINANT * cb.delta_chi2):
            dominant[ch] = h
    usable = [c for ch, c in best.items() if ch not in dominant]
    extra = [ModelTerm(cat[c.term], c.sensor, tuple(AXES.index(a) for a in c.axes))
             for c in usable]  # fmt: skip
    aug = fit_model(ds, merge_model(list(model) + extra)) if extra else fit
    misfit = max(fit.chi2 - fit.dof, 0.0)
    removed = fit.chi2 - aug.chi2
    recommended = tuple(c.label for c in usable) if usable and removed >= MOST * misfit else ()
    hits = scan_signals(ds, aug, alpha)
    notes = list(ds.notes)
    if fit.undetermined:
        notes.append("not determined by these records: " + ", ".join(fit.undetermined))
        combos = [c.describe() for ch in fit.channels for c in ch.combinations]
        if combos:
            notes.append("identifiable from these records: only " + "; ".join(combos))
    if fit.untestable:
        notes.append(
            f"no degrees of freedom on {', '.join(fit.untestable)}: the model passes through "
            "these records exactly, so they cannot test it (add records: other attitudes, "
            "turns both ways)"
        )
    if fit.uncertainty_note():
        notes.append(fit.uncertainty_note())
    if usable and not recommended:
        notes.append(
            f"the best candidates ({', '.join(c.label for c in usable)}) remove only "
            f"{100 * removed / misfit:.0f} % of the misfit (χ² − dof = {misfit:.1f}): "
            "none of them is what is missing"
        )
    for c in cands:
        if c.implausible:
            notes.append(f"{c.label} is significant but not physical: {c.implausible}")
    if dominant:
        verdict = "unexplained"
    elif recommended:
        verdict = "missing_effect"
    elif hits or aug.chi2_p < alpha or any(c.significant for c in cands):
        verdict = "unexplained"
    elif fit.untestable:
        verdict = "untestable"
    else:
        verdict = "adequate"
    if verdict == "missing_effect" and aug.chi2_p < alpha and not hits:
        notes.append(
            f"even with the recommended terms the fit is poor (χ² p = {aug.chi2_p:.2g}): "
            "more is missing, or the noise model is too optimistic"
        )
    return Diagnosis(
        fit, tuple(cands), tuple(hits), verdict, tuple(notes), recommended,
        tuple(dominant.values()), model_spec(merge_model(extra)) if recommended else None, ds.g,
    )  # fmt: skip


def _after_shared(
    ds: Dataset,
    fit: Fit,
    cands: Sequence[Candidate],
    top: Candidate,
    model: Sequence[ModelTerm],
    cat: Mapping[str, Term],
    alpha: float,
) -> Diagnosis:
    """The diagnosis when the strongest candidate is a shared (bench) term: the model with it
    is diagnosed again; its recommendation (if any) follows the shared term's."""
    shared = ModelTerm(cat[top.term], top.sensor, tuple(AXES.index(a) for a in top.axes))
    inner = diagnose(ds, merge_model([*model, shared]), cat, alpha)
    misfit = max(fit.chi2 - fit.dof, 0.0)
    removed = fit.chi2 - inner.fit.chi2
    notes = list(ds.notes)
    notes.append(
        f"{top.label} (one set of parameters for every channel) explains the most; the "
        f"diagnosis of the model with it: {inner.verdict}"
    )
    notes.extend(n for n in inner.notes if n not in ds.notes)
    if inner.verdict == "unexplained" or removed < MOST * misfit:
        return Diagnosis(fit, tuple(cands), inner.unexplained, "unexplained", tuple(notes), (),
                         inner.dominant, None, ds.g)  # fmt: skip
    recommended = (top.label, *inner.recommended)
    extra = [shared] + [mt for mt in inner.fit.model if mt.label in inner.recommended]
    return Diagnosis(
        fit, tuple(cands), inner.unexplained, "missing_effect", tuple(notes), recommended,
        (), model_spec(merge_model(extra)), ds.g,
    )  # fmt: skip


# ---- add / ladder ---------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class Addition:
    """Before → after of adding ``added`` to a model."""

    before: Fit
    after: Fit
    added: tuple[ModelTerm, ...]
    #: leave-one-record-out prediction error before and after (:func:`host.model.leave_one_out`)
    held_out: tuple[Prediction, Prediction] | None = None

    @property
    def new_parameters(self) -> list[Any]:
        labels = {mt.label for mt in self.after.model}
        old = {p.name for p in self.before.parameters}
        return [p for p in self.after.parameters if p.name not in old and p.term in labels]


def add_term(
    ds: Dataset,
    model: Sequence[ModelTerm],
    item: str,
    catalogue: Mapping[str, Term] | None = None,
) -> Addition:
    """Refit with ``item`` (``term[:sensor[:axes]]``) added."""
    new = parse_model(item, catalogue)
    have = {(mt.term.name, mt.sensor, a) for mt in model for a in mt.axes}
    if all((mt.term.name, mt.sensor, a) in have for mt in new for a in mt.axes):
        raise UserError(f"{item} is already in the model {model_spec(model)}")
    before = fit_model(ds, model)
    after = fit_model(ds, merge_model(list(model) + new))
    return Addition(
        before, after, tuple(new), (leave_one_out(ds, before), leave_one_out(ds, after))
    )


@dataclass(frozen=True)
class LadderStep:
    """One rung: the model after adding ``added`` (``""`` for the start)."""

    added: str
    model: str
    n_params: int
    chi2: float
    dof: int
    rms_z: float
    bic: float
    p_value: float  # of the addition's LR test (NaN for the start)
    #: leave-one-record-out prediction RMS z (:func:`host.model.leave_one_out`)
    held_out_rms_z: float = math.nan


def ladder(
    ds: Dataset,
    start: str = "bias",
    catalogue: Mapping[str, Term] | None = None,
    alpha: float = ALPHA,
    max_steps: int = 20,
) -> list[LadderStep]:
    """Greedy forward selection from ``start``: at each rung add the (term, sensor) — all three
    axes — that lowers BIC most, while its LR test is significant after Bonferroni over that
    rung's candidates; stop otherwise."""
    cat = catalogue if catalogue is not None else CATALOGUE
    model = parse_model(start, cat)
    fit = fit_model(ds, model)
    steps = [LadderStep("", model_spec(model), fit.n_params, fit.chi2, fit.dof, fit.rms_z,
                        fit.bic, math.nan, leave_one_out(ds, fit).rms_z)]  # fmt: skip
    for _ in range(max_steps):
        have = {(mt.term.name, mt.sensor) for mt in model}
        options = [
            ModelTerm(t, s, (0, 1, 2))
            for t in cat.values()
            for s in t.sensors
            if (t.name, s) not in have
        ]
        if not options:
            break
        results = []
        for mt in options:
            f = fit_model(ds, merge_model(list(model) + [mt]))
            k = f.n_params - fit.n_params
            if k <= 0:
                continue
            results.append((f.bic, mt, f, chi2_sf(fit.chi2 - f.chi2, k)))
        if not results:
            break
        bic, mt, f, p = min(results, key=lambda r: r[0])
        if bic >= fit.bic or p > alpha / len(results):
            break
        model = merge_model(list(model) + [mt])
        fit = f
        steps.append(LadderStep(mt.label, model_spec(model), f.n_params, f.chi2, f.dof,
                                f.rms_z, f.bic, p, leave_one_out(ds, f).rms_z))  # fmt: skip
    return steps


# ---- text -----------------------------------------------------------------------------------
def _fmt(v: float, unit: str) -> str:
    if not math.isfinite(v):
        return "—"
    a = abs(v)
    s = f"{v:.4g}" if a >= 1e-3 or a == 0 else f"{v:.3e}"
    return f"{s} {unit}".strip()


def describe_residual(g: GroupResidual) -> str:
    """'gyro x, record y_up: measured 0.731 °/s, model 0.702, 8.1 σ'."""
    what = "integral" if g.unit == "°" else "mean"
    return (
        f"{g.sensor} {g.axis}, record {g.record}: measured {what} {g.measured:.4f} {g.unit}, "
        f"model {g.model:.4f}, residual {g.residual:+.4f} = {g.z:+.1f} σ"
    )


def format_fit(fit: Fit, compare: bool = True) -> list[str]:
    """The fit's summary (and the compare table)."""
    lines = [
        f"model: {model_spec(fit.model)}",
        f"fit: RMS z = {fit.rms_z:.2f} over {len(fit.groups)} record/channel values; "
        f"χ² = {fit.chi2:.1f} on {fit.dof} dof (p = {fit.chi2_p:.3g})",
    ]
    if compare:
        lines.append("compare (record, channel: measured, model, residual, z):")
        for g in fit.groups:
            lines.append(
                f"  {g.record:<10} {g.sensor} {g.axis}: {g.measured:>11.4f} {g.model:>11.4f} "
                f"{g.residual:>+9.4f} {g.unit:<4} {g.z:>+6.1f}"
            )
    return lines


def format_candidate(c: Candidate) -> str:
    if not c.identifiable:
        return f"{c.label}: NOT identifiable — {c.reason}; would need {c.needs}"
    mark = "SIGNIFICANT" if c.significant else "not significant"
    extra = ""
    if c.confounded_with:
        extra += f"; CONFOUNDED with {', '.join(c.confounded_with)}"
    if c.explained_by:
        extra += f"; explained by {c.explained_by}"
    if c.implausible:
        extra += f"; IMPLAUSIBLE: {c.implausible}"
    return (
        f"{c.label}: {mark}, Δχ² = {c.delta_chi2:.1f} (p = {c.p_value:.2g}), "
        f"ΔBIC = {c.delta_bic:+.1f}, RMS z after {c.rms_z_after:.2f}, "
        f"coefficient {_fmt(c.coefficient, '')} ± {_fmt(c.stderr, c.unit)}{extra}"
    )


def format_diagnosis(d: Diagnosis, compare: bool = True, max_candidates: int = 12) -> str:
    """The human-readable report of :func:`diagnose`."""
    lines = ["== 1. compare: measured vs model"] + format_fit(d.fit, compare)
    lines.append("== 2. where it fails (|z| > 3, worst first)")
    if not d.worst and not d.worst_spans:
        lines.append("  nowhere: every record and channel within 3 σ")
    for g in d.worst[:15]:
        lines.append("  " + describe_residual(g))
    for s in d.worst_spans[:5]:
        lines.append(
            f"  {s.sensor} {s.axis}, record {s.record}, {s.t0_s:.1f}–{s.t1_s:.1f} s: departs "
            f"from the record's mean by {s.residual:+.4f} {s.unit} = {s.z:+.1f} σ"
        )
    lines.append("== 3. what is missing (candidates, best first; Holm α = 0.01)")
    sig = [c for c in d.candidates if c.significant]
    shown = (
        sig
        + [c for c in d.candidates if not c.significant and c.identifiable][
            : max(0, max_candidates - len(sig))
        ]
    )
    for c in shown:
        lines.append("  " + format_candidate(c))
    unident = [c for c in d.candidates if not c.identifiable]
    groups: dict[tuple[str, str], list[str]] = {}
    for c in unident:
        groups.setdefault((c.term, c.reason), []).append(f"{c.sensor}:{c.axes}")
    for (name, reason), chans in groups.items():
        needs = next(c.needs for c in unident if c.term == name)
        lines.append(
            f"  {name} ({', '.join(chans)}): NOT identifiable — {reason}; would need {needs}"
        )
    if d.unexplained:
        lines.append("== unexplained structure (no term of the catalogue explains it)")
        for h in d.unexplained[:10]:
            lines.append("  unexplained: " + h.describe())
    for n in d.notes:
        lines.append(f"note: {n}")
    lines.append(f"== verdict: {d.verdict}")
    for h in d.dominant:
        lines.append(
            f"  {h.sensor} {h.axis}: no catalogue term explains it; the residual follows "
            f"{h.signal} (Δχ² = {h.delta_chi2:.1f})"
            + ("; confounded with session time in this plan" if h.time_confounded else "")
        )
    by_label = {c.label: c for c in d.candidates}
    for label in d.recommended:
        c = by_label[label]
        lines.append(f"  {label}: {c.physics}")
        lines.extend("    " + t for t in explain(c, d.g))
        group = [c.label, *c.confounded_with]
        if len(group) > 1:
            lines.append(f"    the data cannot tell apart {' / '.join(group)}; to separate them:")
            for other in group:
                o = by_label.get(other)
                if o is not None:
                    lines.append(f"      {other}: {o.needs}")
    if d.recommended_spec:
        lines.append(f"  try: python -m host model add DIR {d.recommended_spec} --model "
                     f"{model_spec(d.fit.model)}")  # fmt: skip
    elif d.verdict != "adequate":
        lines.append("  recommended: nothing from the catalogue")
    return "\n".join(lines)


def explain(c: Candidate, g: float) -> list[str]:
    """The candidate's coefficients in physical words (for the geometry terms: what tilt puts
    how much gravity on the channel, and which §3 bias estimate it moves)."""
    out = []
    if c.term == "face_error":
        for name, (v, se, _) in c.coefficients.items():
            pair = name.rsplit(".", 1)[-1]
            out.append(
                f"faces {pair} lean {1000 * v:+.2f} ± {1000 * se:.2f} mrad "
                f"({math.degrees(v):+.3f}°) toward {c.axes}: they put {g * v:+.4f} m/s² of "
                f"gravity on accelerometer {c.axes}, so its bias estimate from the {pair} pair "
                "(method.md §3) is off by that much"
            )
    elif c.term == "plate_tilt":
        for name, (v, se, _) in c.coefficients.items():
            side = name.rsplit(".", 1)[-1]
            ruler = " (along the ruler)" if side == "east" else " (across the ruler)"
            out.append(
                f"the plate leans {1000 * v:+.2f} ± {1000 * se:.2f} mrad "
                f"({math.degrees(v):+.3f}°) {side}{ruler}: {g * v:+.4f} m/s² of gravity on "
                "whichever accelerometer points that way, following the heading as the cube turns"
            )
        out.append(
            "  (a fixture error turns with the cube, a plate tilt stays in the room: the still "
            "moments of the turns, at several headings, tell them apart)"
        )
    elif c.term == "lever_arm" and len(c.coefficients) == 3:
        vals = [(float(v), float(e)) for v, e, _ in c.coefficients.values()]
        w2 = math.radians(90.0) ** 2
        perp = max(math.hypot(vals[i][0], vals[j][0]) for i, j in ((1, 2), (0, 2), (0, 1)))
        where = ", ".join(f"{a} {1000 * v:+.1f} ± {1000 * e:.1f} mm"
                          for a, (v, e) in zip("xyz", vals, strict=True))  # fmt: skip
        out.append(
            f"the sensor sits {where} from the centre of the cube (the turn axis): turning at "
            f"90 °/s the centripetal acceleration ω²·r⊥ puts up to {w2 * perp:.3f} m/s² on the "
            "horizontal accelerometers, and each push adds the tangential ω̇×r"
        )
    else:
        for name, (v, se, unit) in c.coefficients.items():
            out.append(f"{name} = {_fmt(v, '')} ± {_fmt(se, unit)}")
    return out


def format_addition(a: Addition) -> str:
    """Before → after of :func:`add_term`."""
    b, f = a.before, a.after
    lines = [
        f"added {', '.join(mt.label for mt in a.added)}",
        f"  RMS z  {b.rms_z:8.2f} → {f.rms_z:.2f}"
        + (f"  ({b.rms_z / f.rms_z:.1f}× smaller)" if f.rms_z > 0 else ""),
        f"  χ²     {b.chi2:8.1f} → {f.chi2:.1f}  (dof {b.dof} → {f.dof}; p {b.chi2_p:.2g} → "
        f"{f.chi2_p:.2g})",
        f"  BIC    {b.bic:8.1f} → {f.bic:.1f}",
        *(
            [
                f"  held-out RMS z (each record predicted from the others) "
                f"{a.held_out[0].rms_z:.2f} → {a.held_out[1].rms_z:.2f}"
            ]
            if a.held_out is not None
            else []
        ),  # fmt: skip
        "  worst residuals before → after:",
    ]
    after_of = {(g.record, g.sensor, g.axis): g for g in f.groups}
    for g in sorted(b.groups, key=lambda g: -abs(g.z))[:5]:
        g2 = after_of[(g.record, g.sensor, g.axis)]
        lines.append(
            f"    {g.sensor} {g.axis}, {g.record}: {g.residual:+.4f} {g.unit} ({g.z:+.1f} σ) → "
            f"{g2.residual:+.4f} ({g2.z:+.1f} σ)"
        )
    lines.append("  new coefficients:")
    for p in a.new_parameters:
        lines.append(f"    {p.name} = {_fmt(p.value, '')} ± {_fmt(p.stderr, p.unit)}")
    return "\n".join(lines)


def format_ladder(steps: Sequence[LadderStep]) -> str:
    lines = [f"{'step':>4}  {'added':<34} {'params':>6} {'chi2':>12} {'dof':>5} {'RMS z':>8} "
             f"{'BIC':>12} {'p':>9} {'held-out z':>10}"]  # fmt: skip
    for i, s in enumerate(steps):
        lines.append(
            f"{i:>4}  {(s.added or 'start: ' + s.model):<34} {s.n_params:>6} {s.chi2:>12.1f} "
            f"{s.dof:>5} {s.rms_z:>8.2f} {s.bic:>12.1f} "
            f"{(f'{s.p_value:.2g}' if math.isfinite(s.p_value) else '—'):>9} "
            f"{s.held_out_rms_z:>10.2f}"
        )
    lines.append(f"final model: {steps[-1].model}")
    return "\n".join(lines)


__all__ = [
    "ALPHA", "BASE", "Addition", "Candidate", "Diagnosis", "LadderStep", "ScanHit", "UNIT",
    "add_term", "candidate_terms", "diagnose", "evaluate_candidates", "format_addition",
    "format_candidate", "format_diagnosis", "format_fit", "format_ladder", "holm", "ladder",
    "scan_signals",
]  # fmt: skip
