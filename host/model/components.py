"""Variance components estimated jointly with the fit (issue 24): the hand's turn-angle error
and its wobble on the turn integrals, each with its own degrees of freedom.

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
measured and the rows carry their white noise only). A component counts only when the
rows' Σr_i² is beyond what their white variance gives (mean Σw_i·(1 − h_i), variance
2·Σ(w_i·(1 − h_i))², :func:`host.model.stats.beyond_white`): a clipped 0 ± se would widen the
yardstick under the null, and one resolved by chance widens it in that session. A turn angle
given by the user (``NoiseModel.turn_angle_sigma_deg``) is kept as given.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from host.model.dataset import Dataset
from host.model.design import BuiltColumns
from host.model.fit import Fit, fit_model
from host.model.spec import ModelTerm
from host.model.stats import beyond_white
from host.model.variance import (
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
    rows: np.ndarray  # the rows the component covers (single-row groups)
    groups: tuple[int, ...]  # their groups in ds.groups
    white: np.ndarray  # each row's variance without the component
    fixed: bool
    absorbs: str
    most: float
    why: str


def _specs(ds: Dataset) -> list[_Spec]:
    """The turn-angle component on the up channels' turn integrals, the wobble on the others."""
    given = not ds.closures and ds.turn_angle_sigma_deg > 0.0
    out = []
    for up, name, old in (
        (True, "turn angle", ds.turn_angle_sigma_deg),
        (False, "turn wobble", ds.turn_wobble_sigma_deg),
    ):
        idx = [
            k
            for k, gr in enumerate(ds.groups)
            if ds.signals[gr.record].kind == "turn"
            and gr.sensor == "gyro"
            and len(gr.rows) == 1
            and (abs(float(ds.signals[gr.record].up[gr.axis])) > 0.5) == up
        ]
        rows = np.array([int(ds.groups[k].rows[0]) for k in idx], dtype=int)
        white = np.array([max(ds.groups[k].sigma ** 2 - old**2, 0.0) for k in idx])
        if up:
            absorbs = (
                "the scatter of the up-axis turn integrals the model leaves: the hand's angle "
                "error, and a gyro scale asymmetry alike unless the model has one"
            )
            most, why = TURN_ANGLE_PLAUSIBLE_DEG, "a turn short or long by a step"
        else:
            absorbs = (
                "the scatter of the cross-axis turn integrals the model leaves: the hand "
                "tilting the cube while it turns (or a tilted turn axis)"
            )
            most, why = TURN_WOBBLE_PLAUSIBLE_DEG, "more than a hand's wobble gives"
        out.append(_Spec(name, rows, tuple(idx), white, up and given, absorbs, most, why))
    return out


def _estimate(spec: _Spec, fit: Fit) -> tuple[float, float, float]:
    """(σ² resolved or 0, its standard error, dof Σ(1 − h)) from ``fit``'s residuals."""
    if not len(spec.rows):
        return 0.0, math.nan, 0.0
    h = np.sum(fit.basis[spec.rows] ** 2, axis=1) if fit.basis.shape[1] else 0.0
    free = np.clip(1.0 - h, 0.0, 1.0)
    dof = float(np.sum(free))
    if dof < 0.5:
        return 0.0, math.nan, dof
    r = fit.residual[spec.rows]
    wf = spec.white * free
    var = float(np.sum(r * r - wf)) / dof
    resolved = var if beyond_white(float(r @ r), float(np.sum(wf)), 2.0 * float(wf @ wf)) else 0.0
    se = math.sqrt(2.0 * float(np.sum((wf + max(var, 0.0) * free) ** 2))) / dof
    return resolved, se, dof


def _reweigh(ds: Dataset, spec: _Spec, var: float) -> Dataset:
    """``ds`` with the rows of ``spec`` weighed by their white variance + ``var``."""
    whiten = ds.whiten
    groups = list(ds.groups)
    for k, row, w in zip(spec.groups, spec.rows, spec.white, strict=True):
        s2 = float(w) + var
        whiten = whiten.with_block(np.array([row]), np.array([[1.0 / math.sqrt(s2)]]))
        groups[k] = dataclasses.replace(groups[k], sigma=math.sqrt(s2))
    field = "turn_angle_sigma_deg" if spec.name == "turn angle" else "turn_wobble_sigma_deg"
    return dataclasses.replace(ds, whiten=whiten, groups=tuple(groups), **{field: math.sqrt(var)})  # type: ignore[arg-type]


def _component(spec: _Spec, var: float, se: float, dof: float) -> Component:
    if spec.fixed:
        value = math.sqrt(var)
        return Component(spec.name, value, 0.0, 0, "°", "the hand's angle error (given)")
    value = math.sqrt(var)
    if value > 0:
        sigma = se / (2.0 * value)
    else:
        sigma = math.sqrt(se) if math.isfinite(se) else math.nan
    plausible = f"{value:.2g}° over {spec.most:g}°: {spec.why}" if value > spec.most else ""
    return Component(spec.name, value, sigma, int(round(dof)), "°", spec.absorbs, plausible)


def without_components(ds: Dataset, names: Sequence[str]) -> Dataset:
    """``ds`` with the rows of the components ``names`` ("turn angle", "turn wobble") weighed by
    their white variance alone, the component at 0: the yardstick on which what an implausible
    component took up (a step, a tilt, an unmodelled term) shows as misfit."""
    for s in _specs(ds):
        if s.name in names and len(s.rows) and not s.fixed:
            ds = _reweigh(ds, s, 0.0)
    return ds


def fit_with_components(
    ds: Dataset, model: Sequence[ModelTerm], max_iter: int = 10, built: BuiltColumns | None = None
) -> JointFit:
    """Fit ``model`` (:func:`host.model.fit.fit_model`) with the turn-angle and wobble
    components estimated jointly with it (module docstring): fit, estimate each from the
    residuals, reweigh its rows, fit again until they settle. Reweighing changes the whitening,
    never the design: every fit reads the terms' columns built once (``built``: those already
    built on these rows, :class:`~host.model.design.BuiltColumns`)."""
    built = built if built is not None else BuiltColumns(ds)
    specs = _specs(ds)
    var = {
        s.name: (ds.turn_angle_sigma_deg if s.name == "turn angle" else ds.turn_wobble_sigma_deg)
        ** 2
        for s in specs
    }
    est: dict[str, tuple[float, float, float]] = {}
    cur = ds
    fit = fit_model(cur, model, built=built)
    iterations = 1
    for _ in range(max_iter):
        moved = False
        for s in specs:
            if s.fixed:
                est[s.name] = (var[s.name], 0.0, 0.0)
                continue
            est[s.name] = _estimate(s, fit)
            new = est[s.name][0]
            scale = float(np.mean(s.white)) if len(s.white) else 1.0
            if abs(new - var[s.name]) > SETTLE * max(scale, 1e-30):
                moved = True
            var[s.name] = new
            cur = _reweigh(cur, s, new)
        if not moved:
            break
        fit = fit_model(cur, model, built=built)
        iterations += 1
    comps = tuple(_component(s, var[s.name], *est[s.name][1:]) for s in specs)
    notes = tuple(n for n in cur.notes if not n.startswith("a named variance component: turn"))
    cur = dataclasses.replace(
        cur,
        components=tuple(c for c in cur.components if c.name not in var) + comps,
        notes=(*notes, *("a named variance component: " + c.describe() for c in comps)),
    )
    return JointFit(fit, cur, comps, iterations)
