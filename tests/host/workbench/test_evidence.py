"""A term against the best step on its channel, each fitted with the other (issue 39, item 1),
on the independent simulator's sessions."""

from __future__ import annotations

from pathlib import Path

import pytest

from host.model.components import fit_with_components
from host.model.dataset import load_dataset
from host.model.spec import parse_model
from host.workbench.candidates import ALPHA, evaluate_candidates
from host.workbench.evidence import Weighed, weigh_steps
from host.workbench.scan import ScanColumns, scan_signals
from tests.independent.simulate import SessionSpec, write_session


def _weigh(tmp_path: Path, effect: str, seed: int) -> tuple[Weighed, dict, list[str]] | None:
    """The drift on the effect's channel weighed against the best step there; None when the
    drift is not significant on that session (nothing to weigh)."""
    d = tmp_path / f"{effect}_{seed}"
    truth = write_session(d, SessionSpec(seed=seed, effect=effect)).truth()["effect"]
    joint = fit_with_components(load_dataset(d), parse_model("base"))
    ds, fit = joint.dataset, joint.fit
    cands, tried = evaluate_candidates(ds, fit)
    columns = ScanColumns(ds)
    hits = scan_signals(ds, fit, ALPHA, columns)
    drift = f"time_drift:{truth['sensor']}:{truth['axis']}"
    usable = [c for c in cands if c.label == drift and c.significant]
    if not usable:
        return None
    by = {c.label: t for c, t in zip(cands, tried, strict=True)}
    level = ALPHA / sum(c.identifiable for c in cands)
    return weigh_steps(ds, fit, usable, by, hits, level, len(columns.cuts)), truth, [drift]


@pytest.mark.slow
def test_a_drift_is_not_recommended_for_a_step_it_lines_up_with(tmp_path: Path) -> None:
    """A gyro step in the pause between two pairs: time_drift on its channel is significant,
    but with the step in the model it adds nothing; the step takes the channel, and the note
    states both likelihood ratios and the ΔBIC."""
    found = [x for seed in range(1000, 1006)
             if (x := _weigh(tmp_path, "bias_step_gyro_at_pairs", seed)) is not None]  # fmt: skip
    assert found, "in some of six sessions the drift explains part of the step's misfit"
    w, e, (drift,) = found[0]
    assert not w.kept
    assert list(w.stepped) == [("gyro", e["axis"])]
    (note,) = w.notes
    assert drift in note and "ΔBIC" in note and "with the step in the model" in note


@pytest.mark.slow
def test_a_drift_is_kept_over_the_step_that_fits_part_of_it(tmp_path: Path) -> None:
    """A true drift: the best step on its channel explains part of it, but with the step in the
    drift still adds significantly: it stays recommended."""
    found = _weigh(tmp_path, "bias_drift_gyro", 1002)
    assert found is not None, "a drift of 0.7 °/s/h is significant"
    w, _, (drift,) = found
    assert [c.label for c in w.kept] == [drift]
    assert not w.stepped and not w.groups
    (note,) = w.notes  # it was weighed against a step
    assert "the term explains what the step does not" in note
