"""``calibrate --plan adaptive --resume`` (issues 30 and 31): a session cut after an extra turn
pair or after a planner's record continues with every record of the sitting — those named
``x_ccw_2`` … and the planner's ``…_3`` too — and the next record is the one the adaptive
plan's engine asks for given them; no accepted record is measured again or moved aside."""

from __future__ import annotations

import contextlib
import hashlib
import io
import json
import re
from collections.abc import Callable
from pathlib import Path

import pytest

from host.dialogue import flow, options
from host.dialogue.adaptive import adaptive_plan
from host.dialogue.console import ScriptedConsole
from host.session.directory import EARLIER_DIR, read_record, read_session
from host.session.method import local_gravity
from tests.host.dialogue.flat_options import flat_options

UNIT_URL = "sim://?seed=9&noise_seed=9&speed=max&effects=linear,noise&earth_rate=0"
SERIAL = "AR1"
STATIC_S = 2.0
#: the planner's records a session may add: two show that --max-extra counts both sittings'
#: (one before the cut, one after) as well as four did, at half the planner's steps (each a
#: fit of every candidate record, ~2 s: most of this file's time)
MAX_EXTRA = 2


class CutAfter(ScriptedConsole):
    """A console whose operator presses Ctrl+C at the first line shown once ``cut(text)``
    holds (with ``--yes`` no key is read: the interrupt comes as the terminal's would)."""

    def __init__(self, cut: Callable[[str], bool]) -> None:
        super().__init__()
        self.cut = cut
        self.fired = False

    def say(self, text: str = "") -> None:
        if not self.fired and self.cut(self.text):
            self.fired = True
            raise KeyboardInterrupt
        super().say(text)


def _opts(out: Path, **kw: object) -> options.DialogueOptions:
    return flat_options(
        # a unit the base model fits: the target is out of reach by noise, not misfit, so the
        # planner measures until --max-extra (one with misfit stops at once, issue 46)
        port=UNIT_URL, serial=SERIAL, out=out, static_seconds=STATIC_S,
        turns=1, warmup_s=0.0, yes=True, ready_s=0.0, plan="adaptive", target=1e-6,
        **{"max_extra": MAX_EXTRA, **kw},  # type: ignore[arg-type]
    )  # fmt: skip


def _run(o: options.DialogueOptions, con: ScriptedConsole) -> int:
    with contextlib.redirect_stdout(io.StringIO()):
        return flow.run_dialogue(o, con, None)


def _saved(text: str) -> list[str]:
    """The records saved, in the order the dialogue saved them (its own lines)."""
    return re.findall(rf"Saved \S+/{SERIAL}_(\w+)\.txt", text)


def _planners(text: str) -> int:
    """The planner's records a sitting saved: those after its first "Next:" line."""
    told = text.split("Next: ", 1)
    return len(_saved(told[1])) if len(told) > 1 else 0


def _hashes(out: Path) -> dict[str, str]:
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in out.glob(f"{SERIAL}_*")}


def _after_extra_pair(text: str) -> bool:
    return f"{SERIAL}_x_cw_2.txt" in text


def _within_an_extra_pair(text: str) -> bool:
    return f"{SERIAL}_x_ccw_2.txt" in text  # its cw turn not yet measured


def _after_a_planner_record(text: str) -> bool:
    # the planner's first record saved and fitted: its next step is about to be said
    return "Next: " in text and "Adaptive plan: worst" in text.split("Next: ", 1)[1]


@pytest.mark.slow
@pytest.mark.timeout(300)  # two sittings, a fit per planner step: 80 s alone at load 20
@pytest.mark.parametrize("cut", [_within_an_extra_pair, _after_extra_pair, _after_a_planner_record])
def test_a_resumed_adaptive_session_keeps_every_record_and_asks_the_engine(
    tmp_path: Path, cut: Callable[[str], bool]
) -> None:
    out = tmp_path / SERIAL
    first = CutAfter(cut)
    assert _run(_opts(out), first) == 130, first.text[-1500:]
    order = _saved(first.text)
    assert any(re.fullmatch(r"[xyz]_(ccw|cw)_2", n) for n in order), order  # an extra turn
    before = _hashes(out)
    assert {f"{SERIAL}_{n}.txt" for n in order} <= set(before)

    # what the engine asks for next, given those records in the order they were measured
    o = _opts(out, resume=True)
    plan = adaptive_plan(o, SERIAL, local_gravity(), STATIC_S, 1)
    recs = {n: read_record(out / f"{SERIAL}_{n}.txt") for n in order}
    taken = (options.CLOSING_NAME,)
    ask = plan.next_first(recs, taken)
    added = _planners(first.text)
    if ask is None:  # the first records are done: the planner's turn
        _, ask, why = plan.planned(recs, 0.0, taken, added)
        assert ask is not None, why
    assert not set(ask.names) & set(order)  # a new name, never an accepted record's

    again = ScriptedConsole()
    assert _run(o, again) in (0, 1), again.text[-1500:]
    resumed = _saved(again.text)
    assert tuple(resumed[: len(ask.names)]) == ask.names, (resumed, ask.names)
    assert not set(resumed) & set(order)  # nothing measured again
    # kept: every record of the sitting, in the order measured (the engine's order matters)
    kept = re.search(r"Resuming: kept (.+?)\n(?!  )", again.text, re.S)
    assert kept is not None and re.split(r",\s+", kept.group(1).strip()) == order
    long = [ln for ln in again.text.splitlines() if len(ln) > 80 and str(out) not in ln]
    assert not [ln for ln in long if ln.startswith(("Resuming", "  ", "Adaptive"))], long
    # --max-extra counts the planner's records of both sittings
    said = f"goes on from the {len(order)} records kept, {added} of them the planner's"
    assert said in again.text
    assert f"--max-extra {MAX_EXTRA} reached" in again.text
    assert MAX_EXTRA <= added + _planners(again.text) <= MAX_EXTRA + 1  # a pair: one over
    # every earlier record's bytes unchanged, where they were; nothing moved aside
    after = _hashes(out)
    assert {k: after.get(k) for k in before} == before
    assert not (out / EARLIER_DIR).exists()
    # the result is computed over all of them
    assert set(order) | set(resumed) <= set(read_session(out, SERIAL).records)
    result = json.loads((out / f"{SERIAL}_result.json").read_text())
    assert set(order) | set(resumed) <= set(result["records"])


@pytest.mark.slow
def test_redo_measures_a_repeat_again_by_its_name_and_keeps_the_earlier_aside(
    tmp_path: Path,
) -> None:
    """``--redo x_ccw_2`` (the name a failed check gives): the engine would never ask for that
    name again, so the record was not measured and the results failed on it once more; now it
    is measured first, the earlier file is kept aside unchanged, nothing else is touched."""
    out = tmp_path / SERIAL
    con = ScriptedConsole()
    assert _run(_opts(out, max_extra=0, closing=False), con) in (0, 1), con.text[-1500:]
    assert "x_ccw_2" in _saved(con.text)
    before = _hashes(out)
    again = ScriptedConsole()
    assert _run(_opts(out, max_extra=0, closing=False, redo=("x_ccw_2",)), again) in (0, 1)
    assert _saved(again.text)[0] == "x_ccw_2"
    assert "Turn now! x_ccw_2" in again.text
    after = _hashes(out)
    old = f"{SERIAL}_x_ccw_2.txt"
    assert after[old] != before[old]
    (aside,) = (out / EARLIER_DIR).iterdir()
    assert _hashes(aside) == {old: before[old]}
    kept = [k for k in before if k != old and "_result." not in k]  # the result is new
    assert {k: after.get(k) for k in kept} == {k: before[k] for k in kept}
    assert json.loads((out / f"{SERIAL}_result.json").read_text())["records"].count("x_ccw_2") == 1
