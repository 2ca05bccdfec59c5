"""The results of one computation are published together or not at all (issue 17): the signed
report ``SERIAL_result.txt`` and the ``SERIAL_result.json`` that ``apply()`` reads never
disagree. Before, a full disk between the two files left the new report beside the old JSON.
Write errors name the user's file, not a hidden temp file."""

from __future__ import annotations

import errno
import json
import os
from pathlib import Path

import numpy as np
import pytest

from host.__main__ import main
from host.bench.sim import Plan, SensorTruth, simulate_session, write_session


@pytest.fixture(scope="module")
def records_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp("pub") / "P1"
    truth = SensorTruth.random(np.random.default_rng(5))
    write_session(d, "P1", simulate_session(truth, Plan(static_s=5.0, turns=1, warmup_s=0), 5))
    return d


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
