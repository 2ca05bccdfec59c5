"""A hand that measures on request: what an adaptive plan asks for, measured on one unit of the
independent simulator (the same unit, noise stream and plan; each further record appended).
Like the rest of this directory it imports nothing from ``host``: the caller turns a
:class:`SimRecord` into its own record type."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from typing import Any

from tests.independent.simulate import SessionSpec, SimRecord, simulate


class IndependentHand:
    """``hand(candidate, names)``: the records of ``spec``'s plan under their own names, and
    every other name appended to the plan (a static for the candidate's seconds, a turn in
    the plan's window). ``candidate.records`` rows are (name, up, kind, seconds, …)."""

    def __init__(self, spec: SessionSpec) -> None:
        self.spec = spec
        self.planned = {r.name for r in simulate(spec).records}
        self.extra: list[str | tuple[str, float]] = []

    def __call__(self, candidate: Any, names: Sequence[str]) -> Mapping[str, SimRecord]:
        for name, (_, _, kind, seconds, *_) in zip(names, candidate.records, strict=True):
            if name not in self.planned:
                self.extra.append((name, float(seconds)) if kind == "static" else name)
        spec = dataclasses.replace(self.spec, extra=tuple(self.extra))
        recs = {r.name: r for r in simulate(spec).records}
        return {n: recs[n] for n in names}
