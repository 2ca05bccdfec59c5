"""Measure until enough: the first records, then the planner's next record until every
value's σ meets its target.

:class:`AdaptivePlan` is the one engine of an adaptive run: what to measure next, when a record
has enough, what it cost the operator. Its first records (:class:`Stopping`) go axis by axis —
the down face until the σ of its mean meets the target, the up face until the face pair's
g-sensitivity does with the rest its turns will add, then turn pairs about that axis right after
the up face until its gyro scale meets the target (:mod:`host.workbench.stopping`); then the
planner's records (:func:`host.workbench.planner.plan_next` with a target: every step takes the
record that removes the most σ/tolerance above the target per minute of the operator's time).

Two hands ask it: :func:`adaptive_run` drives one callable, ``measure(candidate, names)``, that
measures the candidate's records and returns them under the given names (the virtual bench, an
independent simulator in a benchmark); the operator's dialogue (``calibrate --plan adaptive``,
:mod:`host.dialogue.adaptive`) asks it the same questions between its prompts.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Collection, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from host.errors import UserError
from host.model.noise import NoiseModel
from host.model.spec import ModelTerm
from host.session.directory import Session
from host.session.method import DEFAULT_HEIGHT_M, DEFAULT_LATITUDE_DEG, TOLERANCES
from host.session.records import STATIC_NAMES, STOPPED_KEY, Record, turn_window_s
from host.workbench.planner import (
    OPERATOR_TIME,
    Candidate,
    NextPlan,
    OperatorTime,
    Ranked,
    candidates,
    excess,
    plan_next,
    unique_name,
)
from host.workbench.stopping import StaticRule, mean_sigma, stop_index, turn_scale_ratio, turns_stop

#: measure(candidate, names) -> the candidate's records, measured, under ``names`` (one name per
#: record of the candidate, in order)
Measure = Callable[[Candidate, Sequence[str]], Mapping[str, Record]]


@dataclass(frozen=True)
class Step:
    """One record (or turn pair) of an adaptive run: what was measured, the operator's time
    spent so far (s), the worst σ/tolerance (with its value's name) once it was fitted, and
    the σ the planner predicted for it."""

    label: str
    names: tuple[str, ...]
    operator_s: float
    worst: float
    worst_name: str
    #: the σ of every value the planner predicted for this record before it was measured
    #: (empty for the first records)
    predicted: Mapping[str, float] = dataclasses.field(default_factory=dict)


@dataclass(frozen=True)
class AdaptiveRun:
    """An adaptive run: the records measured, each step, the operator's time in all (s), the
    worst σ/tolerance at the end, whether it met the target, and the record the planner
    would measure next."""

    records: Mapping[str, Record]
    steps: tuple[Step, ...]
    operator_s: float
    worst: float
    worst_name: str
    reached: bool
    #: the record the planner would take next (its first-ranked, with the σ it predicts),
    #: None when it ranks none
    next: Ranked | None = None
    #: why the planner asked for no more (:meth:`AdaptivePlan.planned`)
    why: str = ""


def cost_after(
    c: Candidate,
    previous_up: Sequence[float] | np.ndarray | None,
    time: OperatorTime = OPERATOR_TIME,
) -> float:
    """What ``c`` costs the operator right after a record whose up vector (chip axes) was
    ``previous_up`` (None: nothing measured before), s: its ``operator_s`` less one placement
    when its first record rests on that same face or edge — the cube is already there, against
    the ruler (a static leaves it so; a turn returns it there, method.md §4). The second turn
    of a pair keeps its placement, as :func:`host.workbench.planner.candidates` counts it."""
    if previous_up is None:
        return c.operator_s
    up = np.asarray(c.records[0][1], dtype=float)
    if not np.allclose(up / np.linalg.norm(up), previous_up, atol=1e-6):
        return c.operator_s
    on_edge = np.count_nonzero(np.abs(up) > 1e-9) > 1
    return c.operator_s - (time.place_tilted if on_edge else time.place)


def last_up(records: Mapping[str, Record]) -> np.ndarray | None:
    """The up vector (unit, chip axes) of the last of ``records`` (None: no records)."""
    if not records:
        return None
    up = np.asarray(list(records.values())[-1].up, dtype=float)
    return up / np.linalg.norm(up)


def minimal_plan(
    static_s: float, turns: int, time: OperatorTime = OPERATOR_TIME
) -> list[Candidate]:
    """The six faces of method.md §3 for ``static_s`` s each and a turn pair about each axis
    (§4, ``turns`` each way): the least that determines the base model."""
    by_label = {c.label: c for c in candidates(static_s, turns, time, tilted=False)}
    faces = [by_label[f"{f} again"] for f in STATIC_NAMES]
    pairs = [by_label[f"{ax} turns, {turns} each way"] for ax in "xyz"]
    return [Candidate(f.label.replace(" again", ""), f.records, f.operator_s) for f in faces] + [
        Candidate(p.label, p.records, p.operator_s) for p in pairs
    ]


def fixed_plan_s(
    static_s: float, turns: int, time: OperatorTime = OPERATOR_TIME, closing: bool = False
) -> float:
    """The operator's time of the method's fixed plan, s: the six faces of ``static_s`` s,
    then a turn pair of ``turns`` turns each way about each axis (method.md §3–§4; and the
    closing X up again when ``closing``), in that order, counted as an adaptive plan's
    records are (:func:`cost_after`)."""
    by_label = {c.label: c for c in candidates(static_s, turns, time, tilted=False)}
    order = [f"{f} again" for f in STATIC_NAMES] + [f"{ax} turns, {turns} each way" for ax in "xyz"]
    order += ["x_up again"] if closing else []
    spent, up = 0.0, None
    for label in order:
        spent += cost_after(by_label[label], up, time)
        up = np.asarray(by_label[label].records[-1][1], dtype=float)
    return spent


@dataclass(frozen=True)
class Stopping:
    """How the first records of an adaptive run stop: a face under ``rule`` (the σ of its
    mean, at least ``rule.min_s`` and at most ``rule.max_s`` s), turn pairs of ``turns`` turns
    each way about an axis until its gyro scale meets the target (at most
    :data:`host.workbench.stopping.TURN_PAIRS_MAX` pairs). ``by_axis``: axis by axis — the
    down face, the up face, then the pairs about that axis made without placing the cube
    again (False: the method's order, six faces then the turns). ``pair_rule``: the second
    face of an axis stops when the face pair's g-sensitivity meets the target, counting the
    rest its turns will add to the up face (:meth:`StaticRule.gyro_pair_sigma`; False: on its
    own mean)."""

    rule: StaticRule
    turns: int = 1
    by_axis: bool = True
    pair_rule: bool = True

    def faces(self) -> tuple[str, ...]:
        """The six faces in the order they are measured."""
        if self.by_axis:
            return tuple(f"{ax}_{side}" for ax in "xyz" for side in ("dn", "up"))
        return STATIC_NAMES

    def rest_of_turns_s(self) -> float:
        """The rest a turn pair adds on its up face, s: its two turn windows (a turn about
        the vertical keeps the face up)."""
        return 2.0 * turn_window_s(self.turns)


@dataclass(frozen=True)
class Ask:
    """What an adaptive plan asks for next: ``candidate`` (a face, a turn pair, or the
    planner's record), the names its records get, ``first``: one of the first records (a
    face that stops when it has enough, or a turn pair about an axis until its gyro scale
    does), else the planner's ``ranked`` line (the σ it predicts) on its answer ``plan``."""

    candidate: Candidate
    names: tuple[str, ...]
    first: bool
    ranked: Ranked | None = None
    plan: NextPlan | None = None

    @property
    def static(self) -> bool:
        """A static record (a face), not a turn pair."""
        return self.candidate.records[0][2] == "static"


#: why the planner asks for nothing more: it added as many records as it may
MAX_EXTRA_REACHED = "the most records the planner may add were added"
#: the start of why the planner asks for nothing more when the model's misfit alone keeps a
#: value above the target (:func:`out_of_reach`)
OUT_OF_REACH = "out of reach with this model"


def out_of_reach(misfit: float, whose: str, target: float) -> str:
    """Why no record is planned when the model's misfit alone sets σ/tolerance ``misfit``
    on ``whose``, above ``target``: no record lowers that part (a model that explains the
    records does: the diagnosis names what it lacks)."""
    return (
        f"{OUT_OF_REACH}: its misfit alone sets σ/tolerance {misfit:.3g} on {whose}, above "
        f"the target {target:g}, and no record lowers that part"
    )


#: why the planner asks for nothing more: its last two records did not lower what is above
#: the target (:meth:`AdaptivePlan.check`; one may not by chance, as the fit's widening moves)
DID_NOT_HELP = "the last two records did not bring the values closer to the target"


@dataclass(frozen=True)
class Check:
    """A planner's record against its prediction: the worst σ/tolerance before it, as
    predicted and as it gave once fitted, and whether it lowered the :func:`excess` over the
    target (``helped``)."""

    before: float
    predicted: float
    gave: float
    helped: bool

    def line(self) -> str:
        """One line for the operator."""
        d = self.gave - self.predicted
        verdict = "as predicted" if abs(d) <= 0.1 * self.predicted else (
            "better than predicted" if d < 0 else "worse than predicted"
        )  # fmt: skip
        # within 80 columns with the dialogue's indent: "worse than predicted" is the longest
        return (
            f"it gave worst {self.gave:.3g} (predicted {self.predicted:.3g}, before "
            f"{self.before:.3g}): {verdict}"
        )


@dataclass(frozen=True)
class AdaptivePlan:
    """The engine of an adaptive run: towards every value's σ/tolerance ≤ ``target`` for
    ``model``, first the records of ``stopping`` (None: none), then the candidate of ``menu``
    the planner ranks first, while the operator's time is below ``max_operator_s`` (s).
    :meth:`next_first` and :meth:`planned` say what to measure next (the planner's records
    while its operator's time is below ``max_operator_s`` and it added fewer than
    ``max_extra``), :meth:`static_stop` (live) or :meth:`cut` (a record
    measured to its maximum) when a face has enough, :meth:`turns_decision` whether another
    turn pair follows, :meth:`cost` what a record cost the operator (``time``)."""

    model: Sequence[ModelTerm]
    target: float
    menu: Sequence[Candidate]
    stopping: Stopping | None = None
    serial: str = "ADAPT"
    noise: NoiseModel | None = None
    tolerances: Mapping[str, float | None] = dataclasses.field(default_factory=lambda: TOLERANCES)
    latitude_deg: float = DEFAULT_LATITUDE_DEG
    height_m: float = DEFAULT_HEIGHT_M
    time: OperatorTime = OPERATOR_TIME
    max_operator_s: float = 3600.0
    #: records the planner may add at most (a turn pair is two)
    max_extra: float = math.inf
    #: (axis, the records (name, samples, first time)) -> turns_decision's answer: one fit
    #: per decision (a turn measured again is another record)
    _decided: dict[tuple[str, tuple[tuple[str, int, float], ...]], tuple[bool, str]] = (
        dataclasses.field(default_factory=dict, compare=False, repr=False)
    )

    # ---- the first records ----------------------------------------------------------------
    def next_first(self, records: Mapping[str, Record], taken: Collection[str] = ()) -> Ask | None:
        """The first record still to measure after ``records`` (None: the first records are
        done): a face not yet measured, or another turn pair about an axis whose faces are
        (its first pair, or one more while :meth:`turns_decision` says so). Names avoid
        ``records`` and ``taken``."""
        st = self.stopping
        if st is None:
            return None
        menu = candidates(st.rule.max_s, st.turns, self.time, tilted=False)
        faces = {c.records[0][0]: c for c in menu if c.records[0][2] == "static"}
        pairs = {c.records[0][0][0]: c for c in menu if c.records[0][2] == "turn"}

        def face(name: str) -> Ask:
            c = faces[name]
            return Ask(Candidate(name, c.records, c.operator_s), (name,), True)

        def pair(ax: str) -> Ask:
            names: list[str] = []
            for base, *_ in pairs[ax].records:
                names.append(unique_name(base, [*records, *taken, *names]))
            return Ask(pairs[ax], tuple(names), True)

        order = st.faces()
        for ax in "xyz":
            for name in order if not st.by_axis else (f"{ax}_dn", f"{ax}_up"):
                if name not in records:
                    return face(name)
            if not _pairs_about(records, ax) or self.turns_decision(records, ax)[0]:
                return pair(ax)
        return None

    def _pair_need(
        self, name: str, records: Mapping[str, Record]
    ) -> tuple[np.ndarray | None, float]:
        """For :meth:`StaticRule.stop`: (σ of the opposite face's gyro mean, °/s, as it will
        be once the rest still to come on it is counted; the rest still to come on this
        face, s) — (None, 0) when ``name`` stops on its own mean."""
        st = self.stopping
        if st is None or not st.pair_rule or name not in STATIC_NAMES:
            return None, 0.0
        other = records.get(name[0] + ("_dn" if name.endswith("_up") else "_up"))
        if other is None:  # the first face of its axis
            return None, 0.0
        window = st.rest_of_turns_s()
        sigma = mean_sigma(other.gyro)
        if name.endswith("_up"):  # the turns to come rest on this face
            return sigma, window
        t_s = other.t_ms / 1000.0  # the opposite (up) face: its σ after its turns' rest
        span = float(t_s[-1] - t_s[0])
        return sigma * math.sqrt(span / (span + window)), 0.0

    def static_stop(
        self,
        name: str,
        records: Mapping[str, Record],
        accel: np.ndarray,
        gyro: np.ndarray,
        elapsed_s: float,
    ) -> str | None:
        """Why face ``name`` stops now with these samples (accel m/s², gyro °/s, (N, 3);
        ``elapsed_s`` s of device time), the records before it ``records`` — its header's
        ``stopped`` — or None: go on (:meth:`StaticRule.stop`, the pair rule as
        :class:`Stopping` says; a record that is not one of the six faces on its own mean)."""
        assert self.stopping is not None
        opposite, extra = self._pair_need(name, records)
        return self.stopping.rule.stop(
            accel, gyro, elapsed_s, opposite=opposite, extra_rest_s=extra
        )

    def cut(self, name: str, records: Mapping[str, Record], rec: Record) -> Record:
        """``rec``, face ``name`` measured to its maximum, cut where it had enough, looked at
        once a second as the live measurement does (:func:`host.workbench.stopping.
        stop_index`); its header says why."""
        assert self.stopping is not None
        opposite, extra = self._pair_need(name, records)
        n, why = stop_index(self.stopping.rule, rec.t_ms / 1000.0, rec.accel, rec.gyro,
                            opposite=opposite, extra_rest_s=extra)  # fmt: skip
        meta = {**rec.meta, STOPPED_KEY: why}
        return Record(name, rec.t_ms[:n], rec.accel[:n], rec.gyro[:n], rec.temp[:n], meta)

    def turns_decision(self, records: Mapping[str, Record], axis: str) -> tuple[bool, str]:
        """After the last turn pair about ``axis`` among ``records`` (in the order measured):
        (another pair follows, why — the cw turn's header's ``stopped``), from the
        σ/tolerance of the axis's gyro scale in the fit of the records measured up to that
        pair (:func:`host.workbench.stopping.turns_stop`). Decided once: records measured
        after the pair (the next axis's faces) do not reopen it."""
        names = list(records)
        last = max((i for i, n in enumerate(names) if _is_cw_about(n, axis)), default=-1)
        records = {n: records[n] for n in names[: last + 1]}
        key = (axis, tuple((n, len(r), float(r.t_ms[0]) if len(r) else 0.0)
                           for n, r in records.items()))  # fmt: skip
        if key in self._decided:
            return self._decided[key]
        pairs = _pairs_about(records, axis)
        try:
            ratio, misfit = turn_scale_ratio(
                Session(self.serial, dict(records)), self.model, axis, noise=self.noise,
                tolerances=self.tolerances, latitude_deg=self.latitude_deg,
                height_m=self.height_m,
            )  # fmt: skip
        except UserError as exc:
            out = (False, f"not decided after {pairs} pair(s): the records do not fit yet ({exc})")
        else:
            why = turns_stop(ratio, self.target, pairs, misfit)
            out = (
                (False, why) if why is not None
                else (True, f"another pair follows: gyro scale σ/tolerance {ratio:.3g} above "
                            f"the target {self.target:g} after {pairs} pair(s)")
            )  # fmt: skip
        self._decided[key] = out
        return out

    # ---- the planner's records --------------------------------------------------------------
    def check(self, previous: Ask, p: NextPlan) -> Check:
        """The planner's record ``previous`` (measured) against what it predicted, from the
        planner's answer ``p`` on the records with it."""
        assert previous.ranked is not None and previous.plan is not None
        before = excess(previous.plan.sigma_now, self.target, self.tolerances)
        now = excess(p.sigma_now, self.target, self.tolerances)
        return Check(previous.plan.worst_now, previous.ranked.worst_after, p.worst_now,
                     now < before)  # fmt: skip

    def planned(
        self,
        records: Mapping[str, Record],
        spent_s: float,
        taken: Collection[str] = (),
        added: int = 0,
        previous: Ask | None = None,
        missed: int = 0,
    ) -> tuple[NextPlan, Ask | None, str]:
        """The planner's answer on ``records`` and the record to measure next, or None and why
        not: the target is met; the model's misfit alone keeps a value above it
        (:func:`out_of_reach`); the planner's record measured last (``previous``) did not
        lower the values above it, nor the one before it (``missed``: how many before
        ``previous`` in a row did not; :data:`DID_NOT_HELP`); the operator's time (``spent_s`` s
        so far) reached ``max_operator_s``; no record of the menu brings any value closer to
        the target; or the planner added ``max_extra`` records already (``added``:
        :data:`MAX_EXTRA_REACHED`). Names avoid ``records`` and ``taken``."""
        p = plan_next(
            Session(self.serial, dict(records)), self.model, noise=self.noise,
            tolerances=self.tolerances, time=self.time, latitude_deg=self.latitude_deg,
            height_m=self.height_m, only=self.menu, target=self.target,
        )  # fmt: skip
        ask, why = self._next_of(p, records, spent_s, taken, added, previous, missed)
        return p, ask, why

    def _next_of(
        self,
        p: NextPlan,
        records: Mapping[str, Record],
        spent_s: float,
        taken: Collection[str],
        added: int,
        previous: Ask | None,
        missed: int,
    ) -> tuple[Ask | None, str]:
        """:meth:`planned`'s record to measure next on the planner's answer ``p``."""
        if p.worst_now <= self.target:
            return None, f"target {self.target:g} met"
        misfit, whose = p.misfit_worst(self.tolerances)
        if misfit > self.target:
            return None, out_of_reach(misfit, whose, self.target)
        if previous is not None and missed >= 1 and not self.check(previous, p).helped:
            return None, DID_NOT_HELP
        if spent_s >= self.max_operator_s:
            return None, f"the operator's time reached {self.max_operator_s:g} s"
        if not p.ranked or p.ranked[0].gain_per_min <= 0.0:
            return None, "no record brings it closer"
        if added >= self.max_extra:
            return None, MAX_EXTRA_REACHED
        best = p.ranked[0]
        names: list[str] = []
        for base, *_ in best.candidate.records:
            names.append(unique_name(base, [*records, *taken, *names]))
        return Ask(best.candidate, tuple(names), False, best, p), ""

    def cost(self, ask: Ask, before: Mapping[str, Record], measured: Mapping[str, Record]) -> float:
        """What ``ask`` cost the operator once measured (``measured``, after ``before``), s:
        :func:`cost_after` — a first face counted with the length it had when it stopped
        (its span and one sample), not its maximum."""
        c = ask.candidate
        spent = cost_after(c, last_up(before), self.time)
        if ask.first and ask.static:
            t_s = measured[ask.names[0]].t_ms / 1000.0
            spent += float(t_s[-1] - t_s[0]) + float(t_s[1] - t_s[0]) - c.records[0][3]
        return spent


def _is_cw_about(name: str, axis: str) -> bool:
    """``name`` is a cw turn about ``axis`` (x_cw, x_cw_2, …): the turn that ends a pair."""
    cw = f"{axis}_cw"
    return name == cw or name.startswith(cw + "_")


def _pairs_about(records: Mapping[str, Record], axis: str) -> int:
    """The turn pairs about ``axis`` among ``records`` (its cw turns)."""
    return sum(1 for n in records if _is_cw_about(n, axis))


def adaptive_run(
    measure: Measure,
    model: Sequence[ModelTerm],
    *,
    target: float,
    first: Sequence[Candidate],
    menu: Sequence[Candidate],
    stopping: Stopping | None = None,
    serial: str = "ADAPT",
    noise: NoiseModel | None = None,
    tolerances: Mapping[str, float | None] = TOLERANCES,
    max_operator_s: float = 3600.0,
    max_extra: float = math.inf,
    on_step: Callable[[Step], None] | None = None,
    measured: Mapping[str, Record] | None = None,
    measured_s: float = 0.0,
    time: OperatorTime = OPERATOR_TIME,
) -> AdaptiveRun:
    """Measure the first records of ``stopping`` (each face measured to its maximum and cut
    where it had enough, :meth:`AdaptivePlan.cut`; turn pairs until the axis's gyro scale
    meets ``target``), then ``first`` (e.g. :func:`minimal_plan`), after the records
    ``measured`` already (they cost the operator ``measured_s`` s), then, while the worst
    σ/tolerance of ``model`` is above ``target`` and :meth:`AdaptivePlan.planned` asks for
    a record (within the model's reach, the last one helped, the operator's time below
    ``max_operator_s`` s, fewer than ``max_extra`` records added), the candidate of ``menu``
    that :func:`plan_next` ranks first — the questions of one :class:`AdaptivePlan`.
    ``on_step`` is called after each record is fitted (a progress line). A record on the face
    the cube already rests on costs one placement less (:func:`cost_after`, ``time``)."""
    plan = AdaptivePlan(model, target, menu, stopping, serial, noise, tolerances, time=time,
                        max_operator_s=max_operator_s, max_extra=max_extra)  # fmt: skip
    hand = _Hand(plan, measure, dict(measured or {}), float(measured_s))
    while (ask := plan.next_first(hand.records)) is not None:
        hand.take(ask)
    for c in first:
        names: list[str] = []
        for base, *_ in c.records:
            names.append(unique_name(base, list(hand.records) + names))
        hand.take(Ask(c, tuple(names), False))
    return hand.planner_records(on_step)


class _Hand:
    """:func:`adaptive_run`'s records as they are measured, and the operator's time spent."""

    def __init__(
        self, plan: AdaptivePlan, measure: Measure, records: dict[str, Record], spent: float
    ) -> None:
        self.plan, self.measure, self.records, self.spent = plan, measure, records, spent

    def take(self, ask: Ask) -> tuple[str, ...]:
        """Measure ``ask``; returns the names of its records."""
        new = dict(self.measure(ask.candidate, ask.names))
        if ask.first and ask.static:
            new = {n: self.plan.cut(n, self.records, r) for n, r in new.items()}
        self.spent += self.plan.cost(ask, self.records, new)
        self.records.update(new)
        return tuple(new)

    def planner_records(self, on_step: Callable[[Step], None] | None) -> AdaptiveRun:
        """The planner's records after the first, until :meth:`AdaptivePlan.planned` asks for
        none; the run."""
        steps: list[Step] = []
        pending = Step("first records", tuple(self.records), self.spent, math.nan, "")
        added, previous, missed = 0, None, 0
        while True:
            p, ask, why = self.plan.planned(self.records, self.spent, added=added,
                                            previous=previous, missed=missed)  # fmt: skip
            if previous is not None:
                missed = 0 if self.plan.check(previous, p).helped else missed + 1
            done = dataclasses.replace(pending, worst=p.worst_now, worst_name=p.worst_name)
            steps.append(done)
            if on_step is not None:
                on_step(done)
            if ask is None:
                break
            new = self.take(ask)
            added += len(new)
            assert ask.ranked is not None
            pending = Step(ask.candidate.label, new, self.spent, math.nan, "",
                           ask.ranked.sigma_after)  # fmt: skip
            previous = ask
        last = steps[-1]
        return AdaptiveRun(
            dict(self.records), tuple(steps), self.spent, last.worst, last.worst_name,
            last.worst <= self.plan.target, p.ranked[0] if p.ranked else None, why,
        )  # fmt: skip
