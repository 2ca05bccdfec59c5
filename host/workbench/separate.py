"""The record that tells two explanations apart.

When the diagnosis holds a group of equals (:mod:`host.workbench.equals`: two terms that fit the
records equally well, e.g. a face lean and an accelerometer reading (f/g)²), the question for the
bench is which record to measure so that the data can choose. For two explanations A and B (each
a list of model terms added to the model), each with the size the records give it, the
separation a record buys is the noncentrality

    λ = min(χ²(model + B fitted to what model + A predicts), the same with A and B swapped)

on the session with the record added (:class:`host.workbench.planner.Augmenter`): the Δχ² by
which the true one of the two would beat the other, noise aside. λ ≥ 9 is a 3σ choice. The
records are ranked by λ per minute of the operator's time. Both are weighed on the yardstick
the diagnosis tests them on (:func:`yardstick`: a gyro scale asymmetry or quadratic scale
without the turn-angle σ of its axis, which would otherwise take its signal for the hand's).
A group of three or more (``others``) is separated when every pair is: λ is the smallest over
the pairs.

Where static records carry no placement heading, the plate's tilt joins such a group (each
static then carries the tilt as it sees it as two unknowns of its own,
:func:`host.model.catalogue.plate_tilt`, which hold the static's horizontal readings whatever
they are). A record at an unknown heading is held the same way, so the menu then adds the
records whose heading the operator records (:func:`heading_candidates`): a 45° attitude placed
at the dialogue's heading and noted, and a face again at two noted headings 90° apart (the
cube turned on the face) — where a heading noted against the fence is in the frame of the
tilt (:func:`headings_can_be_noted`). A plate's tilt is fixed in the room, a face lean in the
cube, an (f/g)² effect in the sensor: at a noted heading the tilt the turns' rests measured
is known there, and only the 45° attitude puts (f/g)² at ½ where a face lean, on a square
wedge, is 0.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

from host.bench.plan import tilted_45
from host.errors import UserError
from host.model.dataset import Dataset, build_dataset
from host.model.design import BuiltColumns, same_records
from host.model.fit import Fit, fit_model, predict
from host.model.geometry import DIALOGUE_HEADING_DEG
from host.model.noise import NoiseModel
from host.model.plate import LEVEL_P, session_plate
from host.model.rows import RecordWork
from host.model.signals import AXES
from host.model.solve import fitted_chi2
from host.model.spec import ModelTerm, parse_model
from host.model.terms import Term
from host.session.directory import Session
from host.session.method import DEFAULT_HEIGHT_M, DEFAULT_LATITUDE_DEG, local_gravity
from host.session.records import HEADING_KEY, STATIC_NAMES
from host.workbench.absorbed import closure_axes, without_turn_angle
from host.workbench.equals import signal_term
from host.workbench.planner import (
    OPERATOR_TIME,
    OTHER_TEMPERATURE_C,
    Augmenter,
    Candidate,
    OperatorTime,
    _face_up,
    _format_up,
    candidates,
    has_temperature_term,
)

#: λ at which the data choose between the two at 3σ
CLEAR = 9.0


@dataclass(frozen=True)
class Separating:
    """A record and the separation it buys: ``lam`` (λ with it added), ``per_min`` (λ gained
    over the session's own per minute of operator time); ``pairs`` λ of each pair of
    explanations (i, j, λ; indices into a, b, others…), ``lam`` their smallest."""

    candidate: Candidate
    lam: float
    per_min: float
    pairs: tuple[tuple[int, int, float], ...] = ()


@dataclass(frozen=True)
class Separation:
    """The separation now (``lam_now``), the records ranked best first, and what the data
    say now: ``chi2_a``/``chi2_b`` the χ² of the model with ``a``/``b`` fitted to the records
    (``chi2_b − chi2_a`` > 0: the records prefer ``a``); ``others`` the further members of
    the group (λ the smallest over every pair)."""

    a: str
    b: str
    lam_now: float
    ranked: tuple[Separating, ...]
    chi2_a: float = math.nan
    chi2_b: float = math.nan
    others: tuple[str, ...] = ()


def _values(fit: Fit) -> dict[tuple[str, str, str, str], float]:
    return {
        (p.term_name, p.sensor, p.axis, p.key): p.value
        for p in fit.parameters
        if math.isfinite(p.value)
    }


#: a signal of the scan as a group of equals names it (:func:`host.workbench.equals.signal_label`)
_SIGNAL_RE = re.compile(r"^(accel|gyro) ([xyz]) follows (.+)$")


@dataclass(frozen=True)
class Explanation:
    """One of the two explanations: model ``terms`` (catalogue or term file), or a ``signal``
    of the scan (sensor, axis letter, signal name: an off-catalogue shape such as '(specific
    force z)²'), whose term is built on each dataset it is weighed on (a signal such as dT/dt
    is read from the session's records around each one)."""

    label: str
    terms: tuple[ModelTerm, ...] = ()
    signal: tuple[str, str, str] | None = None

    def on(self, ds: Dataset) -> tuple[ModelTerm, ...]:
        """The explanation's terms on ``ds``."""
        if self.signal is None:
            return self.terms
        sensor, axis, name = self.signal
        term = signal_term(name, sensor, ds)
        if term is None:
            raise UserError(f"{self.label!r}: the scan has no signal {name!r} on {sensor} "
                            "(give it as model diagnose names it)")  # fmt: skip
        return (ModelTerm(term, sensor, (AXES.index(axis),)),)


def explanation(text: str, catalogue: Mapping[str, Term]) -> Explanation:
    """``text`` as ``plan --separate`` takes it: a model spec (``scale_asymmetry:gyro:z``) or
    a signal as a group of equals names it (``accel y follows (specific force z)²``)."""
    m = _SIGNAL_RE.match(text.strip())
    if m:
        return Explanation(text.strip(), signal=(m.group(1), m.group(2), m.group(3)))
    return Explanation(text.strip(), tuple(parse_model(text, catalogue)))


def noncentralities(
    ds: Dataset,
    model: Sequence[ModelTerm],
    terms: Sequence[Sequence[ModelTerm]],
    values: Sequence[dict[tuple[str, str, str, str], float]],
    built: BuiltColumns | None = None,
) -> tuple[tuple[int, int, float], ...]:
    """(i, j, λ) for each pair i < j of the explanations ``terms`` (each a list of terms added
    to ``model``, with its ``values``): λ the min over the two directions of χ² of one
    explanation fitted to the other's noise-free prediction (the whitening of ``ds`` kept).
    Each explanation predicts once, and each is fitted to the others' predictions on one
    whitened design (``built``: the columns already built on the rows of ``ds``,
    :class:`~host.model.design.BuiltColumns`, else built here once for all)."""
    built = BuiltColumns(ds) if built is None else built
    models = [(*model, *t) for t in terms]
    ys = [predict(ds, m, v, built) for m, v in zip(models, values, strict=True)]
    chi2: dict[tuple[int, int], float] = {}  # (fitted, predicted) -> χ²
    for j, m in enumerate(models):
        truths = [i for i in range(len(models)) if i != j]
        for i, c in zip(truths, fitted_chi2(ds, m, [ys[i] for i in truths], built), strict=True):
            chi2[(j, i)] = c
    out = []
    for i in range(len(models)):
        for j in range(i + 1, len(models)):
            out.append((i, j, min(math.inf, chi2[(j, i)], chi2[(i, j)])))
    return tuple(out)


def yardstick(ds: Dataset, terms: Sequence[ModelTerm]) -> Dataset:
    """The yardstick the two explanations are weighed on: ``ds`` without the turn-angle σ of
    the axes whose turn closures one of ``terms`` moves (:mod:`host.workbench.absorbed`, as
    the diagnosis tests them), so that neither explanation's signal is taken for the hand's."""
    axes = frozenset().union(*(closure_axes(ds, mt) for mt in terms))
    return without_turn_angle(ds, axes) if axes else ds


#: the fitted values of a fit's parameters by (term, sensor, axis, key)
_Values = dict[tuple[str, str, str, str], float]


@dataclass(frozen=True, eq=False)
class _Weighing:
    """How a session (the one measured, or it with a candidate record) is weighed: its dataset
    on the yardstick of the explanations ``exps`` and each explanation's terms on it, built
    with the same noise and site; ``work`` the records' own reads, kept between the builds."""

    exps: tuple[Explanation, ...]
    noise: NoiseModel
    latitude_deg: float
    height_m: float
    work: RecordWork

    def weighed(self, s: Session) -> tuple[Dataset, list[tuple[ModelTerm, ...]]]:
        """The dataset of ``s`` on the yardstick and each explanation's terms on it."""
        raw = build_dataset(s, noise=self.noise, latitude_deg=self.latitude_deg,
                            height_m=self.height_m, work=self.work)  # fmt: skip
        on_raw = [e.on(raw) for e in self.exps]
        ds = yardstick(raw, [mt for t in on_raw for mt in t])
        # the yardstick weighs the same records' rows anew: the terms built on them hold
        return ds, on_raw if same_records(ds, raw) else [e.on(ds) for e in self.exps]


def separate(
    session: Session,
    model: Sequence[ModelTerm],
    a: Sequence[ModelTerm] | Explanation,
    b: Sequence[ModelTerm] | Explanation,
    *,
    others: Sequence[Sequence[ModelTerm] | Explanation] = (),
    noise: NoiseModel | None = None,
    time: OperatorTime = OPERATOR_TIME,
    latitude_deg: float = DEFAULT_LATITUDE_DEG,
    height_m: float = DEFAULT_HEIGHT_M,
    only: Sequence[Candidate] | None = None,
    progress: Callable[[int, int, str], None] | None = None,
) -> Separation:
    """Rank the records that would tell explanation ``a`` from ``b`` (and from each of
    ``others``, and those from each other; each a list of terms added to ``model``, or an
    :class:`Explanation`), each at the size this session's records give it."""
    exps = tuple(x if isinstance(x, Explanation) else Explanation(_label(x), tuple(x))
                 for x in (a, b, *others))  # fmt: skip
    weighing = _Weighing(exps, noise or NoiseModel(), latitude_deg, height_m, RecordWork())
    ds, terms = weighing.weighed(session)
    built = BuiltColumns(ds)
    base = fit_model(ds, model, built=built)
    fits = [fit_model(ds, (*model, *t), built=built) for t in terms]
    values = [_values(f) for f in fits]
    lam_now = min(x[2] for x in noncentralities(ds, model, terms, values, built))
    base_values = {p.name: p.value for p in base.parameters if math.isfinite(p.value)}
    hand = Augmenter(session, base_values, local_gravity(latitude_deg, height_m))
    todo = _menu(session, ds, hand, terms, exps, time) if only is None else list(only)
    ranked = _ranked(weighing, hand, model, values, todo, lam_now, progress)
    return Separation(exps[0].label, exps[1].label, lam_now, tuple(ranked), fits[0].chi2,
                      fits[1].chi2, tuple(e.label for e in exps[2:]))  # fmt: skip


def _menu(
    session: Session,
    ds: Dataset,
    hand: Augmenter,
    terms: Sequence[tuple[ModelTerm, ...]],
    exps: Sequence[Explanation],
    time: OperatorTime,
) -> list[Candidate]:
    """The records worth weighing: the planner's menu (at another temperature too when an
    explanation follows temperature; the noted-heading records when the statics carry no
    heading and one noted now is in the tilt's frame), those the session's range allows."""
    temp = has_temperature_term([mt for t in terms for mt in t]) or any(
        "temperature" in e.signal[2] for e in exps if e.signal
    )
    temps = (OTHER_TEMPERATURE_C,) if temp else ()
    menu = candidates(hand.static_s, hand.turns, time, paces=(1.0, 0.5, 2.0),
                      temperatures=temps)  # fmt: skip
    if unknown_headings(session) and headings_can_be_noted(session, ds):
        menu += heading_candidates(hand.static_s, time)
    return [c for c in menu if hand.fits_range(c)]


def _ranked(
    weighing: _Weighing,
    hand: Augmenter,
    model: Sequence[ModelTerm],
    values: Sequence[_Values],
    todo: Sequence[Candidate],
    lam_now: float,
    progress: Callable[[int, int, str], None] | None,
) -> list[Separating]:
    """Each of ``todo`` added to the session and weighed (λ of every pair at the sizes
    ``values`` the records give them), best λ gained per minute first."""
    ranked = []
    for i, cand in enumerate(todo):
        if progress is not None:
            progress(i, len(todo), cand.label)
        ds, terms = weighing.weighed(hand.with_candidate(cand))
        pairs = noncentralities(ds, model, terms, values)
        got = min(x[2] for x in pairs)
        ranked.append(Separating(cand, got, (got - lam_now) / (cand.operator_s / 60.0), pairs))
    if progress is not None:
        progress(len(todo), len(todo), "")
    ranked.sort(key=lambda s: (-s.per_min, s.candidate.operator_s))
    return ranked


def unknown_headings(session: Session) -> bool:
    """Whether a static record of ``session`` carries no placement heading (the plate's tilt
    then holds its horizontal readings: :func:`host.model.catalogue.plate_tilt`)."""
    return any(r.kind == "static" and HEADING_KEY not in r.meta
               for r in session.records.values())  # fmt: skip


def headings_can_be_noted(session: Session, ds: Dataset) -> bool:
    """Whether a heading noted now is in the frame of the plate's tilt: the fence's, when a
    turn record carries its heading, or any, when the turns' rests show no tilt (or there are
    none). With no turn heading recorded on a tilted plate the frame is the first turn's
    reference axis (:func:`host.model.plate.resolve_placements`), which the operator cannot
    find again: a heading noted against the fence would be off by that unknown angle.
    ``ds``: the session's dataset (its turns' rests)."""
    if any(r.kind == "turn" and HEADING_KEY in r.meta for r in session.records.values()):
        return True
    plate = session_plate(ds.signals)
    return plate is None or plate.p_level >= LEVEL_P


#: the heading the operator is asked to place a noted record at, ° (the dialogue's)
NOTED_HEADING_DEG = DIALOGUE_HEADING_DEG


def heading_candidates(static_s: float, time: OperatorTime = OPERATOR_TIME) -> list[Candidate]:
    """The records whose placement heading the operator notes (for sessions whose statics
    carry none): each 45° attitude of :func:`host.bench.plan.tilted_45` at the dialogue's
    heading, noted; and each face again twice, at the dialogue's heading and turned 90°
    counter-clockwise on the same face, both noted. ``static_s`` each, s."""
    out = []
    for name, up in tilted_45():
        rec = (name, up, "static", static_s, 0, 0)
        out.append(Candidate(f"{name} (up {_format_up(up)}), heading noted", (rec,),
                             time.place_tilted + time.settle + static_s,
                             headings=(NOTED_HEADING_DEG,)))  # fmt: skip
    for face in STATIC_NAMES:
        recs = tuple((face, _face_up(face), "static", static_s, 0, 0) for _ in range(2))
        out.append(Candidate(f"{face} at 0° and 90°, noted", recs,
                             2 * (time.place + time.settle + static_s),
                             headings=(NOTED_HEADING_DEG, NOTED_HEADING_DEG + 90.0)))  # fmt: skip
    return out


def _label(terms: Sequence[ModelTerm]) -> str:
    return ", ".join(m.label for m in terms)
