"""``python -m host archive`` (host/cli/archive.py): a result calibrate wrote goes in once,
comes back by serial, the checks answer with their exit codes, bad options are one line."""

from __future__ import annotations

import csv
import hashlib
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
    # within 80 columns, the archive's path (its words) whole across the lines
    assert all(len(ln) <= 80 for ln in said.splitlines()) and len(said.splitlines()) > 1
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


@pytest.mark.parametrize(
    "argv, words",
    [
        (["drift", "--tol", "A0x"], "--tol: expected NAME=VALUE"),
        (["trend", "NOPE"], "NOPE: no calibration of this serial"),
        (["export", "x.xlsx"], "write .csv or .parquet"),
        (["show", "--id", "99"], "99: no archived calibration"),
    ],
)
def test_bad_input_is_one_line(
    argv: list[str], words: str, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    db = str(tmp_path / "e.sqlite")
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
    assert "archived as #1 in sqlite:///" in err
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


@settings(max_examples=200, deadline=None)
@given(st.lists(st.text(max_size=20), max_size=3))
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
    parameter's n, mean, spread, band, limit and datasheet verdict, in its own row."""
    from host.archive import checks

    monkeypatch.delenv("COLUMNS", raising=False)
    db, _ = line_archive
    assert main(["archive", "lot", "--archive", db]) == 1
    lines = capsys.readouterr().out.splitlines()
    head = next(i for i, ln in enumerate(lines) if ln.split()[:1] == ["parameter"])
    headers = lines[head].split()
    assert headers == ["parameter", "n", "mean", "spread", "mean−3σ", "mean+3σ", "limit",
                       "datasheet"]  # fmt: skip
    with Archive(db) as a:
        rep = checks.lot_report(a)
    rows = {ln.split()[0]: ln.split() for ln in lines[head + 1 : head + 1 + len(rep.rows)]}
    assert set(rows) == {r.name for r in rep.rows}
    for r in rep.rows:
        s, cells = r.summary, rows[r.name]
        assert int(cells[1]) == s.n
        got = [float(c) for c in cells[2:7]]
        assert got == pytest.approx([s.mean, s.spread, s.low, s.high, s.limit], rel=2e-3)
        assert cells[7] == {True: "within", False: "OUTSIDE"}[bool(s.within)]
