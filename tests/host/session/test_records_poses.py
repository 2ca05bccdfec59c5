"""Pose and move records: a rest at an unknown attitude and the motion between two rests."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from host.errors import RecordCheckError
from host.session.checks import check_move, check_pose
from host.session.directory import read_session, record_path, split_file_name, write_record
from host.session.method import record_stats
from host.session.records import (
    Record,
    RecordError,
    is_standard_name,
    move_name,
    pose_name,
)

G = 9.80665


def _rest(name: str, force: np.ndarray, meta: dict[str, str] | None = None) -> Record:
    rng = np.random.default_rng(5)
    n = 40
    return Record(
        name,
        np.arange(n) * 20.0,
        force + rng.normal(0, 0.02, (n, 3)),
        rng.normal(0, 0.05, (n, 3)),
        np.full(n, 30.0),
        meta if meta is not None else {},
    )


def _move(name: str, meta: dict[str, str] | None = None) -> Record:
    return _rest(name, np.array([0.0, 0.0, G]), meta)


def test_names_and_kinds() -> None:
    assert pose_name(1) == "pose_01" and pose_name(123) == "pose_123"
    assert move_name(1, 2) == "move_01_02" and move_name(12, 3) == "move_12_03"
    with pytest.raises(ValueError):
        pose_name(0)
    with pytest.raises(ValueError):
        move_name(2, 2)
    up = np.array([0.0, 0.0, G])
    assert _rest("pose_01", up).kind == "pose"
    assert _move("move_01_02").kind == "move"
    # the header's kind names other names too
    assert _rest("rest_a", up, {"kind": "pose"}).kind == "pose"
    assert _move("m1", {"kind": "move", "from": "rest_a", "to": "rest_b"}).move_to == "rest_b"
    # a pose is no face: a name like pose_1 (one digit) or posed_01 is not one
    assert _rest("pose_1", up).kind == "unknown" and _rest("posed_01", up).kind == "unknown"
    for name in ("pose_01", "move_01_02", "x_up", "z_cw_2"):
        assert is_standard_name(name)
    assert not is_standard_name("move_01")


def test_a_pose_has_no_up() -> None:
    pose = _rest("pose_01", np.array([0.0, 0.0, G]))
    with pytest.raises(RecordError, match="a pose has no up direction"):
        _ = pose.up
    with pytest.raises(RecordError, match="not a move"):
        _ = pose.move_from


def test_move_poses_from_header_or_name() -> None:
    m = _move("move_03_07")
    assert (m.move_from, m.move_to) == ("pose_03", "pose_07")
    h = _move("move_03_07", {"from": "pose_03", "to": "pose_07"})
    assert (h.move_from, h.move_to) == ("pose_03", "pose_07")
    with pytest.raises(RecordError, match="names its poses in its header"):
        _ = _move("m", {"kind": "move"}).move_from


def test_round_trip_and_file_names(tmp_path: Path) -> None:
    write_record(record_path(tmp_path, "A_B", "pose_01"), _rest("pose_01", np.array([0, 0, G])))
    write_record(record_path(tmp_path, "A_B", "pose_02"), _rest("pose_02", np.array([G, 0, 0])))
    mv = _move("move_01_02", {"from": "pose_01", "to": "pose_02"})
    write_record(record_path(tmp_path, "A_B", "move_01_02"), mv)
    # a serial with underscores keeps them: the standard name is matched at the end
    assert split_file_name("A_B_pose_01.txt") == ("A_B", "pose_01")
    assert split_file_name("A_B_move_01_02.txt") == ("A_B", "move_01_02")
    s = read_session(tmp_path)
    assert s.serial == "A_B" and sorted(s.records) == ["move_01_02", "pose_01", "pose_02"]
    back = s.records["move_01_02"]
    assert back.kind == "move" and (back.move_from, back.move_to) == ("pose_01", "pose_02")
    assert s.records["pose_02"].kind == "pose"


def test_check_pose() -> None:
    ok = _rest("pose_01", np.array([3.0, 4.0, 8.45]))
    check_pose(ok, record_stats(ok), G, "S_pose_01.txt")
    with_up = _rest("pose_01", np.array([0, 0, G]), {"up": "+z"})
    with pytest.raises(RecordCheckError, match="has no up direction") as err:
        check_pose(with_up, record_stats(with_up), G, "S_pose_01.txt")
    assert err.value.file_name == "S_pose_01.txt"
    light = _rest("pose_02", np.array([0, 0, 2.0]))
    with pytest.raises(RecordCheckError, match="specific force is 1.9|specific force is 2.0"):
        check_pose(light, record_stats(light), G, "S_pose_02.txt")
    moving = Record(
        "pose_03",
        ok.t_ms,
        ok.accel + np.linspace(-2, 2, len(ok))[:, None],
        ok.gyro,
        ok.temp,
        {},
    )
    with pytest.raises(RecordCheckError, match="moved during the pose"):
        check_pose(moving, record_stats(moving), G, "S_pose_03.txt")


def test_check_move() -> None:
    poses = {"pose_01", "pose_02"}
    check_move(_move("move_01_02"), poses, "S_move_01_02.txt")
    with pytest.raises(RecordCheckError, match="has no pose_03"):
        check_move(_move("move_02_03"), poses, "S_move_02_03.txt")
    wrong = _move("move_01_02", {"from": "pose_02", "to": "pose_01"})
    with pytest.raises(RecordCheckError, match="its name says otherwise"):
        check_move(wrong, poses, "S_move_01_02.txt")
    same = _move("m", {"kind": "move", "from": "pose_01", "to": "pose_01"})
    with pytest.raises(RecordCheckError, match="starts and ends at pose_01"):
        check_move(same, poses, "S_m.txt")
    fast = _move("move_01_02", {"gyro_range_dps": "0.1"})
    with pytest.raises(RecordCheckError, match="outside the working range"):
        check_move(fast, poses, "S_move_01_02.txt")
