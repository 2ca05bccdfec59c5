"""Add a term, climb the ladder: the refits of the workbench.

:func:`add_term` refits with one term added and says before → after (with the leave-one-record-out
prediction error of both); :func:`ladder` is the greedy path of models from ``bias`` upward, each
rung the (term, sensor) that lowers BIC most while its LR test stays significant.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from host.errors import UserError
from host.model.catalogue import CATALOGUE
from host.model.components import fit_with_components
from host.model.dataset import Dataset
from host.model.fit import Fit, fit_model
from host.model.loo import Prediction, leave_one_out
from host.model.spec import ModelTerm, merge_model, model_spec, parse_model
from host.model.stats import chi2_sf
from host.model.terms import Term
from host.workbench.absorbed import closure_axes, without_turn_angle
from host.workbench.candidates import ALPHA


@dataclass(frozen=True, eq=False)
class Addition:
    """Before → after of adding ``added`` to a model."""

    before: Fit
    after: Fit
    added: tuple[ModelTerm, ...]
    #: leave-one-record-out prediction error before and after (:func:`host.model.loo.leave_one_out`)
    held_out: tuple[Prediction, Prediction] | None = None
    #: how the yardstick of ``before`` differs from the model's own ("" when it does not): a term
    #: that moves the turn closures is measured without the turn angle of its axes
    yardstick: str = ""

    @property
    def new_parameters(self) -> list[Any]:
        labels = {mt.label for mt in self.after.model}
        old = {p.name for p in self.before.parameters}
        return [p for p in self.after.parameters if p.name not in old and p.term in labels]

    def to_dict(self) -> dict[str, Any]:
        """The ``add --json`` object: before → after."""

        def fit_d(f: Fit) -> dict[str, Any]:
            return {"model": [mt.label for mt in f.model], "rms_z": f.rms_z, "chi2": f.chi2,
                    "chi2_p": f.chi2_p, "dof": f.dof, "bic": f.bic}  # fmt: skip

        return {
            "added": [mt.label for mt in self.added],
            "held_out_rms_z": None
            if self.held_out is None
            else {"before": self.held_out[0].rms_z, "after": self.held_out[1].rms_z},
            "before": fit_d(self.before),
            "before_yardstick": self.yardstick,
            "after": fit_d(self.after),
            "new_parameters": [
                {"name": p.name, "value": p.value, "stderr": p.stderr, "unit": p.unit}
                for p in self.new_parameters
            ],  # fmt: skip
        }


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
    # each with the turn components estimated jointly (host.model.components): the new term
    # may explain the closures a turn-angle σ measured before it would keep. The model before
    # is measured on the yardstick the term was tested on (host.workbench.absorbed): without
    # the turn angle of the axes whose closures it moves, or that σ would hide the very misfit
    # the term takes away and before → after would not show it. Only while some other axis's
    # closure is left to measure the hand's angle error: with none, that yardstick would call
    # the hand's error the term's, and before stays the model's own
    joint = fit_with_components(ds, model)
    axes = frozenset().union(*(closure_axes(joint.dataset, mt) for mt in new))
    others = [c for c in joint.dataset.closures if c.axis not in axes]
    ds_before = without_turn_angle(joint.dataset, axes) if axes and others else joint.dataset
    before = joint.fit if ds_before is joint.dataset else fit_model(ds_before, model)
    after = fit_with_components(ds, merge_model(list(model) + new)).fit
    own = ds_before is not joint.dataset
    held_out = (leave_one_out(ds_before if own else ds, before), leave_one_out(ds, after))
    note = ds_before.notes[-1] if own else ""
    return Addition(before, after, tuple(new), held_out, note)


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
    #: leave-one-record-out prediction RMS z (:func:`host.model.loo.leave_one_out`)
    held_out_rms_z: float = math.nan


def ladder(
    ds: Dataset,
    start: str = "bias",
    catalogue: Mapping[str, Term] | None = None,
    alpha: float = ALPHA,
    max_steps: int = 20,
    on_step: Callable[[LadderStep], None] | None = None,
    on_try: Callable[[int, int, int], None] | None = None,
) -> list[LadderStep]:
    """Greedy forward selection from ``start``: at each rung add the (term, sensor) — all three
    axes — that lowers BIC most, while its LR test is significant after Bonferroni over that
    rung's candidates; stop otherwise. ``on_step(step)`` hears each rung as it is found,
    ``on_try(rung, tried, of)`` each candidate fit (a fit takes up to seconds: the waiting
    user sees it move)."""
    tell = on_step or (lambda step: None)
    trying = on_try or (lambda rung, tried, of: None)
    cat = catalogue if catalogue is not None else CATALOGUE
    model = parse_model(start, cat)
    fit = fit_model(ds, model)
    steps = [LadderStep("", model_spec(model), fit.n_params, fit.chi2, fit.dof, fit.rms_z,
                        fit.bic, math.nan, leave_one_out(ds, fit).rms_z)]  # fmt: skip
    tell(steps[0])
    for rung in range(1, max_steps + 1):
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
        for i, mt in enumerate(options):
            trying(rung, i, len(options))
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
        tell(steps[-1])
    return steps
