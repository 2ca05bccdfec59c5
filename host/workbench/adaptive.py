"""Measure until enough: the minimal plan, then the planner's next record until every value's
σ meets its target.

:func:`adaptive_run` drives any measuring hand — the virtual bench, an independent simulator in
a benchmark, the operator in the dialogue — through one callable, ``measure(candidate, names)``,
that measures the candidate's records and returns them under the given names. The ranking is
:func:`host.workbench.planner.plan_next` with a target: every step takes the record that removes
the most σ/tolerance above the target per minute of the operator's time.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from host.model.noise import NoiseModel
from host.model.spec import ModelTerm
from host.session.directory import Session
from host.session.method import TOLERANCES
from host.session.records import STATIC_NAMES, Record
from host.workbench.planner import (
    OPERATOR_TIME,
    Candidate,
    OperatorTime,
    Ranked,
    candidates,
    plan_next,
    unique_name,
)

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


def adaptive_run(
    measure: Measure,
    model: Sequence[ModelTerm],
    *,
    target: float,
    first: Sequence[Candidate],
    menu: Sequence[Candidate],
    serial: str = "ADAPT",
    noise: NoiseModel | None = None,
    tolerances: Mapping[str, float | None] = TOLERANCES,
    max_operator_s: float = 3600.0,
    on_step: Callable[[Step], None] | None = None,
    measured: Mapping[str, Record] | None = None,
    measured_s: float = 0.0,
    time: OperatorTime = OPERATOR_TIME,
) -> AdaptiveRun:
    """Measure ``first`` (e.g. :func:`minimal_plan`) after the records ``measured`` already
    (they cost the operator ``measured_s`` s: e.g. records that stopped when they had enough,
    :mod:`host.workbench.stopping`), then, while the worst σ/tolerance of
    ``model`` is above ``target`` and the operator's time is below ``max_operator_s`` (s),
    the candidate of ``menu`` that :func:`plan_next` ranks first. ``on_step`` is called after
    each record is fitted (a progress line). A record on the face the cube already rests on
    costs one placement less (:func:`cost_after`, ``time``)."""
    records: dict[str, Record] = dict(measured or {})
    steps: list[Step] = []
    spent = float(measured_s)

    def take(c: Candidate) -> None:
        nonlocal spent
        names: list[str] = []
        for base, *_ in c.records:
            names.append(unique_name(base, list(records) + names))
        spent += cost_after(c, last_up(records), time)
        records.update(measure(c, names))

    for c in first:
        take(c)
    pending = Step("first records", tuple(records), spent, math.nan, "")
    while True:
        p = plan_next(
            Session(serial, dict(records)), model, noise=noise, tolerances=tolerances,
            only=menu, target=target,
        )  # fmt: skip
        done = dataclasses.replace(pending, worst=p.worst_now, worst_name=p.worst_name)
        steps.append(done)
        if on_step is not None:
            on_step(done)
        if p.worst_now <= target or spent >= max_operator_s or not p.ranked:
            break
        best = p.ranked[0]
        if best.gain_per_min <= 0.0:
            break  # nothing on the menu brings any value closer to the target
        before = set(records)
        take(best.candidate)
        added = tuple(n for n in records if n not in before)
        pending = Step(best.candidate.label, added, spent, math.nan, "", best.sigma_after)
    last = steps[-1]
    return AdaptiveRun(
        dict(records), tuple(steps), spent, last.worst, last.worst_name, last.worst <= target,
        p.ranked[0] if p.ranked else None,
    )  # fmt: skip
