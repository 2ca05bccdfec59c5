"""Shell commands laid out to be pasted: :func:`command_lines` breaks a command too long for
a line between its words with ``\\`` continuations, so that it still runs when pasted — the
report's and the screen's next command (:mod:`host.calib.report`) and every command the
command line prints (:mod:`host.cli`); :func:`said_with_command`, a sentence that ends on a
command (an error's resume command) laid out the same way."""

from __future__ import annotations

import re
import shlex
import textwrap
from collections.abc import Sequence

#: the columns a printed error's ``error: `` takes before its text (``python3 -m host``)
ERROR_LEAD = len("error: ")


def _split_word(word: str, room: int) -> list[str]:
    """A shell word longer than ``room`` cut after commas into pieces of at most ``room``
    (joined by a backslash-newline with no indent, the shell reads them as one word)."""
    pieces: list[str] = []
    cur = ""
    for part in re.findall(r"[^,]*,|[^,]+", word):
        if cur and len(cur) + len(part) > room:
            pieces.append(cur)
            cur = ""
        cur += part
    return pieces + [cur]


def command_lines(cmd: Sequence[str], width: int, lead: str = "") -> str:
    """The shell command ``cmd`` (its words) after ``lead``, on one line when it fits, else
    broken between words with `` \\`` and a 4-space indent (a word too long for a line, such
    as a model spec, after its commas with ``\\`` and no indent): pasted, it runs unchanged."""
    w = width
    words = [shlex.quote(a) for a in cmd]
    lines: list[str] = []
    cur = lead + (words[0] if words else "")
    for arg, word in zip(cmd[1:], words[1:], strict=True):
        if len(cur) + 1 + len(word) + 2 <= w:
            cur += " " + word
            continue
        lines.append(cur + " \\")
        cur = "    " + word
        # cut only a word the shell reads unquoted: inside quotes a backslash-newline stays
        if len(cur) + 2 > w and "," in word and word == arg:
            pieces = _split_word(word, w - 6)
            lines.append("    " + pieces[0] + "\\")
            lines += [p + "\\" for p in pieces[1:-1]]
            cur = pieces[-1]
    lines.append(cur)
    return "\n".join(lines)


def said_with_command(
    text: str, cmd: Sequence[str], width: int = 80, first: int = ERROR_LEAD
) -> str:
    """``text`` (a sentence ending on e.g. ``continue with:``) wrapped at words within
    ``width``, its first line ``first`` columns shorter (the ``error: `` printed before it); a
    word longer than a line, a path, stays whole on a line of its own. Then the shell command
    ``cmd`` on lines of its own, indented 2 and broken by :func:`command_lines`, so that only
    a path can run past ``width`` and the command still runs as printed when pasted."""
    lines = textwrap.wrap(text, width, initial_indent=" " * first, break_long_words=False,
                          break_on_hyphens=False) or [" " * first]  # fmt: skip
    lines[0] = lines[0][first:]
    return "\n".join(lines) + "\n" + command_lines(cmd, width, lead="  ")
