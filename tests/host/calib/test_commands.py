"""Commands laid out to be pasted (host/calib/commands.py): a sentence that ends on a command
(an error's resume command) keeps to the width but for a path, and the shell reads back the
very words, whatever the path holds (spaces, commas, quotes, a ``$``)."""

from __future__ import annotations

import shlex
import subprocess

from hypothesis import given, settings
from hypothesis import strategies as st

from host.calib.commands import ERROR_LEAD, command_lines, said_with_command
from tests.host.cli.cli_run import pasted, too_wide

#: what a directory name may hold (no control characters: a newline is not typed at a prompt)
PATH_TEXT = st.text(st.characters(blacklist_categories=("Cc", "Cs")), min_size=1, max_size=120)


def resume_words(out: str) -> list[str]:
    return ["python3", "-m", "host", "calibrate", "--port", "sim://?seed=6&noise_seed=6&a=1,2",
            "--serial",
            "F1", "--out", out, "--static-seconds", "2", "--warmup", "0", "--resume"]  # fmt: skip


@settings(max_examples=200, deadline=None)
@given(out=PATH_TEXT, first=st.sampled_from([0, ERROR_LEAD]))
def test_a_resume_command_keeps_to_80_columns_and_reads_back_whatever_the_path(
    out: str, first: int
) -> None:
    text = f"the board did not come back; 3 accepted records are kept in {out}; continue with:"
    said = said_with_command(text, resume_words(out), first=first)
    lines = said.split("\n")
    assert too_wide(" " * first + said) == []  # only a single word (the path) passes 80
    k = next(i for i, ln in enumerate(lines) if ln.startswith("  python3 -m host calibrate"))
    assert " ".join(" ".join(lines[:k]).split()) == " ".join(text.split())  # nothing lost
    assert pasted(lines[k:]) == resume_words(out)  # the --out argument round-trips
    assert all(ln.startswith("  ") for ln in lines[k:])  # the command on lines of its own


def test_a_shell_runs_the_command_as_printed() -> None:
    """Through a real shell: a path with spaces, commas and quotes, longer than a line."""
    out = "/tmp/Bob's data, run 2/" + "a long directory name, with a comma " * 3 + "F1"
    said = said_with_command("3 records are kept; continue with:", resume_words(out), first=0)
    body = said.split("\n", 1)[1].replace("python3 -m host", "printf '%s\\n'", 1)
    got = subprocess.run(["sh", "-c", body], capture_output=True, text=True, check=True).stdout
    assert got.split("\n")[:-1] == resume_words(out)[3:]


def test_a_quoted_word_is_never_cut_inside_its_quotes() -> None:
    """Was: a word over a line with commas was cut after a comma by a backslash-newline even
    when quoted (a space in it), where the shell keeps the backslash and the newline."""
    word = "my dir/" + "a,b," * 40
    text = command_lines(["python3", "-m", "host", "x", "--out", word], 80)
    assert shlex.split(text.replace("\\\n", "")) == ["python3", "-m", "host", "x", "--out", word]
