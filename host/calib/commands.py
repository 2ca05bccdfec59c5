"""Shell commands laid out to be pasted: :func:`command_lines` breaks a command too long for
a line between its words with ``\\`` continuations, so that it still runs when pasted — the
report's and the screen's next command (:mod:`host.calib.report`) and every command the
command line prints (:mod:`host.cli`)."""

from __future__ import annotations

import re
import shlex
from collections.abc import Sequence


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
    for word in words[1:]:
        if len(cur) + 1 + len(word) + 2 <= w:
            cur += " " + word
            continue
        lines.append(cur + " \\")
        cur = "    " + word
        if len(cur) + 2 > w and "," in word and word == shlex.quote(word.strip("'")):
            pieces = _split_word(word, w - 6)
            lines.append("    " + pieces[0] + "\\")
            lines += [p + "\\" for p in pieces[1:-1]]
            cur = pieces[-1]
    lines.append(cur)
    return "\n".join(lines)
