"""The live calibration program end to end in a pseudo-terminal: a real process
(``python3 -m host calibrate ...``), its screen read from the pty master, keys written to it.
Ctrl+C is the byte 0x03 through the terminal (the tty turns it into SIGINT).

The board is ``sim://`` at ``speed=max`` (or a few times real time where a measurement must
last long enough to be interrupted); the range alarm and the Ctrl+C/resume tests also run on
``emu://`` — the real firmware in the emulator, the same virtual operator driving its sensor.
"""

from __future__ import annotations

import os
import re
import select
import shlex
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from host.dialogue.console import STRAY_ENTER_S
from host.session.directory import read_record
from host.session.records import STATIC_NAMES, TURN_NAMES

pytestmark = pytest.mark.skipif(sys.platform == "win32", reason="needs a POSIX pty")

ROOT = Path(__file__).resolve().parents[3]
LINEAR = "effects=linear,noise&earth_rate=0"

#: the placement every prompt asks for (the dialogue's heading, 0°)
PLACED = (
    r", against the fence, its [XYZ] arrow pointing right, along the fence "
    r"\(placement heading 0°\)\. Press any key\."
)


def emu_missing() -> str | None:
    """Why the real firmware cannot run in the emulator here (no toolchain), or None."""
    from host.bench.build import toolchain_problem

    return toolchain_problem(need_avr=True)


#: the two boards a test can run on: the virtual board, and the real firmware in the emulator
BOARDS = [
    pytest.param("sim", id="sim"),
    pytest.param(
        "emu",
        id="emu",
        marks=[
            pytest.mark.emulator,
            pytest.mark.skipif(emu_missing() is not None, reason=str(emu_missing())),
        ],
    ),
]


def board_url(board: str, seed: int, speed: str, operator_fault: str = "") -> str:
    """A virtual-bench URL on ``board``; ``operator_fault`` e.g. ``too_fast@1``."""
    url = f"{board}://?seed={seed}&noise_seed={seed}&speed={speed}&{LINEAR}"  # deterministic
    if operator_fault:  # emu://'s own ``fault`` names sensor faults
        url += f"&{'fault' if board == 'sim' else 'operator_fault'}={operator_fault}"
    return url


CMD = [sys.executable, "-m", "host", "calibrate"]


class Screen:
    """A child process on a pty: read what it shows, type keys."""

    def __init__(self, args: list[str], cwd: Path, size: tuple[int, int] | None = None) -> None:
        """``size``: (rows, columns) of the terminal, set on the pty as a terminal window
        does (TIOCSWINSZ); None leaves the pty unsized and says COLUMNS=1000 (no line is
        wrapped: the prompts are matched whole; the 80-column layout has its own tests)."""
        import fcntl
        import pty
        import struct
        import termios

        env = dict(os.environ, PYTHONPATH=str(ROOT), TERM="xterm", COLUMNS="1000")
        if size is not None:  # the program must read the terminal, not a stale COLUMNS
            env.update(COLUMNS="200", LINES=str(size[0] + 30))
        self.pid, self.fd = pty.fork()
        if self.pid == 0:  # child: the pty is its controlling terminal
            try:
                if size is not None:
                    fcntl.ioctl(0, termios.TIOCSWINSZ, struct.pack("HHHH", *size, 0, 0))
                # Ctrl+C must reach the program even when this test runs in a background job
                # (a non-interactive shell's `cmd &` ignores SIGINT, and exec keeps SIG_IGN)
                signal.signal(signal.SIGINT, signal.SIG_DFL)
                os.chdir(cwd)
                os.execvpe(CMD[0], CMD + args, env)
            finally:
                os._exit(127)
        self.text = ""
        self.pos = 0
        self.status: int | None = None

    def _read(self, timeout: float) -> bool:
        r, _, _ = select.select([self.fd], [], [], timeout)
        if not r:
            return True
        try:
            data = os.read(self.fd, 65536)
        except OSError:  # EIO: the child closed the terminal
            data = b""
        if not data:
            return False
        self.text += data.decode("utf-8", "replace")
        return True

    def expect(self, pattern: str, timeout: float = 20.0) -> re.Match[str]:
        """Wait until ``pattern`` (regex) appears after the last match; move past it."""
        rx = re.compile(pattern)
        end = time.monotonic() + timeout
        while True:
            m = rx.search(self.text, self.pos)
            if m:
                self.pos = m.end()
                return m
            left = end - time.monotonic()
            if left <= 0 or not self._read(min(left, 0.5)):
                m = rx.search(self.text, self.pos)
                if m:
                    self.pos = m.end()
                    return m
                raise AssertionError(
                    f"{pattern!r} not on the screen; last output:\n{self.text[-1500:]}"
                )

    def send(self, keys: str) -> None:
        os.write(self.fd, keys.encode())

    def wait(self, timeout: float = 30.0) -> int:
        """Read to the end; the exit status."""
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            if not self._read(0.2):
                break
        pid, st = os.waitpid(self.pid, 0 if time.monotonic() < end else os.WNOHANG)
        if pid == 0:
            os.kill(self.pid, signal.SIGKILL)
            os.waitpid(self.pid, 0)
            raise AssertionError(f"the program did not end; screen:\n{self.text[-1500:]}")
        os.close(self.fd)
        self.status = os.waitstatus_to_exitcode(st)
        return self.status

    def close(self) -> None:
        if self.status is None:
            try:
                os.kill(self.pid, signal.SIGKILL)
                os.waitpid(self.pid, 0)
            except OSError:
                pass
            try:
                os.close(self.fd)
            except OSError:
                pass


@pytest.fixture
def screens() -> list[Screen]:
    started: list[Screen] = []
    yield started
    for s in started:
        s.close()


def start(screens: list[Screen], cwd: Path, *args: str) -> Screen:
    s = Screen(list(args), cwd)
    screens.append(s)
    return s


def leftovers(d: Path) -> list[str]:
    """Temp files or hidden files (what an interrupted atomic write would leave)."""
    return [p.name for p in d.iterdir() if p.name.endswith(".tmp") or p.name.startswith(".")]


def static_table_mean(text: str) -> float:
    """Ax of the last 'mean' row shown."""
    return float(text.rsplit("mean ", 1)[1].split()[0])


# --------------------------------------------------------------------------- tests


@pytest.mark.slow
@pytest.mark.parametrize("board", BOARDS)
def test_interactive_session_with_a_repeat(
    tmp_path: Path, screens: list[Screen], board: str
) -> None:
    """The whole dialogue typed by hand: serial, stages, seconds, one 'repeat', the turns."""
    s = start(screens, tmp_path, "--port", board_url(board, 21, "max"),
              "--warmup", "0", "--ready-seconds", "0")  # fmt: skip
    s.expect(r"Ctrl\+C ends the session \(accepted records are kept, the command to resume is "
             r"printed\); Esc aborts only the current measurement")  # fmt: skip
    s.expect(r"Level the base\. Connect the unit by USB")
    s.expect(r"WHO_AM_I 0x68 \(MPU-6000\)", timeout=60)  # emu://: may build the firmware first
    s.expect(r"Serial number \(1-12 characters: letters, digits, _ or -\): ")
    s.send("P1\r")
    s.expect(r"Measure the 6 static orientations <Y> or go to the integral gyro calibration <N>\?")
    s.send("y")
    s.expect(r"Accumulation time per orientation, seconds.*: ")
    s.send("2\r")
    shown: dict[str, float] = {}
    for name in STATIC_NAMES:
        axis, side = name.split("_")
        where = "up" if side == "up" else "down"
        s.expect(rf"Put the cube on the base with {axis.upper()} {where}{PLACED}")
        s.send(" ")
        s.expect(r"\*\*\* BEEP \*\*\*")
        s.expect(rf"Measuring {name}")
        s.expect(r"\*\*\* BEEP \*\*\*")
        s.expect(r"std .*\n")
        s.expect(r"Save <Y> or repeat <N>\? \[Y\]")
        if name == "x_up" and "x_up" not in shown:
            shown["x_up_first"] = static_table_mean(s.text[: s.pos])
            s.send("n")
            s.expect(rf"Put the cube on the base with X up{PLACED}")
            s.send(" ")
            s.expect(r"Measuring x_up")
            s.expect(r"Save <Y> or repeat <N>\? \[Y\]")
        shown[name] = static_table_mean(s.text[: s.pos])
        s.send("y")
        s.expect(rf"Saved .*P1_{name}\.txt")
    s.expect(r"Stage 1 constants")
    s.expect(r"Integral gyro calibration <Y> or results <N>\?")
    s.send("y")
    s.expect(r"Number of turns per rotation.*\[2\]: ")
    s.send("1\r")
    for name in TURN_NAMES:
        axis, direction = name.split("_")
        s.expect(rf"Put the cube {axis.upper()} up{PLACED}")
        s.send(" ")
        words = "counter-clockwise" if direction == "ccw" else "clockwise"
        s.expect(rf"Get ready to turn 1 turn {words}")
        s.expect(rf"Turn now! {name}: 7 s")
        s.expect(r"∫Gx")
        s.expect(r"Save <Y> or repeat <N>\?")
        s.send("y")
        s.expect(rf"Saved .*P1_{name}\.txt")
    # the closing check: X up once more, and the drift it shows
    s.expect(r"Closing check: x_up once more")
    s.expect(rf"Put the cube on the base with X up{PLACED}")
    s.send(" ")
    s.expect(r"Measuring x_up_2")
    s.expect(r"Save <Y> or repeat <N>\? \[Y\]")
    s.send("y")
    s.expect(r"Saved .*P1_x_up_2\.txt")
    s.expect(r"Closing − opening [0-9.]+ min later: accel .* m/s², gyro .* °/s \(x y z\)")
    s.expect(r"TEST REPORT, IMU MPU-6000 rev \w+, serial No\. P1")  # the sensor the records name
    assert s.wait() in (0, 1)
    out = tmp_path / "P1"  # the default output directory
    assert (out / "P1_result.txt").exists() and (out / "P1_result.json").exists()
    assert s.text.count("Measuring x_up:") == 2
    saved = read_record(out / "P1_x_up.txt")
    assert saved.accel[:, 0].mean() == pytest.approx(shown["x_up"], abs=1e-4)
    assert abs(shown["x_up"] - 9.81) < 0.3  # what was shown and saved: +g on X
    assert all(read_record(r).meta["lost_frames"] == "0" for r in out.glob("P1_*_*.txt"))
    assert read_record(out / "P1_z_cw.txt").meta["turns"] == "1"
    assert "\a" in s.text  # the terminal bell rings with each beep
    assert leftovers(out) == []


@pytest.mark.parametrize("board", BOARDS)
def test_esc_aborts_only_the_measurement(tmp_path: Path, screens: list[Screen], board: str) -> None:
    s = start(screens, tmp_path, "--port", board_url(board, 22, "max"), "--serial",
              "E1", "--static-seconds", "200", "--warmup", "0")  # fmt: skip
    s.expect(r"Measure the 6 static orientations <Y>")
    s.send("y")
    s.expect(rf"with X up{PLACED}")
    s.send(" ")
    s.expect(r"Measuring x_up: 200 s \(Esc aborts\)")
    t0 = time.monotonic()
    s.send("\x1b")
    s.expect(r"Measurement of x_up aborted \(Esc\): nothing kept")
    assert time.monotonic() - t0 < 2.0  # 200 s at max speed would take far longer
    s.expect(rf"Put the cube on the base with X up{PLACED}")  # the same one again
    s.send("\x03")
    s.expect(r"Aborted \(Ctrl\+C\)")
    assert s.wait() == 130
    out = tmp_path / "E1"
    assert sorted(p.name for p in out.iterdir()) == ["E1_session.cap"]


@pytest.mark.slow
@pytest.mark.parametrize("board", BOARDS)
def test_range_alarm_offers_to_repeat(tmp_path: Path, screens: list[Screen], board: str) -> None:
    url = board_url(board, 23, "max", "too_fast@1")
    s = start(screens, tmp_path, "--port", url, "--serial", "R1", "--warmup", "0",
              "--ready-seconds", "0")  # fmt: skip
    s.expect(r"Measure the 6 static orientations <Y> or go to the integral gyro calibration <N>")
    s.send("n")  # straight to the turns
    s.expect(r"Number of turns.*: ")
    time.sleep(STRAY_ENTER_S + 0.1)  # sooner, an Enter is taken as typed with the "n"
    s.send("\r")  # the default, 2
    s.expect(rf"Put the cube X up{PLACED}")
    s.send(" ")
    s.expect(r"Turn now! x_ccw: 12 s")
    s.expect(r"RANGE ALARM: \d+ gyro samples at or beyond ±250 °/s \(peak 250\.\d °/s\)")
    s.expect(r"Repeat <Y> or save anyway <N>\? \[Y\]")
    s.send("y")
    s.expect(rf"Put the cube X up{PLACED}")
    s.send(" ")
    s.expect(r"Turn now! x_ccw: 12 s")
    s.expect(r"peak rate \d+\.\d °/s")
    s.expect(r"Save <Y> or repeat <N>\? \[Y\]")
    s.send("y")
    s.expect(r"Saved .*R1_x_ccw\.txt")
    s.expect(rf"Put the cube X up{PLACED}")
    s.send("\x03")
    assert s.wait() == 130
    assert "\a" in s.text.split("RANGE ALARM")[0][-40:]
    assert s.text.count("RANGE ALARM") == 1  # one alarm per event
    rec = read_record(tmp_path / "R1" / "R1_x_ccw.txt")
    assert float(np.abs(rec.gyro).max()) < 249.99
    assert 700 < rec.gyro[:, 0].sum() * 0.02 < 760  # about two turns, the second attempt


@pytest.mark.slow
@pytest.mark.parametrize("board", BOARDS)
def test_ctrl_c_during_a_measurement_then_resume(
    tmp_path: Path, screens: list[Screen], board: str
) -> None:
    """Ctrl+C in the middle of y_up: x_up and x_dn stay, nothing half-written; --resume then
    measures only what is missing."""
    url = board_url(board, 24, "4")  # a 3 s static lasts 0.75 s: time to hit it
    s = start(screens, tmp_path, "--port", url, "--serial", "C1", "--static-seconds", "3",
              "--warmup", "0")  # fmt: skip
    s.expect(r"Measure the 6 static orientations <Y>")
    s.send("y")
    for name in ("x_up", "x_dn"):
        s.expect(r"Press any key\.")
        s.send(" ")
        s.expect(r"Save <Y> or repeat <N>\?")
        s.send("y")
        s.expect(rf"Saved .*C1_{name}\.txt")
    s.expect(rf"with Y up{PLACED}")
    s.send(" ")
    s.expect(r"Measuring y_up")
    s.expect(r"y_up \[#*-+\]")  # the progress line is running
    s.send("\x03")
    s.expect(r"Aborted \(Ctrl\+C\): the measurement in progress is discarded")
    m = s.expect(r"continue with:\s*\n((?:.*\\\s*\n)*.*--resume)")
    printed = shlex.split(m.group(1).replace("\r", "").replace("\\\n", ""))
    assert printed[4:] == ["--port", printed[5], "--serial", "C1", "--out", "C1",
                           "--static-seconds", "3", "--warmup", "0", "--resume"]  # fmt: skip
    assert s.wait() == 130
    assert "Save <Y> or repeat <N>?" not in s.text.split("Measuring y_up")[1]
    out = tmp_path / "C1"
    assert sorted(p.name for p in out.glob("*.txt")) == ["C1_x_dn.txt", "C1_x_up.txt"]
    assert leftovers(out) == []
    kept = {n: (out / f"C1_{n}.txt").read_bytes() for n in ("x_up", "x_dn")}
    for n in kept:
        read_record(out / f"C1_{n}.txt")

    # resume with the printed command, non-interactive: no terminal at all (stdin closed, no
    # controlling tty); full speed, one turn, no pause before the turns, nobody to answer
    assert printed[:4] == ["python3", "-m", "host", "calibrate"]
    words = printed[4:]  # the same board at full speed (a second --port is a second board)
    words[words.index("--port") + 1] = board_url(board, 24, "max")
    proc = subprocess.run(
        CMD + words + ["--turns", "1", "--ready-seconds", "0", "--yes", "--json"],
        cwd=tmp_path, stdin=subprocess.DEVNULL, capture_output=True, text=True, timeout=60,
        env=dict(os.environ, PYTHONPATH=str(ROOT)), start_new_session=True,
    )  # fmt: skip
    assert proc.returncode in (0, 1), proc.stderr[-2000:]
    assert "Resuming: kept x_up, x_dn" in proc.stderr
    measured = re.findall(r"(?:Measuring|Turn now!) (\w+):", proc.stderr)
    assert measured == ["y_up", "y_dn", "z_up", "z_dn", *TURN_NAMES, "x_up_2"]
    for n, data in kept.items():
        assert (out / f"C1_{n}.txt").read_bytes() == data
    import json

    assert sorted(json.loads(proc.stdout)["records"]) == sorted(
        [*STATIC_NAMES, *TURN_NAMES, "x_up_2"]
    )
    assert leftovers(out) == []


@pytest.mark.slow
def test_an_80x24_terminal_redraws_in_place_and_ends_with_the_verdict(
    tmp_path: Path, screens: list[Screen]
) -> None:
    """80×24 (the pty sized as a terminal window sizes it): every progress redraw, running
    means included, fits in one line (a wrapped one leaves a line per redraw and pushes the
    instructions off the screen), the means carry their units, as the table of each static
    does, and the last line is the verdict, the report's path above it."""
    s = Screen(["--port", board_url("sim", 31, "max"), "--serial", "DEMO01", "--yes",
                "--warmup", "0", "--static-seconds", "3", "--turns", "1"], tmp_path,
               size=(24, 80))  # fmt: skip
    screens.append(s)
    assert s.wait() in (0, 1)
    redraws = [seg for line in s.text.split("\n") for seg in line.split("\r")[1:]]
    redraws = [seg.replace("\x1b[K", "") for seg in redraws if seg.strip()]
    assert len(redraws) > 12, "the progress lines are drawn in place"
    assert max(len(seg) for seg in redraws) <= 79, max(redraws, key=len)
    # the running means are all there, not cut off: 3 accel and 3 gyro values, with units
    running = r" A( [+-]\d+\.\d{2}){3} m/s²  G( [+-]\d+\.\d{2}){3} °/s$"
    means = [seg for seg in redraws if re.search(running, seg)]
    assert len(means) > 6, redraws[:20]
    # the mean/std table of each static names its units under the channels
    units = r"unit +m/s² +m/s² +m/s² +°/s +°/s +°/s +°C"
    assert len(re.findall(units, s.text)) >= 6, s.text[:3000]
    shown = [ln for ln in s.text.replace("\r", "\n").split("\n") if ln.strip()]
    last = shown[-1]
    assert re.fullmatch(
        r"PASS: every value within tolerance|PASS \(conditional: the model does not fit, "
        r"RMS z \d+\.\d\d\)|FAIL: \d+ value\(s\) .*",
        last.strip(),
    ), last
    assert "Report: DEMO01/DEMO01_result.txt" in [ln.strip() for ln in shown[-5:]], shown[-5:]
    # the mark just above it: on one line when it fits, else the mark and the board's URL
    # whole below it (this URL, with its options, does not fit beside the mark)
    mark = "*** SIMULATED BOARD: not a measurement of a unit ***"
    assert mark in shown[-4:-1], shown[-4:]
    url = shown[shown.index(mark, len(shown) - 4) + 1].strip()
    assert url.startswith("sim://?seed=") and url.endswith("earth_rate=0"), url
    # every line keeps to the 80 columns (the erase-to-end code takes none)
    cols = [ln.replace("\x1b[K", "") for ln in shown]
    assert all(len(ln) <= 80 for ln in cols), [ln for ln in cols if len(ln) > 80]
    assert len(last) <= 80  # the verdict is one line, not wrapped


@pytest.mark.slow
def test_a_face_that_stops_early_ends_its_bar_where_it_stopped(
    tmp_path: Path, screens: list[Screen]
) -> None:
    """``--plan adaptive`` at 80×24: a face that has enough before its 30 s ends its progress
    bar at the second it stopped (the bar read ``[##########] 30.0/30 s`` and then ``stopped
    … at 11 s``)."""
    s = Screen(["--port", board_url("sim", 31, "max"), "--serial", "AD1", "--yes", "--warmup",
                "0", "--static-seconds", "30", "--turns", "1", "--plan", "adaptive",
                "--max-extra", "0", "--no-closing"], tmp_path, size=(24, 80))  # fmt: skip
    screens.append(s)
    assert s.wait() in (0, 1)
    lines = [ln for ln in s.text.replace("\r", "\n").split("\n") if ln.strip()]
    stops = [i for i, ln in enumerate(lines) if re.match(r"[xyz]_(up|dn): stopped, .* at \d+ s$",
                                                           ln.strip())]  # fmt: skip
    assert len(stops) == 6, lines[:80]
    for i in stops:
        bar = next(ln for ln in reversed(lines[:i]) if re.search(r"\] +\d+\.\d/30 s", ln))
        shown = float(re.search(r"\] +(\d+\.\d)/30 s", bar).group(1))  # type: ignore[union-attr]
        said = int(re.search(r"at (\d+) s$", lines[i].strip()).group(1))  # type: ignore[union-attr]
        assert shown < 30.0 and abs(shown - said) <= 1.0, (bar, lines[i])


@pytest.mark.slow
def test_an_enter_typed_with_a_one_key_answer_is_not_the_next_answer(
    tmp_path: Path, screens: list[Screen]
) -> None:
    """80×24, keys typed as a hand types them: "y⏎" at the first Y/N question left the
    accumulation time an empty answer ("give the accumulation time in seconds"); "y⏎" at
    "Save" started the next face before the cube was placed. The Enter typed with the key
    (in one write, or 50 ms after it) is dropped; the next question waits for its answer."""
    s = Screen(["--port", board_url("sim", 25, "max"), "--serial", "K1", "--warmup", "0"],
               tmp_path, size=(24, 80))  # fmt: skip
    screens.append(s)
    s.expect(r"Measure the 6 static orientations <Y> or go to the integral gyro\s+"
             r"calibration\s+<N>\? \[Y\]", timeout=60)  # fmt: skip
    s.send("y\r")
    s.expect(r"Accumulation time per orientation, seconds[^\n]*: ")
    s.send("2\r")
    s.expect(r"with X up[^\n]*\n?[^\n]*Press\s+any\s+key\.")
    for name, typed in (("x_up", ["y\r"]), ("x_dn", ["y", "\r"])):
        s.send(" ")
        s.expect(rf"Measuring {name}")
        s.expect(r"Save <Y> or repeat <N>\? \[Y\]")
        for i, keys in enumerate(typed):
            time.sleep(0.05 if i else 0.0)
            s.send(keys)
        s.expect(rf"Saved .*K1_{name}\.txt")
        s.expect(r"with (X down|Y up)[^\n]*\n?[^\n]*Press\s+any\s+key\.")
        time.sleep(1.0)  # the Enter typed with "y" would have started the face by now
        s._read(0.2)
        assert "Measuring" not in s.text[s.pos :], s.text[-600:]
    s.send("\x03")
    assert s.wait() == 130
    assert "give the accumulation time" not in s.text
    assert re.search(r"seconds[^\n]*: 2\r?\n", s.text), s.text[-2000:]
    out = tmp_path / "K1"
    assert sorted(p.name for p in out.glob("*.txt")) == ["K1_x_dn.txt", "K1_x_up.txt"]


def measure_x_up(s: Screen) -> None:
    """Answer Y to measuring the statics, place x_up, and save it."""
    s.expect(r"Measure the 6 static orientations <Y>", timeout=60)
    s.send("y")
    s.expect(r"with X up[^\n]*\n?[^\n]*Press\s+any\s+key\.")
    s.send(" ")
    s.expect(r"Save <Y> or repeat <N>\? \[Y\]")
    s.send("y")


def one_line(text: str) -> str:
    """The screen's words with every run of whitespace (line breaks of an 80-column wrap,
    redraws) as one space."""
    return re.sub(r"\s+", " ", text.replace("\x1b[K", ""))


@pytest.mark.slow
def test_a_warm_up_ended_by_a_key_is_not_called_a_warm_unit_on_resume(
    tmp_path: Path, screens: list[Screen]
) -> None:
    """80×24: the warm-up ended by a key after x_up is kept; --resume then said "the kept
    records were measured on a warm unit". It says no whole warm-up was recorded."""
    url = board_url("sim", 26, "max")
    s = Screen(["--port", url, "--serial", "W1", "--warmup", "3600", "--static-seconds", "2"],
               tmp_path, size=(24, 80))  # fmt: skip
    screens.append(s)
    s.expect(r"warm-up", timeout=60)
    s.send(" ")  # ends the warm-up an hour early
    measure_x_up(s)
    s.expect(r"Saved .*W1_x_up\.txt")
    s.send("\x03")
    assert s.wait() == 130
    assert not (tmp_path / "W1" / "W1_warmup.txt").exists()  # no whole warm-up was recorded
    r = Screen(["--port", url, "--serial", "W1", "--resume"], tmp_path, size=(24, 80))
    screens.append(r)
    r.expect(r"Measure the 6 static orientations <Y>", timeout=60)
    r.send("\x03")
    assert r.wait() == 130
    said = one_line(r.text)
    assert "no whole warm-up was recorded before them (it was ended by a key or not made)" in said
    assert "measured on a warm unit" not in said


@pytest.mark.slow
def test_redo_says_what_it_keeps_in_redo_words(tmp_path: Path, screens: list[Screen]) -> None:
    """80×24: --redo x_up on a whole session said the turns were "already measured
    (--resume)"; it names --redo and the one record it measures again."""
    url = board_url("sim", 27, "max")
    first = subprocess.run(
        CMD + ["--port", url, "--serial", "R1", "--yes", "--warmup", "0", "--static-seconds",
               "2", "--turns", "1", "--ready-seconds", "0"],
        cwd=tmp_path, stdin=subprocess.DEVNULL, capture_output=True, text=True, timeout=120,
        env=dict(os.environ, PYTHONPATH=str(ROOT)), start_new_session=True,
    )  # fmt: skip
    assert first.returncode in (0, 1), first.stderr[-2000:]
    s = Screen(["--port", url, "--serial", "R1", "--redo", "x_up"], tmp_path, size=(24, 80))
    screens.append(s)
    measure_x_up(s)
    s.expect(r"already\s+measured", timeout=60)
    s.send("\x03")
    assert s.wait() in (0, 1, 130)
    said = one_line(s.text)
    assert "already measured (kept: --redo measures x_up only)" in said, said[-1500:]
    assert "(--resume)" not in said
