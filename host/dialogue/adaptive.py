"""``calibrate --plan adaptive``: after the six faces and the turns, the records the planner
names, one at a time, until every value's σ meets its target (σ/tolerance ≤ ``--target``).

Each step the planner (:func:`host.workbench.planner.plan_next`) ranks a face again (the
accumulation time asked, or three times it) and a turn pair about each axis by the σ/tolerance
above the target each removes per minute of the operator's time; the dialogue says what it
asks for and why, measures it as any record (the same prompts, checks and Save/repeat), and
fits again. It stops when the target is met, when nothing on the list helps any more, or after
``--max-extra`` records.
"""

from __future__ import annotations

import math
from typing import Protocol

from host.dialogue.console import Questions
from host.dialogue.options import CLOSING_NAME, DialogueOptions
from host.model.catalogue import CATALOGUE
from host.model.loader import load_term_file
from host.model.spec import ModelTerm, parse_model
from host.session.directory import Session
from host.session.records import Record, turn_window_s
from host.workbench.planner import candidates, plan_next, unique_name
from host.workbench.stopping import StaticRule


class Measuring(Protocol):
    """What the adaptive phase needs of the dialogue (:class:`host.dialogue.recorder.
    Recorder`)."""

    op: Questions
    serial: str
    done: dict[str, Record]
    static_seconds: float | None
    turns: int | None
    static_rule: StaticRule | None

    def _measure_static(self, name: str) -> None: ...

    def _measure_turn(self, name: str, n: int, window: float) -> None: ...


def model_of(opts: DialogueOptions) -> list[ModelTerm]:
    """The model the dialogue fits (``--model``, its ``--terms`` files)."""
    cat = dict(CATALOGUE)
    for f in opts.term_files:
        cat = load_term_file(f, cat)
    return parse_model(opts.model, cat)


def measure_until_enough(dlg: Measuring, opts: DialogueOptions) -> list[str]:
    """The adaptive phase with ``opts.target``, ``opts.model`` (its ``term_files``) and
    ``opts.max_extra``; never names the closing record. Returns the names it added, in order."""
    target, max_extra = opts.target, opts.max_extra
    mts = model_of(opts)
    static_s = float(dlg.static_seconds or 10.0)
    turns = int(dlg.turns or 1)
    menu = candidates((static_s, 3 * static_s), turns, tilted=False)
    op, added = dlg.op, list[str]()
    while True:
        p = plan_next(Session(dlg.serial, dict(dlg.done)), mts, only=menu, target=target)
        now = _ratio(p.worst_now)
        if p.worst_now <= target:
            op.say(
                f"Adaptive plan: worst σ/tolerance {now} ({p.worst_name}): target {target:g} met."
            )
            return added
        best = p.ranked[0] if p.ranked else None
        if best is None or best.gain_per_min <= 0.0 or len(added) >= max_extra:
            limit = best is not None and best.gain_per_min > 0
            why = f"--max-extra {max_extra} reached" if limit else "no record brings it closer"
            op.say(f"Adaptive plan: worst σ/tolerance {now} ({p.worst_name}), above {target:g}:")
            op.say(f"  stopped, {why}.")
            return added
        op.say(f"Adaptive plan: worst σ/tolerance {now} ({p.worst_name}), target {target:g}.")
        op.say(
            f"Next: {best.candidate.label} (about {best.candidate.operator_s:.0f} s of your "
            f"time); the worst then {_ratio(best.worst_after)}."
        )
        for base, _, kind, seconds, n, _ in best.candidate.records:
            name = unique_name(base, [*dlg.done, CLOSING_NAME])
            if kind == "static":  # as long as the planner said: its gain assumed that
                keep, dlg.static_seconds = dlg.static_seconds, seconds
                rule, dlg.static_rule = dlg.static_rule, None
                try:
                    dlg._measure_static(name)
                finally:
                    dlg.static_seconds, dlg.static_rule = keep, rule
            else:
                dlg._measure_turn(name, n, turn_window_s(n))
            added.append(name)


def _ratio(r: float) -> str:
    return f"{r:.3g}" if math.isfinite(r) else "∞ (a value not determined)"
