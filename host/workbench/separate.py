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
"""

from __future__ import annotations

import dataclasses
import math
import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

from host.errors import UserError
from host.model.dataset import Dataset, build_dataset
from host.model.fit import Fit, fit_model, predict
from host.model.noise import NoiseModel
from host.model.signals import AXES
from host.model.spec import ModelTerm, parse_model
from host.model.terms import Term
from host.session.directory import Session
from host.session.method import DEFAULT_HEIGHT_M, DEFAULT_LATITUDE_DEG, local_gravity
from host.workbench.absorbed import closure_axes, without_turn_angle
from host.workbench.equals import signal_term
from host.workbench.planner import (
    OPERATOR_TIME,
    OTHER_TEMPERATURE_C,
    Augmenter,
    Candidate,
    OperatorTime,
    candidates,
    has_temperature_term,
)

#: λ at which the data choose between the two at 3σ
CLEAR = 9.0


@dataclass(frozen=True)
class Separating:
    """A record and the separation it buys: ``lam`` (λ with it added), ``per_min`` (λ gained
    over the session's own per minute of operator time)."""

    candidate: Candidate
    lam: float
    per_min: float


@dataclass(frozen=True)
class Separation:
    """The separation now (``lam_now``), the records ranked best first, and what the data
    say now: ``chi2_a``/``chi2_b`` the χ² of the model with ``a``/``b`` fitted to the records
    (``chi2_b − chi2_a`` > 0: the records prefer ``a``)."""

    a: str
    b: str
    lam_now: float
    ranked: tuple[Separating, ...]
    chi2_a: float = math.nan
    chi2_b: float = math.nan


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


def noncentrality(
    ds: Dataset,
    model: Sequence[ModelTerm],
    a: Sequence[ModelTerm],
    b: Sequence[ModelTerm],
    va: dict[tuple[str, str, str, str], float],
    vb: dict[tuple[str, str, str, str], float],
) -> float:
    """min over the two directions of χ² of one explanation fitted to the other's noise-free
    prediction with values ``va``/``vb`` (the whitening of ``ds`` kept)."""
    ma, mb = (*model, *a), (*model, *b)
    lam = math.inf
    for truth, values, other in ((ma, va, mb), (mb, vb, ma)):
        y = predict(ds, truth, values)
        lam = min(lam, fit_model(dataclasses.replace(ds, y=y), other).chi2)
    return lam


def yardstick(ds: Dataset, terms: Sequence[ModelTerm]) -> Dataset:
    """The yardstick the two explanations are weighed on: ``ds`` without the turn-angle σ of
    the axes whose turn closures one of ``terms`` moves (:mod:`host.workbench.absorbed`, as
    the diagnosis tests them), so that neither explanation's signal is taken for the hand's."""
    axes = frozenset().union(*(closure_axes(ds, mt) for mt in terms))
    return without_turn_angle(ds, axes) if axes else ds


def separate(
    session: Session,
    model: Sequence[ModelTerm],
    a: Sequence[ModelTerm] | Explanation,
    b: Sequence[ModelTerm] | Explanation,
    *,
    noise: NoiseModel | None = None,
    time: OperatorTime = OPERATOR_TIME,
    latitude_deg: float = DEFAULT_LATITUDE_DEG,
    height_m: float = DEFAULT_HEIGHT_M,
    only: Sequence[Candidate] | None = None,
    progress: Callable[[int, int, str], None] | None = None,
) -> Separation:
    """Rank the records that would tell explanation ``a`` from ``b`` (each a list of terms
    added to ``model``, or an :class:`Explanation`), each at the size this session's records
    give it."""
    ea = a if isinstance(a, Explanation) else Explanation(_label(a), tuple(a))
    eb = b if isinstance(b, Explanation) else Explanation(_label(b), tuple(b))
    kw = {"noise": noise or NoiseModel(), "latitude_deg": latitude_deg, "height_m": height_m}

    def weighed(s: Session) -> tuple[Dataset, tuple[ModelTerm, ...], tuple[ModelTerm, ...]]:
        raw = build_dataset(s, **kw)  # type: ignore[arg-type]
        ta, tb = ea.on(raw), eb.on(raw)
        ds = yardstick(raw, [*ta, *tb])
        return ds, ea.on(ds), eb.on(ds)

    ds, ta, tb = weighed(session)
    base = fit_model(ds, model)
    fa, fb = fit_model(ds, (*model, *ta)), fit_model(ds, (*model, *tb))
    va, vb = _values(fa), _values(fb)
    lam_now = noncentrality(ds, model, ta, tb, va, vb)
    base_values = {p.name: p.value for p in base.parameters if math.isfinite(p.value)}
    hand = Augmenter(session, base_values, local_gravity(latitude_deg, height_m))
    if only is None:
        temp = has_temperature_term([*ta, *tb]) or any(
            "temperature" in e.signal[2] for e in (ea, eb) if e.signal
        )
        temps = (OTHER_TEMPERATURE_C,) if temp else ()
        menu = candidates(hand.static_s, hand.turns, time, paces=(1.0, 0.5, 2.0),
                          temperatures=temps)  # fmt: skip
        todo = [c for c in menu if hand.fits_range(c)]
    else:
        todo = list(only)
    ranked = []
    for i, cand in enumerate(todo):
        if progress is not None:
            progress(i, len(todo), cand.label)
        aug, ta, tb = weighed(hand.with_candidate(cand))
        lam = noncentrality(aug, model, ta, tb, va, vb)
        ranked.append(Separating(cand, lam, (lam - lam_now) / (cand.operator_s / 60.0)))
    if progress is not None:
        progress(len(todo), len(todo), "")
    ranked.sort(key=lambda s: (-s.per_min, s.candidate.operator_s))
    return Separation(ea.label, eb.label, lam_now, tuple(ranked), fa.chi2, fb.chi2)


def _label(terms: Sequence[ModelTerm]) -> str:
    return ", ".join(m.label for m in terms)
