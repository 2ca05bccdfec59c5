"""``calibrate --plan adaptive`` (host/dialogue/adaptive.py): after the method's records the
dialogue measures what the planner names, on the virtual board, and stops at the target."""

from __future__ import annotations

import contextlib
import io
import math
import re
from collections.abc import Sequence
from pathlib import Path

import pytest

from host.dialogue import flow, options
from host.dialogue.console import ScriptedConsole
from host.model.catalogue import CATALOGUE
from host.model.spec import parse_model
from host.session.directory import read_session
from host.session.method import local_gravity
from host.session.records import STATIC_NAMES, STOPPED_KEY, TURN_NAMES, Record
from host.workbench.adaptive import Stopping, adaptive_run
from host.workbench.planner import Candidate, candidates
from host.workbench.stopping import TURN_PAIRS_MAX, StaticRule
from tests.host.dialogue.flat_options import flat_options


def _run(tmp: Path, **kw: object) -> tuple[str, Path, int]:
    o = flat_options(
        port="sim://?seed=9&noise_seed=9&speed=max&effects=linear,noise", serial="AD1",
        out=tmp / "AD1",
        static_seconds=2.0,
        turns=1, warmup_s=0.0, yes=True, ready_s=0.0, plan="adaptive", **kw,  # type: ignore[arg-type]
    )  # fmt: skip
    con = ScriptedConsole()
    with contextlib.redirect_stdout(io.StringIO()):
        rc = flow.run_dialogue(o, con, None)
    return con.text, tmp / "AD1", rc


@pytest.mark.slow
@pytest.mark.timeout(300)  # ~38 s of CPU alone; over 120 s once on a machine at load 15-20
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
    # each planner record says in its header why it stopped: as long as the planner asked
    # for what (the label the screen named) and the worst σ/tolerance it predicted
    recs = read_session(out).records
    labels = {label for label, _ in nexts}
    for n in extra:
        why = recs[n].meta.get(STOPPED_KEY, "")
        m = re.fullmatch(r"as long as the planner asked \(([0-9.]+) s\): (.+), the worst then "
                         r"\S+ predicted", why)  # fmt: skip
        assert m is not None and m.group(2) in labels, (n, why, labels)
        assert abs(float(m.group(1)) - recs[n].duration_s) < 1.0, (why, recs[n].duration_s)
        assert re.search(rf"{n}: stopped, as long as the planner asked|[xyz] turns: as long",
                         text), n  # fmt: skip
    assert "Target of the adaptive plan, worst σ/tolerance ≤ 1e-06: NOT met" in (
        out / "AD1_result.txt"
    ).read_text(encoding="utf-8")
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
        o = flat_options(serial="AD1", **kw)  # type: ignore[arg-type]
        with pytest.raises(options.UserError, match=word):
            o.check()


@pytest.mark.slow
def test_the_dialogue_measures_what_the_benchmarks_adaptive_run_plans(tmp_path: Path) -> None:
    """On a seeded virtual unit (its linear terms and noise only, so that the target is a
    matter of noise) the dialogue measures axis by axis — the down face, the up face, turn
    pairs about that axis — each face stopping as the pair rule says, and the benchmark's
    :func:`host.workbench.adaptive.adaptive_run`, handed the dialogue's records, asks for the
    same records in the same order and counts the same operator time."""
    target, static_s = 0.005, 60.0
    o = flat_options(
        port="sim://?seed=9&noise_seed=9&speed=max&effects=linear,noise", serial="PR1",
        out=tmp_path / "PR1",
        static_seconds=static_s, turns=1, warmup_s=0.0, yes=True, ready_s=0.0, plan="adaptive",
        target=target, max_extra=2, closing=False,
    )  # fmt: skip
    con = ScriptedConsole()
    with contextlib.redirect_stdout(io.StringIO()):
        assert flow.run_dialogue(o, con, None) in (0, 1), con.text[-2000:]
    saved = re.findall(r"Saved \S+/PR1_(\w+)\.txt", con.text)
    recs = read_session(tmp_path / "PR1").records
    assert sorted(saved) == sorted(recs)

    # the order: axis by axis, each turn pair right after its up face; then the planner's
    pairs = r"(?:{a}_ccw(?:_\d)? {a}_cw(?:_\d)? )+"
    first = "".join(f"{a}_dn {a}_up " + pairs.format(a=a) for a in "xyz")
    assert re.fullmatch(first + r"(?:[xyz]_(?:up|dn|ccw|cw)_\d+ ?){1,2}", " ".join(saved)), saved
    # why each stopped: the down face on its own mean, the up face on the pair's
    # g-sensitivity with the rest its two 7 s turn windows add; the cw turn of each pair
    for a in "xyz":
        down, up = recs[f"{a}_dn"].meta[STOPPED_KEY], recs[f"{a}_up"].meta[STOPPED_KEY]
        assert re.match(r"σ of the mean met its target at \d+ s: gyro \S+ °/s \(", down), down
        assert "with the opposite face and 14 s of turns to come" in up, up
        # the turns to come carry the up face: it needs less rest than its down face
        assert recs[f"{a}_up"].duration_s < recs[f"{a}_dn"].duration_s - 5.0
        cws = [n for n in saved if re.fullmatch(rf"{a}_cw(_\d)?", n)]
        # the pair rule's turns (a planner record's stop says the planner asked for it)
        planned = "as long as the planner asked"
        cws = [n for n in cws if not recs[n].meta.get(STOPPED_KEY, planned).startswith(planned)]
        for n in cws[:-1]:
            assert recs[n].meta[STOPPED_KEY].startswith("another pair follows"), n
        assert re.match(rf"gyro scale σ/tolerance \S+ met the target {target:g}|the maximum",
                        recs[cws[-1]].meta[STOPPED_KEY])  # fmt: skip
    assert re.search(r"stopped, --max-extra 2 reached", con.text)

    # the benchmark's run on the same unit: the dialogue's records are its measuring hand
    asked: list[str] = []

    def measure(c: Candidate, names: Sequence[str]) -> dict[str, Record]:
        asked.extend(names)
        return {n: recs[n] for n in names}

    rule = StaticRule.for_target(target, local_gravity(), max_s=static_s)
    run = adaptive_run(
        measure, parse_model("base", CATALOGUE), target=target, first=[],
        menu=candidates((static_s, 3 * static_s), 1, tilted=False), stopping=Stopping(rule, 1),
        max_operator_s=math.inf, max_extra=2,
    )  # fmt: skip
    assert asked == saved
    for n in saved:  # each face cut where the dialogue stopped it
        assert len(run.records[n]) == len(recs[n]), n
    told = re.search(r"Adaptive plan: about (\d+) s of your time", con.text)
    assert told is not None
    # within 1 s: the dialogue says whole seconds
    assert abs(float(told.group(1)) - run.operator_s) <= 1.0, (told.group(0), run.operator_s)


@pytest.mark.slow
def test_out_of_reach_it_says_so_and_takes_no_longer_than_the_fixed_plan(tmp_path: Path) -> None:
    """On the whole virtual truth (effects the base model lacks: its σ widened by the misfit),
    ``--target 0.05`` is out of reach with the base model: the dialogue says so once it knows
    (after the first records, naming the diagnosis), plans at most two records after that, and
    its records cost the operator no more than the fixed plan's of the same faces and turns
    (counted here from the saved records, in the order saved); the report and the last screen
    say the target was not met."""
    o = flat_options(
        port="sim://?seed=9&noise_seed=9&speed=max", serial="MF1", out=tmp_path / "MF1",
        static_seconds=30.0,
        turns=1, warmup_s=0.0, yes=True, ready_s=0.0, plan="adaptive", target=0.05,
        closing=False,
    )  # fmt: skip
    con = ScriptedConsole()
    with contextlib.redirect_stdout(io.StringIO()):
        assert flow.run_dialogue(o, con, None) in (0, 1), con.text[-2000:]
    text = con.text
    assert "stopped, out of reach with this model: its misfit alone sets" in text.replace(
        "\n  ", " "
    )
    assert f"python3 -m host model diagnose {tmp_path / 'MF1'}" in text
    after = text.split("out of reach with this model")[0]
    assert len(re.findall(r"Next: .+ \(about \d+ s of your", after)) <= 2
    assert not re.findall(r"Next: .+ \(about \d+ s of your", text.split("out of reach")[1])
    # the operator's time of the records saved, counted as method.md's bench is worked: a
    # placement (15 s) unless the cube already rests on that face (a static or a turn leaves
    # it there), 3 s to settle and the record; a turn its 'get ready' (8 s) and its window,
    # the second of a pair placed against the ruler again
    saved = re.findall(r"Saved \S+/MF1_(\w+)\.txt", text)
    recs = read_session(tmp_path / "MF1").records
    spent, up = 0.0, None
    for n in saved:
        r = recs[n]
        u = tuple(float(x) for x in r.up)
        spent += 0.0 if u == up and "_cw" not in n else 15.0
        spent += 3.0 + r.duration_s if r.kind == "static" else 8.0 + 7.0
        up = u
    fixed = 6 * (15.0 + 3.0 + 30.0) + 6 * (15.0 + 8.0 + 7.0)
    assert spent <= fixed, (spent, saved)
    told = re.search(r"about (\d+) s of your time on its records this sitting\s+\(the "
                     r"fixed\s+plan: about (\d+) s\)", text)  # fmt: skip
    assert told is not None and int(told.group(2)) == fixed
    assert abs(int(told.group(1)) - spent) <= 2.0, (told.group(0), spent)
    line = "Target of the adaptive plan, worst σ/tolerance ≤ 0.05: NOT met"
    assert line in (tmp_path / "MF1" / "MF1_result.txt").read_text()
    assert line in "\n".join(text.splitlines()[-24:])
