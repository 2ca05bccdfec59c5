"""The one width rule of the command line: every line within the terminal's width, wrapped at
words, never cut mid-word by the terminal.

- :func:`terminal_width` — the terminal's columns now (the terminal, else ``COLUMNS``, else 80).
- :func:`wrap` — text wrapped at words; a continuation keeps the line's indent (a bullet's text
  indent), so tables and lists stay readable.
- a shell command too long for one line: :func:`host.calib.commands.command_lines` (the
  report names commands too, below the command line).
- :func:`table` — columns side by side; when they do not fit, the least needed columns are left
  out (and named in a last line), a table row is never wrapped.
- :class:`Progress` — the line that shows a long wait moving; :func:`working` — that line
  for a step that cannot say how far it is: its name and the seconds it has taken.
- :class:`ScreenWriter` — a text stream that wraps what passes through it at words as it is
  written (prompts without a newline too), when it goes to a terminal — never inside a
  shell-quoted word nor before a command's ``\\`` continuation, so a command still pastes;
  ``python3 -m host`` puts its stdout and stderr through it (``\\r`` redraws and terminal
  escapes pass unchanged and take no width). Into a pipe or a file lines stay whole, for
  ``grep`` and for programs.

Tables are made narrow where they are built (dropping or shortening columns); the writer only
wraps prose, so a table row that is still too wide shows up in the 80-column test.
"""

from __future__ import annotations

import contextlib
import io
import math
import os
import re
import textwrap
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from typing import TextIO

#: the width when the terminal does not say (a pipe, a file, a CI log)
DEFAULT_WIDTH = 80
_BULLET = re.compile(r"^(\s*)([-*•]\s+|\d+[.)]\s+)?")
#: zero-width pieces (terminal escapes), line controls, spaces, words
_TOKENS = re.compile(r"\x1b\[[0-9;?]*[A-Za-z]|[\r\n\b\a\x1b]|[ \t]+|[^ \t\r\n\b\a\x1b]+")


def terminal_width(stream: TextIO | None = None) -> int:
    """Columns of the terminal now: the size of the terminal ``stream`` (default: stdout)
    shows on (read each time: a window may be resized), else ``COLUMNS``, else 80."""
    import sys

    out = stream if stream is not None else sys.stdout
    try:
        cols = os.get_terminal_size(out.fileno()).columns
    except (OSError, ValueError, AttributeError, io.UnsupportedOperation):
        cols = 0
    if cols <= 0:
        try:
            cols = int(os.environ.get("COLUMNS", "0"))
        except ValueError:
            cols = 0
    return cols if cols > 0 else DEFAULT_WIDTH


def hang_of(line: str) -> int:
    """Indent of a line's continuation: its leading spaces, plus a bullet's width."""
    m = _BULLET.match(line)
    return len(m.group(0)) if m else 0


def wrap(text: str, width: int | None = None) -> str:
    """``text`` with every line longer than ``width`` wrapped at spaces (never inside a word,
    never at a hyphen); continuations indented like the line's text. A single word longer than
    the line stays whole (a path is not broken)."""
    w = width or terminal_width()
    out: list[str] = []
    for line in text.split("\n"):
        if len(line) <= w:
            out.append(line)
            continue
        h = hang_of(line)
        out.extend(
            textwrap.wrap(
                line[h:],
                w,
                initial_indent=line[:h],
                subsequent_indent=" " * min(h, w // 2),
                break_long_words=False,
                break_on_hyphens=False,
            )  # fmt: skip
            or [line]
        )
    return "\n".join(out)


#: how an example of a command's help starts: the command, on lines of its own
EXAMPLE_START = "  python3 -m host "


def help_examples(text: str, width: int) -> str:
    """A help text whose examples (lines starting with :data:`EXAMPLE_START`, continued by
    lines after a trailing `` \\``) are laid out whole: each command on lines of its own,
    broken only between words with `` \\`` and a 4-space indent, as written (a quote or a
    glob kept), so that it runs when pasted; its description — the lines indented more, after
    it — and every other line wrapped at words under their indent."""
    out: list[str] = []
    lines = text.split("\n")
    i = 0
    while i < len(lines):
        line = lines[i]
        if not line.startswith(EXAMPLE_START):
            out.append(wrap(line, width))
            i += 1
            continue
        while line.endswith("\\") and i + 1 < len(lines):  # its continuation lines
            i += 1
            line = line[:-1] + lines[i].strip()
        out.append(_example_command(line, width))
        i += 1
    return "\n".join(out)


def _example_command(line: str, width: int) -> str:
    """One example's command (its words as written, shell quotes kept) on one line when it
    fits in ``width``, else broken with `` \\`` before an option (an option and its values
    kept together where they fit a line), continued 4 columns in."""
    import shlex

    units: list[list[str]] = []
    for word in shlex.split(line, posix=False):  # each word as written, quotes and all
        if not units or (word.startswith("--") and units[-1][0] != ""):
            units.append([word])
        else:
            units[-1].append(word)
    lines: list[str] = []
    cur = "  " + units[0][0]
    for unit in [units[0][1:], *units[1:]]:
        if not unit:
            continue
        text = " ".join(unit)
        if len(cur) + 1 + len(text) + 2 <= width:
            cur += " " + text
            continue
        for word in unit if len("    " + text) + 2 > width else [text]:
            if len(cur) + 1 + len(word) + 2 <= width:
                cur += " " + word
            else:
                lines.append(cur + " \\")
                cur = "    " + word
    return "\n".join([*lines, cur])


@dataclass(frozen=True)
class Column:
    """One column of :func:`table`: its header, its cells (one per row), ``<`` or ``>``
    alignment, ``rank`` (when the table is too wide, the highest rank goes first; rank 0 is
    never left out) and ``size``, a least width (for rows printed as they come)."""

    header: str
    cells: Sequence[str] = ()
    align: str = ">"
    rank: int = 0
    size: int = 0

    @property
    def width(self) -> int:
        return max([self.size, len(self.header), *(len(c) for c in self.cells)])


def fit_columns(columns: Sequence[Column], width: int, gap: int = 2) -> list[Column]:
    """The columns that fit in ``width``: the highest rank left out first, until the rest fit."""
    shown = list(columns)

    def total(cols: Sequence[Column]) -> int:
        return sum(c.width for c in cols) + gap * max(len(cols) - 1, 0)

    while total(shown) > width and any(c.rank > 0 for c in shown):
        shown.remove(max((c for c in shown if c.rank > 0), key=lambda c: c.rank))
    return shown


def table_row(columns: Sequence[Column], cells: Sequence[str], gap: int = 2) -> str:
    """One row of cells (one per column, in order), each padded to its column's width."""
    return (
        (" " * gap)
        .join(f"{t:{c.align}{c.width}}" for c, t in zip(columns, cells, strict=True))
        .rstrip()
    )


def left_out(columns: Sequence[Column], shown: Sequence[Column], width: int) -> list[str]:
    """The line naming the columns :func:`fit_columns` left out (none when all are shown)."""
    left = [c.header for c in columns if not any(c is s for s in shown)]
    if not left:
        return []
    return [f"(not shown at {width} columns: {', '.join(left)}; a wider terminal shows them)"]


def table(columns: Sequence[Column], width: int | None = None, gap: int = 2) -> list[str]:
    """The rows of ``columns`` (header first) within ``width``: columns are left out, highest
    rank first, until the rest fits; a last line names what was left out."""
    w = width or terminal_width()
    shown = fit_columns(columns, w, gap)
    rows = len(shown[0].cells) if shown else 0
    out = [table_row(shown, [c.header for c in shown], gap)]
    out += [table_row(shown, [c.cells[i] for c in shown], gap) for i in range(rows)]
    return out + left_out(columns, shown, w)


class Progress:
    """What a command is doing while the user waits: on a terminal one line redrawn in place
    (within the width), into a log a line at most every ``every_s`` seconds."""

    def __init__(self, stream: TextIO | None = None, every_s: float = 5.0) -> None:
        import sys

        self.stream = stream if stream is not None else sys.stderr
        self.every_s = every_s
        self._shown = False
        self._last = -math.inf

    def show(self, text: str) -> None:
        import time

        if self.stream.isatty():
            w = terminal_width(self.stream)
            self.stream.write("\r" + text[: w - 1] + "\x1b[K")
            self._shown = True
        else:
            now = time.monotonic()
            if now - self._last < self.every_s:
                return
            self._last = now
            self.stream.write(text + "\n")
        self.stream.flush()

    def done(self) -> None:
        """Clear the line (the next output starts on a clean line)."""
        if self._shown:
            self.stream.write("\r\x1b[K")
            self.stream.flush()
            self._shown = False


@contextlib.contextmanager
def working(label: str, stream: TextIO | None = None, after_s: float = 1.0) -> Iterator[None]:
    """While the body runs: after ``after_s`` s, the progress line ``label … N s``, redrawn
    every half second (a step that cannot count its parts still shows it is alive); cleared
    at the end. The body must not print meanwhile (its text and the line would mix)."""
    import threading
    import time

    progress = Progress(stream)
    stop = threading.Event()
    start = time.monotonic()

    def beat() -> None:
        if stop.wait(after_s):
            return
        while True:
            progress.show(f"{label} … {time.monotonic() - start:.0f} s")
            if stop.wait(0.5):
                return

    thread = threading.Thread(target=beat, name="progress", daemon=True)
    thread.start()
    try:
        yield
    finally:
        stop.set()
        thread.join()
        progress.done()


def quote_after(word: str, quote: str = "") -> str:
    """The shell quote (``'``, ``"`` or none) open after ``word``, read from ``quote``."""
    for c in word:
        if quote:
            quote = "" if c == quote else quote
        elif c in "'\"":
            quote = c
    return quote


class ScreenWriter(io.TextIOBase):
    """A text stream that wraps at words what is written through it, as it is written, when
    ``raw`` is a terminal (else it passes everything through unchanged).

    It keeps the screen column: a word that would run past ``width`` starts a new line
    (indented like the line it continues); spaces at a break are dropped. ``\\r`` returns to
    column 0 (a progress line redrawn in place), terminal escapes take no width. Everything
    else — ``isatty``, ``fileno``, ``flush``, the encoding — is the wrapped stream's."""

    def __init__(self, raw: TextIO, width: Callable[[], int] | None = None) -> None:
        super().__init__()
        self.raw = raw
        self._width = width or (lambda: terminal_width(raw))
        self._col = 0
        self._line = ""  # the current screen line's start (for its indent)
        self._spaces = ""  # spaces written but not shown yet (dropped at a break)
        self._hang = 0
        self._quote = ""  # the shell quote a command's word left open on this line ('' none)
        self.on_terminal = self.isatty()
        self._out: list[str] = []

    # the stream the writer stands for
    @property
    def encoding(self) -> str:  # type: ignore[override]
        return str(getattr(self.raw, "encoding", "utf-8") or "utf-8")

    @property
    def errors(self) -> str | None:  # type: ignore[override]
        return getattr(self.raw, "errors", None)

    def isatty(self) -> bool:
        return bool(getattr(self.raw, "isatty", lambda: False)())

    def fileno(self) -> int:
        return self.raw.fileno()

    def writable(self) -> bool:
        return True

    def flush(self) -> None:
        if self.on_terminal and self._spaces and self._col + len(self._spaces) < self._width():
            self.raw.write(self._spaces)
            self._col += len(self._spaces)
            self._line += self._spaces
            self._spaces = ""
        self.raw.flush()

    def _emit(self, s: str) -> None:
        self._out.append(s)

    def write(self, s: str) -> int:  # type: ignore[override]
        if not self.on_terminal:
            return self.raw.write(s)
        width = max(self._width(), 1)
        for tok in _TOKENS.findall(s):
            if tok[0] in "\x1b\a":
                self._emit(tok)
            elif tok == "\n":
                self._spaces, self._quote = "", ""
                self._emit("\n")
                self._col, self._line = 0, ""
            elif tok == "\r":
                self._spaces, self._quote = "", ""
                self._emit("\r")
                self._col, self._line = 0, ""
            elif tok == "\b":
                self._emit(tok)
                self._col = max(0, self._col - 1)
            elif tok[0] in " \t":
                if self._col == 0 and not self._line:
                    self._emit(tok)  # a line's own indent is shown as written
                    self._col += len(tok)
                    self._line += tok
                else:
                    self._spaces += tok.replace("\t", " ")
            else:
                if not self._line.strip():
                    self._hang = hang_of(self._line + tok + " ")
                need = len(self._spaces) + len(tok)
                # a command laid out to be pasted is never broken inside a quoted word (a
                # path with spaces) nor before its line's continuation: a newline there would
                # end the word or the command; the terminal folds the long line instead
                whole = bool(self._quote) or tok == "\\"
                if self._col + need > width and self._line.strip() and not whole:
                    hang = min(self._hang, width // 2)
                    self._emit("\n" + " " * hang)
                    self._col, self._line, self._spaces = hang, " " * hang, ""
                self._emit(self._spaces + tok)
                self._col += len(self._spaces) + len(tok)
                self._line += self._spaces + tok
                self._spaces = ""
                if self._quote or tok.startswith("'"):  # shlex.quote's words start so
                    self._quote = quote_after(tok, self._quote)
        self.raw.write("".join(self._out))  # one write: a redraw is not torn apart
        self._out.clear()
        return len(s)
