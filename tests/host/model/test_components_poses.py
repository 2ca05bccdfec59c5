"""A hand-held pose's variance components (host.model.components: ``pose rate`` on the poses'
gyro means, ``pose hold`` on the moves' rows), on sessions of the independent simulator
(tests/independent/poses.py) whose hand creeps during each rest, or holds perfectly still."""

from __future__ import annotations

from pathlib import Path

import pytest

from host.model.components import fit_with_components
from host.model.dataset import load_dataset
from host.model.fit import fit_model
from host.model.spec import parse_model
from host.model.variance import POSE_RATE_PLAUSIBLE_DPS
from host.workbench.sinks import implausible
from tests.independent.poses import PoseSpec, simulate_poses, write_poses

#: each fit of 20 poses and 19 moves takes a second or two
pytestmark = [pytest.mark.slow, pytest.mark.timeout(300)]


def _joint(tmp_path: Path, creep: float, seed: int = 7):  # type: ignore[no-untyped-def]
    d = tmp_path / f"creep_{creep}_{seed}"
    write_poses(str(d), simulate_poses(PoseSpec(seed=seed, poses=20, creep_dps=creep)))
    ds = load_dataset(d)
    return ds, fit_with_components(ds, parse_model("base"))


def test_a_creeping_hand_is_the_pose_rate_and_the_moves_see_it_as_the_hold(
    tmp_path: Path,
) -> None:
    """The hand turns the unit at 0.03 °/s (sd per axis) during each rest: the pose rate reads
    that rate within 3σ (its σ from ~57 dof), the hold is resolved on the moves (the rests'
    ends 0.05° or so off their mean attitude), both plausible; the fit then explains its rows
    (RMS z about 1), where without them the gyro means read RMS z well over 1."""
    ds, joint = _joint(tmp_path, 0.03)
    comps = {c.name: c for c in joint.components}
    rate, hold = comps["pose rate"], comps["pose hold"]
    assert rate.unit == "°/s" and hold.unit == "°"
    assert abs(rate.value - 0.03) < 3 * rate.sigma + 0.003, rate
    assert rate.dof >= 40 and hold.dof >= 20
    assert 0.0 < hold.value < 0.5 and not implausible(joint.dataset)
    assert 0.85 < joint.fit.rms_z < 1.2, joint.fit.rms_z
    assert fit_model(ds, parse_model("base")).rms_z > 1.5
    assert any(n.startswith("a named variance component: pose rate: ") for n in joint.dataset.notes)


def test_a_still_hand_resolves_neither_and_the_fit_is_the_plain_fit(tmp_path: Path) -> None:
    """No creep: neither component beyond the white noise, so every row keeps its weight and the
    joint fit's χ² is the plain fit's."""
    ds, joint = _joint(tmp_path, 0.0)
    comps = {c.name: c for c in joint.components}
    assert comps["pose rate"].value == 0.0 and comps["pose hold"].value == 0.0
    assert joint.fit.chi2 == pytest.approx(fit_model(ds, parse_model("base")).chi2, rel=1e-9)


def test_a_rate_beyond_a_hand_is_implausible(tmp_path: Path) -> None:
    """A pose that turns at 0.3 °/s is no pose held still (a gyro step, an unmodelled effect):
    the pose rate is over its plausible range and named so, which keeps the diagnosis from
    ``adequate`` (host.workbench.sinks)."""
    _, joint = _joint(tmp_path, 0.3)
    bad = {c.name: c for c in implausible(joint.dataset)}
    assert "pose rate" in bad and bad["pose rate"].value > POSE_RATE_PLAUSIBLE_DPS
    assert "°/s over 0.1°/s" in bad["pose rate"].plausible
