"""The adaptive run (host/workbench/adaptive.py) on a unit of the independent simulator, which
measures whatever the planner asks for (tests/independent/hand.py)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pytest

from host.model.catalogue import CATALOGUE
from host.model.dataset import build_dataset
from host.model.fit import fit_model
from host.model.spec import parse_model
from host.session.directory import Session
from host.session.method import TOLERANCES
from host.session.records import Record
from host.workbench.adaptive import AdaptivePlan, Stopping, adaptive_run, cost_after, minimal_plan
from host.workbench.planner import Candidate, candidates, unscaled_sigmas, worst_ratio
from host.workbench.stopping import StaticRule, turn_scale_ratio
from tests.independent.hand import IndependentHand
from tests.independent.simulate import SessionSpec, simulate

BASE = parse_model("base", CATALOGUE)


def _measure(spec: SessionSpec):  # type: ignore[no-untyped-def]
    hand = IndependentHand(spec)

    def measure(c: Candidate, names: Sequence[str]) -> dict[str, Record]:
        return {
            n: Record(r.name, r.t_ms, r.accel, r.gyro, r.temp_c, r.meta)
            for n, r in hand(c, names).items()
        }

    return measure


def _face(name: str) -> str:
    """The face a record rests on: 'x_up' for x_up, x_up_2, x_ccw, x_cw_2; 'x_dn' for x_dn."""
    return name[0] + ("_dn" if name[1:].startswith("_dn") else "_up")


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
    # the operator's time is the minimal plan's plus each step's candidate, one placement
    # less for a step whose first record rests on the face the step before it ended on
    by_label = {c.label: c.operator_s for c in menu}
    cost = sum(c.operator_s for c in first) + sum(by_label[s.label] for s in run.steps[1:])
    ends = [_face(s.names[-1]) for s in run.steps]
    same = sum(_face(s.names[0]) == e for s, e in zip(run.steps[1:], ends, strict=False))
    assert run.operator_s == pytest.approx(cost - 15.0 * same)
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


def test_a_record_on_the_face_the_cube_rests_on_costs_no_placement() -> None:
    """A 1-turn pair costs 2·(15 + 8 + 7) = 60 s; right after a record with its axis up the
    cube is already there (a static leaves it, a turn returns it against the ruler): 45 s.
    A face on an edge again right after itself: 40 + 3 + 10 s less the 40 s of placing it."""
    menu = {c.label: c for c in candidates(10.0, 1)}
    pair = menu["x turns, 1 each way"]
    assert pair.operator_s == pytest.approx(60.0)
    assert cost_after(pair, None) == pytest.approx(60.0)
    assert cost_after(pair, [1.0, 0.0, 0.0]) == pytest.approx(45.0)
    assert cost_after(pair, [-1.0, 0.0, 0.0]) == pytest.approx(60.0)
    assert cost_after(pair, [0.0, 1.0, 0.0]) == pytest.approx(60.0)
    (edge,) = [c for c in menu.values() if c.label.startswith("tilt_45_1 ")]
    up = np.asarray(edge.records[0][1], dtype=float)
    assert cost_after(edge, up / np.linalg.norm(up)) == pytest.approx(13.0)
    assert cost_after(menu["z_dn again"], [0.0, 0.0, -1.0]) == pytest.approx(13.0)


@pytest.mark.slow
@pytest.mark.timeout(600)
def test_the_sigma_predicted_for_what_it_plans_is_the_scatter_over_sessions() -> None:
    """Over 24 units of the independent simulator, the record the adaptive run plans first
    after the minimal plan (towards a target finer than the minimal plan gives) is predicted
    before it is measured: its σ is the scatter of (fitted − truth) once it is measured —
    pooled pulls of every value with a tolerance, and of the nine g-sensitivities the target
    is about, with unit spread (±15 %)."""
    first = minimal_plan(10.0, 1)
    menu = candidates(10.0, 1, tilted=False)
    limit = sum(c.operator_s for c in first) + 1.0  # the minimal plan and one planned record
    pulls: list[float] = []
    gsens: list[float] = []
    labels = set()
    for seed in range(24):
        spec = SessionSpec(seed=100 + seed, static_s=10.0, turns=1, closing=False)
        run = adaptive_run(_measure(spec), BASE, target=0.003, first=first, menu=menu,
                           max_operator_s=limit)  # fmt: skip
        assert len(run.steps) == 2 and run.steps[1].predicted
        labels.add(run.steps[1].label)
        fit = fit_model(build_dataset(Session("ADAPT", dict(run.records))), BASE)
        truth = simulate(spec).truth()["constants"]
        for p in fit.parameters:
            if TOLERANCES.get(p.name) and p.name in truth:
                z = (p.value - truth[p.name]) / run.steps[1].predicted[p.name]
                pulls.append(z)
                if p.name.startswith("GA"):
                    gsens.append(z)
    assert 0.85 <= float(np.sqrt(np.mean(np.square(pulls)))) <= 1.15, labels
    assert 0.85 <= float(np.sqrt(np.mean(np.square(gsens)))) <= 1.15, labels


def test_an_axis_turns_are_decided_on_the_records_up_to_its_last_pair() -> None:
    """Whether another pair about x follows is decided once, on the fit of the records up to
    x's last pair: the y faces measured after it, which change the fit's σ of Gxx, do not
    reopen x (the first records would go back to x after y otherwise)."""
    spec = SessionSpec(seed=23, static_s=10.0, turns=1, closing=False)
    menu = {c.records[0][0]: c for c in candidates(10.0, 1, tilted=False)}
    hand = _measure(spec)
    records: dict[str, Record] = {}
    for name in ("x_dn", "x_up", "x_ccw", "y_dn", "y_up"):
        records.update(hand(menu[name], [name] if name != "x_ccw" else ["x_ccw", "x_cw"]))
    records = {n: records[n] for n in ("x_dn", "x_up", "x_ccw", "x_cw", "y_dn", "y_up")}
    up_to_pair = {n: records[n] for n in ("x_dn", "x_up", "x_ccw", "x_cw")}
    ratio_then, _ = turn_scale_ratio(Session("ADAPT", up_to_pair), BASE, "x")
    ratio_now, _ = turn_scale_ratio(Session("ADAPT", records), BASE, "x")
    assert f"{ratio_then:.3g}" != f"{ratio_now:.3g}"  # the y faces move it
    for target in (ratio_then * 1.01, ratio_then * 0.99):  # met, or not met
        rule = StaticRule.for_target(target, 9.81, max_s=10.0)
        plan = AdaptivePlan(BASE, target, [], Stopping(rule, 1))
        more, why = plan.turns_decision(records, "x")
        assert more == (target < ratio_then)
        assert f"σ/tolerance {ratio_then:.3g}" in why, why
        nxt = plan.next_first(records)
        assert nxt is not None and nxt.names == (
            ("x_ccw_2", "x_cw_2") if more else ("y_ccw", "y_cw")
        )
