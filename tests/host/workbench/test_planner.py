"""The planner (host/workbench/planner.py) on sessions of the independent simulator
(tests/independent: written apart from host/bench and the model)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from host.model.catalogue import CATALOGUE
from host.model.dataset import build_dataset
from host.model.fit import fit_model
from host.model.spec import parse_model
from host.session.directory import read_session
from host.session.method import local_gravity, trapezoid_integral
from host.workbench.planner import (
    Candidate,
    candidates,
    plan_next,
    synthetic_record,
    worst_ratio,
)
from tests.independent.simulate import SessionSpec, write_session

BASE = parse_model("base", CATALOGUE)


def _pick(label: str, turns: int = 2) -> Candidate:
    (c,) = [c for c in candidates(10.0, turns) if c.label == label]
    return c


@pytest.mark.slow
@pytest.mark.parametrize(
    ("label", "extra", "names"),
    [
        ("y_dn again", ("y_dn_2",), ("Axz", "Ayy", "A0y", "Azx")),
        ("x turns, 2 each way", ("x_ccw_2", "x_cw_2"), ("Gxx", "Gyz", "Gzy", "GAxx")),
    ],
)
def test_predicted_sigma_is_the_sigma_once_measured(
    tmp_path: Path, label: str, extra: tuple[str, ...], names: tuple[str, ...]
) -> None:
    """The σ the planner predicts for a record is the σ the fit states when that record is
    really measured (independent simulator), and it differs from the σ without it."""
    for seed in (3, 4):
        write_session(tmp_path / f"a{seed}", SessionSpec(seed=seed))
        p = plan_next(read_session(tmp_path / f"a{seed}"), BASE, only=[_pick(label)])
        write_session(tmp_path / f"b{seed}", SessionSpec(seed=seed, extra=extra))
        fit = fit_model(build_dataset(read_session(tmp_path / f"b{seed}")), BASE)
        for n in names:
            predicted, stated = p.ranked[0].sigma_after[n], fit.parameter(n).stderr
            assert predicted == pytest.approx(stated, rel=0.05), n
            assert p.sigma_now[n] > 1.05 * predicted, n  # the record matters for n


@pytest.mark.slow
def test_missing_turns_are_ranked_first_and_named(tmp_path: Path) -> None:
    """Without the turns about x the gyro's x scale and the misalignments about x are not
    determined: the pair of x turns is ranked first and says what it determines."""
    d = tmp_path / "s"
    write_session(d, SessionSpec(seed=7))
    for name in ("x_ccw", "x_cw"):
        (d / f"IND01_{name}.txt").unlink()
    p = plan_next(read_session(d), BASE)
    assert not math.isfinite(p.worst_now)
    first = p.ranked[0]
    assert first.candidate.label == "x turns, 2 each way"
    assert {"Gxx", "Gyz", "Gzy"} <= set(first.determines)
    assert math.isfinite(first.worst_after)
    assert all(not r.determines for r in p.ranked[1:])  # no static record measures a rate


def test_a_face_again_shrinks_what_it_excites(tmp_path: Path) -> None:
    """Repeating a face shrinks the σ of the values that face excites (its scale and bias)
    and leaves a gyro scale (turns only) as it was."""
    write_session(tmp_path / "s", SessionSpec(seed=8))
    p = plan_next(read_session(tmp_path / "s"), BASE, only=[_pick("z_dn again")])
    after = p.ranked[0].sigma_after
    assert after["Azz"] < 0.95 * p.sigma_now["Azz"]
    assert after["Gxx"] == pytest.approx(p.sigma_now["Gxx"], rel=0.02)


def test_operator_time_enters_the_ranking(tmp_path: Path) -> None:
    write_session(tmp_path / "s", SessionSpec(seed=2))
    # a record that lowers the worst σ (z_up again leaves this session's worst, GAxy, where
    # it is: its gain is noise about 0, and ranks by time only when it is positive)
    rec = _pick("y_dn again")
    slow = Candidate("slow", rec.records, 4 * rec.operator_s)
    fast = Candidate("fast", rec.records, rec.operator_s)
    p = plan_next(read_session(tmp_path / "s"), BASE, only=[slow, fast])
    assert [r.candidate.label for r in p.ranked] == ["fast", "slow"]
    a, b = p.ranked
    assert a.worst_after == pytest.approx(b.worst_after, rel=1e-9)
    assert a.gain_per_min == pytest.approx(4 * b.gain_per_min, rel=1e-6)


def test_synthetic_record_is_the_fitted_sensor() -> None:
    """method.md §2: a static x up reads (1+Axx)·g + A0x on x; a turn about z integrates to
    (1+Gzz)·360·n on z, and its rests at the ends are still."""
    g = local_gravity(55.75, 150.0)
    values = {"Axx": 0.01, "A0x": 0.1, "Ayx": 0.002, "Gzz": -0.02, "G0z": 0.5}
    zero = np.zeros(3)
    st = synthetic_record("s", (1, 0, 0), "static", 20.0, g=g, values=values,
                          accel_sd=zero, gyro_sd=zero, dt_s=0.02, temp_c=25.0)  # fmt: skip
    assert st.accel[:, 0].mean() == pytest.approx(1.01 * g + 0.1, abs=1e-9)
    assert st.accel[:, 1].mean() == pytest.approx(0.0, abs=1e-9)  # Ayx multiplies the z input
    assert st.kind == "static" and np.allclose(st.up, [1, 0, 0])
    tr = synthetic_record("t", (0, 0, 1), "turn", 12.0, g=g, values=values, accel_sd=zero,
                          gyro_sd=zero, dt_s=0.02, temp_c=25.0, turns=2, direction=-1)  # fmt: skip
    assert tr.kind == "turn" and tr.sign == -1
    integral = trapezoid_integral(tr.t_ms, tr.gyro[:, 2] - 0.5)
    assert integral == pytest.approx(-0.98 * 720.0, rel=1e-3)
    assert abs(tr.gyro[0, 2] - 0.5) < 1e-9 and abs(tr.gyro[-1, 2] - 0.5) < 1e-9


def test_worst_ratio_skips_values_without_tolerance() -> None:
    tol = {"a": 0.1, "b": None, "c": 2.0}
    assert worst_ratio({"a": 0.01, "b": 99.0, "c": 0.4}, tol) == (pytest.approx(0.2), "c")
    assert worst_ratio({"a": math.nan, "c": 0.4}, tol) == (math.inf, "a")


@pytest.mark.slow
@pytest.mark.timeout(300)
def test_predicted_sigma_is_the_scatter_over_sessions(tmp_path: Path) -> None:
    """Over 40 independent sessions, the σ predicted before measuring y_dn again is the
    scatter of (fitted − truth) once it is measured: pooled pulls with unit spread (±15 %)."""
    names = ("Axz", "Azx", "Ayy", "A0y", "A0x", "Ayz", "Ayx")
    pulls = []
    for seed in range(40):
        write_session(tmp_path / f"a{seed}", SessionSpec(seed=seed))
        p = plan_next(read_session(tmp_path / f"a{seed}"), BASE, only=[_pick("y_dn again")])
        sim = write_session(tmp_path / f"b{seed}", SessionSpec(seed=seed, extra=("y_dn_2",)))
        fit = fit_model(build_dataset(read_session(tmp_path / f"b{seed}")), BASE)
        truth = sim.truth()["constants"]
        for n in names:
            pulls.append((fit.parameter(n).value - truth[n]) / p.ranked[0].sigma_after[n])
    spread = float(np.sqrt(np.mean(np.square(pulls))))
    assert 0.85 <= spread <= 1.15, spread
