"""The planner's augmented session reads its noise and record length from the rests, poses
too: a session of poses alone (no face) has them (``model diagnose`` ranks the next record)."""

from __future__ import annotations

import math

import numpy as np

from host.session.directory import Session
from host.session.records import Record, pose_name
from host.workbench.planner import Augmenter


def test_a_session_of_poses_alone_gives_the_planner_its_noise() -> None:
    rng = np.random.default_rng(1)
    records = {}
    for i in range(1, 11):
        up = rng.normal(size=3)
        up /= np.linalg.norm(up)
        n = 100
        accel = 9.8 * up + rng.normal(0, 0.02, (n, 3))
        gyro = rng.normal(0, 0.05, (n, 3))
        records[pose_name(i)] = Record(pose_name(i), np.arange(n) * 20.0, accel, gyro,
                                       np.full(n, 30.0), {})  # fmt: skip
    aug = Augmenter(Session(serial="P", records=records), {}, 9.8)
    assert math.isclose(aug.static_s, 1.98, rel_tol=1e-9)
    assert np.all(np.abs(aug.accel_sd - 0.02) < 0.005) and math.isclose(aug.dt_s, 0.02)
