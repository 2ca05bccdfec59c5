"""Per-channel statistics of a fit (host.model.channels) in a session without a cube: the moves'
rows are a channel of their own, and each channel's dof is what the fit leaves its rows, on a
session of the independent simulator (tests/independent/poses.py)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from host.model.channels import MOVES, move_rows
from host.model.dataset import load_dataset
from host.model.fit import fit_model
from host.model.spec import parse_model
from tests.independent.poses import PoseSpec, simulate_poses, write_poses


@pytest.fixture(scope="module")
def fitted(tmp_path_factory: pytest.TempPathFactory):  # type: ignore[no-untyped-def]
    d = tmp_path_factory.mktemp("poses")
    write_poses(str(d), simulate_poses(PoseSpec(seed=5, poses=12)))
    ds = load_dataset(d)
    return ds, fit_model(ds, parse_model("base"))


def test_the_moves_rows_are_their_own_channel_not_gyro_x_or_y(fitted) -> None:  # type: ignore[no-untyped-def]
    ds, fit = fitted
    by = {c.channel: c for c in fit.channels}
    assert set(by) == {"accel x", "accel y", "accel z", "gyro x", "gyro y", "gyro z", "gyro moves"}
    moving = move_rows(ds)
    assert moving.sum() == 2 * 11  # two rows per move
    assert by["gyro moves"].chi2 == pytest.approx(float(np.sum(fit.white_residual[moving] ** 2)))
    # the three gyro channels hold the same rows (the poses' block means): the same dof
    assert len({by[f"gyro {a}"].dof for a in "xyz"}) == 1, [by[f"gyro {a}"].dof for a in "xyz"]
    moves = [g for g in fit.groups if g.kind == "move"]
    assert {g.axis for g in moves} == {"move a", "move b"} and {g.unit for g in moves} == {"°"}
    assert by["gyro moves"].axis == MOVES


def test_each_channels_dof_is_its_share_of_the_fits(fitted) -> None:  # type: ignore[no-untyped-def]
    """A pose's attitude is read by the three accelerometer channels, a move by every gyro
    channel's terms: the channels' dof add up to the fit's (rows − parameters), each rounded."""
    _, fit = fitted
    total = sum(c.dof for c in fit.channels)
    assert abs(total - fit.dof) <= len(fit.channels) / 2, (total, fit.dof)
    # under the null no channel's σ is widened
    seen = [(c.channel, c.chi2, c.dof) for c in fit.channels]
    assert all(c.se_scale == 1.0 for c in fit.channels), seen


def test_the_moves_widening_reaches_every_parameter_they_read(tmp_path: Path) -> None:
    """A hand that creeps in each pose, fitted without its variance components: the moves'
    rows miss by more than their noise, so their channel's σ is widened, and so is every
    parameter the moves read (the gyro's, the poses' attitudes) — the accelerometer's scales
    keep their own channel's factor."""
    write_poses(str(tmp_path), simulate_poses(PoseSpec(seed=5, poses=12, creep_dps=0.05)))
    fit = fit_model(load_dataset(tmp_path), parse_model("base"))
    by = {c.channel: c for c in fit.channels}
    moves = by["gyro moves"].se_scale
    assert moves > 1.5, by["gyro moves"]
    for name in ("Gxx", "Gyz", "G0x", "misalignment.pose_03.attitude_a"):
        assert fit.se_scales[name] >= moves, (name, fit.se_scales[name])
    for a in "xyz":
        assert fit.se_scales[f"A{a}{a}"] == by[f"accel {a}"].se_scale
