"""The independent simulator writes the project's record format (our own writer), and the
host reads it: through the command line, which does not move when the modules do."""

from __future__ import annotations

import dataclasses
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from tests.independent.hand import extra_record
from tests.independent.simulate import HEADING_KEY, Extra, SessionSpec, simulate, write_session

ROOT = Path(__file__).resolve().parents[2]


def _rows(path: Path) -> tuple[dict[str, str], np.ndarray, list[str]]:
    meta: dict[str, str] = {}
    rows: list[list[float]] = []
    tail: list[str] = []
    for line in path.read_text(encoding="utf-8").splitlines():
        if line.startswith("# ") and ": " in line:
            k, v = line[2:].split(": ", 1)
            meta[k] = v
        elif line.startswith("#"):
            continue
        elif line.startswith("___"):
            tail.append(line)
        elif tail:
            tail.append(line)
        else:
            rows.append([float(x) for x in line.split("\t")])
    return meta, np.array(rows), tail


def test_file_layout_and_summary_rows(tmp_path: Path) -> None:
    s = write_session(tmp_path, SessionSpec(seed=1, headings="random", record_heading=True))
    files = sorted(p.name for p in tmp_path.glob("IND01_*.txt"))
    assert len(files) == 13 and "IND01_x_up_2.txt" in files
    for r in s.records:
        p = tmp_path / f"IND01_{r.name}.txt"
        assert p.read_text(encoding="utf-8").startswith("# imu-bench record v1\n")
        meta, data, tail = _rows(p)
        assert meta["record"] == r.name and meta["serial"] == "IND01"
        assert float(meta[HEADING_KEY]) == r.heading_deg
        assert data.shape == (len(r.t_ms), 8)
        # printed to the format's decimals: ms 1, m/s² 4, °/s 3, °C 1
        np.testing.assert_allclose(data[:, 1:4], r.accel, atol=5.01e-5)
        np.testing.assert_allclose(data[:, 4:7], r.gyro, atol=5.01e-4)
        np.testing.assert_allclose(data[:, 7], r.temp_c, atol=0.0501)
        assert tail[1].startswith("mean\t") and tail[2].startswith("std\t")
        mean = np.array([float(x) for x in tail[1].split("\t")[1:]])
        std = np.array([float(x) for x in tail[2].split("\t")[1:]])
        np.testing.assert_allclose(mean, data[:, 1:].mean(axis=0), atol=5.01e-5)
        np.testing.assert_allclose(std, data[:, 1:].std(axis=0, ddof=1), atol=5.01e-5)
        if meta["kind"] == "turn":
            assert meta["turns"] == "2" and meta["direction"] in ("ccw", "cw")
    truth = json.loads((tmp_path / "truth.json").read_text(encoding="utf-8"))
    assert truth["constants"]["A0x"] == s.base.constants()["A0x"]
    assert set(truth["headings_deg"]) == {r.name for r in s.records}


def test_heading_is_only_written_when_asked(tmp_path: Path) -> None:
    write_session(tmp_path, SessionSpec(seed=2, headings="random"))
    meta, _, _ = _rows(tmp_path / "IND01_y_dn.txt")
    assert HEADING_KEY not in meta


@pytest.mark.slow
@pytest.mark.parametrize("effect", ["none", "lever_arm"])
def test_host_reads_the_session(tmp_path: Path, effect: str) -> None:
    write_session(tmp_path, SessionSpec(seed=3, effect=effect))
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1")
    out = subprocess.run(
        [sys.executable, "-m", "host", "calibrate", "--from-dir", str(tmp_path), "--json"],
        capture_output=True, text=True, cwd=ROOT, env=env, timeout=120,
    )  # fmt: skip
    assert out.returncode in (0, 1), out.stderr
    result = json.loads(out.stdout)
    names = {"x_up", "x_dn", "y_up", "y_dn", "z_up", "z_dn", "x_up_2"}
    names |= {f"{a}_{d}" for a in "xyz" for d in ("ccw", "cw")}
    assert set(result["records"]) == names
    assert result["turns"] == 2


def test_records_off_the_plan_attitudes_and_paces() -> None:
    """A 45° attitude rests on a square wedge (gravity along the up asked for, no face lean
    even on a unit whose faces lean), and turns at half the pace turn the same whole turns at
    half the rate in a window twice as long."""
    up = (0.0, 0.5**0.5, -(0.5**0.5))
    spec = SessionSpec(seed=4, effect="face_lean", extra=(
        Extra("tilt_45_10", "static", up), Extra("z_ccw_2", "turn", pace=0.5),
    ))  # fmt: skip
    s = simulate(spec)
    recs = {r.name: r for r in s.records}
    tilt = recs["tilt_45_10"]
    np.testing.assert_allclose(tilt.true_force / s.g, np.tile(up, (len(tilt.t_ms), 1)), atol=1e-9)
    assert tilt.meta["up"].startswith("[") and tilt.meta["kind"] == "static"
    own, slow = recs["z_ccw"], recs["z_ccw_2"]
    assert float(slow.meta["window_s"]) == 2 * float(own.meta["window_s"])
    for r in (own, slow):
        assert np.sum(r.true_rate[:, 2]) / 50.0 == pytest.approx(720.0, abs=3.0)
    ratio = np.max(slow.true_rate[:, 2]) / np.max(own.true_rate[:, 2])
    assert 0.4 < ratio < 0.6
    # the plan's records are the same with the extra ones appended
    plain = {r.name: r for r in simulate(dataclasses.replace(spec, extra=())).records}
    np.testing.assert_array_equal(plain["z_cw"].gyro, recs["z_cw"].gyro)


def test_the_hand_asks_for_what_a_candidate_names() -> None:
    assert extra_record("y_dn_2", (0, -1, 0), "static", 20.0) == ("y_dn_2", 20.0)
    assert extra_record("x_ccw_2", (1, 0, 0), "turn", 12.0) == "x_ccw_2"
    slow = extra_record("x_ccw_2", (1, 0, 0), "turn", 24.0, pace=0.5)
    assert isinstance(slow, Extra) and slow.pace == 0.5 and slow.up is None
    tilt = extra_record("tilt_45_1", (0.7071, 0.7071, 0), "static", 10.0)
    assert isinstance(tilt, Extra) and tilt.up == (0.7071, 0.7071, 0.0)
    noted = extra_record("tilt_45_3", (-0.7071, 0.7071, 0), "static", 10.0, heading_deg=0.0)
    assert isinstance(noted, Extra) and noted.heading_deg == 0.0 and noted.up is not None
    face = extra_record("x_dn_2", (-1, 0, 0), "static", 10.0, heading_deg=90.0)
    assert isinstance(face, Extra) and face.up is None and face.heading_deg == 90.0


def test_a_noted_heading_is_where_the_cube_is_placed_and_in_its_header() -> None:
    """A record the operator places at a heading and notes: its header carries the heading
    (the plan's records, unrecorded, do not), and on a tilted plate the tilt seen by the cube
    turned 90° counter-clockwise on the same face is the first one turned by −90°."""
    spec = SessionSpec(seed=4, effect="plate_tilt", extra=(
        Extra("z_up_2", heading_deg=0.0), Extra("z_up_3", heading_deg=90.0),
    ))  # fmt: skip
    recs = {r.name: r for r in simulate(spec).records}
    assert HEADING_KEY not in recs["z_up"].meta
    assert (recs["z_up_2"].meta[HEADING_KEY], recs["z_up_3"].meta[HEADING_KEY]) == ("0", "90")
    f0, f90 = (recs[n].true_force.mean(axis=0) for n in ("z_up_2", "z_up_3"))
    assert np.hypot(f0[0], f0[1]) > 0.01  # the plate leans at least 0.1°
    np.testing.assert_allclose([f90[0], f90[1]], [f0[1], -f0[0]], atol=1e-9)
    # the plan's records are the same with the noted ones appended
    plain = {r.name: r for r in simulate(dataclasses.replace(spec, extra=())).records}
    np.testing.assert_array_equal(plain["z_cw"].accel, recs["z_cw"].accel)


def test_the_table_written_at_once_is_each_cell_as_printed_alone() -> None:
    """The writer formats a record's table in one go; each cell is still the per-cell rule:
    its column's decimals, and a value that rounds to zero printed without a minus sign."""
    from tests.independent.recordfile import COLUMN_DECIMALS, _num, record_text

    rng = np.random.default_rng(17)
    n = 300
    t = np.cumsum(rng.uniform(0.0, 10.0, n))
    accel = rng.normal(0.0, 1.0, (n, 3)) * 10.0 ** rng.uniform(-6, 1, (n, 3))
    gyro = rng.normal(0.0, 1.0, (n, 3)) * 10.0 ** rng.uniform(-6, 1, (n, 3))
    accel[0] = [-0.0, -4.9e-5, -5.1e-5]  # minus zero, one that rounds to it, one that does not
    gyro[1] = [-4e-4, -6e-4, 0.0]
    temp = rng.normal(25.0, 0.05, n)
    lines = record_text("x_up", {"serial": "R1"}, t, accel, gyro, temp).splitlines()
    table = [ln for ln in lines if not ln.startswith("#")]
    data = np.column_stack([t, accel, gyro, temp])
    for row, line in zip(data, table[:n], strict=True):
        cells = [_num(float(v), d) for v, d in zip(row, COLUMN_DECIMALS, strict=True)]
        assert line.split("\t") == cells
    assert table[0].split("\t")[1:4] == ["0.0000", "0.0000", "-0.0001"]
    assert table[1].split("\t")[4:7] == ["0.000", "-0.001", "0.000"]
    assert table[n] == "_" * 72 and table[n + 1].startswith("mean\t")
