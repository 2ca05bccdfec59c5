"""``python3 -m host plan DIR`` and the diagnosis's next record on a session without a cube
(issue 41 item 3): the next pose, never a face or a turn, on a session of the independent
simulator (tests/independent/poses.py)."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np
import pytest

from host.__main__ import main
from tests.independent.poses import PoseSpec, simulate_poses, write_poses

#: what only a session with a cube can measure
CUBE_RECORDS = re.compile(r"\b[xyz]_(up|dn|ccw|cw)\b|tilt_45|turns? about")


@pytest.fixture(scope="module")
def poses_dir(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, np.ndarray]:
    d = tmp_path_factory.mktemp("poses")
    sess = simulate_poses(PoseSpec(seed=21, poses=12))
    write_poses(str(d), sess)
    return d, np.array(sess.ups)


def test_plan_names_the_next_pose_and_no_record_of_a_cube(
    poses_dir: tuple[Path, np.ndarray], capsys: pytest.CaptureFixture[str]
) -> None:
    d, _ = poses_dir
    assert main(["plan", str(d)]) == 0
    out = capsys.readouterr().out
    assert "a session without a cube (12 poses, 11 moves)" in out
    m = re.search(r"next pose: hold it still with X ([+-]\d+)°, Y ([+-]\d+)°, Z ([+-]\d+)°", out)
    assert m, out
    assert not CUBE_RECORDS.search(out), out
    assert all(len(line) <= 80 for line in out.splitlines())


def test_the_next_pose_is_where_gravity_has_not_been(
    poses_dir: tuple[Path, np.ndarray], capsys: pytest.CaptureFixture[str]
) -> None:
    """The pose it names lies far from every pose measured (the sphere's emptiest part is
    what the accelerometer's nine values and the gyro's move to it gain most from), and it
    lowers the planner's RMS σ/tolerance."""
    d, ups = poses_dir
    assert main(["plan", str(d), "--json"]) == 0
    got = json.loads(capsys.readouterr().out)
    up = np.array(got["next_pose"]["up"])
    nearest = math.degrees(math.acos(float(np.max(ups @ up))))
    assert nearest > 30.0, (nearest, up)
    assert got["rms_after"] < got["rms_now"] and got["poses"] == 12 and got["moves"] == 11


def test_separate_on_a_session_without_a_cube_is_one_line(
    poses_dir: tuple[Path, np.ndarray], capsys: pytest.CaptureFixture[str]
) -> None:
    d, _ = poses_dir
    assert main(["plan", str(d), "--separate", "time_drift:gyro:x", "temperature_bias:gyro:x"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no cube" in err[0] and "next pose" in err[0], err


@pytest.mark.slow
def test_the_diagnosis_names_the_next_pose_too(
    poses_dir: tuple[Path, np.ndarray], capsys: pytest.CaptureFixture[str]
) -> None:
    d, _ = poses_dir
    capsys.readouterr()
    assert main(["model", "diagnose", str(d)]) == 0
    out = capsys.readouterr().out
    assert "next record:" not in out
    tail = out.split("== verdict:")[1].split("next pose: ")[1]
    assert re.match(r"X [+-]\d+°, Y [+-]\d+°, Z [+-]\d+°, moved there by hand", tail), tail
    assert not CUBE_RECORDS.search(tail), tail
