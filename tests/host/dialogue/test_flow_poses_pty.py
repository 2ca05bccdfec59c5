"""``calibrate --plan poses`` answered by hand in an 80×24 pseudo-terminal (issue 41 item 4):
the serial typed, a key at every prompt, each pose saved (``y`` once, the default after) but
one repeated; the virtual operator of ``sim://`` holds the unit where each prompt says. Before,
the poses dialogue was tested only with ``--yes``.

``N`` (repeat) to a pose after the first leaves the unit at the rejected attitude, not in the
pose before: asked again "from" that pose, the move saved started elsewhere than its record
said and the fit's pose hold read 7.5° (implausible). The pose is now measured where the unit
is, with no move into it, and the next attitude is asked from there."""

from __future__ import annotations

import math
import re
import sys
from pathlib import Path

import numpy as np
import pytest

from host.session.directory import read_session
from host.session.records import MOVE_NAME_RE, POSE_NAME_RE
from tests.host.dialogue.test_flow_pty import Screen, board_url

pytestmark = pytest.mark.skipif(sys.platform == "win32", reason="needs a POSIX pty")

#: a prompt's attitude: each axis's angle above (+) or below (−) the horizon
ATTITUDE = r"X ([+-]\d+)°, Y ([+-]\d+)°, Z ([+-]\d+)°"
#: the same where the 80-column screen may break the line at a space
WRAPPED = ATTITUDE.replace(", ", r",\s+")


def _asked_up(m: re.Match[str]) -> np.ndarray:
    """Gravity's direction in the body from a prompt's three angles (sin of each)."""
    return np.sin(np.radians([float(m.group(k)) for k in (1, 2, 3)]))


@pytest.mark.slow
@pytest.mark.timeout(600)  # ten poses at full speed, a fit after the tenth
def test_an_operator_answers_the_poses_dialogue_in_80x24(tmp_path: Path) -> None:
    s = Screen(["--port", board_url("sim", 41, "max"), "--plan", "poses", "--warmup", "0",
                "--static-seconds", "3", "--max-extra", "0", "--ready-seconds", "0"],
               tmp_path, size=(24, 80))  # fmt: skip
    try:
        s.expect(r"Serial number \(1-12 characters[^\n]*: ", timeout=60)
        s.send("P7\r")
        first = s.expect(rf"Hold it still with {ATTITUDE} \(no cube needed\)\. Press any key\.")
        asked = {"pose_01": _asked_up(first)}
        s.send(" ")
        s.expect(r"Save <Y> or repeat <N>\? \[Y\]", timeout=60)
        s.send("y")
        for k in range(2, 11):
            s.expect(r"Gravity so far \(\d+ poses, within 45° of\)")
            m = s.expect(rf"Keep it still in pose_{k - 1:02d}; at the beep move it to\s+"
                         rf"{WRAPPED}\s+and hold\s+it still until the "
                         r"second\s+beep\. Press any key\.", timeout=60)  # fmt: skip
            asked[f"pose_{k:02d}"] = _asked_up(m)
            # after the "y" a script's Enter this fast would be taken as typed with it
            s.send(" " if k == 2 else "\r")
            s.expect(r"Save <Y> or repeat <N>\? \[Y\]", timeout=60)
            if k == 3:  # repeated: measured again where the move left the unit
                s.send("n")
                s.expect(r"pose_03 not kept: the unit is no longer in pose_02")
                s.expect(r"Hold it still where it is now \(pose_03\)\. Press any key\.")
                s.send(" ")
                s.expect(r"Save <Y> or repeat <N>\? \[Y\]", timeout=60)
            s.send("\r")  # the default: save
        assert s.wait(timeout=300) in (0, 1)
        assert "IMPLAUSIBLE" not in s.text
    finally:
        s.close()
    shown = [ln for ln in s.text.replace("\r", "\n").split("\n") if ln.strip()]
    assert all(len(ln.replace("\x1b[K", "")) <= 80 for ln in shown), max(shown, key=len)
    url = max(i for i, ln in enumerate(shown) if ln.strip().startswith("sim://"))
    verdict = " ".join(ln.strip() for ln in shown[url + 1 :])
    assert re.fullmatch(r"(PASS|FAIL)\b.*", verdict) and "does not fit" not in verdict, verdict
    recs = read_session(tmp_path / "P7").records
    poses = sorted(n for n in recs if POSE_NAME_RE.match(n))
    moves = sorted(n for n in recs if MOVE_NAME_RE.match(n))
    assert poses == sorted(asked) and len(moves) == 8 and "move_02_03" not in moves
    hold = re.search(r"pose\s+hold:\s+([0-9.]+)\s+(±|°)", s.text)  # the report's note
    assert hold is not None and float(hold.group(1)) < 0.5, s.text[-3000:]
    # every pose where its prompt asked for it (the virtual operator's hand: a few degrees)
    for name, up in asked.items():
        mean = recs[name].accel.mean(axis=0)
        off = math.degrees(math.acos(float(np.clip(up @ mean / np.linalg.norm(mean) /
                                                   np.linalg.norm(up), -1, 1))))  # fmt: skip
        assert off < 8.0, (name, off)
