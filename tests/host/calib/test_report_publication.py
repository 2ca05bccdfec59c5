"""The results of one computation are published together or not at all (issue 17): the signed
report ``SERIAL_result.txt`` and the ``SERIAL_result.json`` that ``apply()`` reads never
disagree. Before, a full disk between the two files left the new report beside the old JSON.
Write errors name the user's file, not a hidden temp file."""

from __future__ import annotations

import errno
import json
import os
from collections.abc import Iterator
from pathlib import Path

import pytest

from host.__main__ import main
from tests.host.sim_sessions import write_sim_session


@pytest.fixture(scope="module")
def records_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_sim_session(tmp_path_factory.mktemp("pub") / "P1", "P1", seed=5)


def calibrate(d: Path, out: Path, latitude: float, capsys: pytest.CaptureFixture[str]) -> tuple:
    rc = main(["calibrate", "--from-dir", str(d), "--out", str(out), "--latitude", str(latitude)])
    o, e = capsys.readouterr()
    return rc, o, e


def disk_fills_at(monkeypatch: pytest.MonkeyPatch, n: int) -> None:
    """The n-th fsync (the n-th file written) finds the disk full."""
    real = os.fsync
    calls = {"k": 0}

    def fsync(fd: int) -> None:
        calls["k"] += 1
        if calls["k"] == n:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        real(fd)

    monkeypatch.setattr(os, "fsync", fsync)


@pytest.mark.parametrize("full_at", [1, 2])
@pytest.mark.slow
def test_disk_full_between_the_two_result_files_changes_neither(
    records_dir: Path,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
    full_at: int,
) -> None:
    out = tmp_path / "out"
    out.mkdir()
    rc, _, _ = calibrate(records_dir, out, 50.0, capsys)
    assert rc in (0, 1)
    txt, js = out / "P1_result.txt", out / "P1_result.json"
    before = (txt.read_bytes(), js.read_bytes())
    assert json.loads(before[1])["latitude_deg"] == 50.0

    disk_fills_at(monkeypatch, full_at)
    rc, _, err = calibrate(records_dir, out, 60.0, capsys)
    assert rc == 2
    failed = (txt, js)[full_at - 1]
    assert f"cannot write {failed}: the disk is full" in err
    assert ".tmp" not in err  # the user's file, not the hidden temp file
    assert (txt.read_bytes(), js.read_bytes()) == before  # both old, together
    assert sorted(p.name for p in out.iterdir()) == ["P1_result.json", "P1_result.txt"]

    monkeypatch.undo()
    rc, _, _ = calibrate(records_dir, out, 60.0, capsys)
    assert rc in (0, 1)
    assert json.loads(js.read_text())["latitude_deg"] == 60.0
    assert "latitude 60.000°" in txt.read_text()


def test_unwritable_directory_is_named(
    records_dir: Path,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    """As a non-root user in a read-only directory: the temp file cannot be created. (Tests
    run as root here, who writes anywhere, so the refusal is simulated where it happens.)"""
    import tempfile

    out = tmp_path / "ro"
    out.mkdir()

    def mkstemp(prefix: str = "", suffix: str = "", dir: str | None = None) -> tuple[int, str]:
        raise PermissionError(errno.EACCES, "Permission denied", f"{dir}/{prefix}x1y2{suffix}")

    monkeypatch.setattr(tempfile, "mkstemp", mkstemp)
    rc, _, err = calibrate(records_dir, out, 50.0, capsys)
    assert rc == 2
    assert f"cannot write {out / 'P1_result.txt'}: permission denied" in err
    assert ".tmp" not in err and list(out.iterdir()) == []


def renames_fail_at(monkeypatch: pytest.MonkeyPatch, n: int, exc: BaseException) -> list[str]:
    """The n-th rename of a temp file over a result file raises ``exc`` (every other rename,
    the rollback's included, works); returns the log of renames done."""
    real = os.replace
    done: list[str] = []

    def replace(src: str | os.PathLike[str], dst: str | os.PathLike[str]) -> None:
        if str(src).endswith(".tmp"):
            if len([d for d in done if d.startswith("publish")]) + 1 == n:
                raise exc
            done.append(f"publish {Path(dst).name}")
        else:
            done.append(f"restore {Path(dst).name}")
        real(src, dst)

    monkeypatch.setattr(os, "replace", replace)
    return done


def test_disk_fills_between_the_two_renames_both_stay_old(
    records_dir: Path,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    """Both files written; the report renamed over the old one; then the JSON's rename fails.
    Before: the new report stood beside the old JSON. Now the report is rolled back."""
    out = tmp_path / "out"
    out.mkdir()
    assert calibrate(records_dir, out, 50.0, capsys)[0] in (0, 1)
    txt, js = out / "P1_result.txt", out / "P1_result.json"
    before = (txt.read_bytes(), js.read_bytes())

    log = renames_fail_at(monkeypatch, 2, OSError(errno.ENOSPC, os.strerror(errno.ENOSPC)))
    rc, _, err = calibrate(records_dir, out, 60.0, capsys)
    assert rc == 2
    assert log == ["publish P1_result.txt", "restore P1_result.txt"]  # it got that far
    assert f"cannot write {js}: the disk is full; every file is unchanged" in err
    assert (txt.read_bytes(), js.read_bytes()) == before
    assert sorted(p.name for p in out.iterdir()) == ["P1_result.json", "P1_result.txt"]


def test_interrupt_between_the_two_renames_rolls_back(tmp_path: Path) -> None:
    """Ctrl+C (or any exception) between the renames: the old pair, and the interrupt goes on."""
    from host.session.atomic import write_texts_atomic

    a, b = tmp_path / "a.txt", tmp_path / "b.json"
    write_texts_atomic({a: "old a", b: "old b"})
    with pytest.MonkeyPatch.context() as mp:
        renames_fail_at(mp, 2, KeyboardInterrupt())
        with pytest.raises(KeyboardInterrupt):
            write_texts_atomic({a: "new a", b: "new b"})
    assert (a.read_text(), b.read_text()) == ("old a", "old b")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.txt", "b.json"]
    write_texts_atomic({a: "new a", b: "new b"})  # and it publishes when nothing fails
    assert (a.read_text(), b.read_text()) == ("new a", "new b")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.txt", "b.json"]


def test_first_publication_failing_between_the_renames_leaves_neither(tmp_path: Path) -> None:
    """No old pair: the rollback removes the one file already renamed into place."""
    from host.errors import UserError
    from host.session.atomic import write_texts_atomic

    a, b = tmp_path / "a.txt", tmp_path / "b.json"
    with pytest.MonkeyPatch.context() as mp:
        renames_fail_at(mp, 2, OSError(errno.EIO, os.strerror(errno.EIO)))
        with pytest.raises(UserError, match=r"cannot write .*b\.json: .*every file is unchanged"):
            write_texts_atomic({a: "new a", b: "new b"})
    assert list(tmp_path.iterdir()) == []


@pytest.fixture
def tiny_disk(tmp_path: Path) -> Iterator[Path]:
    """A real 1 MiB tmpfs (needs root and a kernel that lets this container mount)."""
    import subprocess

    mnt = tmp_path / "disk"
    mnt.mkdir()
    r = subprocess.run(
        ["mount", "-t", "tmpfs", "-o", "size=1m", "tmpfs", str(mnt)],
        capture_output=True,
        check=False,
    )
    if r.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here: {r.stderr.decode(errors='replace').strip()}")
    try:
        yield mnt
    finally:
        subprocess.run(["umount", "-l", str(mnt)], check=False)


def test_a_really_full_disk_between_the_two_files(
    records_dir: Path, tiny_disk: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """No injection: a filler file leaves room for the new report but not the new JSON."""
    out = tiny_disk / "out"
    out.mkdir()
    assert calibrate(records_dir, out, 50.0, capsys)[0] in (0, 1)
    txt, js = out / "P1_result.txt", out / "P1_result.json"
    before = (txt.read_bytes(), js.read_bytes())
    st = os.statvfs(tiny_disk)
    page = st.f_frsize
    room_for_txt = -(-len(before[0]) // page) * page  # the new report is as long as the old
    room_for_lock = page  # --from-dir holds the directory's lock file while it writes
    (tiny_disk / "filler").write_bytes(b"\0" * (st.f_bavail * page - room_for_txt - room_for_lock))
    assert os.statvfs(tiny_disk).f_bavail * page < len(before[1])  # the JSON cannot fit

    rc, _, err = calibrate(records_dir, out, 60.0, capsys)
    assert rc == 2
    assert f"cannot write {js}: the disk is full" in err
    assert (txt.read_bytes(), js.read_bytes()) == before
    assert sorted(p.name for p in out.iterdir()) == ["P1_result.json", "P1_result.txt"]
