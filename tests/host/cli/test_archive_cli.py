"""``python3 -m host archive`` (host/cli/archive.py): a result calibrate wrote goes in once,
comes back by serial, the checks answer with their exit codes, bad options are one line."""

from __future__ import annotations

import csv
import hashlib
import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from host.__main__ import main
from host.archive.store import Archive
from host.calib.publish import ComputeSettings, compute_and_write
from host.cli.archive import parse_tolerances
from host.errors import UserError
from host.session.directory import read_session
from tests.host.archive.lot_sim import simulate_lot
from tests.host.cli.cli_run import pasted, too_wide
from tests.host.sim_sessions import write_sim_session


@pytest.fixture(scope="module")
def calibrated(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = write_sim_session(tmp_path_factory.mktemp("cli") / "C1", "C1", seed=31)
    compute_and_write(read_session(d, None), d, ComputeSettings())
    return d


def test_add_twice_list_show(
    calibrated: Path, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    db = str(tmp_path / " ".join(["a deep folder of the line archives"] * 2) / "a.sqlite")
    Path(db).parent.mkdir()
    assert main(["archive", "add", str(calibrated), "--archive", db, "--bench", "B9"]) == 0
    said = capsys.readouterr().out
    assert said.startswith("archived: #1 C1")
    # within 80 columns but for a word longer than a line (the path's first word is the
    # temporary directory's whole depth), the archive's path (its words) whole across the lines
    assert not too_wide(said) and len(said.splitlines()) > 1, said
    assert db in " ".join(ln.strip() for ln in said.splitlines())
    assert main(["archive", "add", str(calibrated), "--archive", db]) == 0
    assert "already archived: #1 C1" in capsys.readouterr().out
    assert main(["archive", "list", "--archive", db]) == 0
    out = capsys.readouterr().out
    assert out.count("C1") == 1 and "B9" in out
    assert main(["archive", "show", "C1", "--archive", db]) == 0
    out = capsys.readouterr().out
    assert "A0x" in out and "records sha256" in out and "bench B9" in out


def test_checks_exit_one_when_something_needs_attention(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    db = str(tmp_path / "lot.sqlite")
    lot = simulate_lot(np.random.default_rng(3), units=24)
    with Archive(db) as a:
        a.add_many(lot.entries)
    assert main(["archive", "drift", "--archive", db]) == 1
    assert "recalibrate: U0007" in capsys.readouterr().out
    assert main(["archive", "repeat", "U0003", "--archive", db]) == 0
    assert "repeatable" in capsys.readouterr().out
    assert main(["archive", "check-bench", "REF", "--archive", db]) == 1
    assert "bench bias: B3" in capsys.readouterr().out
    assert main(["archive", "lot", "--archive", db]) == 1
    assert "failing: U0011 (self-test failed)" in capsys.readouterr().out
    assert main(["archive", "control", "--serial", "REF", "--param", "G0z", "--archive", db]) == 0
    assert capsys.readouterr().out.count("G0z") == 4
    out_csv = tmp_path / "v.csv"
    assert main(["archive", "export", str(out_csv), "--serial", "U0001", "--archive", db]) == 0
    rows = list(csv.DictReader(out_csv.open()))
    assert len(rows) == 3 * 12 and {r["serial"] for r in rows} == {"U0001"}
    got = sorted(float(r["value"]) for r in rows if r["parameter"] == "A0x")
    want = sorted(
        p.value for e in lot.entries if e.serial == "U0001" for p in e.parameters if p.name == "A0x"
    )
    assert got == pytest.approx(want, rel=1e-15)
    lots = {e.lot for e in lot.entries if e.serial == "U0001"}
    assert {r["lot"] for r in rows} == lots and {r["unit"] for r in rows} >= {"m/s²", "°/s", "1"}
    # an export written before the lot and unit columns is replaced like any earlier export
    out_csv.write_text("calibration_id,serial,bench,measured_at,self_test,verdict,fit_verdict,"
                       "parameter,value,stderr\n1,U0001,B1,x,,pass,,A0x,0.1,0.01\n")  # fmt: skip
    assert main(["archive", "export", str(out_csv), "--serial", "U0001", "--archive", db]) == 0
    assert len(list(csv.DictReader(out_csv.open()))) == 3 * 12


@pytest.mark.parametrize(
    "argv, words",
    [
        (["drift", "--tol", "A0x"], "--tol: expected NAME=VALUE"),
        (["trend", "NOPE"], "NOPE: no calibration of this serial"),
        (["export", "x.xlsx"], "write .csv or .parquet"),
        (["show", "--id", "99"], "99: no archived calibration"),
        # a check of a lot, unit or bench that is not there is not one that passed
        (["lot", "NOLOT"], "no calibration in lot NOLOT"),
        (["lot", "--param", "NOPE"], "--param NOPE: no such parameter in the archive"),
        (["control", "--bench", "B9"], "no calibration on B9"),
        (["drift", "--serial", "NOPE"], "no calibration of NOPE"),
        (["repeat", "--lot", "L9"], "no calibration in lot L9"),
        # an archive with nothing in it: questions to it are not answered as passed
        (["export", "v.csv"], "the archive has no calibration"),
        (["drift"], "the archive has no calibration"),
        (["repeat"], "the archive has no calibration"),
        (["report", "--html", "qc.html"], "the archive has no calibration"),
    ],
)
def test_bad_input_is_one_line(
    argv: list[str], words: str, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    db = str(tmp_path / "e.sqlite")
    Archive(db).close()  # an archive, empty
    assert main(["archive", *argv, "--archive", db]) == 2
    err = capsys.readouterr().err
    assert words in err and err.count("\n") == 1 and "Traceback" not in err


def test_a_bad_alpha_is_refused_by_the_parser(capsys: pytest.CaptureFixture) -> None:
    with pytest.raises(SystemExit) as info:
        main(["archive", "repeat", "--alpha", "2"])
    assert info.value.code == 2
    assert "expected a rate between 0 and 1" in capsys.readouterr().err


def test_calibrate_from_dir_archives_its_result_unless_told_not_to(
    calibrated: Path, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    d = tmp_path / "C1"
    shutil.copytree(calibrated, d)
    db = str(tmp_path / "cal.sqlite")
    code = main(["calibrate", "--from-dir", str(d), "--archive", db, "--bench", "B2"])
    err = capsys.readouterr().err
    assert "archived as #1 in sqlite:///" in " ".join(err.split())
    assert too_wide(err) == []
    with Archive(db) as a:
        (s,) = a.summaries()
        e = a.entry(s.id)
    assert (s.serial, s.bench) == ("C1", "B2")
    assert e.result_hash == hashlib.sha256((d / "C1_result.json").read_bytes()).hexdigest()
    assert (code == 0) == (e.verdict == "pass")
    # --no-archive: nothing more in the archive
    main(["calibrate", "--from-dir", str(d), "--archive", db, "--no-archive"])
    assert "archived" not in capsys.readouterr().err
    with Archive(db) as a:
        assert a.count()[0] == 1
    # an archive that cannot be opened: the result is still written, the line says how to
    # archive it later, the exit status is the calibration's
    (d / "C1_result.json").unlink()
    again = main(["calibrate", "--from-dir", str(d), "--archive", str(tmp_path / "no/x.db")])
    err = capsys.readouterr().err
    assert again == code and (d / "C1_result.json").is_file()
    assert "not archived:" in err and "archive add" in err
    # within 80 columns, and the command to archive it later runs as printed
    assert too_wide(err) == []
    lines = err.splitlines()
    i = next(i for i, ln in enumerate(lines) if ln.strip().startswith("python3 -m host archive"))
    n = next(j for j in range(i, len(lines)) if not lines[j].endswith("\\")) + 1
    assert pasted(lines[i:n]) == ["python3", "-m", "host", "archive", "add", str(d),
                                  "--records", str(d)]  # fmt: skip


@settings(max_examples=200, deadline=None)
@given(st.lists(st.text(max_size=20), max_size=3))
@pytest.mark.slow
def test_any_tolerance_text_is_tolerances_or_one_line(items: list[str]) -> None:
    try:
        out = parse_tolerances(items)
    except UserError as exc:
        assert str(exc).startswith("--tol: expected NAME=VALUE")
    else:
        assert all(v > 0 for v in out.values())


@pytest.mark.slow
@pytest.mark.timeout(300)
def test_a_live_calibration_lands_in_the_archive(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    db = str(tmp_path / "live.sqlite")
    argv = ["calibrate", "--serial", "L9", "--yes", "--warmup", "0", "--static-seconds", "1",
            "--turns", "1", "--no-closing", "--out", str(tmp_path / "L9"), "--archive", db,
            "--bench", "line-2"]  # fmt: skip
    code = main(argv)
    out = capsys.readouterr()
    assert "archived as #1" in out.out + out.err
    with Archive(db) as a:
        (s,) = a.summaries()
        e = a.entry(s.id)
    assert (s.serial, s.bench) == ("L9", "line-2") and len(e.record_hashes) == 12
    assert (code == 0) == (e.verdict == "pass")
    recs = {n: hashlib.sha256((tmp_path / "L9" / f"L9_{n}.txt").read_bytes()).hexdigest()
            for n, _ in e.record_hashes}  # fmt: skip
    assert dict(e.record_hashes) == recs


# ---- the answers within 80 columns ------------------------------------------------------------
PREFIX = "LINE7-IMU-2026-"  # serials as a production line writes them, not the tests' "U0001"


@pytest.fixture(scope="module")
def line_archive(tmp_path_factory: pytest.TempPathFactory) -> tuple[str, object]:
    db = str(tmp_path_factory.mktemp("line") / "line.sqlite")
    lot = simulate_lot(np.random.default_rng(3), units=24, prefix=PREFIX)
    with Archive(db) as a:
        a.add_many(lot.entries)
    return db, lot


QUESTIONS = [["list"], ["show", f"{PREFIX}U0007"], ["trend", f"{PREFIX}U0001"],
             ["repeat", f"{PREFIX}U0003"], ["repeat"], ["drift"], ["lot"], ["control"],
             ["control", "--serial", f"{PREFIX}REF"], ["check-bench", f"{PREFIX}REF"]]  # fmt: skip


@pytest.mark.parametrize("argv", QUESTIONS, ids=" ".join)
def test_every_answer_fits_80_columns(
    line_archive: tuple[str, object], argv: list[str], capsys: pytest.CaptureFixture,
    monkeypatch: pytest.MonkeyPatch,
) -> None:  # fmt: skip
    """Into a pipe or a file (80 columns): every line of every question's answer fits, on a
    lot whose serials are as long as a production line's; the planted problems are still
    named whole."""
    monkeypatch.delenv("COLUMNS", raising=False)
    db, lot = line_archive
    rc = main(["archive", *argv, "--archive", db])
    out = capsys.readouterr().out
    assert rc in (0, 1)
    assert [ln for ln in out.splitlines() if len(ln) > 80] == []
    named = {"drift": lot.drifting, "check-bench": "bench bias: B3", "lot": lot.failing}  # type: ignore[attr-defined]
    if argv == ["repeat"] or argv[0] in named:
        assert (named.get(argv[0]) or lot.drifting) in out  # type: ignore[attr-defined]


def test_the_lot_table_carries_every_value_of_the_lot_report(
    line_archive: tuple[str, object], capsys: pytest.CaptureFixture,
    monkeypatch: pytest.MonkeyPatch,
) -> None:  # fmt: skip
    """The narrowed lot table still says, in its columns, what the lot report computed: each
    parameter's unit, n, mean, spread, band, limit and datasheet verdict, in its own row."""
    from host.archive import checks
    from host.archive.charts import param_unit

    monkeypatch.delenv("COLUMNS", raising=False)
    db, _ = line_archive
    assert main(["archive", "lot", "--archive", db]) == 1
    lines = capsys.readouterr().out.splitlines()
    head = next(i for i, ln in enumerate(lines) if ln.split()[:1] == ["parameter"])
    headers = lines[head].split()
    assert headers == ["parameter", "unit", "n", "mean", "spread", "mean−3σ", "mean+3σ",
                       "limit", "datasheet"]  # fmt: skip
    with Archive(db) as a:
        rep = checks.lot_report(a)
    rows = {ln.split()[0]: ln.split() for ln in lines[head + 1 : head + 1 + len(rep.rows)]}
    assert set(rows) == {r.name for r in rep.rows}
    for r in rep.rows:
        s, cells = r.summary, rows[r.name]
        assert cells[1] == param_unit(r.name) and int(cells[2]) == s.n
        got = [float(c) for c in cells[3:8]]
        assert got == pytest.approx([s.mean, s.spread, s.low, s.high, s.limit], rel=2e-3)
        assert cells[8] == {True: "within", False: "OUTSIDE"}[bool(s.within)]


# ---- a conditional PASS is not a clean pass ---------------------------------------------------
@pytest.fixture(scope="module")
def misfit_lot(tmp_path_factory: pytest.TempPathFactory) -> tuple[str, dict[str, dict]]:
    """Two units of the independent simulator calibrated into one archive: one whose records
    hold a gyro bias step the base model lacks (a PASS on a model that does not fit), in lot
    L1 with nothing else, and one with nothing hidden, in lot L2."""
    from tests.independent.simulate import SessionSpec, write_session

    tmp = tmp_path_factory.mktemp("misfit")
    db = str(tmp / "a.sqlite")
    docs = {}
    for serial, effect, lot_name in (("STEP1", "bias_step_gyro", "L1"), ("CLEAN1", "none", "L2")):
        d = tmp / serial
        write_session(d, SessionSpec(seed=7, effect=effect, serial=serial))
        # judged by the values alone (simple acceptance): the step widens STEP1's U past its
        # limits, which guarded acceptance would leave undecided rather than a PASS
        rc = main(["calibrate", "--from-dir", str(d), "--archive", db, "--lot", lot_name,
                   "--decision-rule", "simple"])  # fmt: skip
        docs[serial] = json.loads((d / f"{serial}_result.json").read_text(encoding="utf-8"))
        assert rc == 0  # both pass their tolerances: the exit status of calibrate is 0
    assert docs["STEP1"]["conditional"] and not docs["CLEAN1"]["conditional"]
    return db, docs


@pytest.mark.slow
def test_a_conditional_pass_is_shown_as_such(
    misfit_lot: tuple[str, dict[str, dict]], capsys: pytest.CaptureFixture,
    monkeypatch: pytest.MonkeyPatch,
) -> None:  # fmt: skip
    monkeypatch.delenv("COLUMNS", raising=False)
    db, docs = misfit_lot
    rms_z = docs["STEP1"]["fit"]["rms_z"]
    capsys.readouterr()
    # the lot check names it, counts it apart from the clean passes and asks for attention
    assert main(["archive", "lot", "--archive", db]) == 1
    out = capsys.readouterr().out
    said = " ".join(ln.strip() for ln in out.splitlines())
    assert (
        f"conditional: STEP1 (PASS*: the model does not fit its records, RMS z {rms_z:.3g})" in said
    )
    assert "latest verdicts: 1 PASS, 1 PASS*" in said and "CLEAN1" not in said
    assert "* conditional PASS:" in said
    # a lot of clean passes only is not flagged
    assert main(["archive", "lot", "L2", "--archive", db]) == 0
    out = capsys.readouterr().out
    assert "latest verdicts: 1 PASS\n" in out and "no conditional pass" in out
    assert "PASS*" not in out
    assert main(["archive", "lot", "L1", "--archive", db]) == 1
    assert "conditional: STEP1" in capsys.readouterr().out
    # the list marks it, with the star's meaning below the table
    assert main(["archive", "list", "--archive", db]) == 0
    lines = capsys.readouterr().out.splitlines()
    verdicts = {ln.split()[1]: ln.split()[5] for ln in lines[1:3]}
    assert verdicts == {"STEP1": "PASS*", "CLEAN1": "PASS"}, lines
    assert lines[3].startswith("* conditional PASS")
    assert all(len(ln) <= 80 for ln in lines)
    # show says the whole verdict
    assert main(["archive", "show", "STEP1", "--archive", db]) == 0
    out = capsys.readouterr().out
    assert f"verdict PASS* (conditional: the model does not fit, RMS z {rms_z:.3g})" in out
    # the QC lead's page lists it among the units that need attention
    page = Path(db).parent / "qc.html"
    assert main(["archive", "report", "--html", str(page), "--archive", db]) == 0
    attention = page.read_text(encoding="utf-8").split('id="attention"')[1].split("</ul>")[0]
    assert "<b>STEP1</b>: conditional PASS" in attention and "CLEAN1" not in attention
    # and what leaves for the line's own counting carries the fit's verdict
    out_csv = Path(db).parent / "v.csv"
    assert main(["archive", "export", str(out_csv), "--archive", db]) == 0
    rows = list(csv.DictReader(out_csv.open(encoding="utf-8")))
    fits = {(r["serial"], r["verdict"], r["fit_verdict"]) for r in rows}
    assert fits == {
        ("STEP1", "pass", "inadequate"),
        ("CLEAN1", "pass", docs["CLEAN1"]["fit"]["verdict"]),
    }


def test_a_file_that_is_no_archive_or_no_result_is_one_line(
    tmp_path: Path, line_archive: tuple[str, object], capsys: pytest.CaptureFixture
) -> None:
    """A text or binary file given as the archive, a binary file given as a result, a
    parameter the lot does not have: one line each, exit 2, the file unchanged."""
    text, binary = tmp_path / "notes.db", tmp_path / "noise.bin"
    text.write_text("not a database\n")
    binary.write_bytes(bytes(range(256)) * 8)
    for argv, words in (
        (["list", "--archive", str(text)], "cannot open it (file is not a database)"),
        (["list", "--archive", str(binary)], "cannot open it (file is not a database)"),
        (["add", str(binary), "--archive", str(tmp_path / "a.sqlite")], "not UTF-8 text"),
        (["trend", f"{PREFIX}U0001", "--param", "A0w", "--archive", line_archive[0]],
         "--param A0w: no such parameter in the archive (it has A0x, A0y"),
    ):  # fmt: skip
        assert main(["archive", *argv]) == 2, argv
        err = capsys.readouterr().err
        assert words in err and err.count("\n") == 1 and "Traceback" not in err, err
    assert text.read_text() == "not a database\n"
    assert binary.read_bytes() == bytes(range(256)) * 8


@pytest.mark.parametrize(
    "argv, words",
    [
        # a lot, a parameter or a tolerance that is not there: was a page, a file or
        # "no unit moved" with exit 0
        (["report", "--html", "p.html", "--lot", "NOLOT"], "no calibration in lot NOLOT"),
        (["report", "--html", "p.html", "--param", "NOPE"], "--param NOPE: no such parameter"),
        (["drift", "--tol", "NOPE=0.1"], "--tol NOPE: no such parameter in these calibrations"),
        (["export", "v.csv", "--serial", "NOPE"], "no calibration of NOPE"),
        (["export", "v.csv", "--param", "NOPE"], "--param NOPE: no such parameter"),
        (["report", "--html", ""], "--html '': an empty value (an unset variable?)"),
        (["report", "--html", "/nonexistent/dir/p.html"], "cannot write /nonexistent/dir/p.html"),
        (["list", "--archive", "postgresql://qc@db:5432x/line"], "not a database URL"),
        (["list", "--archive", ""], "--archive '': an empty value"),
    ],
)
@pytest.mark.slow
def test_what_is_not_there_is_one_line_and_writes_nothing(
    calibrated: Path,
    tmp_path: Path,
    capsys: pytest.CaptureFixture,
    monkeypatch: pytest.MonkeyPatch,
    argv: list[str],
    words: str,
) -> None:
    db = str(tmp_path / "a.sqlite")
    assert main(["archive", "add", str(calibrated), "--archive", db]) == 0
    capsys.readouterr()
    monkeypatch.chdir(tmp_path)
    before = sorted(p.name for p in tmp_path.iterdir())
    given = argv if "--archive" in argv else [*argv, "--archive", db]
    assert main(["archive", *given]) == 2
    err = capsys.readouterr().err
    assert words in err and err.count("\n") == 1 and "Traceback" not in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == before  # no file left behind


def test_report_into_a_directory_writes_qc_html_in_it(
    calibrated: Path, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    """Was: 'cannot write DIR: permission denied' for a directory that exists, and a file
    named DIR for 'DIR/' that did not. A directory means the page in it, named qc.html."""
    db = str(tmp_path / "a.sqlite")
    assert main(["archive", "add", str(calibrated), "--archive", db]) == 0
    capsys.readouterr()
    (tmp_path / "pages").mkdir()
    for html, page in ((tmp_path / "pages", tmp_path / "pages" / "qc.html"),
                       (f"{tmp_path / 'new'}/", tmp_path / "new" / "qc.html")):  # fmt: skip
        assert main(["archive", "report", "--html", str(html), "--archive", db]) == 0
        assert capsys.readouterr().err == f"written: {page}\n"
        assert page.read_text(encoding="utf-8").lstrip().lower().startswith("<!doctype html")
    (tmp_path / "pages" / "qc.html").write_text("the earlier page")
    assert main(["archive", "report", "--html", str(tmp_path / "pages"), "--archive", db]) == 0
    new = (tmp_path / "pages" / "qc.html").read_text(encoding="utf-8")  # a new page, on which
    assert "1 simulated calibration(s)" in new  # C1, a simulated unit, is left out of the lot
