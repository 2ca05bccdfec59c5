"""The independent simulator writes the project's record format (our own writer), and the
host reads it: through the command line, which does not move when the modules do."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from tests.independent.simulate import HEADING_KEY, SessionSpec, write_session

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
