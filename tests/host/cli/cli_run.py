"""One command run in-process for the CLI tests: its exit status and what it printed."""

from __future__ import annotations

import contextlib
import io


def run(argv: list[str]) -> tuple[int, str, str]:
    """``python3 -m host ARGV`` in this process: (exit status, stdout, stderr); argparse's
    SystemExit counts as the exit status."""
    from host.__main__ import main

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            rc = main(argv)
        except SystemExit as exc:
            rc = int(exc.code or 0)
    return rc, out.getvalue(), err.getvalue()


def one_word(line: str) -> bool:
    """Whether ``line`` is a single word the shell reads whole (a path, or one quoted for the
    shell), alone on its line or before a ``\\`` continuation: the only text that cannot be
    broken to fit a line."""
    import shlex

    body = line.strip().removesuffix("\\").strip()
    if body and not any(c.isspace() for c in body):
        return True
    try:
        return len(shlex.split(body)) == 1
    except ValueError:
        return False


def too_wide(text: str, width: int = 80) -> list[str]:
    """The lines of ``text`` wider than ``width`` that could have been broken: any but
    :func:`one_word` lines."""
    return [ln for ln in text.splitlines() if len(ln) > width and not one_word(ln)]


def pasted(lines: list[str]) -> list[str]:
    """The words a shell reads from ``lines`` pasted (``\\``-newline continuations joined)."""
    import shlex

    return shlex.split("\n".join(lines).replace("\\\n", ""))


def command_from(lines: list[str], lead: str = "Next: ") -> list[str]:
    """The words of the command on the first of ``lines`` that starts (stripped) with
    ``lead``, over its ``\\`` continuations, as a shell reads it pasted (a report's
    ``(what the model lacks)`` after it left out)."""
    i = next(i for i, ln in enumerate(lines) if ln.strip().startswith(lead))
    n = next(j for j in range(i, len(lines)) if not lines[j].rstrip().endswith("\\")) + 1
    body = [lines[i].strip().removeprefix(lead), *lines[i + 1 : n]]
    body[-1] = body[-1].removesuffix("(what the model lacks)")
    return pasted(body)


def command_after(text: str, said: str = "with:") -> list[str]:
    """The words of the command printed on the lines after the last line of ``text`` that ends
    with ``said`` (a resume hint's ``continue with:``, its last word alone on a line when the
    sentence is wrapped), over its ``\\`` continuations, as a shell reads it pasted."""
    lines = text.splitlines()
    i = max(k for k, ln in enumerate(lines) if ln.rstrip().endswith(said)) + 1
    n = next(j for j in range(i, len(lines)) if not lines[j].rstrip().endswith("\\")) + 1
    return pasted(lines[i:n])
