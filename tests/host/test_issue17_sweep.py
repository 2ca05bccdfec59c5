"""Issue 17's sweep of bad inputs, re-run on every CI run (the cases: tests/host/issue17_sweep.py,
issue31_sweep.py and issue44_sweep.py;
``python3 -m tests.host.issue17_sweep`` runs them as real processes). Each gives its exit code,
one ``error:`` line naming the problem when it is 2, never a traceback, in bounded time."""

from __future__ import annotations

import contextlib
import io
import threading
import time
from pathlib import Path

import pytest

from host.__main__ import main
from tests.host.issue17_sweep import CASES, Case, check, run_process
from tests.host.issue31_sweep import CASES as WAVE
from tests.host.issue44_sweep import CASES as RULES


def run_in_process(case: Case, d: Path) -> tuple[int, str, float, str]:
    argv = case.make(d)
    feeder = None
    if case.feed_fifo:

        def feed() -> None:
            with open(d / "fifo", "wb") as f:
                f.write((d / "fifo.src").read_bytes())

        feeder = threading.Thread(target=feed, daemon=True)
        feeder.start()
    out, err = io.StringIO(), io.StringIO()
    t0 = time.monotonic()
    try:
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            rc = main(argv)
    except SystemExit as exc:
        rc = exc.code if isinstance(exc.code, int) else 2
    except Exception:  # what a user would see as a traceback
        import traceback

        err.write(traceback.format_exc())
        rc = -1
    if feeder is not None:
        feeder.join(timeout=10)
    return rc, err.getvalue(), time.monotonic() - t0, out.getvalue()


@pytest.mark.slow
@pytest.mark.timeout(90)
@pytest.mark.parametrize("case", CASES, ids=[c.name for c in CASES])
def test_bad_input_of_the_sweep(case: Case, tmp_path: Path) -> None:
    _one_case(case, tmp_path)


@pytest.mark.timeout(90)
@pytest.mark.parametrize("case", WAVE, ids=[c.name for c in WAVE])
def test_bad_input_of_the_second_round(case: Case, tmp_path: Path) -> None:
    """The new input kinds (tests/host/issue31_sweep.py): each a few seconds at most."""
    _one_case(case, tmp_path)


@pytest.mark.timeout(90)
@pytest.mark.parametrize("case", RULES, ids=[c.name for c in RULES])
@pytest.mark.slow
def test_one_rule_for_every_input(case: Case, tmp_path: Path) -> None:
    """Issue 44's cases (tests/host/issue44_sweep.py); those only a process can show (its own
    end, a closed pipe) run as real processes."""
    if case.process:
        rc, err, took, out = run_process(case, tmp_path)
        assert not check(case, rc, err, took, out), (case.why, rc, err[-800:], out[-300:])
    else:
        _one_case(case, tmp_path)


def _one_case(case: Case, tmp_path: Path) -> None:
    if case.interrupt_after_s is not None:  # Ctrl+C: a real process (once, not per CI case)
        if case.name != "decode-dev-zero":
            pytest.skip("interrupted cases run as processes")
        rc, err, took, out = run_process(case, tmp_path)
    else:
        rc, err, took, out = run_in_process(case, tmp_path)
    assert not check(case, rc, err, took, out), (case.why, rc, err[-800:], out[-300:])


def test_one_case_as_a_real_process(tmp_path: Path) -> None:
    """The script's own path (a subprocess per case) works: one quick case."""
    (case,) = [c for c in CASES if c.name == "hello-codes"]
    rc, err, took, out = run_process(case, tmp_path)
    assert not check(case, rc, err, took, out), err
    assert rc == 2 and err.count("\n") == 1  # one line, from a real process
