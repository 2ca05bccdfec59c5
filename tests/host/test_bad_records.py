"""Record files and headers are validated where they enter (issue 17): a one-row static record
was accepted, ``--turns`` contradicting the records' header was ignored, dangling symlinks and
directories named like records were skipped silently; a FIFO named like a record would block.
Every refusal is one line naming the file."""

from __future__ import annotations

import os
import re
from pathlib import Path

import pytest

from host.__main__ import main
from host.session.directory import read_record, read_session
from host.session.records import RecordError
from tests.host.sim_sessions import write_sim_session


@pytest.fixture(scope="module")
def session_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_sim_session(tmp_path_factory.mktemp("recs") / "R1", "R1", seed=9, turns=2)


def copy_of(session_dir: Path, tmp_path: Path) -> Path:
    d = tmp_path / "R1"
    d.mkdir()
    for p in session_dir.iterdir():
        (d / p.name).write_bytes(p.read_bytes())
    return d


def calibrate(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str]:
    rc = main(["calibrate", *argv])
    return rc, capsys.readouterr().err


def one_row(path: Path) -> None:
    lines = path.read_text().splitlines()
    head = [x for x in lines if x.startswith("#")]
    data = [x for x in lines if x and x[0].isdigit()]
    row = data[0].split("\t")
    mean = "mean\t" + "\t".join(row[1:])
    path.write_text("\n".join([*head, data[0], "_" * 40, mean, "std\t" + "\t".join(["0"] * 7)]))


def test_a_one_row_static_record_is_refused(
    session_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    d = copy_of(session_dir, tmp_path)
    one_row(d / "R1_y_dn.txt")
    rc, err = calibrate(["--from-dir", str(d)], capsys)
    assert rc == 2 and "R1_y_dn.txt: 1 data row" in err


def test_turns_contradicting_the_header_is_refused(
    session_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "out"
    out.mkdir()
    rc, err = calibrate(["--from-dir", str(session_dir), "--out", str(out), "--turns", "3"], capsys)
    assert rc == 2
    assert "--turns 3, but record x_ccw says 'turns: 2' in its header" in err
    assert list(out.iterdir()) == []
    rc, _ = calibrate(["--from-dir", str(session_dir), "--out", str(out), "--turns", "2"], capsys)
    assert rc in (0, 1)


@pytest.mark.parametrize("kind", ["dangling-link", "directory", "fifo"])
def test_things_named_like_records_that_are_not_files_are_named(
    session_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], kind: str
) -> None:
    d = copy_of(session_dir, tmp_path)
    victim = d / "R1_z_cw.txt"
    victim.unlink()
    if kind == "dangling-link":
        victim.symlink_to(tmp_path / "gone.txt")
        words = "a broken link (its target is missing)"
    elif kind == "directory":
        victim.mkdir()
        words = "a directory, named like a record"
    else:
        os.mkfifo(victim)  # reading it would block forever
        words = "not a regular file"
    with pytest.raises(RecordError, match=r"R1_z_cw\.txt: " + re.escape(words)):
        read_session(d)
    rc, err = calibrate(["--from-dir", str(d)], capsys)
    assert rc == 2 and f"{victim}: {words}" in err


def test_a_record_file_above_the_stated_size_is_refused(tmp_path: Path) -> None:
    from host.session import directory

    big = tmp_path / "S1_x_up.txt"
    with open(big, "wb") as f:
        f.truncate(directory.MAX_RECORD_BYTES + 1)  # sparse: no disk used
    with pytest.raises(RecordError, match=r"S1_x_up\.txt: 64 MiB, more than a record can be"):
        read_record(big)
