"""The diagnosis: compare the model with the measurements, locate the misfit, say what is missing.

method.md §8: "large or trending residuals mean the model misses an effect (cross-coupling,
temperature …)"; §3: "the three bias estimates disagreeing is itself a sign the linear model is
missing something". :func:`diagnose` turns that into a test:

1. compare — per record and channel measured vs model, residual and z (the engine's ``Fit``),
   the turns' angle error and wobble estimated jointly with the model
   (:func:`host.model.components.fit_with_components`): the components diagnose prints, the
   yardstick of its fit and of every candidate are the same;
2. where it fails — |z| > 3, worst first, and within-record time spans that depart;
3. what is missing — the candidates of :mod:`host.workbench.candidates`;
4. unexplained structure — the residuals of the model plus the best candidate per channel are
   scanned against every signal (:mod:`host.workbench.scan`), Holm-corrected;
5. verdict — ``adequate`` / ``missing_effect`` / ``unexplained``, or ``untestable`` when
   nothing is found but some channel's record values leave no degrees of freedom (the model
   passes through them exactly: it is not tested at all, so it is never called adequate).

The words for people are :mod:`host.workbench.text`.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from host.errors import UserError
from host.model.catalogue import CATALOGUE
from host.model.components import fit_with_components
from host.model.dataset import Dataset
from host.model.design import BuiltColumns
from host.model.fit import Fit, GroupResidual, SpanResidual, fit_model
from host.model.signals import AXES
from host.model.spec import ModelTerm, merge_model, model_spec, parse_model
from host.model.stats import chi2_sf
from host.model.terms import Term
from host.workbench.absorbed import closure_axes, without_turn_angle
from host.workbench.candidates import ALPHA, Candidate, evaluate_candidates, json_number
from host.workbench.equals import Equals, EqualsFinder
from host.workbench.evidence import Weighed, weigh_steps
from host.workbench.nuisance import seen_tilt_test
from host.workbench.scan import ScanColumns, ScanHit, scan_signals
from host.workbench.sinks import Absorbed, rest_hits, what_absorbed
from host.workbench.steps import STEP

VERDICTS = ("adequate", "missing_effect", "unexplained", "untestable")
#: the verdict advises adding terms only when together they remove at least this fraction of
#: the misfit (χ² − dof) of the model
MOST = 0.5
#: a signal of the residual scan "explains the channel better" than its best candidate when its
#: Δχ² exceeds the candidate's by this factor (equal: the candidate IS that signal)
DOMINANT = 1.05


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
    #: groups of explanations the records cannot tell apart (:mod:`host.workbench.equals`):
    #: none of their members is recommended alone
    equals: tuple[Equals, ...] = ()
    #: channels the recommended terms leave with no degrees of freedom between records (the
    #: model with them passes exactly through each): untestable with them
    untestable_with: tuple[str, ...] = ()

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
            "fit": {"rms_z": json_number(f.rms_z), "chi2": json_number(f.chi2),
                    "chi2_p": json_number(f.chi2_p), "dof": f.dof, "n_rows": len(f.residual),
                    "n_params": f.n_params},
            "parameters": [{"name": p.name, "term": p.term, "value": json_number(p.value),
                            "stderr": json_number(p.stderr), "unit": p.unit}
                           for p in f.parameters],
            "compare": [_group_dict(g) for g in f.groups],
            "worst": [_group_dict(g) for g in self.worst],
            "worst_spans": [{"record": s.record, "channel": f"{s.sensor} {s.axis}",
                             "t0_s": s.t0_s, "t1_s": s.t1_s, "residual": json_number(s.residual),
                             "z": json_number(s.z), "unit": s.unit} for s in self.worst_spans],
            "candidates": [c.to_dict() for c in self.candidates],
            "unexplained": [h.to_dict() for h in self.unexplained],
            "verdict": self.verdict,
            "recommended": self.recommended_spec,
            "unexplained_signals": [h.to_dict() for h in self.dominant],
            "equals": [e.to_dict() for e in self.equals],
            "untestable_with": list(self.untestable_with),
            "notes": list(self.notes),
        }  # fmt: skip


def _group_dict(g: GroupResidual) -> dict[str, Any]:
    return {
        "record": g.record, "channel": g.channel, "sensor": g.sensor, "axis": g.axis,
        "measured": json_number(g.measured), "model": json_number(g.model),
        "residual": json_number(g.residual), "sigma": json_number(g.sigma),
        "z": json_number(g.z), "unit": g.unit,
    }  # fmt: skip


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
    # every fit and candidate of the diagnosis reads the terms' columns built once on these rows
    built = BuiltColumns(ds)
    joint = fit_with_components(ds, model, built=built)
    found = _diagnose(joint.dataset, joint.fit, model, catalogue, alpha, built)
    cat = catalogue if catalogue is not None else CATALOGUE
    rec = parse_model(found.recommended_spec, cat) if found.recommended_spec else []
    found = _not_a_sink(found, what_absorbed(joint.dataset, model, alpha, built, rec))
    return _at_rest(found, joint.dataset, rest_hits(joint.dataset, alpha), cat, built)


def _at_rest(
    d: Diagnosis,
    ds: Dataset,
    hits: Sequence[ScanHit],
    cat: Mapping[str, Term],
    built: BuiltColumns,
) -> Diagnosis:
    """``d`` with the bias changes the gyro reads at the turns' rests
    (:func:`host.workbench.sinks.rest_hits`): on a channel where nothing is recommended and
    no signal named, a change is the channel's finding; a group of equals there whose terms
    are nothing at rest (they move only the turns' closures: a scale asymmetry) cannot be what
    moved the rests, and is dropped."""
    named = {(h.sensor, h.axis) for h in d.dominant}
    by_label = {c.label: c for c in d.candidates}
    on = {(c.sensor, a) for lab in d.recommended if (c := by_label.get(lab)) for a in c.axes}
    dominant, groups, notes = list(d.dominant), list(d.equals), list(d.notes)
    for h in hits:
        ch = (h.sensor, h.axis)
        if ch in named or ch in on:
            continue
        here = [e for e in groups if any(_on_channel(t, ch) for t in e.terms)]
        if any(not _only_turns(t, ds, cat, built) for e in here for t in e.terms):
            continue
        groups = [e for e in groups if e not in here]
        # before the weaker signals named: a gyro step inside a turn leaves the accel a shadow
        k = next((i for i, o in enumerate(dominant) if o.delta_chi2 < h.delta_chi2), None)
        dominant.insert(len(dominant) if k is None else k, h)
        notes.append(
            f"the gyro at the turns' rests: {h.signal[len(STEP) + 1 :]}"
            + (f"; not {', '.join(t for e in here for t in e.terms)}, which give nothing at "
               "rest" if here else "")
        )  # fmt: skip
    if len(dominant) == len(d.dominant):
        return d
    return dataclasses.replace(
        d, verdict="unexplained", dominant=tuple(dominant), equals=tuple(groups),
        notes=tuple(notes),
    )  # fmt: skip


def _on_channel(label: str, ch: tuple[str, str]) -> bool:
    parts = label.split(":")
    return len(parts) == 3 and parts[1] == ch[0] and ch[1] in parts[2]


def _only_turns(label: str, ds: Dataset, cat: Mapping[str, Term], built: BuiltColumns) -> bool:
    """Does the term ``label`` move only the turns' closures (nothing at rest)?"""
    name, sensor, axes = label.split(":")
    if name not in cat:
        return False
    mt = ModelTerm(cat[name], sensor, tuple(AXES.index(a) for a in axes))
    return bool(closure_axes(ds, mt, built))


def _diagnose(
    ds: Dataset,
    fit: Fit,
    model: Sequence[ModelTerm],
    catalogue: Mapping[str, Term] | None,
    alpha: float,
    built: BuiltColumns,
) -> Diagnosis:
    """:func:`diagnose` of the joint fit ``fit`` on ``ds`` (its components estimated with it),
    before its variance components are checked for what they absorbed."""
    _require_dof(ds, fit)
    cands, tried = evaluate_candidates(ds, fit, catalogue, alpha, built)
    #: a candidate tested against its own yardstick (host.workbench.absorbed): the scan is
    #: weighed against it on that yardstick too
    own = {c.label: (t.ds, t.fit) for c, t in zip(cands, tried, strict=True) if t.ds is not ds}
    cat = catalogue if catalogue is not None else CATALOGUE
    columns = ScanColumns(ds)  # the fit and the fit with the extra terms scan the same rows
    scanned = scan_signals(ds, fit, alpha, columns)
    finder = EqualsFinder(ds, fit, cands, tried, scanned, cat, alpha)
    top = _shared_first(cands, scanned, cat, finder)
    if top is not None:
        # a property of the bench explains more than any one channel's term or signal: take
        # it first and diagnose what is left after it (:func:`_shared_first`)
        return _after_shared(ds, fit, cands, top, model, cat, alpha)
    best, dominant = _best_and_dominant(cands, scanned, own, alpha)
    usable = [c for ch, c in best.items()
              if ch not in dominant and not _beaten(c, dominant.values())]  # fmt: skip
    # a term is recommended only when it explains what the best step on its channel does not
    weighed = weigh_steps(
        ds, fit, usable, {c.label: t for c, t in zip(cands, tried, strict=True)}, scanned,
        finder.level, len(columns.cuts), built,
    )  # fmt: skip
    usable = weighed.kept
    for ch, h in weighed.stepped.items():
        dominant.setdefault(ch, h)
    groups, grouped = _grouped(usable, finder)
    for e in weighed.groups:
        groups.setdefault(e.members[0], e)
    extra = [_model_term(c, cat) for c in usable]
    aug = fit_model(ds, merge_model(list(model) + extra), built=built) if extra else fit
    misfit, removed = _misfit_removed(ds, fit, model, extra, aug, built)
    # a signal no term explains may have equals too (temperature², dT/dt and time measured
    # together): the group is reported beside it
    for h in dominant.values():
        g = finder.signal_group(h)
        if g is not None and not any(g.members[0] in k.members for k in groups.values()):
            groups[g.members[0]] = g
    alone = [c for c in usable if c.label not in grouped]
    if len(extra) > 1:
        # each recommended term adds significantly to the others (a term significant only
        # through a misfit another explains is not what is missing)
        alone = [c for c in alone if c.label in own
                 or _adds_to_rest(ds, model, extra, c, cat, finder.level, aug, built)]  # fmt: skip
    recommended = tuple(c.label for c in alone) if alone and removed >= MOST * misfit else ()
    rec_extra = [_model_term(c, cat) for c in alone if c.label in recommended]
    hits = scan_signals(ds, aug, alpha, columns) if aug is not fit else scanned
    return _conclude(
        ds, fit, cands, aug, hits, dominant, groups, grouped, set(own), weighed, alone,
        recommended, rec_extra, (misfit, removed), alpha,
    )  # fmt: skip


def _verdict_of(
    dominant: bool,
    missing: bool,
    hits: bool,
    aug: Fit,
    cands: Sequence[Candidate],
    fit: Fit,
    alpha: float,
) -> str:
    """The verdict: a signal no term explains, a term (or a group of equals) that is missing,
    structure or misfit left, no degrees of freedom to test, or adequate."""
    if dominant:
        return "unexplained"
    if missing:
        return "missing_effect"
    if hits or aug.chi2_p < alpha or any(c.significant for c in cands):
        return "unexplained"
    return "untestable" if fit.untestable else "adequate"


def _shared_first(
    cands: Sequence[Candidate],
    scanned: Sequence[ScanHit],
    cat: Mapping[str, Term],
    finder: EqualsFinder,
) -> Candidate | None:
    """The strongest usable candidate when it is a shared (bench) term (one set of parameters
    for every channel) with no equals and no plain signal beats it, else None (an
    accelerometer's bias step inside the turns moves their still moments as a tilted plate
    does: the step, one parameter, explains more than the tilt)."""
    usable = [c for c in cands if c.significant and not c.explained_by and not c.implausible]
    top = max(usable, key=lambda c: c.delta_chi2, default=None)
    if (top is not None and cat[top.term].shared and finder.group(top) is None
            and not _beaten(top, scanned)):  # fmt: skip
        return top
    return None


def _require_dof(ds: Dataset, fit: Fit) -> None:
    """UserError when the records leave the fit no degrees of freedom."""
    if fit.dof <= 0:
        n = len(ds.signals)
        raise UserError(
            f"{n} record{' leaves' if n == 1 else 's leave'} the model no "
            f"degrees of freedom ({fit.n_params} parameters determined by as many values): "
            "nothing tests it; diagnose needs more records (at least the six static faces)"
        )


def _conclude(
    ds: Dataset,
    fit: Fit,
    cands: Sequence[Candidate],
    aug: Fit,
    hits: Sequence[ScanHit],
    dominant: Mapping[tuple[str, str], ScanHit],
    groups: Mapping[str, Equals],
    grouped: set[str],
    own: set[str],
    weighed: Weighed,
    alone: Sequence[Candidate],
    recommended: tuple[str, ...],
    rec_extra: Sequence[ModelTerm],
    misfit_removed: tuple[float, float],
    alpha: float,
) -> Diagnosis:
    """The notes and the verdict of :func:`_diagnose` from what it found; ``misfit_removed``:
    the model's misfit (χ² − dof) and what the extra terms remove of it."""
    misfit, removed = misfit_removed
    notes = [*ds.notes, *weighed.notes, *_fit_notes(fit)]
    if alone and not recommended and not groups:
        notes.append(
            f"the best candidates ({', '.join(c.label for c in alone)}) remove only "
            f"{100 * removed / misfit:.0f} % of the misfit (χ² − dof = {misfit:.1f}): "
            "none of them is what is missing"
        )
    notes += [f"{c.label} is significant but not physical: {c.implausible}"
              for c in cands if c.implausible]  # fmt: skip
    equal = bool(weighed.groups) or bool(groups and (removed >= MOST * misfit or grouped & own))
    verdict = _verdict_of(
        bool(dominant), bool(recommended) or equal, bool(hits), aug, cands, fit, alpha
    )
    if verdict == "missing_effect" and aug.chi2_p < alpha and not hits:
        notes.append(
            f"even with the recommended terms the fit is poor (χ² p = {aug.chi2_p:.2g}): "
            "more is missing, or the noise model is too optimistic"
        )
    return Diagnosis(
        fit, tuple(cands), tuple(hits), verdict, tuple(notes), recommended,
        tuple(dominant.values()), model_spec(merge_model(rec_extra)) if recommended else None,
        ds.g, tuple(groups.values()),
    )  # fmt: skip


def _best_and_dominant(
    cands: Sequence[Candidate],
    scanned: Sequence[ScanHit],
    own: Mapping[str, tuple[Dataset, Fit]],
    alpha: float,
) -> tuple[dict[tuple[str, str], Candidate], dict[tuple[str, str], ScanHit]]:
    """The best usable candidate of each channel (significant, plausible, not made redundant)
    and the structure in the model's residual that a plain signal explains better than it (a
    candidate on its own yardstick, ``own``, is weighed against that yardstick's scan)."""
    best: dict[tuple[str, str], Candidate] = {}
    for c in cands:
        if c.significant and not c.explained_by and not c.implausible:
            best.setdefault(c.channel, c)
    dominant: dict[tuple[str, str], ScanHit] = {}
    own_scans: dict[str, list[ScanHit]] = {}  # each own yardstick scanned once
    for h in scanned:
        ch = (h.sensor, h.axis)
        cb = best.get(ch)
        if ch in dominant:
            continue
        if cb is not None and cb.label in own:
            if cb.label not in own_scans:
                own_scans[cb.label] = scan_signals(*own[cb.label], alpha)
            same = [g for g in own_scans[cb.label] if (g.sensor, g.axis) == ch]
            if same and same[0].delta_chi2 > DOMINANT * cb.delta_chi2:
                dominant[ch] = same[0]
        elif cb is None or h.delta_chi2 > DOMINANT * cb.delta_chi2:
            dominant[ch] = h
    return best, dominant


def _grouped(
    usable: Sequence[Candidate], finder: EqualsFinder
) -> tuple[dict[str, Equals], set[str]]:
    """A candidate the records cannot tell apart from another explanation is not recommended
    alone: its group of equals is reported instead (the fit after it still holds it, so that
    what is left is scanned). -> the groups by their strongest anchor, the candidates in one."""
    groups: dict[str, Equals] = {}
    grouped: set[str] = set()
    for c in sorted(usable, key=lambda c: -c.delta_chi2):
        # two channels' bests can be each other's equals (a face lean and a plate tilt on
        # unknown headings): one group, not two
        if any(c.label in h.members for h in groups.values()):
            grouped.add(c.label)
            continue
        g = finder.group(c)
        if g is not None:
            grouped.add(c.label)
            groups[c.label] = g
    return groups, grouped


def _fit_notes(fit: Fit) -> list[str]:
    """What the fit itself says: the parameters the records leave undetermined, the channels
    with no degrees of freedom, how the σ were made."""
    notes = []
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
    return notes


def _not_a_sink(d: Diagnosis, absorbed: Absorbed | None) -> Diagnosis:
    """``d`` with its implausible variance components as a finding (:mod:`host.workbench.sinks`):
    never ``adequate``; what they absorbed named as its channel's unexplained signal, and a
    recommended term on that channel dropped (the signal explains it)."""
    if absorbed is None:
        return d
    said = absorbed.describe()
    notes = [*d.notes, *([] if said in d.notes else [said])]
    if absorbed.by_terms:
        return dataclasses.replace(d, notes=tuple(notes))
    h = absorbed.hit
    dominant = list(d.dominant)
    recommended = d.recommended
    if h is not None:
        dominant = [h, *(x for x in dominant if (x.sensor, x.axis) != (h.sensor, h.axis))]
        dominant.sort(key=lambda x: -x.delta_chi2)  # the strongest finding first
        by_label = {c.label: c for c in d.candidates}
        mine = {lab for lab in recommended if lab in by_label
                and by_label[lab].sensor == h.sensor and h.axis in by_label[lab].axes}  # fmt: skip
        if mine:
            notes.append(
                f"not recommended: {', '.join(sorted(mine))} (what the component absorbed, "
                f"{h.signal}, explains its channel)"
            )
            recommended = tuple(lab for lab in recommended if lab not in mine)
    spec = d.recommended_spec if recommended == d.recommended else (
        ",".join(recommended) or None
    )  # fmt: skip
    verdict = "unexplained" if dominant or d.verdict in ("adequate", "untestable") else d.verdict
    return dataclasses.replace(
        d, verdict=verdict, notes=tuple(notes), recommended=recommended,
        dominant=tuple(dominant), recommended_spec=spec,
    )  # fmt: skip


def _misfit_removed(
    ds: Dataset,
    fit: Fit,
    model: Sequence[ModelTerm],
    extra: Sequence[ModelTerm],
    aug: Fit,
    built: BuiltColumns,
) -> tuple[float, float]:
    """The misfit (χ² − dof) and how much of it the ``extra`` terms remove, on the yardstick
    they are tested on (:mod:`host.workbench.absorbed`): a term that moves the closure of the
    turns about an axis (a gyro scale asymmetry, a quadratic scale) is weighed without the
    turn-angle σ of that axis, which would otherwise hold its misfit as the hand's angle error
    and leave it nothing to remove. ``aug``: the model with ``extra`` fitted on ``ds``."""
    axes = frozenset().union(*(closure_axes(ds, mt, built) for mt in extra))
    yard = without_turn_angle(ds, axes) if axes else ds
    if yard is not ds:
        fit = fit_model(yard, model, built=built)
        aug = fit_model(yard, merge_model([*model, *extra]), built=built)
    return max(fit.chi2 - fit.dof, 0.0), fit.chi2 - aug.chi2


def _beaten(c: Candidate, hits: Iterable[ScanHit]) -> bool:
    """Does a plain signal on one of ``c``'s channels explain more than ``c`` does on all of
    them (Δχ² beyond :data:`DOMINANT` times its)?"""
    return any(h.sensor == c.sensor and h.axis in c.axes
               and h.delta_chi2 > DOMINANT * c.delta_chi2 for h in hits)  # fmt: skip


def _model_term(c: Candidate, cat: Mapping[str, Term]) -> ModelTerm:
    return ModelTerm(cat[c.term], c.sensor, tuple(AXES.index(a) for a in c.axes))


def _adds_to_rest(
    ds: Dataset,
    model: Sequence[ModelTerm],
    extra: Sequence[ModelTerm],
    c: Candidate,
    cat: Mapping[str, Term],
    level: float,
    aug: Fit,
    built: BuiltColumns,
) -> bool:
    """Does ``c`` lower χ² significantly (at ``level``) when the other ``extra`` terms are
    already in the model? ``aug``: the model with all of ``extra`` fitted."""
    mine = _model_term(c, cat)
    rest = [mt for mt in extra if mt.label != mine.label]
    without = fit_model(ds, merge_model([*model, *rest]), built=built)
    return chi2_sf(max(without.chi2 - aug.chi2, 0.0), mine.count(ds.signals)) <= level


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
    if fit.uncertainty_note():  # the parameters shown are this fit's: say how their σ were made
        notes.append(fit.uncertainty_note())
    notes.append(
        f"{top.label} (one set of parameters for every channel) explains the most; the "
        f"diagnosis of the model with it: {inner.verdict}"
    )
    notes.extend(n for n in inner.notes if n not in ds.notes)
    views = [t.describe() for t in map(seen_tilt_test, (fit, inner.fit)) if t is not None]
    notes.extend(v for v in views[:1] if v not in notes)  # the records' own tilts tested
    if inner.verdict == "unexplained" or removed < MOST * misfit:
        return Diagnosis(fit, tuple(cands), inner.unexplained, "unexplained", tuple(notes), (),
                         inner.dominant, None, ds.g, inner.equals)  # fmt: skip
    by_label = {c.label: c for c in inner.candidates}
    inner_terms = [_model_term(by_label[x], cat) for x in inner.recommended]
    others = inner_terms + [_model_term(by_label[e.members[0]], cat) for e in inner.equals]
    keep = True
    if others:
        # the shared term still adds to what the inner diagnosis found (else it was only
        # taking up part of a misfit that those explain)
        level = alpha / max(sum(1 for c in cands if c.identifiable), 1)
        without = fit_model(ds, merge_model([*model, *others]))
        with_it = fit_model(ds, merge_model([*model, shared, *others]))
        keep = chi2_sf(max(without.chi2 - with_it.chi2, 0.0), top.n_params) <= level
        if not keep:
            notes.append(f"{top.label} adds nothing once the others are in: not recommended")
    recommended = ((top.label,) if keep else ()) + tuple(inner.recommended)
    extra = ([shared] if keep else []) + inner_terms
    exact = [c for c in (*inner.fit.untestable, *inner.untestable_with) if c not in fit.untestable]
    return Diagnosis(
        fit, tuple(cands), inner.unexplained, "missing_effect", tuple(notes), recommended,
        (), model_spec(merge_model(extra)) if extra else None, ds.g, inner.equals,
        tuple(dict.fromkeys(exact)) if keep else inner.untestable_with,
    )  # fmt: skip
