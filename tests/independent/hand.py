"""A hand that measures on request: what an adaptive plan asks for, measured on one unit of the
independent simulator (the same unit, noise stream and plan; each further record appended).
Like the rest of this directory it imports nothing from ``host``: the caller turns a
:class:`SimRecord` into its own record type."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from typing import Any

from tests.independent.simulate import Extra, SessionSpec, SimRecord, simulate


def extra_record(name: str, up: Sequence[float], kind: str, seconds: float, pace: float = 1.0,
                 heading_deg: float | None = None) -> str | tuple[str, float] | Extra:  # fmt: skip
    """How the simulator's plan names a record asked for by ``name``, ``up`` (body unit
    vector), ``kind`` ('static'|'turn'), ``seconds``, ``pace`` (turns this many times as
    fast as the hand's own) and ``heading_deg`` (placed at this heading and noted; None: as
    the plan's): a face or a turn at the hand's pace as before, an attitude off the faces, a
    turn at another pace or a noted heading as an :class:`Extra`."""
    u = [float(c) for c in up]
    on_face = sorted(abs(c) for c in u) == [0.0, 0.0, 1.0]
    if heading_deg is not None:
        return Extra(name, kind, None if on_face else (u[0], u[1], u[2]), float(seconds), pace,
                     float(heading_deg))  # fmt: skip
    if kind == "turn":
        return (
            name
            if pace == 1.0 and on_face
            else Extra(name, "turn", None if on_face else (u[0], u[1], u[2]), pace=pace)
        )
    if on_face:
        return (name, float(seconds))
    return Extra(name, "static", (u[0], u[1], u[2]), float(seconds))


class IndependentHand:
    """``hand(candidate, names)``: the records of ``spec``'s plan under their own names, and
    every other name appended to the plan (:func:`extra_record`: a static for the candidate's
    seconds, a turn in the plan's window, an attitude off the faces, turns at the candidate's
    ``pace``). ``candidate.records`` rows are (name, up, kind, seconds, …)."""

    def __init__(self, spec: SessionSpec) -> None:
        self.spec = spec
        self.planned = {r.name for r in simulate(spec).records}
        self.extra: list[str | tuple[str, float] | Extra] = []

    def __call__(self, candidate: Any, names: Sequence[str]) -> Mapping[str, SimRecord]:
        pace = float(getattr(candidate, "pace", 1.0))
        for name, (_, up, kind, seconds, *_) in zip(names, candidate.records, strict=True):
            if name not in self.planned:
                self.extra.append(extra_record(name, up, kind, seconds, pace))
        spec = dataclasses.replace(self.spec, extra=tuple(self.extra))
        recs = {r.name: r for r in simulate(spec).records}
        return {n: recs[n] for n in names}
