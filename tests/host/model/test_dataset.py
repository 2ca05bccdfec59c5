"""The turn-angle σ is measured from every pair of turns made both ways about an axis (issue
24): repeated turns (the adaptive plan's further pairs) each add a closure, paired in the order
measured. On sessions of the independent simulator (tests/independent) with a known hand
turn-angle error, which the bench's physics did not write."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from host.model.dataset import Dataset, load_dataset
from tests.independent.simulate import SessionSpec, write_session

#: the hand's turn-angle error the sessions are made with, ° per turn record
HAND_DEG = 0.5


def _extra(pairs: int) -> tuple[str, ...]:
    """The further turn pairs after the plan's one per axis, measured pair by pair."""
    return tuple(f"{a}_{d}_{i}" for i in range(2, pairs + 1) for a in "xyz" for d in ("ccw", "cw"))


def _dataset(root: Path, seed: int, pairs: int, extra: tuple[str, ...] = ()) -> Dataset:
    d = root / f"{pairs}-{seed}"
    spec = SessionSpec(seed=seed, turns=1, turn_angle_sd_deg=HAND_DEG, extra=_extra(pairs) + extra)
    write_session(d, spec)
    return load_dataset(d)


@pytest.mark.parametrize("pairs", [2, 3])
def test_every_turn_pair_gives_a_closure(tmp_path: Path, pairs: int) -> None:
    # a ccw turn about x without its cw partner is left out, as an axis turned one way is
    ds = _dataset(tmp_path, 1100 + pairs, pairs, extra=(f"x_ccw_{pairs + 1}",))
    assert len(ds.closures) == 3 * pairs, "one closure per pair on the up channel"
    for a in range(3):
        assert sum(c.axis == a for c in ds.closures) == pairs
    comps = {c.name: c for c in ds.components}
    assert comps["turn angle"].dof == 3 * pairs
    assert comps["turn wobble"].dof == 6 * pairs, "two cross channels per pair"
    # each pair's closure is its own: the integrals of distinct records
    ints = [c.integrals_deg for c in ds.closures]
    assert len(set(ints)) == len(ints)


@pytest.mark.slow
def test_more_pairs_measure_the_turn_angle_closer(tmp_path: Path) -> None:
    """Over sessions the σ is unbiased-ish and scatters less with three pairs per axis than
    with one (about 1/√3 as much: three times the closures)."""
    got: dict[int, np.ndarray] = {}
    for pairs in (1, 3):
        got[pairs] = np.array(
            [_dataset(tmp_path, 1200 + s, pairs).turn_angle_sigma_deg for s in range(20)]
        )
    sd1, sd3 = float(np.std(got[1], ddof=1)), float(np.std(got[3], ddof=1))
    assert abs(float(np.mean(got[3])) - HAND_DEG) < 0.1 * HAND_DEG, got[3]
    assert abs(float(np.mean(got[1])) - HAND_DEG) < 0.25 * HAND_DEG, got[1]
    assert sd3 < 0.75 * sd1, (sd1, sd3)
