"""``calibrate --plan poses`` against the emulated board (the real firmware in simavr): no cube,
the simulator's operator holds the unit in the attitudes asked for and moves it between them
(host/dialogue/poses.py, host/bench/operator.py)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from host.session.directory import read_session
from host.session.records import MOVE_NAME_RE, POSE_NAME_RE
from host.transports.protocol_emu import truth_for_url

pytestmark = [
    pytest.mark.emulator,
    pytest.mark.skipif(sys.platform == "win32", reason="needs a POSIX pty"),
]

ROOT = Path(__file__).resolve().parents[2]
LINEAR = "effects=linear,noise&earth_rate=0"


@pytest.mark.slow
@pytest.mark.timeout(900)  # the emulated AVR and a fit after each pose from the tenth on
def test_plan_poses_end_to_end_on_the_emulated_board(tmp_path: Path, fw_elf: Path) -> None:
    url = f"emu://?elf={fw_elf}&seed=4&noise_seed=4&{LINEAR}"
    proc = subprocess.run(
        [sys.executable, "-m", "host", "calibrate", "--port", url, "--serial", "EP1", "--yes",
         "--warmup", "0", "--static-seconds", "3", "--plan", "poses", "--target", "0.05",
         "--max-extra", "1", "--json", "--out", "EP1"],
        cwd=tmp_path, capture_output=True, text=True, timeout=600,
        env=dict(os.environ, PYTHONPATH=str(ROOT)), start_new_session=True,
    )  # fmt: skip
    assert proc.returncode in (0, 1), proc.stderr[-3000:]
    recs = read_session(tmp_path / "EP1").records
    poses = [n for n in recs if POSE_NAME_RE.match(n)]
    moves = [n for n in recs if MOVE_NAME_RE.match(n)]
    assert len(poses) >= 10 and len(moves) == len(poses) - 1
    for name in moves:
        mv = recs[name]
        assert mv.meta["lost_frames"] == "0" and mv.meta["port"] == url
        assert np.all(np.abs(np.diff(mv.t_ms) - 20.0) < 0.1)  # the firmware's own clock
    got = json.loads(proc.stdout)["constants"]
    truth = truth_for_url(url)
    assert truth is not None
    want = truth.constants()
    for name in ("Axx", "Ayy", "Azz", "Gxx", "Gyy", "Gzz", "G0x", "G0y", "G0z"):
        tol = 0.01 if name.startswith("G0") else 2e-3
        assert abs(got[name] - want[name]) < tol, (name, got[name], want[name])
    assert "Gravity so far" in proc.stderr and "Poses: worst σ/tolerance" in proc.stderr
