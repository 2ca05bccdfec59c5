"""One command run in-process for the CLI tests: its exit status and what it printed."""

from __future__ import annotations

import contextlib
import io


def run(argv: list[str]) -> tuple[int, str, str]:
    """``python -m host ARGV`` in this process: (exit status, stdout, stderr); argparse's
    SystemExit counts as the exit status."""
    from host.__main__ import main

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            rc = main(argv)
        except SystemExit as exc:
            rc = int(exc.code or 0)
    return rc, out.getvalue(), err.getvalue()
