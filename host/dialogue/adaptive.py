"""``calibrate --plan adaptive``: the records the adaptive plan's engine asks for, one at a time,
until every value's σ meets its target (σ/tolerance ≤ ``--target``).

The dialogue asks :class:`host.workbench.adaptive.AdaptivePlan` — the engine the benchmark's
adaptive run asks (``benchmarks/planning.py``) — what to measure next and when a record has
enough. First, axis by axis: the down face until the σ of its mean meets the target, the up
face until the face pair's g-sensitivity does with the rest its turns will add, then turn pairs
about that axis, right after the up face, until its gyro scale meets the target (each record
says why it stopped in its header). Then the planner's records (a face again, the accumulation
time or three times it, or a turn pair about an axis, ranked by the σ/tolerance above the target
each removes per minute of the operator's time): the dialogue says what it asks for and why,
measures it as any record (the same prompts, checks and Save/repeat), and fits again. It stops
when the target is met, when nothing on the list helps any more, or after ``--max-extra``
records, and says the operator's time the records cost (placing, settling, measuring, turning;
:meth:`host.workbench.adaptive.AdaptivePlan.cost`).
"""

from __future__ import annotations

import math
import textwrap
from collections.abc import Callable, Collection, Mapping
from pathlib import Path
from typing import Protocol

import numpy as np

from host.dialogue import screens
from host.dialogue.console import Questions
from host.dialogue.options import CLOSING_NAME, DialogueOptions
from host.model.catalogue import CATALOGUE
from host.model.loader import load_term_file
from host.model.spec import ModelTerm, parse_model
from host.session.records import STATIC_NAMES, Record, turn_window_s
from host.workbench.adaptive import (
    MAX_EXTRA_REACHED,
    OUT_OF_REACH,
    AdaptivePlan,
    Ask,
    Stopping,
    cost_after,
    fixed_plan_s,
    last_up,
)
from host.workbench.planner import NextPlan, candidates, worst_ratio
from host.workbench.stopping import STATIC_MIN_S, StaticRule

#: when a static record has enough (:data:`host.dialogue.recorder.StaticStop`)
Stop = Callable[[np.ndarray, np.ndarray, float], str | None]


class Measuring(Protocol):
    """What the adaptive plan needs of the dialogue (:class:`host.dialogue.recorder.
    Recorder`)."""

    op: Questions
    serial: str
    g: float
    done: dict[str, Record]
    out_dir: Path

    def _ask_static_seconds(self) -> float: ...

    def _ask_turns(self) -> tuple[int, float]: ...

    def _measure_static(
        self, name: str, seconds: float | None = None, stop: Stop | None = None,
        planned: str = "",
    ) -> None: ...  # fmt: skip

    def _measure_turn(
        self, name: str, n: int, window: float, decide: Callable[[Record], str] | None = None
    ) -> None: ...

    def _show_stage1(self) -> None: ...


def model_of(opts: DialogueOptions) -> list[ModelTerm]:
    """The model the dialogue fits (``--model``, its ``--terms`` files)."""
    cat = dict(CATALOGUE)
    for f in opts.compute.term_files:
        cat = load_term_file(f, cat)
    return parse_model(opts.compute.model, cat)


def adaptive_plan(
    opts: DialogueOptions, serial: str, g: float, static_s: float, turns: int
) -> AdaptivePlan:
    """The engine of ``--plan adaptive`` for this dialogue: ``--target``, ``--model``,
    ``--max-extra``; a face measured at least the method's 10 s (or ``static_s`` when
    shorter) and at most ``static_s`` s (``--static-seconds``), turn pairs of ``turns`` turns
    each way; the planner's records a face again of ``static_s`` or three times it, or a turn
    pair. ``g``: local gravity, m/s²."""
    target, site = opts.planning.target, opts.compute
    rule = StaticRule.for_target(target, g, min_s=min(STATIC_MIN_S, static_s), max_s=static_s)
    menu = candidates((static_s, 3 * static_s), turns, tilted=False)
    return AdaptivePlan(
        model_of(opts), target, menu, Stopping(rule, turns), serial,
        latitude_deg=site.latitude_deg, height_m=site.height_m, max_operator_s=math.inf,
        max_extra=opts.planning.max_extra,
    )  # fmt: skip


def measure_adaptive(dlg: Measuring, opts: DialogueOptions) -> AdaptivePlan:
    """The records of ``--plan adaptive`` (those in ``dlg.done`` already are kept): the first
    records, then the planner's; says why it stopped and the operator's time they cost
    beside the fixed plan's. Returns the engine (the closing check stops as it says)."""
    static_s = dlg._ask_static_seconds()
    turns, _ = dlg._ask_turns()
    plan = adaptive_plan(opts, dlg.serial, dlg.g, static_s, turns)
    assert plan.stopping is not None
    dlg.op.say(screens.stops_when_enough_line(plan.stopping.rule))
    spent = 0.0
    taken = (CLOSING_NAME,)
    added = planner_records(plan, dlg.done, taken)  # kept by --resume: --max-extra counts them
    if dlg.done:
        dlg.op.say(screens.adaptive_resumed_line(len(dlg.done), added))
    while (ask := plan.next_first(dlg.done, taken)) is not None:
        spent += _measure(dlg, plan, ask)
    if all(n in dlg.done for n in STATIC_NAMES):
        dlg._show_stage1()
    spent += _planner_records(dlg, plan, opts, spent, added)
    dlg.op.say(screens.operator_time_line(spent, fixed_plan_s(static_s, turns, plan.time)))
    return plan


def _planner_records(
    dlg: Measuring, plan: AdaptivePlan, opts: DialogueOptions, spent: float, added: int
) -> float:
    """The planner's records, each checked against its prediction, until it asks for none
    (and says why); returns the operator's time they cost, s."""
    taken, previous, more, missed = (CLOSING_NAME,), None, 0.0, 0
    while True:
        p, ask, why = plan.planned(dlg.done, spent + more, taken, added, previous, missed)
        if previous is not None:
            check = plan.check(previous, p)
            dlg.op.say(f"  {check.line()}")
            missed = 0 if check.helped else missed + 1
        if ask is None:
            _say_end(dlg, plan, opts, p, why)
            return more
        assert ask.ranked is not None
        dlg.op.say(
            f"Adaptive plan: worst σ/tolerance {_ratio(p.worst_now)} ({p.worst_name}), target "
            f"{plan.target:g}."
        )
        cost = cost_after(ask.candidate, last_up(dlg.done), plan.time)  # as the count says
        dlg.op.say(
            f"Next: {ask.candidate.label} (about {cost:.0f} s of your "
            f"time); the worst then {_ratio(ask.ranked.worst_after)}."
        )
        more += _measure(dlg, plan, ask)
        added += len(ask.names)
        previous = ask


def _say_end(
    dlg: Measuring, plan: AdaptivePlan, opts: DialogueOptions, p: NextPlan, why: str
) -> None:
    """Why the planner asks for no more records: the target met, or why not."""
    now = _ratio(p.worst_now)
    if p.worst_now <= plan.target:
        dlg.op.say(
            f"Adaptive plan: worst σ/tolerance {now} ({p.worst_name}): target {plan.target:g} met."
        )
        return
    if why == MAX_EXTRA_REACHED:
        why = f"--max-extra {opts.planning.max_extra} reached"
    dlg.op.say(f"Adaptive plan: worst σ/tolerance {now} ({p.worst_name}), above {plan.target:g}:")
    dlg.op.say(textwrap.fill(f"stopped, {why}.", 80, initial_indent="  ",
                             subsequent_indent="  ", break_on_hyphens=False))  # fmt: skip
    if why.startswith(OUT_OF_REACH):
        noise = {n: math.sqrt(max(s * s - p.misfit.get(n, 0.0) ** 2, 0.0))
                 for n, s in p.sigma_now.items()}  # fmt: skip
        worst, whose = worst_ratio(noise, plan.tolerances)
        dlg.op.say(f"  The noise alone leaves {_ratio(worst)} ({whose}); records lower only that.")
        dlg.op.say(f"  What the model lacks: python3 -m host model diagnose {dlg.out_dir}")


def planner_records(
    plan: AdaptivePlan, records: Mapping[str, Record], taken: Collection[str] = ()
) -> int:
    """How many of ``records`` (kept by ``--resume``, in the order measured) the planner
    added: those after the engine's first records were done — the first prefix of
    ``records`` after which :meth:`host.workbench.adaptive.AdaptivePlan.next_first` asks for
    nothing. The closing check is none of them."""
    names = [n for n in records if n != CLOSING_NAME]
    for i in range(len(names) + 1):
        if plan.next_first({n: records[n] for n in names[:i]}, taken) is None:
            return len(names) - i
    return 0


def _measure(dlg: Measuring, plan: AdaptivePlan, ask: Ask) -> float:
    """Measure what ``ask`` names through the dialogue; returns what it cost the operator, s."""
    before: Mapping[str, Record] = dict(dlg.done)
    for name, (_, _, kind, seconds, n, _) in zip(ask.names, ask.candidate.records, strict=True):
        if kind == "static" and ask.first:  # until it has enough, at most ``seconds``

            def stop(a: np.ndarray, g: np.ndarray, t: float, name: str = name) -> str | None:
                return plan.static_stop(name, before, a, g, t)

            dlg._measure_static(name, seconds, stop)
        elif kind == "static":  # as long as the planner said: its gain assumed that
            dlg._measure_static(name, seconds, planned=planned_why(ask, seconds))
        elif ask.first and name == ask.names[-1]:  # the turn that ends a pair

            def decide(rec: Record, axis: str = name[0]) -> str:
                return plan.turns_decision({**dlg.done, rec.name: rec}, axis)[1]

            dlg._measure_turn(name, n, turn_window_s(n), decide)
        elif ask.first:
            dlg._measure_turn(name, n, turn_window_s(n))
        else:

            def planned(_rec: Record, why: str = planned_why(ask, turn_window_s(n))) -> str:
                return why

            dlg._measure_turn(name, n, turn_window_s(n), planned)
    return plan.cost(ask, before, dlg.done)


def planned_why(ask: Ask, seconds: float) -> str:
    """Why a planner's record (not one of the first) stopped, for its header's ``stopped``:
    it is as long as the planner said, and what the planner asked it for."""
    worst = "" if ask.ranked is None else f", the worst then {_ratio(ask.ranked.worst_after)}"
    return f"as long as the planner asked ({seconds:g} s): {ask.candidate.label}{worst} predicted"


def _ratio(r: float) -> str:
    return f"{r:.3g}" if math.isfinite(r) else "∞ (a value not determined)"
