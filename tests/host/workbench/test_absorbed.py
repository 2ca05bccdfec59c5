"""A candidate is tested against a yardstick without its own signal (issue 24): the turn-angle
variance component must not swallow a gyro scale asymmetry. On sessions of the independent
simulator (tests/independent), which the bench's physics did not write."""

from __future__ import annotations

from pathlib import Path

import pytest

from host.model.catalogue import CATALOGUE
from host.model.dataset import Dataset, load_dataset
from host.model.spec import ModelTerm, parse_model
from host.workbench.absorbed import closure_axes, without_turn_angle
from host.workbench.ladder import add_term
from host.workbench.verdict import diagnose
from tests.independent.simulate import SessionSpec, write_session

AXES = "xyz"


def _session(tmp_path: Path, seed: int, effect: str) -> tuple[Dataset, dict]:
    s = write_session(tmp_path / f"{effect}-{seed}", SessionSpec(seed=seed, effect=effect))
    return load_dataset(tmp_path / f"{effect}-{seed}"), s.truth()["effect"]


def test_closure_axes_even_terms_only(tmp_path: Path) -> None:
    ds, _ = _session(tmp_path, 1000, "none")
    assert ds.closures, "the turns are made both ways: the turn angle is measured"
    for a in range(3):
        assert closure_axes(ds, ModelTerm(CATALOGUE["scale_asymmetry"], "gyro", (a,))) == {a}
        assert closure_axes(ds, ModelTerm(CATALOGUE["scale_nonlinearity"], "gyro", (a,))) == {a}
        # odd in the direction (cancels in ccw + cw) or acting at rest too: not angle-like
        for name in ("scale", "bias", "time_drift"):
            assert not closure_axes(ds, ModelTerm(CATALOGUE[name], "gyro", (a,))), name
        assert not closure_axes(ds, ModelTerm(CATALOGUE["scale_asymmetry"], "accel", (a,)))


def test_without_turn_angle_reweighs_only_the_up_integrals(tmp_path: Path) -> None:
    ds, truth = _session(tmp_path, 1000, "scale_asymmetry")
    a = AXES.index(truth["axis"])
    assert ds.turn_angle_sigma_deg > 0, "the closure takes up the asymmetry (the regression)"
    d2 = without_turn_angle(ds, frozenset({a}))
    assert d2.turn_angle_sigma_deg < ds.turn_angle_sigma_deg
    changed = [
        (g1.record, g1.sensor, g1.axis)
        for g1, g2 in zip(ds.groups, d2.groups, strict=True)
        if g1.sigma != g2.sigma
    ]
    assert changed
    for r, s, ax in changed:
        assert ds.signals[r].kind == "turn" and s == "gyro" and abs(ds.signals[r].up[ax]) > 0.5


@pytest.mark.parametrize("seed", [1000, 1001, 1002])
@pytest.mark.slow
def test_scale_asymmetry_is_not_adequate(tmp_path: Path, seed: int) -> None:
    ds, truth = _session(tmp_path, seed, "scale_asymmetry")
    d = diagnose(ds, parse_model("base"))
    label = f"scale_asymmetry:gyro:{truth['axis']}"
    assert d.verdict != "adequate"
    sig = {c.label for c in d.candidates if c.significant}
    assert label in sig, (d.verdict, sorted(sig))


@pytest.mark.parametrize("seed", [1000, 1001, 1002, 1003])
@pytest.mark.slow
def test_controls_stay_adequate(tmp_path: Path, seed: int) -> None:
    ds, _ = _session(tmp_path, seed, "none")
    d = diagnose(ds, parse_model("base"))
    assert d.verdict == "adequate", [c.label for c in d.candidates if c.significant]


@pytest.mark.parametrize("seed", [1000, 1001, 1002])
@pytest.mark.slow
def test_adding_the_asymmetry_shows_the_misfit_it_takes(tmp_path: Path, seed: int) -> None:
    """Before → after is measured on the yardstick the term is tested on: with the turn angle
    of its axis in the yardstick, base reads RMS z ~1 (the closure is called the hand's) and
    adding the very term that explains it shows no fall."""
    ds, truth = _session(tmp_path, seed, "scale_asymmetry")
    a = add_term(ds, parse_model("base"), f"scale_asymmetry:gyro:{truth['axis']}")
    assert a.after.rms_z <= 1.5 and a.before.rms_z >= 3.0 * a.after.rms_z, (
        a.before.rms_z,
        a.after.rms_z,
    )
    assert f"about {truth['axis']}" in a.yardstick


@pytest.mark.slow
def test_a_term_that_leaves_the_closures_keeps_the_models_yardstick(tmp_path: Path) -> None:
    """A term odd in the turn direction does not move the closures: before is the model's own
    fit; on a control (no turn angle to take out) the asymmetry's before is too, and adding it
    moves RMS z by little (no signal, no fall)."""
    ds, _ = _session(tmp_path, 1000, "none")
    base = diagnose(ds, parse_model("base")).fit
    a = add_term(ds, parse_model("base"), "time_drift:gyro:z")
    assert not a.yardstick and a.before.rms_z == pytest.approx(base.rms_z)
    b = add_term(ds, parse_model("base"), "scale_asymmetry:gyro:z")
    assert b.before.rms_z == pytest.approx(base.rms_z) and b.before.rms_z < 1.5 * b.after.rms_z


@pytest.mark.slow
def test_a_term_on_every_turned_axis_keeps_the_models_yardstick(tmp_path: Path) -> None:
    """With every closure taken by the term none is left to measure the hand's angle error:
    a yardstick without it would sell the hand's error as the term's, so before is the
    model's own fit."""
    ds, _ = _session(tmp_path, 1000, "scale_asymmetry")
    base = diagnose(ds, parse_model("base")).fit
    a = add_term(ds, parse_model("base"), "scale_asymmetry:gyro")
    assert not a.yardstick and a.before.rms_z == pytest.approx(base.rms_z)
