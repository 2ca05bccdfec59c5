"""Board.self_test (host/board/driver.py) on the virtual board (``sim://``, whose firmware runs
the self-test as the real one does: host/bench/firmware.py): the verdict, the stream after it,
and a board that cannot run it. The real firmware on the emulated chip:
tests/emulator/test_emu_selftest.py."""

from __future__ import annotations

import numpy as np
import pytest

from host.bench.firmware import SELF_TEST_S
from host.board.driver import Board
from host.wire import protocol_gen as gen
from host.wire.frames import IMU_SAMPLE, Frame

CONFIG_CHANGED = gen.ENUMS["sample_flags"]["CONFIG_CHANGED"]


@pytest.mark.parametrize(("part", "outcome"), [("pass", "pass"), ("fail", "fail")])
def test_self_test_on_the_virtual_board(part: str, outcome: str) -> None:
    board = Board(f"sim://?speed=max&self_test={part}")
    board.connect()
    try:
        seen: list[Frame] = []  # every frame read, during the self-test too
        read = board.read_frames

        def recording() -> list[tuple[int, Frame]]:
            out = read()
            seen.extend(f for _, f in out)
            return out

        board.read_frames = recording  # type: ignore[method-assign]
        while len(seen) < 20:
            board.pump()
        st = board.self_test()
        assert board.self_test_result is st
        assert st.outcome == outcome and st.samples > 10
        assert [a.name for a in st.axes if a.passed is False] == (
            ["ay", "gz"] if part == "fail" else []
        )
        while len(seen) < 150:
            board.pump()
        # one pause of the self-test's length; then the restored stream, its first sample
        # flagged CONFIG_CHANGED, at ±2 g again
        samples = [f.fields for f in seen if f.type == IMU_SAMPLE]
        t = np.array([f["t_us"] for f in samples])
        (pause,) = np.flatnonzero(np.diff(t) > 30_000)
        assert SELF_TEST_S * 1e6 < t[pause + 1] - t[pause] < (SELF_TEST_S + 0.1) * 1e6
        flagged = [i for i, f in enumerate(samples) if f["flags"] & CONFIG_CHANGED]
        assert flagged == [pause + 1]
        assert abs(np.mean([f["az"] for f in samples[pause + 1 :]]) - 16384) < 500  # z up
    finally:
        board.close()


def test_a_board_without_self_test_gives_no_verdict_and_says_why() -> None:
    board = Board("sim://?speed=max")
    board.connect()
    try:
        fw = board.port.firmware
        fw._handle = _unsupported(fw._handle)  # a firmware that answers UNSUPPORTED
        st = board.self_test(timeout_s=2.0)
        assert st.outcome == "" and "does not run it" in st.reason
        assert st.meta() == {"self_test_note": st.reason}
    finally:
        board.close()


def _unsupported(handle):  # type: ignore[no-untyped-def]
    self_test = next(t for t, m in gen.MESSAGES.items() if m[0] == "SELF_TEST")

    def wrapped(mtype: int, cmd_seq: int, fields: dict[str, int]) -> None:
        handle(0xFF if mtype == self_test else mtype, cmd_seq, fields)  # as an unknown type

    return wrapped
