"""Explanations compared by evidence, not by order (issue 39, item 1).

A bias step, a drift, a temperature term and the hand's variance components compete for the
same misfit. A bias step in a pause of the plan can line up with the plan's order (the pairs
measured at equal spacing: g-sensitivity takes half the step of the split pair and the pair
means lie on a line), so a drift or a temperature term explains most of it too. A catalogue
term is recommended only when it explains what the best step on its channel does not: each is
fitted with the other available, and the likelihood ratio of the term given the step (its Δχ²
with the step in the model, χ² with the term's parameters) must be significant at the
candidates' Bonferroni level. Otherwise the step takes the channel when it adds to the term
(Bonferroni over the scan's cuts: its time was chosen among them), and the two are a group of
equals when neither adds to the other, with the record that tells them apart named: the
attitude measured just before the step, measured again.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

from host.model.dataset import Dataset
from host.model.design import BuiltColumns
from host.model.fit import Fit
from host.model.signals import AXES
from host.model.spec import ModelTerm
from host.model.stats import chi2_sf
from host.workbench.candidates import Candidate, Tried, conditional_delta, try_term
from host.workbench.equals import Equals, advice, signal_label, signal_term
from host.workbench.scan import ScanHit
from host.workbench.steps import STEP

#: the parameters of a placed step: its time and its size
STEP_PARAMS = 2


@dataclass
class Weighed:
    """The outcome of :func:`weigh_steps`: the candidates ``kept`` for recommendation, the
    channels a step takes (``stepped``), the groups of a term and a step that are equals, and
    the notes that state the evidence."""

    kept: list[Candidate] = field(default_factory=list)
    stepped: dict[tuple[str, str], ScanHit] = field(default_factory=dict)
    groups: list[Equals] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)


def _step_on(c: Candidate, hits: Sequence[ScanHit]) -> ScanHit | None:
    """The strongest step of the scan on one of ``c``'s channels."""
    on = [h for h in hits if h.signal.startswith(STEP) and h.sensor == c.sensor
          and h.axis in c.axes]  # fmt: skip
    return max(on, key=lambda h: h.delta_chi2, default=None)


def record_before(ds: Dataset, h: ScanHit) -> str:
    """The record measured last before the step ``h`` (its earliest time), '' if none."""
    at = h.steps[0].lo_s if h.steps else math.nan
    before = [s for s in ds.signals if len(s.t_s) and float(s.t_s[0]) <= at]
    return max(before, key=lambda s: float(s.t_s[0])).name if before else ""


def separating_record(ds: Dataset, h: ScanHit) -> str:
    """The record that tells a step from a term that explains the same misfit, in words."""
    rec = record_before(ds, h)
    again = f"{rec} (the attitude measured just before the step)" if rec else "the first attitude"
    return (
        f"{again} measured again now: a bias step stays at its new level, while a drift or a "
        "temperature term moves on with time or temperature"
    )


def _step_tried(ds: Dataset, fit: Fit, h: ScanHit, built: BuiltColumns | None) -> Tried | None:
    term = signal_term(h.signal, h.sensor, ds)
    if term is None:
        return None
    t = try_term(ds, fit, ModelTerm(term, h.sensor, (AXES.index(h.axis),)), built)
    return None if t.reason else t


def weigh_steps(
    ds: Dataset,
    fit: Fit,
    usable: Sequence[Candidate],
    tried: Mapping[str, Tried],
    hits: Sequence[ScanHit],
    level: float,
    n_cuts: int,
    built: BuiltColumns | None = None,
) -> Weighed:
    """Each of ``usable`` against the best step of the scan (``hits``, of ``fit``) on its
    channel (module docstring). ``tried``: each candidate's :class:`Tried` by label;
    ``level``: the candidates' Bonferroni level; ``n_cuts``: the scan's step cuts."""
    out = Weighed()
    n = max(len(fit.residual), 2)
    for c in usable:
        h = _step_on(c, hits)
        th = _step_tried(ds, fit, h, built) if h is not None else None
        if h is None or th is None or c.label not in tried:
            out.kept.append(c)
            continue
        tc = tried[c.label]
        term_given = conditional_delta(th, tc, built)
        step_given = conditional_delta(tc, th, built)
        p_term = chi2_sf(term_given, c.n_params)
        p_step = min(chi2_sf(step_given, 1) * max(n_cuts, 1), 1.0)
        bic = -(h.delta_chi2 - c.delta_chi2) + (STEP_PARAMS - c.n_params) * math.log(n)
        said = (
            f"{c.label} (Δχ² = {c.delta_chi2:.1f}) against {h.sensor} {h.axis} {h.signal} "
            f"(Δχ² = {h.delta_chi2:.1f}; ΔBIC of the step over the term {bic:+.1f}): with the "
            f"step in the model the term adds Δχ² = {term_given:.1f} (p = {p_term:.2g}), with "
            f"the term in the step adds {step_given:.1f} (p = {p_step:.2g}, over the scan's "
            f"{n_cuts} cuts)"
        )
        if p_term <= level:
            out.kept.append(c)
            out.notes.append(f"{said}: the term explains what the step does not")
        elif p_step <= level:
            out.stepped[(h.sensor, h.axis)] = h
            out.notes.append(f"{said}: the step explains the records, not recommended")
        else:
            out.groups.append(_group(ds, c, h, th))
            out.notes.append(f"{said}: the records cannot tell them apart")
    return out


def _group(ds: Dataset, c: Candidate, h: ScanHit, th: Tried) -> Equals:
    """The group of equals of a term and a step."""
    return Equals(
        (c.label, signal_label(h)), (c.label,), (c.delta_chi2, th.delta),
        (advice(c.needs or "records in which its input varies apart", ds),
         separating_record(ds, h)),
        ((h.sensor, h.axis, h.signal),),
    )  # fmt: skip
