"""The advice of a group of equals fits the session (host/workbench/equals.py, ``advice``): on
a session without a cube (poses and moves only) it names poses and moves, never a cube record;
on a cube session it is the catalogue's text unchanged."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import pytest

from host.model.catalogue import CATALOGUE
from host.model.dataset import Dataset, load_dataset
from host.model.spec import parse_model
from host.workbench.equals import SEPARATES, advice, pose_session
from host.workbench.text import format_diagnosis
from host.workbench.verdict import diagnose
from tests.independent import poses as independent_poses
from tests.independent.poses import PoseSpec, simulate_poses, write_poses
from tests.independent.simulate import SessionSpec, write_session

#: what a user without a cube cannot make: the cube's records and its words
CUBE = re.compile(r"x_up|x_ccw|tilt_45|\bfaces?\b|\bturns?\b|\bCW\b|\bCCW\b|fixture|plate")
#: what such a user can make
HAND = re.compile(r"\bposes?\b|\bmoves?\b")


@pytest.fixture(scope="module")
def poses(tmp_path_factory: pytest.TempPathFactory) -> Dataset:
    d = tmp_path_factory.mktemp("poses")
    write_poses(str(d), simulate_poses(PoseSpec(seed=5, poses=4, pose_s=1.0)))
    return load_dataset(d)


@pytest.fixture(scope="module")
def cube(tmp_path_factory: pytest.TempPathFactory) -> Dataset:
    d = tmp_path_factory.mktemp("cube")
    write_session(d, SessionSpec(seed=5))
    return load_dataset(d)


def _texts() -> list[str]:
    """Every advice a group can print: each catalogue term's needs and each signal's."""
    return [t.needs for t in CATALOGUE.values() if t.needs] + [w for _, w in SEPARATES]


def test_the_session_kind_is_read_from_its_records(poses: Dataset, cube: Dataset) -> None:
    assert {s.kind for s in poses.signals} == {"pose", "move"} and pose_session(poses)
    assert "static" in {s.kind for s in cube.signals} and not pose_session(cube)


def test_on_a_pose_session_no_advice_names_a_cube_record(poses: Dataset) -> None:
    said_cube = [t for t in _texts() if CUBE.search(t)]
    assert len(said_cube) >= 6, said_cube  # the cube's words are there to be replaced
    for text in _texts():
        got = advice(text, poses)
        assert not CUBE.search(got), (text, got)
    for text in said_cube:
        assert HAND.search(advice(text, poses)), text


def test_the_specific_force_advice_names_a_pose_between_axes(poses: Dataset) -> None:
    words = dict(SEPARATES)["specific force"]
    got = advice(words, poses)
    assert "poses with gravity between two axes" in got and "plan DIR" in got, got
    assert got.count("(") == got.count(")"), got


def test_on_a_cube_session_the_advice_is_unchanged(cube: Dataset) -> None:
    for text in _texts():
        assert advice(text, cube) == text
    assert "tilt_45_*" in advice(dict(SEPARATES)["specific force"], cube)


def _cross_square(monkeypatch: pytest.MonkeyPatch) -> None:
    """The independent simulator's accelerometer x reads 0.05 m/s²·(f_z/g)² more: an effect
    off the catalogue, which the scan finds beside other shapes it cannot tell from it."""
    orig = independent_poses._outputs

    def outputs(rng: Any, truth: Any, g: float, ups: Any, rate: Any) -> tuple[Any, Any]:
        accel, gyro = orig(rng, truth, g, ups, rate)
        accel = accel.copy()
        accel[:, 0] += 0.05 * ups[:, 2] ** 2
        return accel, gyro

    monkeypatch.setattr(independent_poses, "_outputs", outputs)


def test_a_group_on_a_pose_session_advises_poses(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    _cross_square(monkeypatch)
    write_poses(str(tmp_path), simulate_poses(PoseSpec(seed=1, poses=12)))
    d = diagnose(load_dataset(tmp_path), parse_model("base"))
    g = next(g for g in d.equals if "accel x follows (specific force z)²" in g.members)
    assert len(g.members) >= 2 and g.separate, g
    for words in g.separate:
        assert not CUBE.search(words), words
    assert any("poses with gravity between two axes" in w for w in g.separate), g.separate
    text = format_diagnosis(d, compare=False)
    block = text[text.index("a group of equals") :]
    assert "poses with gravity between two axes" in block and "tilt_45" not in block


def test_a_group_on_a_cube_session_still_names_the_cube_record(tmp_path: Path) -> None:
    write_session(tmp_path, SessionSpec(seed=1000, effect="cross_g2"))
    d = diagnose(load_dataset(tmp_path), parse_model("base"))
    assert d.equals
    assert any("tilt_45_*" in w for g in d.equals for w in g.separate), d.equals
