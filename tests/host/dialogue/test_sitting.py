"""Nothing accepted is replaced (issue 31): a new sitting moves the earlier one aside, one
process at a time writes a directory (a lock a kill -9 does not leave stuck), SIGTERM/SIGHUP end
a session as Ctrl+C does, and a capture is never overwritten. Each whole-session test ends by
comparing the SHA-256 of every record accepted before with what is on disk after.

The sessions are real ``python3 -m host calibrate`` processes on the virtual board with short
options; the quick ones test the lock and the moves in-process."""

from __future__ import annotations

import contextlib
import hashlib
import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from host.errors import UserError
from host.session.directory import (
    LOCK_NAME,
    DirectoryBusy,
    lock_directory,
    set_aside,
    sitting_files,
)
from tests.host.cli.cli_run import command_after
from tests.host.dialogue.flat_options import flat_options

SHORT = ["--yes", "--warmup", "0", "--static-seconds", "2", "--turns", "1", "--no-archive"]
#: slow enough to be interrupted mid-session: 4 simulated s per wall second, so its first record
#: is accepted ≈ 1 s after the start and the whole session lasts ≈ 14 s more, while a signal
#: follows the record the test sees within one poll (50 ms). (At 0.5×, 8 s of waiting for each
#: first record made up most of this file's 35 s.) A test that needs the session to outlast
#: something slower holds it still with SIGSTOP (:func:`frozen`).
SLOW_PORT = "sim://?speed=4&seed=3&noise_seed=3"


def env() -> dict[str, str]:
    root = str(Path(__file__).resolve().parents[3])
    return {**os.environ, "PYTHONPATH": root, "OPENBLAS_NUM_THREADS": "1"}


def calibrate(out: Path, *extra: str, port: str = "sim://?speed=max") -> list[str]:
    return [sys.executable, "-m", "host", "calibrate", "--serial", "S1", "--out", str(out),
            "--port", port, *SHORT, *extra]  # fmt: skip


def hashes(directory: Path, pattern: str = "S1_*.txt") -> dict[str, str]:
    """SHA-256 of each record file (``S1_*.txt``, the result report aside) in ``directory``."""
    return {
        p.name: hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(directory.glob(pattern))
        if p.name != "S1_result.txt"
    }


def wait_for(cond: object, timeout_s: float = 90.0) -> None:
    end = time.monotonic() + timeout_s
    while not cond():  # type: ignore[operator]
        assert time.monotonic() < end, "timed out"
        time.sleep(0.05)


def a_whole_session(out: Path) -> dict[str, str]:
    done = subprocess.run(calibrate(out), env=env(), capture_output=True, text=True, timeout=300)
    assert done.returncode in (0, 1), done.stderr
    before = hashes(out)
    assert len(before) == 13, before  # 6 statics, 6 turns, the closing check
    return before


def started(out: Path, *extra: str) -> subprocess.Popen[str]:
    """A slow session into ``out``, returned once it has accepted a record of its own."""
    earlier = set(hashes(out).values()) if out.exists() else set()
    proc = subprocess.Popen(
        calibrate(out, *extra, port=SLOW_PORT), env=env(), text=True,
        stdout=subprocess.PIPE, stderr=subprocess.PIPE,
    )  # fmt: skip
    wait_for(lambda: bool(set(hashes(out).values()) - earlier) or proc.poll() is not None)
    assert proc.poll() is None, proc.communicate()
    return proc


@contextlib.contextmanager
def frozen(proc: subprocess.Popen[str]) -> Iterator[None]:
    """``proc`` stopped (SIGSTOP) while inside, then let go (SIGCONT): a stopped process is
    alive and keeps its lock, but its session cannot end meanwhile, however long what is done
    beside it takes on a loaded machine. A signal sent inside is acted on when it goes on."""
    proc.send_signal(signal.SIGSTOP)
    try:
        yield
    finally:
        proc.send_signal(signal.SIGCONT)


# --------------------------------------------------------------------------- quick


def test_the_lock_names_the_living_holder_and_a_killed_one_leaves_none(tmp_path: Path) -> None:
    holder = subprocess.Popen(
        [sys.executable, "-c", "import sys, time; from host.session.directory import "
         "lock_directory; lock_directory(sys.argv[1], 'calibrate --serial S1'); "
         "print('locked', flush=True); time.sleep(60)", str(tmp_path)],
        env=env(), stdout=subprocess.PIPE, text=True,
    )  # fmt: skip
    try:
        assert holder.stdout is not None and holder.stdout.readline() == "locked\n"
        with pytest.raises(DirectoryBusy, match=rf"PID {holder.pid}\b.*calibrate --serial S1"):
            lock_directory(tmp_path)
    finally:
        holder.send_signal(signal.SIGKILL)
        holder.wait()
    assert (tmp_path / LOCK_NAME).exists()  # left behind by the killed process ...
    with lock_directory(tmp_path, "second") as lock:  # ... and holding no lock
        assert f"pid {os.getpid()}\n" in lock.path.read_text()
    assert not (tmp_path / LOCK_NAME).exists()
    with lock_directory(tmp_path):  # released: taken again
        pass


def test_setting_aside_moves_the_bytes_of_a_sitting_and_nothing_of_another_unit(
    tmp_path: Path,
) -> None:
    files = {
        "S1_x_up.txt": b"1", "S1_warmup.txt": b"2", "S1_result.json": b"3",
        "S1_session.cap": b"4", "S1_session_2.cap": b"5", "S1_thermal.json": b"unit",
        "S10_x_up.txt": b"other", "notes.md": b"mine",
    }  # fmt: skip
    for name, data in files.items():
        (tmp_path / name).write_bytes(data)
    mine = sitting_files(tmp_path, "S1")
    assert sorted(p.name for p in mine) == sorted(
        ["S1_x_up.txt", "S1_warmup.txt", "S1_result.json", "S1_session.cap", "S1_session_2.cap"]
    )
    aside = set_aside(tmp_path, "S1", mine)
    again = set_aside(tmp_path, "S1", [])  # a second sitting in the same second: its own place
    assert aside != again and aside.parent == again.parent == tmp_path / "earlier"
    for p in mine:
        assert (aside / p.name).read_bytes() == files[p.name] and not p.exists()
    for name in ("S1_thermal.json", "S10_x_up.txt", "notes.md"):
        assert (tmp_path / name).read_bytes() == files[name]


def test_a_capture_file_is_never_overwritten(tmp_path: Path) -> None:
    from host.wire.capture import CaptureWriter

    cap = tmp_path / "s.cap"
    cap.write_bytes(b"IMUCAP01 earlier")
    with pytest.raises(UserError, match="never overwritten"):
        CaptureWriter(cap)
    opts = flat_options(serial="S1", out=tmp_path / "S1", resume=True, capture=cap)
    with pytest.raises(UserError, match=r"--capture .*never overwritten"):
        opts.check()  # before any board is opened
    done = subprocess.run(
        [sys.executable, "-m", "host", "capture", "--port", "sim://", "--seconds", "1", str(cap)],
        env=env(), capture_output=True, text=True, timeout=60,
    )  # fmt: skip
    assert done.returncode == 2 and "never overwritten" in done.stderr
    assert len(done.stderr.strip().splitlines()) == 1
    assert cap.read_bytes() == b"IMUCAP01 earlier"


# --------------------------------------------------------------------------- whole sessions


@pytest.mark.slow
@pytest.mark.timeout(600)
def test_a_new_sitting_moves_the_earlier_one_aside_bytes_unchanged(tmp_path: Path) -> None:
    out = tmp_path / "S1"
    before = a_whole_session(out)
    cap_before = hashes(out, "S1_session.cap")
    after = a_whole_session(out)  # the same command again: a new sitting
    (aside,) = (out / "earlier").iterdir()
    assert hashes(aside) == before and hashes(aside, "S1_session.cap") == cap_before
    assert set(after) == set(before) and all(after[k] != before[k] for k in before)


@pytest.mark.slow
@pytest.mark.timeout(600)
def test_sigterm_ends_like_ctrl_c_and_kill_9_keeps_every_accepted_record(
    tmp_path: Path,
) -> None:
    out = tmp_path / "S1"
    first = a_whole_session(out)
    # a new sitting, ended by SIGTERM after its first record: one line and the resume command
    proc = started(out)
    kept = hashes(out)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 128 + signal.SIGTERM, err
    assert "Aborted (SIGTERM): the measurement in progress is discarded." in err
    assert command_after(err)[-1] == "--resume" and "Traceback" not in err
    assert set(hashes(out)) >= set(kept) and {k: hashes(out)[k] for k in kept} == kept
    # resumed, then killed with -9 after one more record: nothing accepted is lost, no stuck lock
    proc = started(out, "--resume")
    kept = hashes(out)
    proc.send_signal(signal.SIGKILL)
    proc.communicate(timeout=60)
    assert {k: hashes(out)[k] for k in kept} == kept
    done = subprocess.run(
        calibrate(out, "--resume"), env=env(), capture_output=True, text=True, timeout=300
    )
    assert done.returncode in (0, 1), done.stderr
    final = hashes(out)
    assert len(final) == 13 and {k: final[k] for k in kept} == kept
    (aside,) = (out / "earlier").iterdir()
    assert hashes(aside) == first


@pytest.mark.slow
@pytest.mark.timeout(600)
def test_a_second_process_on_the_same_directory_is_refused_with_the_first_ones_pid(
    tmp_path: Path,
) -> None:
    out = tmp_path / "S1"
    first = started(out)
    ended = False
    try:
        with frozen(first):  # mid-session, holding the lock, for as long as the tries take
            for extra in ((), ("--resume",)):
                kept = hashes(out)
                second = subprocess.run(
                    calibrate(out, *extra), env=env(), capture_output=True, text=True,
                    timeout=120,
                )  # fmt: skip
                assert second.returncode == 2, second.stderr
                assert f"PID {first.pid}" in second.stderr and "in use" in second.stderr
                assert {k: hashes(out)[k] for k in kept} == kept
                assert not (out / "earlier").exists()
            first.send_signal(signal.SIGTERM)  # acted on once it goes on: still mid-session
            ended = True
    finally:
        if not ended:
            first.send_signal(signal.SIGTERM)
        first.communicate(timeout=60)
    assert first.returncode == 128 + signal.SIGTERM


@pytest.mark.slow
@pytest.mark.timeout(300)
def test_sighup_ends_a_session_like_ctrl_c(tmp_path: Path) -> None:
    """The terminal closed: the accepted records stay, bytes unchanged, and the session says
    how to continue (to a log, when stderr still goes somewhere)."""
    out = tmp_path / "S1"
    proc = started(out)
    kept = hashes(out)
    proc.send_signal(signal.SIGHUP)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 128 + signal.SIGHUP, err
    assert "Aborted (SIGHUP)" in err and err.rstrip().endswith("--resume")
    assert {k: hashes(out)[k] for k in kept} == kept and not (out / ".imu-bench.lock").exists()
