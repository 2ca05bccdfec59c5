"""The yardstick's own arithmetic (benchmarks/yardstick.py): truth matching, pulls, summaries
and the table width. The workbench's numbers themselves are not asserted here (README)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from benchmarks import yardstick as ys
from benchmarks import yardstick_pulls as yp
from tests.independent.simulate import SessionSpec, simulate


def _truth(effect: str, seed: int = 5) -> dict[str, object]:
    return simulate(SessionSpec(seed=seed, effect=effect)).truth()


def test_truth_of_maps_workbench_names_to_the_simulator() -> None:
    t = _truth("bias_drift_gyro")
    e = t["effect"]
    assert isinstance(e, dict)
    assert yp.truth_of("A0x", t) == t["constants"]["A0x"]  # type: ignore[index]
    assert yp.truth_of(f"time_drift.gyro.{e['axis']}", t) == e["per_h"]
    other = next(a for a in "xyz" if a != e["axis"])
    assert yp.truth_of(f"time_drift.gyro.{other}", t) == 0.0
    assert yp.truth_of("lever_arm.x", t) is None
    lev = _truth("lever_arm")
    assert yp.truth_of("lever_arm.y", lev) == lev["effect"]["r_m"][1]  # type: ignore[index]
    sim = simulate(SessionSpec(seed=5, effect="face_lean"))
    face = sim.truth()
    lean = face["effect"]["lean_rad"]
    mean = 0.5 * (np.asarray(lean["+z"]) + np.asarray(lean["-z"]))
    # the lean as the accelerometer reads it: its matrix (the simulator's own) puts the lean
    # toward y on channel x too
    ca = sim.base.accel_matrix
    want = float((ca @ mean)[0] / ca[0, 0])
    assert yp.truth_of("face_error.accel.x.±z", face) == pytest.approx(want, rel=1e-12)
    assert abs(want - mean[0]) > 1e-7  # the misalignment's share is not nothing


def test_recommends_matches_term_sensor_and_axis() -> None:
    assert ys._recommends("bias:accel:xyz,time_drift:gyro:y", "time_drift:gyro:y")
    assert not ys._recommends("time_drift:gyro:x", "time_drift:gyro:y")
    assert not ys._recommends("time_drift:accel:y", "time_drift:gyro:y")
    assert ys._recommends("plate_tilt:accel:xyz", "plate_tilt:accel")
    assert not ys._recommends(None, "plate_tilt:accel")


def test_pull_groups() -> None:
    assert yp.pull_group("cal A0x") == "cal accel bias"
    assert yp.pull_group("cal GAxy") == "cal gyro g-sensitivity"
    assert yp.pull_group("cal Gyy") == "cal gyro scale"
    assert yp.pull_group("cal Azx") == "cal accel misalignment"
    assert yp.pull_group("time_drift.gyro.z") == "time_drift.gyro.*"
    assert yp.pull_group("lever_arm.z") == "lever_arm.z"


def _row(seed: int, rms_z: float, p: float, pull: float) -> dict[str, object]:
    return {
        "case": "control", "seed": seed, "effect": {"name": "none"}, "rms_z": rms_z, "p": p,
        "chi2_dof": rms_z**2, "verdict": "adequate", "recommended": None, "signals": [],
        "constants": [["cal A0x", 1.0 + 0.01 * pull, 0.01, 1.0]],
    }  # fmt: skip


def test_summary_of_controls() -> None:
    rng = np.random.default_rng(1)
    pulls = rng.normal(0.0, 2.0, 400)
    ps = np.linspace(0.0025, 0.9975, 400)
    rows = [_row(k, 1.0 + 0.001 * k, float(ps[k]), float(pulls[k])) for k in range(400)]
    s = ys.summarise(rows)["control"]
    assert s["n"] == 400
    assert s["flagged_5pc"] == pytest.approx(0.05, abs=0.005)
    assert s["ks_p"] > 0.5  # evenly spread p-values are uniform
    pb = s["pulls"]["cal accel bias"]
    assert pb["sd"] == pytest.approx(2.0, rel=0.1) and abs(pb["mean"]) < 0.3
    assert math.isclose(s["rms_z_med"], 1.0 + 0.001 * 199.5, rel_tol=1e-9)
    bunched = ys.summarise([_row(k, 0.4, 0.95, 0.0) for k in range(50)])["control"]
    assert bunched["ks_p"] < 1e-6 and bunched["flagged_5pc"] == 0.0
    text = ys.tables({"control": s})
    assert max(len(line) for line in text.splitlines()) <= 100


@pytest.mark.slow
def test_one_session_through_the_command_line(tmp_path: Path) -> None:
    row = ys.run_session(ys.CASES["drift_gyro"], 3, tmp_path)
    assert "error" not in row, row
    assert row["term"].startswith("time_drift:gyro:")
    assert row["rms_z"] > 0 and 0.0 <= row["p"] <= 1.0
    assert any(c[0].startswith("time_drift.gyro.") for c in row["coef"])
