"""What is missing: every catalogue term not in the model, tried on top of the fit.

method.md §8: "large or trending residuals mean the model misses an effect". Each (term, sensor,
axis) of the catalogue that the model does not hold is added to the same data (Frisch-Waugh-Lovell:
its columns orthogonalised to the model's). With the noise model's known variances the drop in χ²
is χ²(k) under the null: p-values are Holm-corrected over all candidates (family α = 0.01). Each
candidate reports ΔBIC, RMS z after, its coefficient ± std error, and whether the records can
identify it at all (and what data would). Significant candidates are tested against each other:
when neither adds significantly to the other they are CONFOUNDED (reported together); when one
adds nothing to a better one it is "explained by" it. The verdict built on them is
:mod:`host.workbench.verdict`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from host.model.catalogue import BASE, CATALOGUE
from host.model.dataset import Dataset
from host.model.design import BuiltColumns, term_columns
from host.model.fit import Fit, fit_model, residual_sigmas
from host.model.signals import AXES
from host.model.spec import ModelTerm
from host.model.stats import chi2_sf
from host.model.terms import Term
from host.model.whitening import group_means
from host.workbench.absorbed import closure_axes, without_turn_angle

#: family-wise error rate of each family of tests (candidates; signal scan; overall χ²)
ALPHA = 0.01
#: a candidate whose columns keep less than this fraction of their norm after removing the
#: model's columns cannot be identified from the records
IDENTIFIABLE_TOL = 1e-3
#: a candidate with p up to this many times the Bonferroni threshold is "just below
#: significance": it is still compared with the significant ones for confounding
NEAR_FACTOR = 100.0


@dataclass(frozen=True)
class Candidate:
    """One term tried on top of the model (per sensor and axis).

    ``delta_chi2``: drop of χ² from ``chi2_before``, the χ² of the model on the yardstick it
    was tested on (``yardstick`` says how that differs from the fit's, "" when it does not);
    ``p_value`` of the LR test (χ² with ``n_params`` dof); ``significant`` after Holm's
    correction and only when it lowers the misfit: ``rms_z_after`` below ``rms_z_before`` (the
    model's RMS z on that yardstick; ``rises`` True when the test passes but RMS z does not
    fall, its parameters taking the records' freedom); ``delta_bic`` = −Δχ² + k·ln n
    (negative: better);
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
    rms_z_before: float = math.nan
    chi2_before: float = math.nan
    yardstick: str = ""
    rises: bool = False
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
            "delta_chi2": json_number(self.delta_chi2), "p_value": json_number(self.p_value),
            "delta_bic": json_number(self.delta_bic),
            "rms_z_after": json_number(self.rms_z_after),
            "rms_z_before": json_number(self.rms_z_before),
            "chi2_before": json_number(self.chi2_before), "yardstick": self.yardstick,
            "rises": self.rises,
            "coefficient": json_number(self.coefficient), "stderr": json_number(self.stderr),
            "unit": self.unit,
            "coefficients": {k: {"value": json_number(v), "stderr": json_number(s), "unit": u}
                             for k, (v, s, u) in self.coefficients.items()},
            "confounded_with": list(self.confounded_with), "explained_by": self.explained_by,
            "reason": self.reason, "needs": self.needs, "physics": self.physics,
            "implausible": self.implausible,
        }  # fmt: skip


def json_number(v: float) -> float | None:
    """``v`` for a JSON file: a float, or None when it is not finite."""
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
class Tried:
    """A term tried on top of a fit: its whitened columns orthogonal to the model, the
    residual they explain, the coefficients and the drop of χ² (``reason``: why not)."""

    mt: ModelTerm
    ds: Dataset  # the yardstick it was tested against (:mod:`host.workbench.absorbed`)
    fit: Fit  # the model fitted on that yardstick
    cw_perp: np.ndarray  # whitened columns, orthogonalised to the model
    r: np.ndarray  # whitened residual to explain (offset of a nonlinear term removed)
    beta: np.ndarray
    cov: np.ndarray
    delta: float
    reason: str

    @property
    def n_params(self) -> int:
        """Its parameters on these records (with the unknowns of records that carry their
        own, e.g. a static's unknown heading on the plate)."""
        return self.mt.count(self.ds.signals)


def try_term(ds: Dataset, fit: Fit, mt: ModelTerm, built: BuiltColumns | None = None) -> Tried:
    """Add ``mt`` to the fitted model by orthogonal projection (exact for linear terms);
    ``built``: the columns already built on these rows (:class:`~host.model.design.BuiltColumns`).
    """
    x, off = built.of(ds, mt) if built is not None else term_columns(ds, mt)
    cw = ds.whiten.apply(x)
    q = fit.basis

    def perp(v: np.ndarray) -> np.ndarray:
        return v - q @ (q.T @ v) if q.shape[1] else v

    cp = perp(cw)
    r = fit.white_residual - perp(ds.whiten.apply(off)) if np.any(off) else fit.white_residual
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
        nan_cov = np.full((k, k), np.nan)
        return Tried(mt, ds, fit, cp, r, np.full(k, np.nan), nan_cov, math.nan, reason)
    beta, *_ = np.linalg.lstsq(cp, r, rcond=None)
    cov = np.linalg.inv(cp.T @ cp)
    after = r - cp @ beta
    delta = float(fit.white_residual @ fit.white_residual - after @ after)
    return Tried(mt, ds, fit, cp, r, beta, cov, delta, "")


def _try_own_yardstick(
    ds: Dataset,
    fit: Fit,
    mt: ModelTerm,
    cache: dict[frozenset[int], tuple[Dataset, Fit]],
    built: BuiltColumns,
) -> Tried:
    """:func:`try_term` against a yardstick without the candidate's own signal: a term that moves
    the turn closures is tested with the turn-angle σ of the other axes
    (:mod:`host.workbench.absorbed`); the model refitted on it once per set of axes."""
    axes = closure_axes(ds, mt, built)
    if not axes:
        return try_term(ds, fit, mt, built)
    if axes not in cache:
        ds2 = without_turn_angle(ds, axes)
        cache[axes] = (ds2, fit if ds2 is ds else fit_model(ds2, fit.model, built=built))
    return try_term(*cache[axes], mt, built)


def _same_yardstick(a: Tried, b: Tried, built: BuiltColumns | None = None) -> tuple[Tried, Tried]:
    """``a`` and ``b`` on one yardstick (the one without the turn-angle σ, if either has it)
    so that one can be tested given the other."""
    if a.ds is b.ds:
        return a, b
    if b.ds.turn_angle_sigma_deg < a.ds.turn_angle_sigma_deg:
        return try_term(b.ds, b.fit, a.mt, built), b
    return a, try_term(a.ds, a.fit, b.mt, built)


def conditional_delta(a: Tried, b: Tried, built: BuiltColumns | None = None) -> float:
    """Δχ² of adding ``b`` to the model that already holds ``a`` (both orthogonal to it);
    ``built``: the columns already built on these rows."""
    a, b = _same_yardstick(a, b, built)
    if a.reason or b.reason:
        return 0.0
    qa, _ = np.linalg.qr(a.cw_perp)
    cb = b.cw_perp - qa @ (qa.T @ b.cw_perp)
    ra = a.r - a.cw_perp @ a.beta
    # a column of b that a already holds adds nothing; b's other columns may still add
    cb = cb[:, np.linalg.norm(cb, axis=0) >= IDENTIFIABLE_TOL * np.linalg.norm(b.cw_perp, axis=0)]
    if not cb.shape[1]:
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
    built: BuiltColumns | None = None,
) -> tuple[list[Candidate], list[Tried]]:
    """Try every candidate on ``fit``; Holm-correct; find confounded groups; sort best first
    (``built``: the columns already built on these rows,
    :class:`~host.model.design.BuiltColumns`)."""
    built = built if built is not None else BuiltColumns(ds)
    cache: dict[frozenset[int], tuple[Dataset, Fit]] = {}
    tried = [
        _try_own_yardstick(ds, fit, mt, cache, built)
        for mt in candidate_terms(fit.model, catalogue)
    ]
    tests = _Tests.of(tried, alpha)
    confounded, explained_by = _compare(tried, tests, alpha, built)
    out = [(_candidate(ds, fit, t, tests, confounded[id(t)], explained_by.get(id(t), "")), t)
           for t in tried]  # fmt: skip
    ordered = _best_first(out)
    return [c for c, _ in ordered], [t for _, t in ordered]


@dataclass(frozen=True)
class _Tests:
    """Each identifiable candidate's test, by ``id`` of its :class:`Tried`: its p-value, its
    RMS z after, whether Holm passes it, whether RMS z then rises instead of falling, and
    whether it is significant (passed, and lowers the misfit it is tested on: a term whose χ²
    drop passes while RMS z rises, its parameters taking the records' degrees of freedom so
    that the residuals' σ shrink faster than the residuals, is not what is missing)."""

    p: dict[int, float]
    after: dict[int, float]
    rises: dict[int, bool]
    sig: dict[int, bool]
    m: int

    @classmethod
    def of(cls, tried: Sequence[Tried], alpha: float) -> _Tests:
        ident = [t for t in tried if not t.reason]
        keys = [id(t) for t in ident]
        pvals = [chi2_sf(t.delta, t.n_params) for t in ident]
        after = {id(t): _rms_z_after(t.ds, t.fit, t) for t in ident}
        passed = dict(zip(keys, holm(pvals, alpha), strict=True))
        rises = {id(t): passed[id(t)] and not after[id(t)] < t.fit.rms_z for t in ident}
        sig = {k: passed[k] and not rises[k] for k in keys}
        return cls(dict(zip(keys, pvals, strict=True)), after, rises, sig, max(len(ident), 1))


def _compare(
    tried: Sequence[Tried], tests: _Tests, alpha: float, built: BuiltColumns
) -> tuple[dict[int, list[str]], dict[int, str]]:
    """Significant candidates of the same channel against each other: the labels each is
    CONFOUNDED with, and the better one that explains it, by ``id`` of its :class:`Tried`.
    Members just below significance (p within NEAR_FACTOR of the threshold) join the
    comparison: a group the data cannot resolve is reported whole."""
    sig, m = tests.sig, tests.m
    significant = [t for t in tried if sig.get(id(t))]
    near = [t for t in tried if id(t) in sig and not sig[id(t)]
            and tests.p[id(t)] <= NEAR_FACTOR * alpha / m]  # fmt: skip
    confounded: dict[int, list[str]] = {id(t): [] for t in tried}
    explained_by: dict[int, str] = {}
    pool = significant + near
    for i, a in enumerate(pool):
        for b in pool[i + 1 :]:
            if (a.mt.sensor, a.mt.axes) != (b.mt.sensor, b.mt.axes):
                continue
            if not (sig[id(a)] or sig[id(b)]):
                continue
            b_given_a = chi2_sf(conditional_delta(a, b, built), b.n_params) <= alpha / m
            a_given_b = chi2_sf(conditional_delta(b, a, built), a.n_params) <= alpha / m
            if not b_given_a and not a_given_b:
                confounded[id(a)].append(b.mt.label)
                confounded[id(b)].append(a.mt.label)
            elif a_given_b and not b_given_a:
                explained_by.setdefault(id(b), a.mt.label)
            elif b_given_a and not a_given_b:
                explained_by.setdefault(id(a), b.mt.label)
    return confounded, explained_by


def _candidate(
    ds: Dataset, fit: Fit, t: Tried, tests: _Tests, confounded: Sequence[str], explained_by: str
) -> Candidate:
    """The report of one tried term (its largest parameter in σ first)."""
    mt = t.mt
    labels = mt.term.param_labels(mt.sensor, mt.axes[0])
    units = mt.term.param_units(mt.sensor)
    coefs: dict[str, tuple[float, float, str]] = {}
    best = 0
    if not t.reason:
        se = np.sqrt(np.diag(t.cov))
        coefs = {labels[j]: (float(t.beta[j]), float(se[j]), units[j]) for j in range(len(labels))}
        best = int(np.argmax(np.abs(t.beta[: len(labels)]) / se[: len(labels)]))
    c0 = coefs.get(labels[best], (math.nan, math.nan, units[best]))
    key = id(t)
    sig = bool(tests.sig.get(key, False))
    n_rows = len(fit.residual)
    return Candidate(
        term=mt.term.name, sensor=mt.sensor, axes="".join(AXES[a] for a in mt.axes),
        n_params=t.n_params, physics=mt.term.physics,
        identifiable=not t.reason, reason=t.reason, needs=mt.term.needs,
        delta_chi2=t.delta, p_value=tests.p.get(key, math.nan), significant=sig,
        delta_bic=(-t.delta + t.n_params * math.log(max(n_rows, 2)))
        if not t.reason else math.nan,
        rms_z_after=tests.after.get(key, math.nan),
        rms_z_before=t.fit.rms_z if not t.reason else math.nan,
        chi2_before=t.fit.chi2 if not t.reason else math.nan,
        yardstick=t.ds.notes[-1] if t.ds is not ds and not t.reason else "",
        rises=tests.rises.get(key, False),
        coefficient=c0[0], stderr=c0[1], unit=c0[2],
        coefficients=coefs, confounded_with=tuple(confounded), explained_by=explained_by,
        implausible=_implausible(mt, coefs, fit) if sig else "",
    )  # fmt: skip


def _best_first(out: list[tuple[Candidate, Tried]]) -> list[tuple[Candidate, Tried]]:
    """Usable first, then significant, not significant, not identifiable; by ΔBIC within;
    confounded partners right after the first of their group."""

    def key(item: tuple[Candidate, Tried]) -> tuple[int, int, float]:
        c = item[0]
        usable = c.significant and not c.explained_by and not c.implausible
        rank = 0 if usable else 1 if c.significant else 2
        if not c.identifiable:
            rank = 3
        # terms that move the rows identically tie up to round-off (the order of a sum may
        # flip them): to 9 digits they tie, and keep the catalogue's order
        bic = float(f"{c.delta_bic:.9g}") if math.isfinite(c.delta_bic) else math.inf
        return (rank, 0, bic)

    out = sorted(out, key=key)
    ordered: list[tuple[Candidate, Tried]] = []
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
    return ordered


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


def _rms_z_after(ds: Dataset, fit: Fit, t: Tried) -> float:
    """RMS of the record/channel z after adding the candidate: the refit's whitened residual
    is r − C⊥·β; W⁻¹ brings it back to the rows."""
    resid_after = ds.whiten.inv_apply(t.r - t.cw_perp @ t.beta)
    q, _ = np.linalg.qr(t.cw_perp)
    basis = np.column_stack([fit.basis, q]) if fit.basis.shape[1] else q
    sd = residual_sigmas(ds, basis)
    means = group_means(resid_after, ds.groups_by_size)
    sigma = np.array([gr.sigma for gr in ds.groups])
    zs = means[sd > 1e-3 * sigma] / sd[sd > 1e-3 * sigma]
    return float(np.sqrt(np.mean(np.square(zs)))) if len(zs) else math.nan
