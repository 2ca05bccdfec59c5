"""Two emulated boards in one virtual cube (``emu://?cube=C&slot=K``, issue 45 item 2): the real
firmware on both, one operator's hand, each board at its own place — measured through the
sitting's one start beep (``host.board.driver.acquire_boards``)."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from host.board.driver import Board, acquire_boards
from host.wire import sensor

pytestmark = [
    pytest.mark.emulator,
    pytest.mark.skipif(sys.platform == "win32", reason="needs a POSIX pty"),
]

ACC_LSB = sensor.G0 / 16384.0


def _measure(boards: list[Board], action: str, seconds: float, **kw: object) -> list[dict]:
    """Hint every board, then one measurement on all: per board what the operator did (the
    motion's start from the board's ``now``), accel, gyro and the sample period."""
    done = [b.hint(action, **kw) for b in boards]
    nows = [b.port.hints[-1][0] for b in boards]
    out = []
    for b, d, now, acq in zip(boards, done, nows, acquire_boards(boards, seconds), strict=True):
        assert d is not None and d["done"], d
        accel, gyro, _ = b.physical(acq.counts)
        dt = float(np.mean(np.diff(acq.t_us))) / 1e6
        out.append({"start": d["start_s"] - now, "accel": accel, "gyro": gyro, "dt": dt})
    return out


@pytest.mark.slow
@pytest.mark.timeout(300)
def test_two_emulated_boards_of_one_cube_make_one_motion_each_at_its_place(fw_elf: Path) -> None:
    """Perfect units in slots 1 and 5 of cube 2. At rest each reads gravity turned by its own
    mounting (Rot(θ)·reading = g·up on both, to the LSB; the raw readings differ by g·θ).
    Through a turn both make the same motion from their ``now`` at the hint, and their gyros'
    integrals, turned back by each mounting, agree while the raw ones differ by the turn's
    angle times the mountings' difference."""
    urls = [f"emu://?elf={fw_elf}&cube=2&slot={k}&seed={s}&truth=ideal&earth_rate=0"
            for k, s in ((1, 1), (5, 2))]  # fmt: skip
    boards = [Board(u) for u in urls]
    try:
        for b in boards:
            b.connect()
        rot = [b.port.truth.mounting for b in boards]
        rest = _measure(boards, "place", 2.0, name="y_up")
        turn = _measure(boards, "turn", 7.0, axis="z", direction="ccw", turns=1, window_s=7.0)
    finally:
        for b in boards:
            b.close()
    means = [r["accel"].mean(axis=0) for r in rest]
    g = float(np.linalg.norm(means[0]))
    for r, m in zip(rot, means, strict=True):
        assert np.max(np.abs(r @ m - g * np.array([0.0, 1.0, 0.0]))) < 1.5 * ACC_LSB, r @ m
    assert np.max(np.abs(means[0] - means[1])) > 4 * ACC_LSB
    assert turn[0]["start"] == pytest.approx(turn[1]["start"], abs=1e-9)
    integral = [r @ t["gyro"].sum(axis=0) * t["dt"] for r, t in zip(rot, turn, strict=True)]
    raw = [t["gyro"].sum(axis=0) * t["dt"] for t in turn]
    assert abs(integral[0][2] - 360.0) < 1.0, integral[0]
    assert np.max(np.abs(integral[0] - integral[1])) < 0.1, integral[0] - integral[1]
    assert np.max(np.abs(raw[0] - raw[1])) > 0.5, raw[0] - raw[1]
