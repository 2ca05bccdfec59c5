"""``calibrate --plan poses`` (host/dialogue/poses.py): no cube, the virtual operator holds the
unit still in the attitudes the planner asks for and moves it by hand between them."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from host.dialogue import poses
from host.dialogue.console import ScriptedConsole
from host.session.directory import read_session
from host.session.records import MOVE_NAME_RE, POSE_NAME_RE
from tests.host.dialogue.test_flow import LINEAR, Ports, opts, run


def test_the_sixteen_attitudes_put_every_axis_at_minus_zero_and_plus_one_g() -> None:
    ups = np.array(poses.SIXTEEN)
    assert ups.shape == (16, 3) and np.allclose(np.linalg.norm(ups, axis=1), 1.0)
    assert len({tuple(np.round(u, 6)) for u in ups}) == 16
    for k in range(3):
        assert {-1.0, 0.0, 1.0} <= set(np.round(ups[:, k], 6))


def test_the_planner_asks_for_gravity_where_no_pose_has_it() -> None:
    ups = [np.array([0.0, 0.0, 1.0]), np.array([0.0, 0.0, -1.0]), np.array([1.0, 0.0, 0.0])]
    up = poses.next_up(ups, (1e-4, 1e-5), 9.8)
    assert np.isclose(np.linalg.norm(up), 1.0)
    # far from every pose so far: not along z, nor +x
    assert float(np.max(np.array(ups) @ up)) < math.cos(math.radians(40.0))
    line = poses.coverage_line(ups)
    assert "+Z 1, −Z 1" in line and "+X 1, −X 0" in line and "farthest from every pose" in line


def test_attitude_words_say_each_axis_above_or_below_the_horizon() -> None:
    assert poses.attitude_words(np.array([0.0, 0.0, 1.0])) == "X +0°, Y +0°, Z +90°"
    u = np.array([1.0, -1.0, 1.0]) / math.sqrt(3)
    assert poses.attitude_words(u) == "X +35°, Y -35°, Z +35°"


def test_cut_move_finds_the_motion_and_its_edges() -> None:
    rng = np.random.default_rng(1)
    gyro = rng.normal(0, 0.05, (400, 3)) + [0.5, -0.2, 0.1]
    gyro[120:200, 1] += 60 * np.sin(np.linspace(0, np.pi, 80))
    start, end = poses.cut_move(gyro, np.array([0.5, -0.2, 0.1]), 0.02, 0.05)
    assert 105 <= start < 122 and 198 < end <= 215
    assert poses.cut_move(gyro[:100], np.array([0.5, -0.2, 0.1]), 0.02, 0.05) == (0, 0)


def _poses_session(tmp_path: Path, plan: str, **kw: object) -> tuple[int, str, Path, Ports]:
    ports = Ports()
    con = ScriptedConsole()
    o = opts(tmp_path, f"sim://?seed=3&noise_seed=3&{LINEAR}", plan=plan, static_seconds=3.0, **kw)
    rc, _ = run(o, con, ports)
    return rc, con.text, tmp_path / "S1", ports


@pytest.mark.slow
@pytest.mark.timeout(600)  # a fit after each pose from the tenth on
def test_plan_poses_runs_end_to_end_on_the_virtual_board(tmp_path: Path) -> None:
    rc, text, out, ports = _poses_session(tmp_path, "poses", target=0.05, max_extra=2)
    assert rc in (0, 1), text[-2000:]
    recs = read_session(out).records
    pose_names = sorted(n for n in recs if POSE_NAME_RE.match(n))
    moves = sorted(n for n in recs if MOVE_NAME_RE.match(n))
    assert len(pose_names) == len(moves) + 1 >= poses.FIRST_FIT_POSES
    for name in moves:  # every move joins the pose before and the pose after, edge to edge
        mv = recs[name]
        assert mv.kind == "move" and recs[mv.move_from].kind == "pose"
        after = recs[mv.move_to]
        assert mv.t_ms[-1] == after.t_ms[0] and mv.accel[-1].tolist() == after.accel[0].tolist()
        assert float(np.abs(mv.gyro).max()) > 20.0  # the hand moved it
    assert "Gravity so far (1 poses" in text and "Poses: worst σ/tolerance" in text
    assert "no record has a set attitude" in (out / "S1_result.txt").read_text(encoding="utf-8")
    # scales are the same in every frame: against the simulator's truth
    res = (out / "S1_result.txt").read_text(encoding="utf-8")
    truth = ports.sim.truth.constants()
    for name in ("Axx", "Ayy", "Azz", "Gxx", "Gyy", "Gzz"):
        line = next(ln for ln in res.splitlines() if ln.split()[:1] == [name])
        assert abs(float(line.split()[1]) - truth[name]) < 2e-3, (name, line, truth[name])


@pytest.mark.slow
@pytest.mark.timeout(600)  # a fit after each pose from the tenth on
def test_plan_poses16_measures_the_sixteen_attitudes(tmp_path: Path) -> None:
    rc, text, out, _ = _poses_session(tmp_path, "poses16")
    assert rc in (0, 1), text[-2000:]
    recs = read_session(out).records
    assert sum(POSE_NAME_RE.match(n) is not None for n in recs) == 16
    assert sum(MOVE_NAME_RE.match(n) is not None for n in recs) == 15
    ups = np.array([r.accel.mean(axis=0) / np.linalg.norm(r.accel.mean(axis=0))
                    for n, r in sorted(recs.items()) if POSE_NAME_RE.match(n)])  # fmt: skip
    # each pose is the scheme's attitude, to the unit's own errors
    assert np.all(np.sum(ups * np.array(poses.SIXTEEN), axis=1) > math.cos(math.radians(3)))


def _angle_deg(a: np.ndarray, b: np.ndarray) -> float:
    c = float(a @ b / np.linalg.norm(a) / np.linalg.norm(b))
    return math.degrees(math.acos(max(-1.0, min(1.0, c))))


@pytest.mark.slow
@pytest.mark.timeout(600)  # ten poses and a fit after the tenth
def test_a_repeated_pose_is_measured_where_the_unit_is_and_the_fit_holds(
    tmp_path: Path,
) -> None:
    """``N`` to pose_03 after its move: the unit is at the rejected attitude, not in pose_02.
    Asking for pose_03 again "from pose_02" filed a move that starts elsewhere than its record
    says (the fit's pose hold read 15°). Now pose_03 is measured where the unit is, with no
    move into it, and the next move starts from it: every move starts at its first pose's
    attitude, the pose hold stays a hand's (< 0.5°) and the values agree with the simulated
    unit's truth within their σ."""
    from host.calib.calibration import CalibrationOptions, calibrate_from_records
    from host.model.components import fit_with_components
    from host.model.dataset import load_dataset
    from host.model.spec import parse_model

    keys = [" ", "y", " ", "y", " ", "n"] + [" ", "y"] * 9  # pose_03's first attempt repeated
    con = ScriptedConsole(keys)
    ports = Ports()
    o = opts(tmp_path, f"sim://?seed=3&noise_seed=3&{LINEAR}", plan="poses", static_seconds=3.0,
             max_extra=0, yes=False)  # fmt: skip
    rc, _ = run(o, con, ports)
    assert rc in (0, 1), con.text[-2000:]
    assert "pose_03 not kept: the unit is no longer in pose_02" in con.text
    assert "Hold it still where it is now (pose_03)" in con.text
    recs = read_session(tmp_path / "S1").records
    assert sum(POSE_NAME_RE.match(n) is not None for n in recs) == 10
    moves = sorted(n for n in recs if MOVE_NAME_RE.match(n))
    assert "move_02_03" not in moves and len(moves) == 8  # none into the pose measured in place
    for name in moves:  # each move starts at rest where its first pose is
        mv, before = recs[name], recs[recs[name].move_from]
        assert _angle_deg(mv.accel[:5].mean(axis=0), before.accel.mean(axis=0)) < 1.0, name
    joint = fit_with_components(load_dataset(tmp_path / "S1"), parse_model("base"))
    hold = {c.name: c for c in joint.components}["pose hold"]
    assert hold.value < 0.5, hold
    res = calibrate_from_records(read_session(tmp_path / "S1"), CalibrationOptions())
    truth = ports.sim.truth.constants()
    # the values the frame's convention leaves alone: biases, scales, g-sensitivity
    scales = ("Axx", "Ayy", "Azz", "Gxx", "Gyy", "Gzz")
    kept = [p for p in res.parameters if p.name in truth]
    named = [p for p in kept if p.name[:2] in ("A0", "G0", "GA") or p.name in scales]
    pulls = np.array([(p.value - truth[p.name]) / p.stderr for p in named])
    assert len(pulls) == 21 and np.all(np.abs(pulls) < 3.5), pulls
    assert 0.5 < float(np.sqrt(np.mean(pulls**2))) < 1.6, pulls
