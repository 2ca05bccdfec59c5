"""The adaptive run (host/workbench/adaptive.py) on a unit of the independent simulator, which
measures whatever the planner asks for (tests/independent/hand.py)."""

from __future__ import annotations

from collections.abc import Sequence

import pytest

from host.model.catalogue import CATALOGUE
from host.model.dataset import build_dataset
from host.model.fit import fit_model
from host.model.spec import parse_model
from host.session.directory import Session
from host.session.records import Record
from host.workbench.adaptive import adaptive_run, minimal_plan
from host.workbench.planner import Candidate, candidates, unscaled_sigmas, worst_ratio
from tests.independent.hand import IndependentHand
from tests.independent.simulate import SessionSpec

BASE = parse_model("base", CATALOGUE)


def _measure(spec: SessionSpec):  # type: ignore[no-untyped-def]
    hand = IndependentHand(spec)

    def measure(c: Candidate, names: Sequence[str]) -> dict[str, Record]:
        return {
            n: Record(r.name, r.t_ms, r.accel, r.gyro, r.temp_c, r.meta)
            for n, r in hand(c, names).items()
        }

    return measure


def _worst(records: dict[str, Record]) -> float:
    fit = fit_model(build_dataset(Session("ADAPT", records)), BASE)
    return worst_ratio(unscaled_sigmas(fit, fit))[0]


@pytest.mark.slow
@pytest.mark.timeout(300)
def test_it_measures_until_the_target_and_counts_the_operators_time() -> None:
    spec = SessionSpec(seed=21, static_s=5.0, turns=1, closing=False)
    first = minimal_plan(5.0, 1)
    probe = adaptive_run(_measure(spec), BASE, target=1.0, first=first, menu=[])
    assert probe.reached and len(probe.steps) == 1  # the minimal plan alone meets σ ≤ tol
    target = 0.85 * probe.worst
    menu = candidates((5.0, 15.0), 1, tilted=False)
    run = adaptive_run(_measure(spec), BASE, target=target, first=first, menu=menu)
    assert run.reached and run.worst <= target
    assert len(run.steps) >= 2  # it had to measure more than the minimal plan
    # the records it measured are the minimal plan's and each step's, named once each
    names = [n for s in run.steps for n in s.names]
    assert sorted(names) == sorted(run.records) and len(set(names)) == len(names)
    assert any(n.endswith("_2") for n in names)  # a face or a turn measured again
    # the operator's time is the minimal plan's plus each step's candidate
    by_label = {c.label: c.operator_s for c in menu}
    cost = sum(c.operator_s for c in first) + sum(by_label[s.label] for s in run.steps[1:])
    assert run.operator_s == pytest.approx(cost)
    # the worst it reports is the fit of what it measured
    assert run.worst == pytest.approx(_worst(dict(run.records)), rel=1e-9)


@pytest.mark.slow
def test_it_stops_at_the_time_limit_when_the_target_is_out_of_reach() -> None:
    spec = SessionSpec(seed=22, static_s=5.0, turns=1, closing=False)
    first = minimal_plan(5.0, 1)
    menu = candidates(5.0, 1, tilted=False)
    limit = sum(c.operator_s for c in first) + 1.0
    run = adaptive_run(_measure(spec), BASE, target=1e-9, first=first, menu=menu,
                       max_operator_s=limit)  # fmt: skip
    assert not run.reached
    assert len(run.steps) == 2  # the minimal plan, then one record past the limit
    assert run.operator_s >= limit
