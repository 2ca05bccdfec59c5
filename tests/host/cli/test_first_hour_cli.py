"""The first hour of a lab user (issue 18), the small things: keys at the prompts, file
permissions, --version, help texts with examples and exit codes, capture until Ctrl+C."""

from __future__ import annotations

import contextlib
import io
import re
from pathlib import Path

import pytest

from host.dialogue.console import ScriptedConsole
from tests.host.cli.cli_run import run
from tests.host.dialogue.flat_options import flat_options


def test_esc_at_press_any_key_does_not_start_the_measurement() -> None:
    from host.dialogue.console import ESC, Questions

    con = ScriptedConsole([ESC, " "])
    assert Questions(con).any_key("Put the cube on the base with X up. Press any key.") == " "
    assert "Esc aborts a measurement; none is running" in con.text and con.keys == []


def test_an_invalid_key_at_a_yes_no_question_is_answered() -> None:
    from host.dialogue.console import Questions

    con = ScriptedConsole(["x", "n"])
    assert Questions(con).yes_no("Save <Y> or repeat <N>?", True) is False
    assert "'x': press Y or N (Enter: Y)" in con.text


@pytest.mark.parametrize("umask, mode", [(0o022, 0o644), (0o027, 0o640)])
def test_records_and_results_get_the_usual_permissions(
    tmp_path: Path, umask: int, mode: int
) -> None:
    import os

    from host.session.atomic import write_text_atomic

    old = os.umask(umask)
    try:
        write_text_atomic(tmp_path / "F1_result.txt", "x\n")
    finally:
        os.umask(old)
    assert (tmp_path / "F1_result.txt").stat().st_mode & 0o777 == mode


def test_version() -> None:
    from host import __version__
    from host.wire.protocol_gen import PROTOCOL_VERSION

    rc, out, _ = run(["--version"])
    assert rc == 0 and out.startswith(f"imu-bench {__version__} (protocol {PROTOCOL_VERSION}")


def test_help_texts_give_examples_and_exit_codes() -> None:
    rc, out, _ = run(["calibrate", "--help"])
    assert rc == 0 and "examples:" in out and "--resume" in out
    assert "exit status:" in out and "130  interrupted" in out
    rc, out, _ = run(["capture", "--help"])
    assert "until Ctrl+C" in out


@pytest.mark.slow
def test_capture_shows_progress_and_runs_until_ctrl_c(tmp_path: Path) -> None:
    import json
    import os
    import signal
    import subprocess
    import sys
    import time

    from host.wire.bulk import decode_bulk

    root = Path(__file__).resolve().parents[3]
    cap = tmp_path / "s.cap"
    proc = subprocess.Popen(
        [sys.executable, "-m", "host", "capture", "--port", "sim://?speed=5", str(cap)],
        cwd=root, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        env=dict(os.environ, PYTHONPATH=str(root)),
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )  # fmt: skip
    assert proc.stderr is not None
    lines = [proc.stderr.readline(), proc.stderr.readline()]
    assert "(Ctrl+C stops)" in lines[0]
    assert re.search(r"\d+\.\d s  \d+ samples  0 CRC errors", lines[1]), lines
    time.sleep(0.3)
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=30)
    assert proc.returncode == 130, err  # interrupted, as every command says (the file is whole)
    stats = json.loads(out)
    assert stats["samples"] > 40 and "holds" in err
    assert len(decode_bulk(cap.read_bytes()).samples) == stats["samples"]


def test_model_terms_lists_the_catalogue_with_units_and_physics() -> None:
    import json

    from host.model.catalogue import CATALOGUE

    rc, out, _ = run(["model", "terms"])
    assert rc == 0
    for name, t in CATALOGUE.items():
        assert f"\n{name}" in f"\n{out}", name
        for sensor in t.sensors:
            for p, u in zip(t.params, t.param_units(sensor), strict=True):
                assert f"{p} [{u}]" in out, (name, p, u)
    assert "per_C [°/s/°C]" in out and "(base model, method.md §2)" in out
    assert max(len(line) for line in out.splitlines()) <= 80
    rc, out, _ = run(["model", "terms", "--json"])
    listed = json.loads(out)
    assert [d["name"] for d in listed] == list(CATALOGUE)
    assert all(d["physics"] and d["parameters"] for d in listed)


def test_demo_takes_static_seconds_and_still_the_old_spelling() -> None:
    from host.__main__ import build_parser

    parser, _ = build_parser()
    args = parser.parse_args(["demo", "hidden-effect", "--static-seconds", "12"])
    assert args.static_s == 12.0
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        args = parser.parse_args(["demo", "hidden-effect", "--static-s", "7"])
    assert args.static_s == 7.0 and "--static-s is now --static-seconds" in err.getvalue()


def test_plot_refuses_an_image_file_name(tmp_path: Path) -> None:
    rc, _, err = run(["model", "diagnose", str(tmp_path), "--plot", "OUT.png"])
    assert rc == 2 and "--plot takes a directory" in err and "--plot OUT/" in err
    assert not Path("OUT.png").exists()


def test_serial_number_message_states_the_rule_and_the_culprit() -> None:
    from host.dialogue import options

    with pytest.raises(ValueError) as e:
        options.parse_serial("my unit/1")
    msg = str(e.value)
    assert "mandatory" not in msg  # it was given
    assert "' '" in msg and "'/'" in msg and "1 to 12 characters" in msg and "_ or -" in msg
    with pytest.raises(ValueError, match="13 characters"):
        options.parse_serial("x" * 13)
    with pytest.raises(ValueError, match="mandatory"):
        options.parse_serial("  ")


def test_yes_without_static_seconds_fails_before_the_board_and_the_warm_up(
    tmp_path: Path,
) -> None:
    from host.dialogue import flow
    from host.errors import UserError

    opened: list[str] = []
    o = flat_options(port="sim://?speed=max", serial="F1", out=tmp_path / "F1",
                            yes=True, warmup_s=600.0)  # fmt: skip
    con = ScriptedConsole()
    with pytest.raises(UserError, match=r"--yes needs --static-seconds S, .*e\.g\."):
        flow.run_dialogue(o, con, lambda u: opened.append(u))
    assert opened == [] and "warm-up" not in con.text


def test_ctrl_c_during_the_warm_up_does_not_speak_of_a_measurement(tmp_path: Path) -> None:
    import contextlib
    import io

    from host.board.link import open_port
    from host.dialogue import flow

    con = ScriptedConsole()

    def interrupt_in_warm_up(text: str) -> None:
        if "warm-up" in text:
            raise KeyboardInterrupt

    con.progress = interrupt_in_warm_up  # type: ignore[method-assign]
    o = flat_options(port="sim://?speed=max&effects=linear,noise&earth_rate=0",
                            serial="W1", out=tmp_path / "W1", static_seconds=2.0, turns=1,
                            warmup_s=30.0, yes=True, ready_s=0.0)  # fmt: skip
    with contextlib.redirect_stdout(io.StringIO()):
        assert flow.run_dialogue(o, con, open_port) == 130
    assert "Aborted (Ctrl+C) during the warm-up (not recorded)." in con.text
    assert "measurement in progress" not in con.text


# the virtual board opened is the unit of --serial
@pytest.mark.parametrize(
    "yes, url", [(True, "sim://?speed=max&serial=F1"), (False, "sim://?serial=F1")]
)
def test_the_default_virtual_board_runs_at_full_speed_when_nobody_watches(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, yes: bool, url: str
) -> None:
    from host.dialogue import flow
    from host.errors import UserError

    monkeypatch.setattr(flow, "default_port", lambda: ("sim://", "NO BOARD FOUND"))
    opened: list[str] = []

    def factory(u: str) -> None:
        opened.append(u)
        raise UserError("enough")

    o = flat_options(serial="F1", out=tmp_path / "F1", static_seconds=2.0, turns=1,
                            warmup_s=0.0, yes=yes)  # fmt: skip
    con = ScriptedConsole()
    with pytest.raises(UserError, match="enough"):
        flow.run_dialogue(o, con, factory)  # type: ignore[arg-type]
    assert opened == [url]
    assert ("at full speed with --yes (--port sim:// shows it in real time)" in con.text) is yes


@pytest.mark.slow
def test_no_pause_before_a_turn_when_nobody_turns_the_cube(tmp_path: Path) -> None:
    """--yes on the virtual board: no 'start in' countdown (nobody is getting ready); a given
    --ready-seconds still counts down."""
    import contextlib
    import io

    from host.board.link import open_port
    from host.dialogue import flow

    for ready, counts in ((None, False), (0.5, True)):
        con = ScriptedConsole()
        shown: list[str] = []
        con.progress = shown.append  # type: ignore[method-assign]
        o = flat_options(port="sim://?speed=max&effects=linear,noise&earth_rate=0",
                                serial="R1", out=tmp_path / f"R{ready}", static_seconds=1.0,
                                turns=1, warmup_s=0.0, yes=True, ready_s=ready)  # fmt: skip
        with contextlib.redirect_stdout(io.StringIO()):
            assert flow.run_dialogue(o, con, open_port) in (0, 1)
        assert any("start in" in t for t in shown) is counts


@pytest.mark.timeout(300)  # a whole session in a subprocess: seconds alone, a minute on a busy CI
@pytest.mark.slow
def test_the_readmes_first_command_gives_a_whole_session(tmp_path: Path) -> None:
    """The command under 'Run a calibration' in README.md, as written (after ``pip install``),
    with no board: the virtual board at full speed, announced, a report, the verdict last."""
    import json
    import os
    import shlex
    import subprocess
    import sys

    root = Path(__file__).resolve().parents[3]
    readme = (root / "README.md").read_text()
    line = next(ln for ln in readme.splitlines() if ln.startswith("pip install -e . && "))
    cmd = shlex.split(line.split(" && ", 1)[1])
    assert cmd[:3] == ["python3", "-m", "host"]
    env = dict(os.environ, PYTHONPATH=str(root))
    proc = subprocess.run([sys.executable, *cmd[1:]], cwd=tmp_path, capture_output=True,
                          text=True, timeout=280, env=env)  # fmt: skip
    assert proc.returncode in (0, 1), proc.stderr[-1500:]
    assert "NO BOARD FOUND (looked at:" in proc.stderr and "at full speed" in proc.stderr
    assert "start in" not in proc.stderr  # no get-ready pause: nobody turns
    serial = cmd[cmd.index("--serial") + 1]
    assert (tmp_path / serial / f"{serial}_result.txt").exists()
    rec = (tmp_path / serial / f"{serial}_x_up.txt").read_text()
    # the virtual board is the unit of the serial: the URL names it, so the records do
    board = f"sim://?speed=max&serial={serial}"
    assert f"SIMULATED BOARD {board}" in rec
    shown = proc.stderr.rstrip("\n").splitlines()
    report = [ln for ln in shown if ln.startswith("Report: ")][-1]
    mark, url, last = shown[-3:]
    verdict = json.loads((tmp_path / serial / f"{serial}_result.json").read_text())["verdict"]
    assert last == verdict and last.startswith(("PASS", "FAIL"))
    assert report == f"Report: {serial}/{serial}_result.txt"
    # too long for the mark's line with it: the URL follows whole on its own
    assert mark == "*** SIMULATED BOARD: not a measurement of a unit ***" and url == f"    {board}"


def test_any_key_ends_the_warm_up_as_the_prompt_says() -> None:
    """The warm-up says 'Press any key when ready' (method.md § 5 step 3): it listens for any
    key, not only Esc; --yes never reads one."""
    from host.dialogue.console import ESC, Questions

    class Pressed:  # a terminal whose operator typed these keys
        interactive = True

        def __init__(self, *keys: str) -> None:
            self.keys = list(keys)

        def key(self, timeout_s: float) -> str | None:
            return self.keys.pop(0) if self.keys else None

    for k in ("x", " ", "\r", ESC):
        q = Questions(Pressed(k))
        assert q.key_pressed() is True and q.key_pressed() is False, k
    assert Questions(Pressed("x"), yes=True).key_pressed() is False
    assert Questions(Pressed("x")).escape_pressed() is False  # a measurement's Esc stays Esc
