"""The record that tells two explanations apart (host/workbench/separate.py), on sessions of
the independent simulator (tests/independent)."""

from __future__ import annotations

from pathlib import Path

import pytest

from host.model.catalogue import CATALOGUE
from host.model.spec import parse_model
from host.session.directory import read_session
from host.workbench.planner import candidates
from host.workbench.separate import CLEAR, separate
from tests.independent.simulate import SessionSpec, write_session

BASE = parse_model("base", CATALOGUE)


@pytest.fixture(scope="module")
def asymmetric(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A unit whose gyro scale differs between the two turning directions."""
    d = tmp_path_factory.mktemp("sep") / "S"
    write_session(d, SessionSpec(seed=3, effect="scale_asymmetry"))
    return d


@pytest.mark.slow
def test_turns_at_another_rate_separate_asymmetry_from_nonlinearity(asymmetric: Path) -> None:
    """Turns made the way the operator made them cannot tell a scale asymmetry (sign of the
    rate) from a quadratic scale (its square) well; the same turns at another pace can, and
    a static record adds nothing to a question about rates."""
    ax = {"x": 0, "y": 1, "z": 2}
    session = read_session(asymmetric)
    menu = candidates(10.0, 2, tilted=False, paces=(1.0, 0.5))
    # the axis whose turns the effect shows on: the largest separation of the same turns
    results = {
        k: separate(session, BASE, parse_model(f"scale_asymmetry:gyro:{k}", CATALOGUE),
                    parse_model(f"scale_nonlinearity:gyro:{k}", CATALOGUE), only=menu)
        for k in ax
    }  # fmt: skip
    k = max(results, key=lambda a: results[a].ranked[0].lam)
    s = results[k]
    assert s.lam_now < CLEAR  # equals on these records
    best = s.ranked[0]
    assert best.candidate.label == f"{k} turns, 2 each way, 0.5× as fast"
    same = next(r for r in s.ranked if r.candidate.label == f"{k} turns, 2 each way")
    assert best.lam > same.lam > s.lam_now
    for r in s.ranked:
        if r.candidate.records[0][2] == "static":
            assert r.lam == pytest.approx(s.lam_now, abs=1e-6)


def test_one_explanation_against_itself_is_never_separated(asymmetric: Path) -> None:
    a = parse_model("scale_asymmetry:gyro:z", CATALOGUE)
    s = separate(read_session(asymmetric), BASE, a, a, only=candidates(10.0, 2)[:3])
    assert s.lam_now == pytest.approx(0.0, abs=1e-6)
    assert all(r.lam == pytest.approx(0.0, abs=1e-6) for r in s.ranked)
