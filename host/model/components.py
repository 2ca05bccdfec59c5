"""Variance components estimated jointly with the fit (issue 24): the hand's turn-angle error
and its wobble on the turn integrals, and a hand-held pose's rate and hold (issue 41), each
with its own degrees of freedom.

Before a fit, :mod:`host.model.variance` measures the turn angle from the closures of the turns
made both ways (ccw + cw less the static reading). A term of the model that explains those
closures (a gyro scale asymmetry, a quadratic scale: even in the direction, nothing at rest)
takes that very scatter: measured before the fit, the component would keep it too and widen the
term's own σ by orders of magnitude. :func:`fit_with_components` therefore estimates the
components from the fit's residuals, REML-style, and fits again until both settle:

    σ² = Σ_i (r_i² − w_i·(1 − h_i)) / Σ_i (1 − h_i)

over the rows i the component covers (one turn integral each, independent), with r_i the
residual, w_i the row's variance without the component (white noise integrated, the floor) and
h_i its leverage in the whitened fit: E[r_i²] = (w_i + σ²)·(1 − h_i). Its degrees of freedom are
Σ(1 − h_i), what the model leaves to it (3 for the turn angle under ``base`` with three axes
turned both ways; 0 once an asymmetry per axis takes every closure: the component is then not
measured and the rows carry their white noise only).

A unit held still by hand in a pose is not quite still: it creeps (a pose's gyro means scatter
beyond their white noise, a gyro bias wandering between records alike: the rows cannot tell the
two apart), and it settles into the pose and out of it (a move starts at the rest's last
sample and ends at the next rest's first, away from the rests' mean attitudes, which the
poses' attitudes are). The first is ``pose rate`` (°/s) over each pose's gyro means — the
row of a group of block means it adds to is their mean, σ² on the mean's variance, the
contrasts as they were —, the second ``pose hold`` (°) over the moves' rows; a session without
poses has neither.

A component counts only when the rows' Σr_i² is beyond what their white variance gives (mean
Σw_i·(1 − h_i), variance 2·Σ(w_i·(1 − h_i))², :func:`host.model.stats.beyond_white`): a
clipped 0 ± se would widen the yardstick under the null, and one resolved by chance widens it
in that session. A turn angle
given by the user (``NoiseModel.turn_angle_sigma_deg``) is kept as given.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from host.model.dataset import Dataset
from host.model.design import BuiltColumns
from host.model.fit import Fit, fit_model
from host.model.spec import ModelTerm
from host.model.stats import NORMAL_DOF, beyond_white, satterthwaite_dof
from host.model.variance import (
    POSE_HOLD_PLAUSIBLE_DEG,
    POSE_RATE_PLAUSIBLE_DPS,
    TURN_ANGLE_PLAUSIBLE_DEG,
    TURN_WOBBLE_PLAUSIBLE_DEG,
    Component,
)

#: the components settle when σ² moves less than this fraction of the rows' white variance
SETTLE = 1e-3


@dataclass(frozen=True, eq=False)
class JointFit:
    """:func:`fit_with_components`'s result: the ``fit`` on ``dataset`` (its turn integrals
    weighed with the ``components`` as estimated jointly with it) after ``iterations`` fits."""

    fit: Fit
    dataset: Dataset
    components: tuple[Component, ...]
    iterations: int


@dataclass(frozen=True)
class _Spec:
    name: str
    unit: str
    groups: tuple[int, ...]  # the groups it covers in ds.groups
    rows: np.ndarray  # per group the whitened row it adds to: a one-row group's, or its mean's
    white: np.ndarray  # each such row's variance without the component
    fixed: bool
    absorbs: str
    most: float
    why: str
    #: the Dataset field that holds its σ ('' : read from ``Dataset.components``)
    field: str = ""


def _spec(ds: Dataset, name: str, idx: list[int], old: float, fixed: bool = False) -> _Spec:
    """The component ``name`` (:data:`_WORDS`) over the groups ``idx`` of ``ds``, at ``old``."""
    unit, absorbs, most, why, field = _WORDS[name]
    rows = np.array([int(ds.groups[k].rows[0]) for k in idx], dtype=int)
    white = np.array([max(ds.groups[k].sigma ** 2 - old**2, 0.0) for k in idx])
    return _Spec(name, unit, tuple(idx), rows, white, fixed, absorbs, most, why, field)


#: name -> (unit, what it absorbs, plausible up to, why not beyond, its Dataset field)
_WORDS: dict[str, tuple[str, str, float, str, str]] = {
    "turn angle": ("°", (
        "the scatter of the up-axis turn integrals the model leaves: the hand's angle "
        "error, and a gyro scale asymmetry alike unless the model has one"),
        TURN_ANGLE_PLAUSIBLE_DEG, "a turn short or long by a step", "turn_angle_sigma_deg"),
    "turn wobble": ("°", (
        "the scatter of the cross-axis turn integrals the model leaves: the hand "
        "tilting the cube while it turns (or a tilted turn axis)"),
        TURN_WOBBLE_PLAUSIBLE_DEG, "more than a hand's wobble gives", "turn_wobble_sigma_deg"),
    "pose rate": ("°/s", (
        "the scatter of the poses' gyro means the model leaves: the unit turning slowly "
        "while held still (a hand's creep), and a gyro bias wandering between records alike"),
        POSE_RATE_PLAUSIBLE_DPS, "more than a hand held still turns", ""),
    "pose hold": ("°", (
        "the scatter of the moves' rows the model leaves: the attitude at a rest's end or "
        "start away from the rest's mean (a hand settling into or out of a pose)"),
        POSE_HOLD_PLAUSIBLE_DEG, "more than a hand settling in a pose gives", ""),
}  # fmt: skip


def _current(ds: Dataset, name: str) -> float:
    """The σ the rows of the component ``name`` carry in ``ds`` (0 before any joint fit)."""
    field = _WORDS[name][4]
    if field:
        return float(getattr(ds, field))
    return next((c.value for c in ds.components if c.name == name and c.dof > 0), 0.0)


def _turn_specs(ds: Dataset) -> list[_Spec]:
    """The turn-angle component on the up channels' turn integrals, the wobble on the others."""
    given = not ds.closures and ds.turn_angle_sigma_deg > 0.0
    out = []
    for up, name in ((True, "turn angle"), (False, "turn wobble")):
        idx = [
            k
            for k, gr in enumerate(ds.groups)
            if ds.signals[gr.record].kind == "turn"
            and gr.sensor == "gyro"
            and len(gr.rows) == 1
            and (abs(float(ds.signals[gr.record].up[gr.axis])) > 0.5) == up
        ]
        out.append(_spec(ds, name, idx, _current(ds, name), up and given))
    return out


def _mean_row(ds: Dataset, k: int) -> bool:
    """Whether group ``k``'s first whitened row is its rows' mean (a static's block means)."""
    rows = ds.groups[k].rows
    w = ds.whiten.block(rows)
    return bool(np.allclose(w[0], w[0, 0]))


def _pose_specs(ds: Dataset) -> list[_Spec]:
    """A hand-held pose (issue 41): the rate on the poses' gyro means, the hold on the moves'
    rows; none in a session without poses (its results unchanged)."""
    kinds = [ds.signals[gr.record].kind for gr in ds.groups]
    rate = [
        k
        for k, gr in enumerate(ds.groups)
        if kinds[k] == "pose" and gr.sensor == "gyro" and _mean_row(ds, k)
    ]
    hold = [k for k, gr in enumerate(ds.groups) if kinds[k] == "move" and len(gr.rows) == 1]
    return [
        _spec(ds, name, idx, _current(ds, name))
        for name, idx in (("pose rate", rate), ("pose hold", hold))
        if idx
    ]


def _specs(ds: Dataset) -> list[_Spec]:
    """Every component ``ds``'s rows carry: the turns' two, and a pose's two with poses."""
    return _turn_specs(ds) + _pose_specs(ds)


def _residuals(spec: _Spec, ds: Dataset, fit: Fit) -> np.ndarray:
    """Each covered row's residual as ``spec.white`` measures it: a one-row group's own, a
    group of block means its mean."""
    return np.array([float(np.mean(fit.residual[ds.groups[k].rows])) for k in spec.groups])


def _estimate(spec: _Spec, ds: Dataset, fit: Fit) -> tuple[float, float, float]:
    """(σ² resolved or 0, its standard error, dof Σ(1 − h)) from ``fit``'s residuals. The
    standard error is exact for normal rows: the covered residuals r = S·e, S = diag(s_i) their
    σ, e ~ N(0, M) with M = I − QQᵀ on those rows, so var(Σr²) = 2·tr((S²M)²) — the
    residuals' correlation counted, not only their leverage."""
    if not len(spec.rows):
        return 0.0, math.nan, 0.0
    q = fit.basis[spec.rows] if fit.basis.shape[1] else np.zeros((len(spec.rows), 0))
    m = np.eye(len(spec.rows)) - q @ q.T
    free = np.clip(np.diag(m), 0.0, 1.0)
    dof = float(np.sum(free))
    if dof < 0.5:
        return 0.0, math.nan, dof
    r = _residuals(spec, ds, fit)
    wf = spec.white * free
    var = float(np.sum(r * r - wf)) / dof
    resolved = var if beyond_white(float(r @ r), float(np.sum(wf)), 2.0 * float(wf @ wf)) else 0.0
    sm = (spec.white + max(var, 0.0))[:, None] * m
    se = math.sqrt(2.0 * max(float(np.sum(sm * sm.T)), 0.0)) / dof
    return resolved, se, dof


def _reweigh(ds: Dataset, spec: _Spec, var: float) -> Dataset:
    """``ds`` with the rows of ``spec`` weighed by their white variance + ``var``: a one-row
    group's weight, a group of block means its mean's (its contrasts as they were)."""
    whiten = ds.whiten
    groups = list(ds.groups)
    for k, w in zip(spec.groups, spec.white, strict=True):
        s2 = float(w) + var
        rows = groups[k].rows
        block = whiten.block(rows).copy()
        block[0] = 1.0 / (len(rows) * math.sqrt(s2)) if len(rows) > 1 else 1.0 / math.sqrt(s2)
        whiten = whiten.with_block(rows, block)
        groups[k] = dataclasses.replace(groups[k], sigma=math.sqrt(s2))
    own = {spec.field: math.sqrt(var)} if spec.field else {}
    return dataclasses.replace(ds, whiten=whiten, groups=tuple(groups), **own)  # type: ignore[arg-type]


def _component(spec: _Spec, var: float, se: float, dof: float) -> Component:
    if spec.fixed:
        value = math.sqrt(var)
        return Component(spec.name, value, 0.0, 0, spec.unit, "the hand's angle error (given)")
    value = math.sqrt(var)
    if value > 0:
        sigma = se / (2.0 * value)
    else:
        sigma = math.sqrt(se) if math.isfinite(se) else math.nan
    unit = spec.unit
    over = value > spec.most
    plausible = f"{value:.2g}{unit} over {spec.most:g}{unit}: {spec.why}" if over else ""
    return Component(spec.name, value, sigma, int(round(dof)), unit, spec.absorbs, plausible)


def _with_dof(
    fit: Fit,
    specs: Sequence[_Spec],
    var: Mapping[str, float],
    est: Mapping[str, tuple[float, float, float]],
) -> Fit:
    """``fit`` with each parameter's ``dof``: its variance's share read through an estimated
    component's rows (Σ over them of the influence² · σ²/s², the standard errors' scale
    applied) on that component's ν = 2σ⁴/se(σ²)², the rest exact (Welch–Satterthwaite,
    :func:`host.model.stats.satterthwaite_dof`); inf at :data:`NORMAL_DOF` or more."""
    if fit.influence is None:
        return fit
    shares: list[np.ndarray] = []
    dofs: list[float] = []
    at = 0
    for s in specs:
        infl = fit.influence[at : at + len(s.rows)]
        at += len(s.rows)
        v, se = var[s.name], est[s.name][1]
        if s.fixed or not (v > 0.0 and math.isfinite(se) and se > 0.0):
            continue
        shares.append(v * np.sum(infl**2 / (s.white + v)[:, None], axis=0))
        dofs.append(2.0 * v * v / (se * se))
    if not shares:
        return fit
    params = []
    for c, p in enumerate(fit.parameters):
        k2 = fit.se_scales.get(p.name, 1.0) ** 2
        nu = satterthwaite_dof(p.stderr**2, [k2 * float(sh[c]) for sh in shares], dofs)
        params.append(dataclasses.replace(p, dof=nu if nu < NORMAL_DOF else math.inf))
    return dataclasses.replace(fit, parameters=tuple(params))


def without_components(ds: Dataset, names: Sequence[str]) -> Dataset:
    """``ds`` with the rows of the components ``names`` (:data:`_WORDS`) weighed by
    their white variance alone, the component at 0: the yardstick on which what an implausible
    component took up (a step, a tilt, an unmodelled term) shows as misfit."""
    for s in _specs(ds):
        if s.name in names and len(s.rows) and not s.fixed:
            ds = _reweigh(ds, s, 0.0)
    return ds


def fit_with_components(
    ds: Dataset, model: Sequence[ModelTerm], max_iter: int = 10, built: BuiltColumns | None = None
) -> JointFit:
    """Fit ``model`` (:func:`host.model.fit.fit_model`) with the variance components (the
    turns' angle and wobble, a pose's rate and hold) estimated jointly with it (module
    docstring): fit, estimate each from the residuals, reweigh its rows, fit again until they
    settle. Reweighing changes the whitening, never the design: every fit reads the terms'
    columns built once (``built``: those already built on these rows,
    :class:`~host.model.design.BuiltColumns`)."""
    built = built if built is not None else BuiltColumns(ds)
    specs = _specs(ds)
    var = {s.name: _current(ds, s.name) ** 2 for s in specs}
    est: dict[str, tuple[float, float, float]] = {}
    cur = ds
    rows = np.concatenate([s.rows for s in specs]) if specs else np.zeros(0, dtype=int)
    fit = fit_model(cur, model, built=built, influence_rows=rows)
    iterations = 1
    for _ in range(max_iter):
        moved = False
        for s in specs:
            if s.fixed:
                est[s.name] = (var[s.name], 0.0, 0.0)
                continue
            est[s.name] = _estimate(s, cur, fit)
            new = est[s.name][0]
            scale = float(np.mean(s.white)) if len(s.white) else 1.0
            if abs(new - var[s.name]) > SETTLE * max(scale, 1e-30):
                moved = True
            var[s.name] = new
            cur = _reweigh(cur, s, new)
        if not moved:
            break
        fit = fit_model(cur, model, built=built, influence_rows=rows)
        iterations += 1
    comps = tuple(_component(s, var[s.name], *est[s.name][1:]) for s in specs)
    old = tuple(f"a named variance component: {name}:" for name in var)
    notes = tuple(n for n in cur.notes if not n.startswith(old))
    cur = dataclasses.replace(
        cur,
        components=tuple(c for c in cur.components if c.name not in var) + comps,
        notes=(*notes, *("a named variance component: " + c.describe() for c in comps)),
    )
    return JointFit(_with_dof(fit, specs, var, est), cur, comps, iterations)
