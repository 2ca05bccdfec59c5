"""A sitting of two boards typed by hand in an 80×24 pseudo-terminal (``python3 -m host
calibrate --port P1 --serial S1 --port P2 --serial S2``): each prompt and question once,
each board's mean/std line, one repeat for the sitting; on ``sim://`` (see test_flow_pty.py)
and, slow, on ``emu://`` — the real firmware in the emulator, two boards at once."""

from __future__ import annotations

import re
import sys
from pathlib import Path

import pytest

from host.session.directory import read_record
from host.session.records import STATIC_NAMES, TURN_NAMES
from tests.host.dialogue.test_flow_pty import BOARDS, LINEAR, Screen

pytestmark = pytest.mark.skipif(sys.platform == "win32", reason="needs a POSIX pty")


def two_boards(board: str) -> list[str]:
    speed = "max" if board == "sim" else "realtime"
    return [f"{board}://?seed={s}&noise_seed={s}&speed={speed}&{LINEAR}" for s in (51, 52)]


@pytest.mark.slow
@pytest.mark.timeout(600)
@pytest.mark.parametrize("board", BOARDS)
def test_two_boards_in_one_dialogue(tmp_path: Path, board: str) -> None:
    """Every prompt once for both boards; a static shows one mean and one std line per
    board; 'repeat' measures the record again on both; both sessions complete; every line
    within 80 columns."""
    p1, p2 = two_boards(board)
    s = Screen(["--port", p1, "--serial", "B1", "--port", p2, "--serial", "B2", "--out", "lot",
                "--warmup", "0", "--ready-seconds", "0", "--static-seconds", "2",
                "--turns", "1", "--no-archive"], tmp_path, size=(24, 80))  # fmt: skip
    try:
        _type_the_sitting(s)
        assert s.wait(timeout=120) in (0, 1)
    finally:
        s.close()
    shown = [ln.replace("\x1b[K", "") for ln in s.text.replace("\r", "\n").split("\n")]
    wide = [ln for ln in shown if len(ln) > 80 and len(ln.split()) > 1]  # a URL: whole
    assert wide == [], wide
    assert s.text.count("Measuring x_up:") == 2  # the repeat, once for the sitting
    assert len(re.findall(r"Save <Y> or repeat <N>\?", s.text)) == 14  # 13 records + repeat
    for serial in ("B1", "B2"):
        d = tmp_path / "lot" / serial
        for name in (*STATIC_NAMES, *TURN_NAMES, "x_up_2"):
            assert read_record(d / f"{serial}_{name}.txt").meta["serial"] == serial
        assert (d / f"{serial}_result.json").exists()
    ax = [
        read_record(tmp_path / "lot" / b / f"{b}_x_up.txt").accel[:, 0].mean()
        for b in "B1 B2".split()
    ]
    assert all(abs(a - 9.81) < 0.3 for a in ax) and ax[0] != ax[1]


def _type_the_sitting(s: Screen) -> None:
    """The keys of the sitting: both stages, a repeat of x_up, the closing check."""
    s.expect(r"B1: Board: ", timeout=90)  # emu://: may build the firmware first
    s.expect(r"B2: Board: ", timeout=90)
    s.expect(r"Measure the 6 static\s+orientations <Y>")
    s.send("y")
    for k, name in enumerate(["x_up", *STATIC_NAMES]):  # x_up rejected once
        s.expect(r"Put the cube on the base")
        s.expect(r"Press any key\.")
        s.send(" ")
        s.expect(rf"Measuring {name}:")
        s.expect(r"B1\s+mean\s+[-\d.]+")
        s.expect(r"B2\s+mean\s+[-\d.]+")
        s.expect(r"Save <Y> or repeat <N>\? \[Y\]")
        s.send("n" if k == 0 else "y")
    s.expect(r"Integral gyro calibration <Y> or results <N>\?")
    s.send("y")
    for name in TURN_NAMES:
        s.expect(r"Put the cube [XYZ] up")
        s.expect(r"Press any key\.")
        s.send(" ")
        s.expect(rf"Turn now! {name}")
        s.expect(r"B2:\s+Integrals")
        s.expect(r"Save <Y> or repeat <N>\?")
        s.send("y")
    s.expect(r"Closing check")
    s.expect(r"Press any key\.")
    s.send(" ")
    s.expect(r"Save <Y> or repeat <N>\? \[Y\]")
    s.send("y")
    s.expect(r"Results of B2:", timeout=120)
