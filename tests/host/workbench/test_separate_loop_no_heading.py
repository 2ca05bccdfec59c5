"""The record that settles a doubt when the statics carry no heading (issue 30): the face
lean, the (f/g)² signal and the plate's tilt are one group, and the record ``plan --separate``
names settles it (the loop of benchmarks/separating.py on sessions of the independent
simulator; apart from test_separate_loop.py so that the two long loops can run side by side)."""

from __future__ import annotations

from pathlib import Path

import pytest

from benchmarks import separating as sp


@pytest.mark.slow
@pytest.mark.timeout(600)
@pytest.mark.parametrize("pair", ["lean_nh", "g2_nh"])
def test_with_no_heading_the_record_the_planner_names_settles_the_doubt(
    tmp_path: Path, pair: str
) -> None:
    """Three sessions a direction whose statics carry no heading (seeds apart from the
    benchmark's, whose ten a direction name the truth alone 10/10: docs/planning.md): the
    diagnosis holds the face lean, the (f/g)² signal and the plate's tilt as one group; once
    the record ``plan --separate`` names first is measured (at most two per doubt) the true
    effect is named alone in every one, and the Δχ² obtained with the first record is the one
    predicted within a factor of two. (Ten a direction took 13 minutes of the suite.)"""
    rows = [sp.run_session(sp.PAIRS[pair], seed, tmp_path, rounds=2) for seed in range(5000, 5003)]
    assert all("error" not in r for r in rows), [r.get("error") for r in rows]
    assert all(r["group"] for r in rows), [r.get("equals") for r in rows if not r["group"]]
    alone = [r for r in rows if r["alone"]]
    assert len(alone) == len(rows), [(r["seed"], r["steps"], r["equals_after"]) for r in rows]
    for r in rows:
        first = r["steps"][0]
        assert 0.5 < first["obtained"] / first["lam"] < 2.0, (r["seed"], first)
