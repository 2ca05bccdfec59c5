"""``calibrate --plan adaptive`` (host/dialogue/adaptive.py): after the method's records the
dialogue measures what the planner names, on the virtual board, and stops at the target."""

from __future__ import annotations

import contextlib
import io
import re
from pathlib import Path

import pytest

from host.dialogue import flow, options
from host.dialogue.console import ScriptedConsole
from host.session.directory import read_session
from host.session.records import STATIC_NAMES, TURN_NAMES
from host.workbench.planner import candidates
from host.workbench.stopping import TURN_PAIRS_MAX


def _run(tmp: Path, **kw: object) -> tuple[str, Path, int]:
    o = options.DialogueOptions(
        port="sim://?seed=9&speed=max", serial="AD1", out=tmp / "AD1", static_seconds=2.0,
        turns=1, warmup_s=0.0, yes=True, ready_s=0.0, plan="adaptive", **kw,  # type: ignore[arg-type]
    )  # fmt: skip
    con = ScriptedConsole()
    with contextlib.redirect_stdout(io.StringIO()):
        rc = flow.run_dialogue(o, con, None)
    return con.text, tmp / "AD1", rc


@pytest.mark.slow
def test_it_measures_what_the_planner_names_until_the_limit(tmp_path: Path) -> None:
    text, out, rc = _run(tmp_path, target=1e-6, max_extra=2)
    assert rc in (0, 1)
    names = set(read_session(out).records)
    # the turn pairs added until the gyro scale met the target (here: the maximum)
    more = {f"{n}_{k}" for n in TURN_NAMES for k in range(2, TURN_PAIRS_MAX + 1)}
    assert more <= names
    extra = names - set(STATIC_NAMES) - set(TURN_NAMES) - {"x_up_2"} - more
    # two records (a face or one turn of a pair each) beyond those and the closing one
    assert len(extra) == 2, names
    menu = {base for c in candidates((2.0, 6.0), 1, tilted=False) for base, *_ in c.records}
    assert all(re.fullmatch(r"[xyz]_(up|dn|ccw|cw)_\d+", n) for n in extra)
    assert {n.rsplit("_", 1)[0] for n in extra} <= menu
    nexts = re.findall(r"Next: (.+?) \(about (\d+) s of your", text)
    assert 1 <= len(nexts) <= 2
    assert "--max-extra 2 reached" in text
    assert all(len(line) <= 80 for line in text.splitlines() if "Adaptive" in line)


@pytest.mark.slow
def test_it_adds_nothing_when_the_target_is_already_met(tmp_path: Path) -> None:
    text, out, rc = _run(tmp_path, target=10.0)
    assert rc in (0, 1)
    assert set(read_session(out).records) == {*STATIC_NAMES, *TURN_NAMES, "x_up_2"}
    assert re.search(r"Adaptive plan: worst σ/tolerance [0-9.e-]+ \(\w+\): target 10 met", text)


def test_bad_plan_options_are_refused_before_the_board() -> None:
    for kw, word in (({"plan": "best"}, "--plan"), ({"target": 0.0}, "--target"),
                     ({"max_extra": -1}, "--max-extra")):  # fmt: skip
        o = options.DialogueOptions(serial="AD1", **kw)  # type: ignore[arg-type]
        with pytest.raises(options.UserError, match=word):
            o.check()
