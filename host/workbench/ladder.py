"""Add a term, climb the ladder: the refits of the workbench.

:func:`add_term` refits with one term added and says before → after (with the leave-one-record-out
prediction error of both); :func:`ladder` is the greedy path of models from ``bias`` upward, each
rung the (term, sensor) that lowers BIC most while its LR test stays significant, and every
earlier rung's term tested again after it, dropped when it no longer earns its place.
"""

from __future__ import annotations

import functools
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
from host.workbench.nuisance import SeenTiltTest, seen_tilt_test


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
    #: the records' own views of the plate's tilt against the plate's one tilt, when the term
    #: gave them (:mod:`host.workbench.nuisance`)
    seen_tilt: SeenTiltTest | None = None

    @property
    def exact(self) -> tuple[str, ...]:
        """Channels the addition leaves with no degrees of freedom that had some before: the
        model passes through their records exactly, so their fall of RMS z is no evidence."""
        return tuple(c for c in self.after.untestable if c not in self.before.untestable)

    def tested_rms_z(self) -> tuple[float, float]:
        """RMS z before and after over the channels that keep degrees of freedom after it
        (NaN when none does): the fall the addition can be judged by."""

        def rms(f: Fit) -> float:
            zs = [g.z for g in f.groups if f"{g.sensor} {g.axis}" not in self.after.untestable
                  and math.isfinite(g.z)]  # fmt: skip
            return math.sqrt(sum(z * z for z in zs) / len(zs)) if zs else math.nan

        return rms(self.before), rms(self.after)

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
            "fitted_exactly": list(self.exact),
            "tested_rms_z": dict(zip(("before", "after"), self.tested_rms_z(), strict=True)),
            "seen_tilt": None if self.seen_tilt is None else self.seen_tilt.describe(),
            "before_yardstick": self.yardstick,
            "after": fit_d(self.after),
            "new_parameters": [
                {"name": p.name, "value": p.value, "stderr": p.stderr, "unit": p.unit}
                for p in self.new_parameters
            ],  # fmt: skip
        }


def new_terms(
    model: Sequence[ModelTerm], item: str, catalogue: Mapping[str, Term] | None = None
) -> list[ModelTerm]:
    """The terms ``item`` adds to ``model``; a :class:`UserError` when it names none or
    only terms the model has (said before any record is read)."""
    new = parse_model(item, catalogue)
    have = {(mt.term.name, mt.sensor, a) for mt in model for a in mt.axes}
    if all((mt.term.name, mt.sensor, a) in have for mt in new for a in mt.axes):
        raise UserError(f"{item} is already in the model {model_spec(model)}")
    return new


def add_term(
    ds: Dataset,
    model: Sequence[ModelTerm],
    item: str,
    catalogue: Mapping[str, Term] | None = None,
) -> Addition:
    """Refit with ``item`` (``term[:sensor[:axes]]``) added."""
    new = new_terms(model, item, catalogue)
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
    return Addition(before, after, tuple(new), held_out, note, seen_tilt_test(after))


#: a term that changes another term of its sensor is offered only once that term is in (the
#: marginality of a regression: a change of the scale with temperature or input size, with no
#: scale in the model, stands in for the scale itself — on the temperature demo's seed 4 the
#: ladder took temperature_scale:gyro as the gyro's scale and shipped it)
PRESUPPOSES = {
    "temperature_scale": "scale",
    "scale_asymmetry": "scale",
    "scale_nonlinearity": "scale",
    "temperature_bias_quadratic": "temperature_bias",
}


@dataclass(frozen=True)
class LadderStep:
    """One rung: the model after adding ``added`` (``""`` for the start), or after dropping
    ``dropped``, an earlier rung's term that no longer earns its place once later ones are in."""

    added: str
    model: str
    n_params: int
    chi2: float
    dof: int
    rms_z: float
    bic: float
    p_value: float  # of the addition's LR test, or the dropped term's (NaN for the start)
    #: leave-one-record-out prediction RMS z (:func:`host.model.loo.leave_one_out`)
    held_out_rms_z: float = math.nan
    dropped: str = ""


def _step(ds: Dataset, fit: Fit, p: float, added: str = "", dropped: str = "") -> LadderStep:
    return LadderStep(added, model_spec(fit.model), fit.n_params, fit.chi2, fit.dof, fit.rms_z,
                      fit.bic, p, leave_one_out(ds, fit).rms_z, dropped)  # fmt: skip


def _best_addition(
    ds: Dataset,
    fit: Fit,
    options: Sequence[ModelTerm],
    alpha: float,
    trying: Callable[[int, int], None],
) -> tuple[ModelTerm, Fit, float] | None:
    """The option that lowers BIC most, with its fit and LR p-value, when it lowers BIC and is
    significant after Bonferroni over the options tried; None otherwise."""
    results = []
    for i, mt in enumerate(options):
        trying(i, len(options))
        f = fit_model(ds, merge_model([*fit.model, mt]))
        k = f.n_params - fit.n_params
        if k > 0:
            results.append((f.bic, mt, f, chi2_sf(fit.chi2 - f.chi2, k)))
    if not results:
        return None
    bic, mt, f, p = min(results, key=lambda r: r[0])
    if bic >= fit.bic or p > alpha / len(results):
        return None
    return mt, f, p


def weakest_term(
    ds: Dataset, fit: Fit, earlier: Sequence[ModelTerm], alpha: float
) -> tuple[ModelTerm, Fit, float] | None:
    """The earlier rung's term that earns its place least, with the fit without it and the
    p-value of its LR test given every other term, when it no longer earns it: removing it
    lowers BIC, or its test is not significant after Bonferroni over the terms tested."""
    worst: tuple[ModelTerm, Fit, float] | None = None
    for mt in earlier:
        f = fit_model(ds, [m for m in fit.model if m.label != mt.label])
        k = fit.n_params - f.n_params
        p = chi2_sf(max(f.chi2 - fit.chi2, 0.0), k) if k > 0 else 1.0
        if (f.bic <= fit.bic or p > alpha / len(earlier)) and (worst is None or p > worst[2]):
            worst = (mt, f, p)
    return worst


def ladder(
    ds: Dataset,
    start: str = "bias",
    catalogue: Mapping[str, Term] | None = None,
    alpha: float = ALPHA,
    max_steps: int = 20,
    on_step: Callable[[LadderStep], None] | None = None,
    on_try: Callable[[int, int, int], None] | None = None,
) -> list[LadderStep]:
    """Stepwise selection from ``start``: at each rung add the (term, sensor) — all three
    axes — that lowers BIC most, while its LR test is significant after Bonferroni over that
    rung's candidates; then test every earlier rung's term again given all the others and drop
    the one that earns its place least while one does not (removing it lowers BIC, or its LR
    test fails after Bonferroni over them), one at a time; stop when nothing enters. A dropped
    term is not tried again, and a term that changes another (:data:`PRESUPPOSES`) is tried
    only once that one is in. The start's terms stay (they are the user's). ``on_step(step)``
    hears each rung as it is found, ``on_try(rung, tried, of)`` each candidate fit (a fit takes
    up to seconds: the waiting user sees it move)."""
    tell = on_step or (lambda step: None)
    trying = on_try or (lambda rung, tried, of: None)
    cat = catalogue if catalogue is not None else CATALOGUE
    fit = fit_model(ds, parse_model(start, cat))
    steps = [_step(ds, fit, math.nan)]
    tell(steps[0])
    added: list[ModelTerm] = []
    out: set[tuple[str, str]] = set()  # dropped (term, sensor): not tried again
    for rung in range(1, max_steps + 1):
        have = {(mt.term.name, mt.sensor) for mt in fit.model} | out
        inside = {(mt.term.name, mt.sensor) for mt in fit.model}
        options = [ModelTerm(t, s, (0, 1, 2)) for t in cat.values() for s in t.sensors
                   if (t.name, s) not in have
                   and (PRESUPPOSES.get(t.name, t.name), s) in inside | {(t.name, s)}]  # fmt: skip
        best = _best_addition(ds, fit, options, alpha, functools.partial(trying, rung))
        if best is None:
            break
        mt, fit, p = best
        added.append(mt)
        steps.append(_step(ds, fit, p, added=mt.label))
        tell(steps[-1])
        while (drop := weakest_term(ds, fit, added[:-1], alpha)) is not None:
            gone, fit, p = drop
            added.remove(gone)
            out.add((gone.term.name, gone.sensor))
            steps.append(_step(ds, fit, p, dropped=gone.label))
            tell(steps[-1])
    return steps
