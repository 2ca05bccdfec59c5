"""Every command as a user meets it in an 80×24 terminal (a pseudo-terminal of that size): no
line wider than the terminal, no word broken across two lines (issue 27)."""

from __future__ import annotations

import fcntl
import json
import os
import re
import select
import struct
import subprocess
import sys
import termios
import time
from pathlib import Path

import pytest

from tests.host.cli.cli_run import one_word

ROOT = Path(__file__).resolve().parents[3]
ESCAPES = re.compile(r"\x1b\[[0-9;?]*[A-Za-z]|[\x07\x08]")


def run_in_pty(
    argv: list[str], cwd: Path, cols: int = 80, rows: int = 24, keys: bytes = b"",
    timeout_s: float = 120.0,
) -> tuple[int, str]:  # fmt: skip
    """``python3 -m host ARGV`` on a pseudo-terminal of ``cols``×``rows``: exit status and what
    it wrote to the screen (stdout and stderr both). ``keys`` are typed after the start."""
    master, slave = os.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", rows, cols, 0, 0))
    env = {k: v for k, v in os.environ.items() if k not in ("COLUMNS", "LINES")}
    env["PYTHONPATH"] = str(ROOT)
    proc = subprocess.Popen(
        [sys.executable, "-m", "host", *argv], cwd=cwd, env=env,
        stdin=slave, stdout=slave, stderr=slave, start_new_session=True,
    )  # fmt: skip
    os.close(slave)
    out = b""
    deadline = time.monotonic() + timeout_s
    pending = keys
    try:
        while time.monotonic() < deadline:
            ready, _, _ = select.select([master], [], [], 0.2)
            if ready:
                try:
                    chunk = os.read(master, 65536)
                except OSError:  # the child closed the terminal
                    break
                if not chunk:
                    break
                out += chunk
            elif proc.poll() is not None:
                break
            if pending and out:
                os.write(master, pending[:1])
                pending = pending[1:]
        else:
            proc.kill()
            raise AssertionError(f"{argv} did not end within {timeout_s} s:\n{out.decode()}")
    finally:
        os.close(master)
    return proc.wait(), out.decode("utf-8", "replace")


def is_data(line: str) -> bool:
    """A line of JSON: data for programs (``capture``'s counters), not text to read."""
    try:
        json.loads(line)
    except ValueError:
        return False
    return line.startswith(("{", "["))


def screen_problems(text: str, cols: int = 80) -> list[str]:
    """Lines the terminal would fold (wider than ``cols``: a word broken where the terminal
    cuts it) but one word the shell reads whole, which nothing could break (the house's rule,
    :func:`tests.host.cli.cli_run.one_word`: a path, a quoted signal of two steps in a
    command); every draw of a progress line redrawn in place counts."""
    lines = [ESCAPES.sub("", line) for line in text.replace("\r\n", "\n").split("\n")]
    bad = []
    for line in lines:
        draws = line.split("\r")
        for draw in draws:  # a progress line redrawn in place: every draw
            if len(draw) > cols and not is_data(draw) and not one_word(draw):
                bad.append(f"{len(draw)} columns: {draw}")
    return bad


@pytest.fixture(scope="module")
def session(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A whole session on the virtual board, run in the terminal: its screen is checked too."""
    cwd = tmp_path_factory.mktemp("screen")
    argv = ["calibrate", "--serial", "W80", "--yes", "--warmup", "0", "--static-seconds", "3",
            "--turns", "1", "--no-archive"]  # fmt: skip
    rc, out = run_in_pty(argv, cwd)
    assert rc in (0, 1), out
    assert screen_problems(out) == []
    return cwd


def test_the_checker_sees_a_folded_line_and_a_wide_redraw() -> None:
    words = "word " * 16  # 80 columns
    assert screen_problems(words + "x") and not screen_problems(words)
    assert screen_problems("\r" + words + "more\rdone\n")
    # one word nothing could break (a path, a quoted signal in a command) is no fold to fix
    assert not screen_problems("x" * 81) and not screen_problems("  'a quoted " + "w" * 80 + "' \\")
    assert screen_problems("  'a quoted " + "w" * 80 + "' and more")
    assert not screen_problems('{"frames": 1, "file": "' + "a" * 90 + '"}')


#: every command as the issue's lab user ran it, on the session the fixture measured
COMMANDS = [
    ["calibrate", "--from-dir", "W80", "--no-archive"],
    ["calibrate", "--serial", "W80", "--out", "W80", "--redo", "x_ccw", "--yes", "--warmup", "0",
     "--static-seconds", "3", "--turns", "1", "--no-archive"],
    ["calibrate", "--serial", "W80", "--out", "W80", "--resume", "--yes", "--warmup", "0",
     "--static-seconds", "3", "--turns", "1", "--no-archive"],
    ["model", "terms"],
    ["model", "diagnose", "W80"],
    ["model", "diagnose", "W80", "--brief"],
    ["model", "add", "W80", "temperature_bias:gyro:y", "--floor", "accel=5e-4,gyro=3e-3"],
    ["model", "ladder", "W80"],
    ["demo", "hidden-effect", "--effect", "temperature", "--seed", "4"],
    ["noise", "W80/W80_x_up.txt"],
    ["noise", "W80/W80_x_cw.txt"],
    ["thermal", "W80"],
    ["thermal", "W80", "--window", "1"],
    ["import", "W80/W80_session.cap", "--serial", "IMP", "--out", "IMP"],
    ["import", "W80/W80_session.cap"],
    ["export", "W80/W80_result.json", "--to", "ardupilot", "--out", "w80.parm"],
    ["plan", "W80"],
    ["archive", "add", "W80", "--archive", "a.sqlite"],
    ["archive", "list", "--archive", "a.sqlite"],
    ["decode", "W80/W80_session.cap", "--stats"],
    ["capture", "--port", "sim://", "--seconds", "1", "c.cap"],
    ["model", "ladder", "W80", "--plot", "d"],
]  # fmt: skip


@pytest.mark.slow
@pytest.mark.parametrize("argv", COMMANDS, ids=" ".join)
def test_every_command_fits_an_80_column_terminal(session: Path, argv: list[str]) -> None:
    rc, out = run_in_pty(argv, session)
    assert "Traceback" not in out, out
    assert screen_problems(out) == [], out


HELP = sorted({(), *(tuple(c[:1]) for c in COMMANDS), ("model", "ladder"), ("model", "diagnose"),
               ("model", "add"), ("model", "terms"), ("demo", "hidden-effect"),
               ("archive", "list"), ("flash",)})  # fmt: skip


@pytest.mark.slow
@pytest.mark.parametrize("path", HELP, ids=lambda p: " ".join(p) or "top")
def test_every_help_fits_an_80_column_terminal(tmp_path: Path, path: tuple[str, ...]) -> None:
    rc, out = run_in_pty([*path, "--help"], tmp_path)
    assert rc == 0, out
    assert screen_problems(out) == [], out
