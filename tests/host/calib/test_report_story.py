"""The first run tells one story (issue 24, item 5): when the model does not fit, the report's
header, its conclusion, the result file and the last line on screen give one conditional
verdict, and the report and the screen give the real next command (``model diagnose`` on the
records' directory). The exit status stays what the tolerances say, under the decision rule
(issue 43: the default, guarded acceptance, makes a value whose ± U reaches across a limit
undecided, not a pass)."""

from __future__ import annotations

import dataclasses
import json
import math
import shlex
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from host.calib.calibration import calibrate_from_records
from host.calib.codec import result_to_json
from host.calib.report import next_command
from host.calib.result import CalibrationResult
from host.session.directory import read_session
from tests.host.cli.cli_run import command_from, run, too_wide
from tests.independent.simulate import SessionSpec, write_session

# the README's session, bit for bit: the unit and the noise its numbers are from
QUICK_START = ["calibrate", "--port", "sim://?seed=0&noise_seed=0&speed=max", "--serial", "DEMO01",
               "--yes", "--warmup", "0", "--static-seconds", "5", "--turns", "1",
               "--no-archive"]  # fmt: skip


def _unwrapped(lines: list[str], start: str) -> str:
    """The line starting (stripped) with ``start``, its wrapped continuation lines joined."""
    i = next(i for i, ln in enumerate(lines) if ln.strip().startswith(start))
    indent = len(lines[i]) - len(lines[i].lstrip())
    out = lines[i].strip()
    for ln in lines[i + 1 :]:
        if len(ln) - len(ln.lstrip()) <= indent or not ln.strip():
            break
        out += " " + ln.strip()
    return out


def _story_of(report: str) -> dict[str, str]:
    """What the report says in its three places: header verdict, its next command, and the
    conclusion's verdict and next command."""
    lines = report.splitlines()
    concl = lines[lines.index("CONCLUSION") + 1 :]
    story = {
        "head": _unwrapped(lines, "Verdict: "),
        "conclusion": _unwrapped(concl, concl[0].strip()),
    }
    head = lines[: lines.index("-" * 80)]  # the head: the lines before the first rule
    for where, part in (("head_next", head), ("conclusion_next", concl[:8])):
        found = any(ln.strip().startswith("Next: ") for ln in part)
        story[where] = _unwrapped(part, "Next: ") if found else ""
    return story


def _ending(err: str) -> list[str]:
    """The lines a run ends on: from the fit story (or the report line) to the verdict."""
    lines = err.rstrip("\n").splitlines()
    start = next(
        (i for i, ln in enumerate(lines) if ln.startswith("The model does not fit")),
        next(i for i, ln in enumerate(lines) if ln.startswith("Report:")),
    )
    return lines[start:]


@pytest.fixture(scope="module")
def quick_start(tmp_path_factory: pytest.TempPathFactory) -> dict[str, object]:
    """The README's quick start on the virtual board, run where a newcomer runs it: the
    records land in ./DEMO01."""
    import os

    here = tmp_path_factory.mktemp("quick")
    cwd = os.getcwd()
    os.chdir(here)
    try:
        rc, out, err = run(QUICK_START)
    finally:
        os.chdir(cwd)
    return {"rc": rc, "out": out, "err": err, "dir": here / "DEMO01"}


def _undecided_by_hand(doc: dict) -> list[str]:
    """The §7 values of a result file whose value ± U reaches across its tolerance: what
    guarded acceptance (ILAC-G8, w = U) marks '?', worked out here from the file — U = k·σ
    with k = 2, or Student's t at 95.45 % on the σ's ``dof`` where the file gives one."""
    from scipy import stats

    out = []
    for p in doc["parameters"]:
        tol, v, se, dof = p["tolerance"], p["value"], p["stderr"], p.get("dof")
        k = 2.0 if dof is None else float(stats.t.isf((1 - math.erf(2 / math.sqrt(2))) / 2, dof))
        if tol is not None and v is not None and se is not None:
            if abs(v) + k * se > tol >= abs(v) - k * se:
                out.append(p["name"])
    return out


@pytest.mark.slow
def test_the_quick_start_ends_on_one_verdict_everywhere(quick_start: dict) -> None:
    d: Path = quick_start["dir"]
    doc = json.loads((d / "DEMO01_result.json").read_text(encoding="utf-8"))
    report = (d / "DEMO01_result.txt").read_text(encoding="utf-8")
    fit = doc["fit"]
    # the simulated bench carries effects the base model lacks: the fit is poor, its standard
    # errors widened, and under the default rule the values whose ± U crosses a limit are '?'
    assert fit["verdict"] == "inadequate" and doc["decision_rule"] == "guarded"
    unsure = _undecided_by_hand(doc)
    assert unsure and sorted(n for n, m in doc["marks"].items() if m == "?") == sorted(unsure)
    assert doc["all_passed"] is False and doc["conditional"] is False
    assert quick_start["rc"] == 1  # a '?' is not a pass
    verdict = doc["verdict"]
    assert verdict.startswith("FAIL: ") and verdict.endswith("; the model does not fit")
    assert all(n in verdict for n in unsure[:3]) and "undecided" in verdict
    assert "Decision rule: guarded acceptance" in report

    # one verdict in every place: the screen's last line, the report's head and conclusion
    ending = _ending(str(quick_start["err"]))
    story = _story_of(report)
    assert ending[-1] == verdict
    assert story["head"] == f"Verdict: {verdict} (RESULT below)"
    assert story["conclusion"] == verdict
    # the report printed on stdout is the one written
    assert str(quick_start["out"]).endswith(report)

    # one next command in every place, on the directory the records are in (./DEMO01)
    nxt = "python3 -m host model diagnose DEMO01"
    assert f"Next: {nxt}" in ending
    assert story["head_next"] == story["conclusion_next"] == f"Next: {nxt} (what the model lacks)"
    assert f"Find it: {nxt}" in " ".join(ln.strip() for ln in report.splitlines())
    # what the misfit means, before the verdict; and the mark right above it
    assert ending[0].startswith(f"The model does not fit these records (RMS z {fit['rms_z']:.2f}")
    assert ending[-3:-1] == [  # the URL is too long for the mark's line: it follows whole
        "*** SIMULATED BOARD: not a measurement of a unit ***",
        f"    {QUICK_START[2]}",
    ]
    assert f"Report: {Path('DEMO01') / 'DEMO01_result.txt'}" in ending
    assert all(len(ln) <= 80 for ln in ending), ending
    assert all(len(ln) <= 80 for ln in report.splitlines())
    # a unit that did not pass does not leave the bench
    rc, parm, err = run(["export", str(d / "DEMO01_result.json"), "--to", "ardupilot"])
    assert rc == 1 and parm == "" and "undecided under guarded acceptance" in err


def test_under_simple_acceptance_the_quick_start_is_a_conditional_pass(
    quick_start: dict, tmp_path: Path
) -> None:
    """The same records judged by simple acceptance (U not used): every value is within
    tolerance as fitted, so a PASS, conditional on a model that does not fit, told alike in
    every place and carried by an export."""
    d: Path = quick_start["dir"]
    rc, _, err = run(["calibrate", "--from-dir", str(d), "--out", str(tmp_path),
                      "--decision-rule", "simple", "--no-archive"])  # fmt: skip
    doc = json.loads((tmp_path / "DEMO01_result.json").read_text(encoding="utf-8"))
    report = (tmp_path / "DEMO01_result.txt").read_text(encoding="utf-8")
    fit = doc["fit"]
    assert doc["decision_rule"] == "simple" and "?" not in doc["marks"].values()
    assert doc["all_passed"] is True and doc["conditional"] is True and rc == 0
    verdict = doc["verdict"]
    assert verdict == f"PASS (conditional: the model does not fit, RMS z {fit['rms_z']:.2f})"
    ending = _ending(err)
    story = _story_of(report)
    assert ending[-1] == verdict == story["conclusion"]
    assert story["head"] == f"Verdict: {verdict} (RESULT below)"
    assert "conditional" in " ".join(ending[:-1])
    assert "Decision rule: simple acceptance" in report
    rc, parm, _ = run(["export", str(tmp_path / "DEMO01_result.json"), "--to", "ardupilot"])
    assert rc == 0 and f"# *** {verdict} ***" in parm.splitlines()[:4]


@pytest.mark.slow
def test_the_next_command_runs_and_finds_the_same_misfit(
    quick_start: dict, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The command the screen names runs as given, from where the quick start ran, and the
    workbench reads the same RMS z the verdict quotes."""
    d: Path = quick_start["dir"]
    argv = command_from(_ending(str(quick_start["err"])))
    assert argv[:4] == ["python3", "-m", "host", "model"]
    monkeypatch.chdir(d.parent)
    rc, out, _ = run(argv[3:] + ["--brief"])
    doc = json.loads((d / "DEMO01_result.json").read_text(encoding="utf-8"))
    assert rc == 0 and f"fit: RMS z = {doc['fit']['rms_z']:.2f} " in out
    # and its own next commands name the same directory, not a placeholder
    said = [ln.strip() for ln in out.splitlines()]
    tries = [ln for ln in said if ln.startswith(("to see one:", "try:"))]
    assert tries and all("python3 -m host model add DEMO01 " in t for t in tries), tries


@pytest.mark.slow
def test_a_model_that_fits_gives_a_plain_verdict_and_no_next_command(tmp_path: Path) -> None:
    """The independent simulator with nothing hidden: the fit is not inadequate; the verdict
    is the plain one everywhere and nothing sends the user to the workbench."""
    d = tmp_path / "ctrl"
    write_session(d, SessionSpec(seed=7, effect="none"))
    rc, _, err = run(["calibrate", "--from-dir", str(d), "--no-archive"])
    doc = json.loads((d / "IND01_result.json").read_text(encoding="utf-8"))
    assert doc["fit"]["verdict"] != "inadequate" and doc["conditional"] is False
    assert rc == 0 and doc["verdict"] == "PASS: every value within tolerance"
    story = _story_of((d / "IND01_result.txt").read_text(encoding="utf-8"))
    ending = _ending(err)  # a path too long for its label's line follows on its own
    assert ending[-1] == doc["verdict"]
    assert " ".join(ln.strip() for ln in ending[:-1]) == f"Report: {d / 'IND01_result.txt'}"
    assert story["head"] == f"Verdict: {doc['verdict']} (RESULT below)"
    assert story["conclusion"] == doc["verdict"]
    assert story["head_next"] == story["conclusion_next"] == ""
    rc, parm, _ = run(["export", str(d / "IND01_result.json"), "--to", "ardupilot"])
    assert rc == 0 and "PASS" not in parm and "conditional" not in parm


@pytest.mark.slow
def test_a_hidden_step_names_the_records_directory_not_the_output(tmp_path: Path) -> None:
    """A gyro bias step between records (independent simulator) read from a directory whose
    name needs quoting, the results written elsewhere (--out): the next command names the
    records' directory, quoted so a shell gives it back whole; a FAIL on a poor fit keeps
    its exit status 1 and says the misfit among its reasons."""
    rec = tmp_path / "step records"
    write_session(rec, SessionSpec(seed=7, effect="bias_step_gyro"))
    out = tmp_path / "out"
    out.mkdir()
    rc, _, err = run(["calibrate", "--from-dir", str(rec), "--out", str(out), "--no-archive"])
    doc = json.loads((out / "IND01_result.json").read_text(encoding="utf-8"))
    assert doc["fit"]["verdict"] == "inadequate"
    ending = _ending(err)
    words = command_from(ending)
    assert words == ["python3", "-m", "host", "model", "diagnose", str(rec)]
    text = (out / "IND01_result.txt").read_text(encoding="utf-8")
    story = _story_of(text)
    concl = text.splitlines()[text.splitlines().index("CONCLUSION") :]
    assert command_from(text.splitlines()) == command_from(concl) == words
    assert ending[-1] == doc["verdict"] == story["conclusion"]
    assert rc == (0 if doc["all_passed"] else 1)

    # the same records judged against tighter limits: FAIL, and the misfit is a reason
    res = calibrate_from_records(read_session(rec))
    failed = dataclasses.replace(res, self_test="fail", decision_rule="simple")
    assert failed.verdict().startswith("FAIL: the sensor failed its self-test; ")
    assert failed.verdict().endswith("; the model does not fit")
    assert not failed.conditional and json.loads(result_to_json(failed))["conditional"] is False


_result_cache: list[CalibrationResult] = []


def _inadequate(tmp: Path) -> CalibrationResult:
    if not _result_cache:
        write_session(tmp, SessionSpec(seed=3, effect="none"))
        r = calibrate_from_records(read_session(tmp))
        assert r.fit is not None
        _result_cache.append(
            dataclasses.replace(r, fit=dataclasses.replace(r.fit, verdict="inadequate"))
        )
    return _result_cache[0]


@settings(max_examples=60, deadline=None)
@given(name=st.text(st.characters(blacklist_categories=("Cs", "Cc")), min_size=1, max_size=30))
@pytest.mark.slow
def test_any_directory_name_comes_back_whole_from_the_next_command(
    tmp_path_factory: pytest.TempPathFactory, name: str
) -> None:
    r = _inadequate(tmp_path_factory.mktemp("any"))
    words = shlex.split(next_command(r, name))
    assert words == ["python3", "-m", "host", "model", "diagnose", name]
    custom = dataclasses.replace(r, model="base,lever_arm:accel", term_files=("my terms.py",))
    words = shlex.split(next_command(custom, name))
    assert words[5:] == [name, "--model", "base,lever_arm:accel", "--term-file", "my terms.py"]


def _noise_file(path: Path) -> Path:
    """A noise file (format of ``noise --save``): white noise and a bias instability on each
    axis, larger than the independent simulator's records carry."""
    chans = {
        c: {
            "white_noise_density": {"value": 0.01, "ci": [0.009, 0.011], "unit": "u"},
            "bias_instability": {"value": b, "ci": [0.9 * b, 1.1 * b], "unit": "u"},
            "rate_random_walk": {"value": 0.0, "ci": [0.0, 0.0], "unit": "u"},
        }
        for c, b in zip(("ax", "ay", "az", "gx", "gy", "gz"), (4e-4,) * 3 + (6e-3,) * 3,
                        strict=True)
    }  # fmt: skip
    path.write_text(json.dumps({"format": "imu-bench noise", "format_version": 1,
                                "channels": chans}), encoding="utf-8")  # fmt: skip
    return path


def _misfit_with(tmp: Path, given: list[str]) -> tuple[dict, list[str], Path]:
    """A gyro bias step (independent simulator) calibrated with the floor options ``given``:
    the result file, the words of the screen's next command and the records' directory."""
    rec = tmp / "step records"
    if not rec.is_dir():
        write_session(rec, SessionSpec(seed=7, effect="bias_step_gyro"))
    for f in rec.glob("IND01_result.*"):
        f.unlink()
    rc, _, err = run(["calibrate", "--from-dir", str(rec), "--no-archive", *given])
    doc = json.loads((rec / "IND01_result.json").read_text(encoding="utf-8"))
    assert doc["fit"]["verdict"] == "inadequate", err
    words = command_from(_ending(err))
    report = (rec / "IND01_result.txt").read_text(encoding="utf-8").splitlines()
    assert command_from(report) == words  # the report's head names the same command
    return doc, words, rec


FLOORS = [["--floor", "accel=5e-4,gyro=3e-3"], ["--noise", "unit noise.json"],
          ["--noise", "unit noise.json", "--floor", "gyro=0.02"]]  # fmt: skip


@pytest.mark.parametrize("given", FLOORS, ids=" ".join)
@pytest.mark.slow
def test_the_next_command_repeats_the_floor_the_fit_was_judged_on(
    tmp_path: Path, given: list[str]
) -> None:
    """Calibrated with --floor or --noise, the result file says where its floor came from and
    the next command (screen and report) repeats those options, quoted, so the workbench
    judges the fit on the same yardstick; without them it names none."""
    import os

    _noise_file(tmp_path / "unit noise.json")
    cwd = os.getcwd()
    os.chdir(tmp_path)  # the noise file as a user names it, relative to where they are
    try:
        doc, words, rec = _misfit_with(tmp_path, given)
        plain, plain_words, _ = _misfit_with(tmp_path, [])
    finally:
        os.chdir(cwd)
    opts = dict(zip(given[::2], given[1::2], strict=True))
    assert doc["floor_source"] == {k.removeprefix("--"): v for k, v in opts.items()}
    assert words[:6] == ["python3", "-m", "host", "model", "diagnose", str(rec)]
    assert words[6:] == [w for k in ("--noise", "--floor") if k in opts for w in (k, opts[k])]
    assert plain["floor_source"] == {} and plain_words[6:] == []
    # the floor it names is the one the fit used: another yardstick, another RMS z
    assert doc["fit"]["rms_z"] != pytest.approx(plain["fit"]["rms_z"], rel=0.05)


@pytest.mark.slow
def test_the_repeated_floor_gives_the_workbench_the_same_rms_z(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The next command, run as printed, reads the RMS z the verdict quotes."""
    _noise_file(tmp_path / "unit noise.json")
    monkeypatch.chdir(tmp_path)
    doc, words, _ = _misfit_with(tmp_path, FLOORS[2])
    rc, out, _ = run(words[3:] + ["--brief"])
    assert rc == 0 and f"fit: RMS z = {doc['fit']['rms_z']:.2f} " in out


def test_a_long_path_leaves_only_itself_past_80_columns(tmp_path: Path) -> None:
    """Records in a directory whose path is longer than a line (and has a space): the screen's
    last lines and the report break every line but the path itself within 80 columns; the
    next command, broken with \\, runs as printed with the same words."""
    rec = tmp_path / ("the records of unit seven from " + "the second bench " * 5).strip()
    write_session(rec, SessionSpec(seed=7, effect="bias_step_gyro"))
    _noise_file(tmp_path / "noise.json")
    rc, out, err = run(["calibrate", "--from-dir", str(rec), "--no-archive",
                        "--noise", str(tmp_path / "noise.json")])  # fmt: skip
    report = (rec / "IND01_result.txt").read_text(encoding="utf-8")
    assert len(str(rec)) > 80 and rc in (0, 1)  # '?' where a σ on few dof widens U
    assert too_wide(err) == [] and too_wide(report) == [] and too_wide(out) == []
    want = ["python3", "-m", "host", "model", "diagnose", str(rec), "--noise",
            str(tmp_path / "noise.json")]  # fmt: skip
    lines = report.splitlines()
    concl = lines[lines.index("CONCLUSION") :]
    for said in (err.splitlines(), lines, concl):
        assert command_from(said) == want
    find = next(i for i, ln in enumerate(lines) if ln.endswith(" Find it:"))
    assert command_from(lines[find + 1 :], "") == want
    # the report's path whole on its own line, after its label
    ending = _ending(err)
    i = ending.index("Report:")
    assert shlex.split(ending[i + 1]) == [str(rec / "IND01_result.txt")]
