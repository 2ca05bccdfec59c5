"""Resume exactly (issue 18): the printed command carries every option and answer, ``--redo
NAME`` re-measures one record, a record kept despite a warning is carried into the report with
it, and a session that cannot use a record names it with the command that re-measures it.
In-process dialogue against ``sim://`` at ``speed=max`` (see test_flow.py)."""

from __future__ import annotations

import contextlib
import io
import json
import shlex
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from host.dialogue import options
from host.dialogue.console import CTRL_C, ScriptedConsole
from host.errors import UserError
from host.session.directory import read_record
from host.session.records import STATIC_NAMES, TURN_NAMES
from tests.host.cli.cli_run import command_after, too_wide
from tests.host.dialogue.flat_options import flat, options_of, with_options
from tests.host.dialogue.test_flow import LINEAR, Ports, run
from tests.host.dialogue.test_flow import opts as live_opts


def opts(tmp_path: Path, url: str, **kw: Any) -> options.DialogueOptions:
    """test_flow's options for unit F1: 2 s statics, one turn each way."""
    short: dict[str, Any] = dict(serial="F1", out=tmp_path / "F1", static_seconds=2.0, turns=1)
    return live_opts(tmp_path, url, **{**short, **kw})


# --------------------------------------------------------------------------- checks first


def test_yes_with_resume_needs_no_static_seconds_when_the_statics_are_kept(
    tmp_path: Path,
) -> None:
    from host.bench.plan import Plan, simulate_session, write_session
    from host.bench.truth import SensorTruth

    recs = simulate_session(SensorTruth.ideal(), Plan(static_s=2.0, turns=1), seed=1)
    write_session(tmp_path / "F1", "F1", {n: r for n, r in recs.items() if n in STATIC_NAMES})
    o = opts(tmp_path, "sim://", static_seconds=None, resume=True)
    o.check()  # nothing static to measure: no question to answer
    o = with_options(o, redo=("y_dn",))
    o.check()  # a static measured again takes the kept statics' length (said, not asked)
    o = with_options(o, redo=STATIC_NAMES)  # none kept: nothing says how long
    with pytest.raises(UserError, match="--static-seconds"):
        o.check()


def test_an_output_directory_that_cannot_be_one_fails_before_the_board(tmp_path: Path) -> None:
    (tmp_path / "afile").write_text("x")
    for out in (tmp_path / "afile", tmp_path / "afile" / "sub"):
        ports = Ports()
        with pytest.raises(UserError, match=r"output directory .*afile.*choose"):
            run(opts(tmp_path, f"sim://?{LINEAR}", out=out, warmup_s=600.0), ScriptedConsole(),
                ports)  # fmt: skip
        assert ports.opened == []


def test_an_output_directory_where_nothing_can_be_written_fails_before_the_board() -> None:
    ports = Ports()
    out = Path("/proc/imu-bench-no-such-dir/F1")  # not writable, even for root
    with pytest.raises(UserError, match=r"output directory /proc/.*/F1: cannot write there"):
        run(opts(Path(), f"sim://?{LINEAR}", out=out), ScriptedConsole(), ports)
    assert ports.opened == []


# --------------------------------------------------------------------------- resume exactly


def test_ctrl_c_prints_a_command_with_every_option_and_the_answers(tmp_path: Path) -> None:
    """Options given (turns, warm-up, site, model) and answered at the prompts (the
    accumulation time) are all in the printed command, quoted so that an output directory
    with spaces pastes back as it was: resuming asks nothing again."""
    keys = ["y", "3\r", " ", "y", " ", CTRL_C]  # statics, 3 s, x_up saved, Ctrl+C in x_dn
    con = ScriptedConsole(keys)
    url = f"sim://?seed=6&noise_seed=6&{LINEAR}"
    out = tmp_path / "my unit's data" / "F1"
    o = opts(tmp_path, url, out=out, yes=False, static_seconds=None, turns=1, warmup_s=12.5,
             ready_s=0.25, latitude_deg=48.137, height_m=300.0,
             model="base,temperature_bias")  # fmt: skip
    rc, _ = run(o, con, Ports())
    assert rc == 130
    assert "Aborted (Ctrl+C): the measurement in progress is discarded." in con.text
    again = flat(options_of(shlex.join(command_after(con.text))))
    assert again.resume and again.port == url and again.serial == "F1"
    assert again.out == out
    assert (again.static_seconds, again.turns, again.warmup_s, again.ready_s) == (
        3.0, 1, 12.5, 0.25,
    )  # fmt: skip
    assert (again.latitude_deg, again.height_m) == (48.137, 300.0)
    assert again.model == "base,temperature_bias" and not again.yes


@pytest.mark.slow
def test_redo_measures_one_record_again_and_keeps_the_others(tmp_path: Path) -> None:
    url = f"sim://?seed=11&noise_seed=11&{LINEAR}"
    assert run(opts(tmp_path, url), ScriptedConsole(), Ports())[0] in (0, 1)
    out = tmp_path / "F1"
    before = {p.name: p.read_bytes() for p in out.glob("F1_*_*.txt")}
    assert len(before) == 13  # with the closing check, kept like the others
    con = ScriptedConsole()
    rc, stdout = run(opts(tmp_path, url, redo=("y_cw",)), con, Ports())
    assert rc in (0, 1) and "TEST REPORT" in stdout
    assert "Measuring again: y_cw (--redo)" in con.text
    starts = ("Turn now! ", "Measuring x", "Measuring y", "Measuring z")
    started = [ln.split(":")[0] for ln in con.text.splitlines() if ln.startswith(starts)]
    assert started == ["Turn now! y_cw"]
    after = {p.name: p.read_bytes() for p in out.glob("F1_*_*.txt")}
    assert after["F1_y_cw.txt"] != before["F1_y_cw.txt"]
    assert {k: v for k, v in after.items() if k != "F1_y_cw.txt"} == {
        k: v for k, v in before.items() if k != "F1_y_cw.txt"
    }


def test_a_resume_hint_keeps_to_80_columns_and_pastes_back_whatever_the_path(
    tmp_path: Path,
) -> None:
    """Was: '… continue with: python3 -m host calibrate … --out DIR …' as one line of 200
    columns when --out was long, and the command left out the adaptive plan, the operator,
    the bench and the archive (a resumed session planned and archived otherwise). Now the
    command is on lines of its own, only the path passes 80 columns, and a shell reads back
    every option, the path with its spaces and commas too."""
    out = tmp_path / ("a long directory, with spaces and a comma, " * 2) / "F1"
    url = f"sim://?seed=6&noise_seed=6&{LINEAR}"
    o = opts(tmp_path, url, out=out, yes=False, plan="adaptive", target=0.08, max_extra=3,
             operator="Ann Lee", bench="B2", lot="L7", archive=str(tmp_path / "a.sqlite"),
             pdf=True)  # fmt: skip
    con = ScriptedConsole(["y", " ", "y", " ", CTRL_C])  # statics, x_up saved, Ctrl+C in x_dn
    rc, _ = run(o, con, Ports())
    assert rc == 130 and list(out.glob("F1_*_*.txt"))  # a record kept (the plan's first)
    hint = con.text.split("Aborted (Ctrl+C)", 1)[1]  # the prose before: wrapped on screen
    assert too_wide(hint) == [], hint
    again = flat(options_of(shlex.join(command_after(con.text))))
    assert again.out == out and again.resume and again.port == url
    assert (again.plan, again.target, again.max_extra) == ("adaptive", 0.08, 3)
    assert (again.operator, again.bench, again.lot, again.pdf) == ("Ann Lee", "B2", "L7", True)
    assert again.archive == str(tmp_path / "a.sqlite")


@pytest.mark.slow
def test_a_turn_kept_despite_its_warning_ends_with_the_record_to_redo(tmp_path: Path) -> None:
    """'Save anyway' on an incomplete turn: the record keeps the warning in its header; the
    results cannot use it, and the session says which record to redo and the exact command;
    that command then ends with a report."""
    keys = ["y"] + [" ", "y"] * 6  # the statics
    keys += ["y"]  # on to the turns
    keys += [" ", "n"]  # x_ccw incomplete: save anyway
    keys += [" ", "y"] * 5
    keys += [" ", "y"]  # the closing check (x_up again)
    url = f"sim://?seed=12&noise_seed=12&{LINEAR}&operator_fault=incomplete_turn@1"
    con = ScriptedConsole(keys)
    with pytest.raises(UserError) as e:
        run(opts(tmp_path, url, yes=False, out=tmp_path / "a b" / "F1"), con, Ports())
    msg = str(e.value)
    assert "F1_x_ccw.txt" in msg and "measure x_ccw again" in " ".join(msg.split())
    assert "--resume" not in msg  # one command, the one that helps
    header = read_record(tmp_path / "a b" / "F1" / "F1_x_ccw.txt").meta
    assert "turn" in header["warning"]
    said = command_after(msg, "with:")
    again = options_of(shlex.join(said))
    read = flat(again)
    assert read.redo == ("x_ccw",) and read.static_seconds == 2.0 and read.turns == 1
    # --resume (everything measured) does not stop on the bare error either: it names the redo
    resumed = options_of(shlex.join([*said[:-2], "--resume"]))
    resumed = with_options(resumed, yes=True)
    with pytest.raises(UserError) as e2:
        run(resumed, ScriptedConsole(), Ports())
    assert "measure x_ccw again" in " ".join(str(e2.value).split())
    assert command_after(str(e2.value), "with:")[-2:] == ["--redo", "x_ccw"]
    assert read.out == tmp_path / "a b" / "F1"
    # the same bench, without the operator's fault
    again = with_options(again, yes=True, port=f"sim://?seed=12&noise_seed=12&{LINEAR}")
    rc, stdout = run(again, ScriptedConsole(), Ports())
    assert rc in (0, 1) and "TEST REPORT" in stdout
    assert "warning" not in read_record(tmp_path / "a b" / "F1" / "F1_x_ccw.txt").meta


def test_from_dir_names_the_record_to_redo(tmp_path: Path) -> None:
    from host.__main__ import main
    from host.bench.plan import Plan, simulate_session, write_session
    from host.bench.truth import SensorTruth

    recs = simulate_session(SensorTruth.ideal(), Plan(static_s=2.0, turns=1), seed=4)
    bad = recs["y_ccw"]
    recs["y_ccw"] = type(bad)(bad.name, bad.t_ms, bad.accel, bad.gyro * 0.8, bad.temp, bad.meta)
    d = tmp_path / ("a directory name long enough to pass 80 columns, " * 2) / "x y"
    write_session(d, "R1", recs)
    err = io.StringIO()
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(err):
        assert main(["calibrate", "--from-dir", str(d)]) == 2
    msg = err.getvalue()
    assert "R1_y_ccw.txt" in msg and "measure y_ccw again" in " ".join(msg.split())
    assert too_wide(msg) == []  # only the path may pass 80 columns, on a line of its own
    argv = command_after(msg, "with:")
    assert argv[argv.index("--out") + 1] == str(d) and argv[-2:] == ["--redo", "y_ccw"]


def test_a_record_kept_despite_a_warning_is_in_the_report_with_it(tmp_path: Path) -> None:
    from host.__main__ import main
    from host.bench.plan import Plan, simulate_session, write_session
    from host.bench.truth import SensorTruth

    recs = simulate_session(SensorTruth.random(np.random.default_rng(2)), Plan(static_s=2.0,
                            turns=1), seed=2)  # fmt: skip
    recs["y_up"].meta["warning"] = "2.1 % of the samples of y_up were lost (limit 1 %)"
    write_session(tmp_path, "W1", recs)
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        assert main(["calibrate", "--from-dir", str(tmp_path)]) in (0, 1)
    text = " ".join((tmp_path / "W1_result.txt").read_text().split())
    note = "y_up kept despite a warning: 2.1 % of the samples of y_up were lost (limit 1 %)"
    assert note in text
    assert [n for n in TURN_NAMES + STATIC_NAMES if f"{n} kept despite" in text] == ["y_up"]
    assert note in json.loads((tmp_path / "W1_result.json").read_text())["notes"]


@pytest.mark.slow
def test_redo_asks_neither_the_warm_up_nor_the_accumulation_time_again(tmp_path: Path) -> None:
    """--redo (and --resume) with records kept: no second warm-up (and, the first sitting
    having recorded none, no claim of a warm unit), and the accumulation time is that of the
    kept statics, said, not asked: the operator typed only --redo x_up."""
    url = f"sim://?seed=12&noise_seed=12&{LINEAR}"
    assert run(opts(tmp_path, url, static_seconds=3.0), ScriptedConsole(), Ports())[0] in (0, 1)
    con = ScriptedConsole()
    o = opts(tmp_path, url, redo=("x_up",), static_seconds=None, warmup_s=600.0)
    rc, _ = run(o, con, Ports())
    assert rc in (0, 1)
    # the first sitting made no warm-up: the line does not claim a warm unit
    assert "No warm-up: records are kept, and no whole warm-up was recorded" in con.text
    assert "measured on a warm unit" not in con.text
    assert "warm-up; recorded" not in con.text and "Accumulation time per" not in con.text
    # the turns kept: said as --redo keeps them, not as --resume
    assert "The six turns are already measured (kept: --redo measures x_up only)." in con.text
    assert "(--resume)" not in con.text
    assert "Accumulation time 3 s per orientation, as the kept records" in con.text
    rec = read_record(tmp_path / "F1" / "F1_x_up.txt")
    assert abs(rec.duration_s - 3.0) < 0.2


@pytest.mark.slow
def test_a_whole_warm_up_recorded_before_the_kept_records_is_said(tmp_path: Path) -> None:
    """A first sitting whose warm-up ran to its end (its record is in the directory): the
    sitting that keeps its records says they were measured on a warm unit."""
    url = f"sim://?seed=12&noise_seed=12&{LINEAR}"
    first = opts(tmp_path, url, static_seconds=3.0, warmup_s=2.0)
    assert run(first, ScriptedConsole(), Ports())[0] in (0, 1)
    assert (tmp_path / "F1" / "F1_warmup.txt").exists()
    con = ScriptedConsole()
    rc, _ = run(opts(tmp_path, url, redo=("x_up",), static_seconds=None, warmup_s=600.0), con,
                Ports())  # fmt: skip
    assert rc in (0, 1)
    assert "No warm-up: the kept records were measured on a warm unit" in con.text
