"""The self-test in a live calibration (host/dialogue/flow.py, measurement.self_test): a part
that fails it is calibrated, but its records say so, its result and its archived calibration
fail, and the screen names the failing axes. The judge itself: tests/host/wire/test_selftest.py;
on the real firmware: tests/emulator/test_emu_selftest.py."""

from __future__ import annotations

from pathlib import Path

import pytest

from host.__main__ import main
from host.archive.store import Archive
from host.board.link import LinkLost
from host.calib.codec import read_result
from host.dialogue.boards import lost_at, lost_line
from host.dialogue.console import Questions, ScriptedConsole
from host.dialogue.measurement import self_test
from host.session.directory import read_record
from host.session.records import STATIC_NAMES
from tests.host.dialogue.flat_options import flat_options


@pytest.mark.slow  # a whole --yes session on the virtual board (~20 s)
def test_a_part_failing_its_self_test_fails_its_calibration_and_its_archive_entry(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out, db = tmp_path / "F1", str(tmp_path / "a.sqlite")
    url = "sim://?speed=max&noise_seed=2&effects=linear,noise&earth_rate=0&self_test=fail"
    args = ["--yes", "--serial", "F1", "--out", str(out), "--static-seconds", "10", "--turns", "1"]
    code = main(["calibrate", "--port", url, *args, "--warmup", "0", "--archive", db])
    screen = capsys.readouterr()
    said = screen.out + screen.err
    assert code == 1  # the values may all pass: the self-test fails the calibration
    assert "MPU-6000 self-test: FAIL — ay, gz outside ±14 % of the factory trim" in said
    for name in STATIC_NAMES:
        meta = read_record(out / f"F1_{name}.txt").meta
        assert meta["self_test"] == "fail" and "ay, gz" in meta["self_test_note"]
    result = read_result(out / "F1_result.json")
    assert result.self_test == "fail" and not result.all_passed
    verdicts = [ln for ln in said.splitlines() if ln.startswith("FAIL")]  # the last screen line
    assert verdicts and "the sensor failed its self-test" in verdicts[-1]
    with Archive(db) as a:
        (s,) = a.summaries()
        e = a.entry(s.id)
    assert (e.self_test, e.verdict) == ("fail", "fail")
    # and its constants cannot be flashed: every format refuses it (issue 43)
    for fmt in ("ardupilot", "px4", "c-header", "imucal"):
        exported = tmp_path / f"F1.{fmt}"
        assert (
            main(["export", str(out / "F1_result.json"), "--to", fmt, "--out", str(exported)]) == 1
        )
        assert "failed its self-test" in capsys.readouterr().err and not exported.exists()


@pytest.mark.slow  # a whole --yes session on the virtual board (~20 s)
def test_a_calibration_without_the_self_test_says_not_run_everywhere(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """--no-self-test on a chip that would fail it: it is not run (so it cannot fail the
    calibration), and the records, the result, the report, its verdict and the archive say
    'not run'."""
    out, db = tmp_path / "N1", str(tmp_path / "a.sqlite")
    url = "sim://?speed=max&noise_seed=2&effects=linear,noise&earth_rate=0&self_test=fail"
    args = ["--yes", "--serial", "N1", "--out", str(out), "--static-seconds", "10", "--turns", "1"]
    main(["calibrate", "--port", url, *args, "--warmup", "0", "--archive", db, "--no-self-test"])
    screen = capsys.readouterr()
    said = screen.out + screen.err
    assert "MPU-6000 self-test: NOT RUN — skipped with --no-self-test" in said
    assert "keep the cube still" not in said and "OUT OF ±14 %" not in said
    for name in STATIC_NAMES:
        assert read_record(out / f"N1_{name}.txt").meta["self_test"] == "not run"
    result = read_result(out / "N1_result.json")
    assert result.self_test == "not run"
    assert result.verdict().endswith("— self-test not run")
    report = (out / "N1_result.txt").read_text()
    assert "MPU-6000 self-test: not run (--no-self-test)" in report
    assert "the sensor failed its self-test" not in report
    with Archive(db) as a:
        (s,) = a.summaries()
    assert s.self_test == "not run" and s.verdict == ("pass" if result.all_passed else "fail")


def test_no_self_test_is_kept_by_the_resume_command_and_refused_with_from_dir(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:

    skip = flat_options(port="sim://", self_test=False)
    assert "--no-self-test" in skip.command("N2", static_seconds=5.0, turns=1, port="sim://")
    run = flat_options(port="sim://")
    assert "--no-self-test" not in run.command("N2", static_seconds=5.0, turns=1, port="sim://")
    assert main(["calibrate", "--from-dir", str(tmp_path), "--no-self-test"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--no-self-test is for a live calibration" in err[0]


class _Unplugged:
    """A board whose link is gone at each self-test."""

    def __init__(self) -> None:
        self.tries = 0

    def self_test(self) -> None:
        self.tries += 1
        raise LinkLost("the board disconnected")


def test_a_board_lost_in_its_self_test_is_tried_again_only_while_it_is_back() -> None:
    """measurement.self_test: each lost link is said and handed to ``recover``; the
    self-test is tried again while ``recover`` says the board is back (one board, or a board
    of a sitting that came back), up to the attempts, and never again once it says the board
    left the sitting. Where such a board is named as lost: during the self-test."""
    for back, tries in ((True, 3), (False, 1)):
        board, con, seen = _Unplugged(), ScriptedConsole(), list[Exception]()

        def recover(exc: Exception, back: bool = back, seen: list[Exception] = seen) -> bool:
            seen.append(exc)
            return back

        self_test(board, Questions(con, yes=True), 3, recover)  # type: ignore[arg-type]
        assert board.tries == len(seen) == tries
        assert con.text.count("!!! the self-test is not recorded: the board disconnected") == tries
    assert lost_at("", self_test=True) == "during the self-test"
    assert (lost_at(""), lost_at("y_dn")) == ("at the start", "at record y_dn")
    line = lost_line("U36", lost_at("", self_test=True), "the board did not come back")
    assert line.startswith("board U36 lost during the self-test (the board did not come back)")
