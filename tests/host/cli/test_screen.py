"""The width rule (host/cli/screen.py): text wrapped at words within the terminal's width."""

from __future__ import annotations

import io
import shlex
import subprocess

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from host.calib.commands import command_lines
from host.cli.screen import ScreenWriter, terminal_width, wrap


class FakeTerminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def screen_lines(text: str) -> list[str]:
    """What stays on the screen, line by line: a ``\\r`` redraw keeps only its last draw."""
    return [line.split("\r")[-1] for line in text.split("\n")]


words = st.lists(
    st.text(alphabet="abcdefghijklmnopqrstuvwxyz°σ²", min_size=1, max_size=12), min_size=1
)


@given(words, st.integers(20, 120), st.integers(0, 6))
def test_wrap_keeps_every_word_whole_and_every_line_within_the_width(
    ws: list[str], width: int, indent: int
) -> None:
    line = " " * indent + " ".join(ws)
    out = wrap(line, width).split("\n")
    assert all(len(x) <= width for x in out)
    assert " ".join(out).split() == ws  # no word broken, none lost, order kept


def test_wrap_indents_a_bullets_continuation_under_its_text() -> None:
    out = wrap("  - " + "word " * 30, 40).split("\n")
    assert out[0].startswith("  - word") and all(x.startswith("    word") for x in out[1:])


@given(words, st.integers(30, 120), st.lists(st.integers(1, 7), max_size=8))
def test_the_writer_wraps_pieces_as_they_come_like_the_whole(
    ws: list[str], width: int, cuts: list[int]
) -> None:
    """Written in pieces (a prompt, then the key's echo), the screen shows the same lines as
    when written at once, every one within the width."""
    text = " ".join(ws) + "\n"
    whole = FakeTerminal()
    ScreenWriter(whole, lambda: width).write(text)
    pieces = FakeTerminal()
    w = ScreenWriter(pieces, lambda: width)
    i = 0
    for c in cuts:  # cut at word boundaries only: a word is written whole
        j = text.find(" ", i + c)
        if j < 0:
            break
        w.write(text[i : j + 1])
        w.flush()
        i = j + 1
    w.write(text[i:])
    for got in (whole.getvalue(), pieces.getvalue()):
        lines = screen_lines(got)
        assert all(len(x) <= width for x in lines)
        assert " ".join(lines).split() == ws


def test_the_writer_lets_a_progress_redraw_and_escapes_pass() -> None:
    t = FakeTerminal()
    w = ScreenWriter(t, lambda: 30)
    w.write("\rx_up [---]  0.2/5 s\x1b[K")
    w.write("\rx_up [#--]  1.2/5 s\x1b[K")
    assert t.getvalue() == "\rx_up [---]  0.2/5 s\x1b[K\rx_up [#--]  1.2/5 s\x1b[K"


def test_the_writer_passes_a_pipe_through_unchanged() -> None:
    raw = io.StringIO()
    ScreenWriter(raw, lambda: 20).write("a " * 40 + "\n")
    assert raw.getvalue() == "a " * 40 + "\n"


@pytest.mark.parametrize("width", [60, 80, 200])
def test_a_long_command_is_broken_so_that_it_still_runs(width: int) -> None:
    cmd = ["python3", "-m", "host", "calibrate", "--from-dir", "my dir/", "--model",
           "base,temperature_bias:gyro:y,lever_arm:accel,scale_nonlinearity:accel,"
           "temperature_scale:accel,temperature_bias_quadratic:gyro",
           "--floor", "accel=5e-4,gyro=3e-3"]  # fmt: skip
    text = command_lines(cmd, width, lead="ship this model: ")
    assert all(len(x) <= width for x in text.split("\n"))
    pasted = text.removeprefix("ship this model: ")
    got = subprocess.run(["sh", "-c", "printf '%s\\n' " + pasted.split(" ", 1)[1]],
                         capture_output=True, text=True, check=True).stdout  # fmt: skip
    assert got.split("\n")[:-1] == cmd[1:]
    assert shlex.split(pasted.replace("\\\n", "")) == cmd  # the shell's line joining


def test_the_width_is_the_terminal_else_columns_else_80(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("COLUMNS", "123")
    assert terminal_width(io.StringIO()) == 123  # not a terminal: COLUMNS
    monkeypatch.delenv("COLUMNS")
    assert terminal_width(io.StringIO()) == 80  # not a terminal: 80


def test_the_width_rule_lets_through_only_a_word_that_cannot_break() -> None:
    """The tests' 80-column rule (``too_wide``): a sentence or a command over 80 columns
    fails it; a path longer than a line, alone or before a ``\\``, quoted or not, passes."""
    from tests.host.cli.cli_run import too_wide

    path = "/tmp/" + "deep/" * 18 + "records"
    assert too_wide("The model does not fit these records " * 3)
    assert too_wide(f"Next: python3 -m host model diagnose {path}")
    assert too_wide(f"Report: {path}")
    assert not too_wide(f"{path}\n    {path} \\\n  '{path}/with a space' \\")
    assert not too_wide("a" * 80 + "\n" + "short line")


@settings(max_examples=150, deadline=None)
@given(
    out=st.text(st.characters(blacklist_categories=("Cc", "Cs")), min_size=1, max_size=100),
    width=st.integers(min_value=30, max_value=120),
)
def test_a_resume_command_on_a_terminal_still_pastes(out: str, width: int) -> None:
    """Was: on a terminal the writer broke a quoted --out with spaces at a space (a newline
    inside the quotes: another directory) and put a line's ``\\`` alone on the next line (the
    command ended there). The terminal folds such a line; the writer leaves it whole."""
    from host.calib.commands import said_with_command

    cmd = ["python3", "-m", "host", "calibrate", "--port", "sim://?seed=1&noise_seed=1&a=1,2",
           "--serial",
           "F1", "--out", out, "--warmup", "0", "--resume"]  # fmt: skip
    t = FakeTerminal()
    ScreenWriter(t, lambda: width).write("error: " + said_with_command("kept; continue with:", cmd))
    lines = screen_lines(t.getvalue())
    k = next(i for i, ln in enumerate(lines) if ln.startswith("  python3 -m host"))
    assert shlex.split("\n".join(lines[k:]).replace("\\\n", "")) == cmd


def test_prose_with_an_apostrophe_still_wraps() -> None:
    t = FakeTerminal()
    text = "the operator's time " * 6 + "'x_side' is not a record name " * 3
    ScreenWriter(t, lambda: 40).write(text)
    lines = screen_lines(t.getvalue())
    assert all(len(x) <= 40 for x in lines) and " ".join(lines).split() == text.split()
