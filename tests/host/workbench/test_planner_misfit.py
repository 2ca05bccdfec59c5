"""The σ the model's misfit sets (host/workbench/planner.py: misfit_sigmas) and the adaptive
plan's "out of reach" (host/workbench/adaptive.py), on sessions of the independent simulator
(tests/independent: written apart from host/bench and the model)."""

from __future__ import annotations

import math
from collections.abc import Mapping

import pytest

from host.model.catalogue import CATALOGUE
from host.model.dataset import build_dataset
from host.model.fit import fit_model
from host.model.spec import parse_model
from host.session.directory import Session
from host.session.method import TOLERANCES
from host.session.records import Record
from host.workbench.adaptive import OUT_OF_REACH, AdaptivePlan
from host.workbench.planner import candidates, misfit_sigmas, unscaled_sigmas, worst_ratio
from tests.independent.simulate import SessionSpec, simulate

BASE = parse_model("base", CATALOGUE)


def _records(spec: SessionSpec) -> dict[str, Record]:
    return {
        r.name: Record(r.name, r.t_ms, r.accel, r.gyro, r.temp_c, r.meta)
        for r in simulate(spec).records
    }


def _floor(records: Mapping[str, Record]) -> tuple[float, str]:
    fit = fit_model(build_dataset(Session("MF", dict(records))), BASE)
    return worst_ratio(misfit_sigmas(fit), TOLERANCES)


@pytest.mark.slow
def test_white_noise_sets_no_floor() -> None:
    """Under the null (the model is the simulator's) no value gets a misfit floor in 11 of
    12 sessions: a channel widened by chance (p < 0.01) is not taken for a misfit."""
    floors = [_floor(_records(SessionSpec(seed=700 + k, static_s=10.0, turns=1)))[0]
              for k in range(12)]  # fmt: skip
    assert sum(f == 0.0 for f in floors) >= 11, floors


@pytest.mark.slow
def test_an_effect_the_model_lacks_sets_one_and_the_plan_says_out_of_reach() -> None:
    """A gyro bias that drifts in time (an effect the base model lacks) widens the gyro's σ:
    the floor is on a gyro value, no larger than its widened σ and a sizeable part of it;
    towards a target under the floor the planner plans nothing and says
    out of reach, towards one above it, it does not say so."""
    recs = _records(SessionSpec(seed=3, effect="bias_drift_gyro", static_s=10.0, turns=1,
                                closing=False))  # fmt: skip
    fit = fit_model(build_dataset(Session("MF", dict(recs))), BASE)
    floor, whose = worst_ratio(misfit_sigmas(fit), TOLERANCES)
    assert floor > 0.0 and whose.startswith("G"), (floor, whose)
    widened = unscaled_sigmas(fit, fit)
    for n, s in misfit_sigmas(fit).items():
        assert s <= widened[n] or not math.isfinite(widened[n]), n
    tol = TOLERANCES[whose]
    assert tol is not None and misfit_sigmas(fit)[whose] > 0.3 * widened[whose]
    menu = candidates((10.0, 30.0), 1, tilted=False)
    _, ask, why = AdaptivePlan(BASE, floor * 0.5, menu).planned(recs, 0.0)
    assert ask is None and why.startswith(OUT_OF_REACH) and whose in why, why
    _, _, why = AdaptivePlan(BASE, floor * 1.5, menu).planned(recs, 0.0)
    assert not why.startswith(OUT_OF_REACH), why
