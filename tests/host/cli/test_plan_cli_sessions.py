"""``plan DIR`` on sessions it did not write (host/cli/plan.py, host/workbench/planner.py):
the independent simulator's (tests/independent: written apart from host/bench), its turns made
in one continuous motion, its records with their headers or stripped of what only our bench
writes, a record removed. The candidates built from the session's own turns must fit that
session's shape: a turn of two whole turns whose header does not say so once made the
planner's turn of one turn in a 7 s window end in motion (issue 46)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from host.__main__ import main
from tests.independent.simulate import SessionSpec, write_session

#: header lines only our bench (and the independent simulator) writes: a foreign session's
#: records may have none of them
OURS = re.compile(r"^# (turns|window_s|power_on_s|session_s|source):")


def _session(d: Path, headers: bool, removed: tuple[str, ...]) -> Path:
    write_session(d, SessionSpec(seed=5, static_s=10.0, turns=2, turn_motion="continuous"))
    for name in (*removed, "x_up_2"):
        (d / f"IND01_{name}.txt").unlink()
    if not headers:
        for f in d.glob("IND01_*.txt"):
            lines = f.read_text().splitlines(keepends=True)
            f.write_text("".join(line for line in lines if not OURS.match(line)))
    return d


@pytest.mark.parametrize(
    ("headers", "removed", "first"),
    [
        pytest.param(False, ("z_ccw", "z_cw"), "z turns, 2 each way", marks=pytest.mark.slow),
        pytest.param(True, ("z_ccw", "z_cw"), "z turns, 2 each way", marks=pytest.mark.slow),
        # one turn of a pair gone: y_ccw alone determines y; the pair is ranked as any
        pytest.param(False, ("y_cw",), None, marks=pytest.mark.slow),
    ],
)
def test_plan_ranks_the_missing_record_first_on_a_foreign_session(
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    headers: bool,
    removed: tuple[str, ...],
    first: str | None,
) -> None:
    d = _session(tmp_path / "S", headers, removed)
    assert main(["plan", str(d), "--top", "3"]) == 0, capsys.readouterr().err
    out = capsys.readouterr().out
    top = next(line for line in out.splitlines() if line.startswith(" 1 "))
    # the turns per record read from the turns themselves when no header says
    assert first is None or (first in top and "determines" in top), out
    assert re.search(r"y turns, 2 each way +\d+ s +0\.\d+", out) or first is not None, out
