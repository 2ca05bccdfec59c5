"""The poses engine on sessions of the independent simulator (tests/independent/poses.py):
random attitudes, moves about random axes, the unit's §2 errors, noise and quantisation. The
figure over 50 sessions: benchmarks/poses_pulls.py; here a lean sample of it."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from host.calib.calibration import CalibrationOptions, calibrate_from_records
from host.session.directory import read_session
from tests.independent.poses import (
    PoseSpec,
    _rq,
    simulate_poses,
    truth_in_frame,
    write_poses,
)


def test_truth_in_the_accelerometers_frame_reads_the_same() -> None:
    sess = simulate_poses(PoseSpec(seed=3, poses=3))
    assert sess.truth is not None
    u, q = _rq(sess.truth.accel_matrix)
    assert np.allclose(u @ q, sess.truth.accel_matrix) and np.allclose(np.tril(u, -1), 0)
    t = truth_in_frame(sess.truth)
    assert t["Ayz"] == pytest.approx(0, abs=1e-15) and t["Azx"] == pytest.approx(0, abs=1e-15)
    assert sorted(sess.records)[:3] == ["move_01_02", "move_02_03", "pose_01"]
    text = sess.records["move_01_02"]
    assert "# from: pose_01" in text and "# to: pose_02" in text


def _pulls(tmp: Path, seed: int) -> dict[str, tuple[float, float, float]]:
    spec = PoseSpec(seed=seed, poses=30)
    sess = simulate_poses(spec)
    write_poses(str(tmp), sess)
    res = calibrate_from_records(
        read_session(tmp), CalibrationOptions(latitude_deg=45.0, height_m=0.0)
    )
    assert sess.truth is not None
    truth = truth_in_frame(sess.truth)
    return {p.name: (p.value, p.stderr, truth[p.name]) for p in res.parameters
            if p.name in truth and math.isfinite(p.value) and p.stderr > 0}  # fmt: skip


@pytest.mark.slow
@pytest.mark.timeout(600)  # three calibrations of 30 poses and 29 moves
def test_thirty_poses_give_every_determined_value_within_3_sigma(tmp_path: Path) -> None:
    zs: list[float] = []
    for seed in (1, 2, 3):
        got = _pulls(tmp_path / str(seed), seed)
        # every value but the frame's three: the gyro's biases and g-sensitivity from the
        # rests, its scales and misalignments from the moves
        assert len(got) == 3 + 3 + 3 + 3 + 3 + 6 + 9, sorted(got)
        assert {"Gxx", "Gzx", "Axz", "GAzz", "G0y"} <= set(got)
        for name, (value, sigma, truth) in got.items():
            assert abs(value - truth) < 3 * sigma, (seed, name, value, truth, sigma)
            if name[1] == name[2]:  # a scale
                assert abs(value - truth) < 0.003
        zs += [(v - t) / s for v, s, t in got.values()]
    assert 0.7 < float(np.std(zs, ddof=1)) < 1.4, np.std(zs, ddof=1)
