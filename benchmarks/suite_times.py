#!/usr/bin/env python3
"""How long the test suite takes: the quick loop (``-m "not slow"``) and, with ``--full``, the
whole suite (issue 31, item 8: quick loop under 2 minutes on 2 cores, full suite under 8 on
an idle 2-core machine).

    python benchmarks/suite_times.py [--full] [--workers N] [--only-full]

Each run is ``python3 -m pytest -q`` in a fresh process, as CI runs it (``--workers N``: with
pytest-xdist's ``-n N``, if installed; not part of CI). Prints its wall time, the CPU
time of pytest and every process it started (``getrusage(RUSAGE_CHILDREN)``), the tests
counted, and the load average before and after: on a shared machine the wall time is the
load's as much as the suite's, the CPU time is not (on an idle machine the wall time of one
worker is about the CPU time, of two workers about half of it).
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import re
import resource
import signal
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def run_suite(marker: str | None, workers: int) -> tuple[float, float, str]:
    """Wall time (s), CPU time (s) and pytest's summary line (and its FAILED lines) of one
    run of the suite."""
    cmd = [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider"]
    if marker:
        cmd += ["-m", marker]
    if workers > 1:
        cmd += ["-n", str(workers)]
    env = dict(os.environ)
    for name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        env.setdefault(name, "1")
    env.setdefault("PYTHONPATH", str(ROOT))
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    # Ctrl+C as a terminal has it: a background job starts with SIGINT ignored, and the tests
    # of Ctrl+C then fail (Python installs its handler only where SIGINT is not ignored)
    r = subprocess.run(
        cmd, cwd=ROOT, env=env, capture_output=True, text=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )  # fmt: skip
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    out = r.stdout.splitlines()
    lines = [ln for ln in out if re.search(r"\d+ (passed|failed)", ln)]
    summary = lines[-1].strip("= ") if lines else f"exit {r.returncode}"
    failed = [ln for ln in out if ln.startswith(("FAILED ", "ERROR "))]
    return wall, cpu, "\n  ".join([summary, *failed])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--full", action="store_true", help="also time the whole suite")
    ap.add_argument("--only-full", action="store_true", help="time the whole suite only")
    has_xdist = importlib.util.find_spec("xdist") is not None
    ap.add_argument(
        "--workers", type=int, default=1,
        help="pytest-xdist workers (-n N; default 1: one process, as CI runs it)",
    )  # fmt: skip
    args = ap.parse_args()
    if args.workers > 1 and not has_xdist:
        ap.error("--workers above 1 needs pytest-xdist (pip install pytest-xdist)")
    runs = [] if args.only_full else [("quick loop (-m 'not slow')", "not slow")]
    if args.full or args.only_full:
        runs.append(("full suite", None))
    print(f"{os.cpu_count()} cores, {args.workers} pytest worker(s)")
    for name, marker in runs:
        load0 = os.getloadavg()[0]
        wall, cpu, summary = run_suite(marker, args.workers)
        load1 = os.getloadavg()[0]
        print(
            f"{name:28s} wall {wall / 60:5.2f} min  CPU {cpu / 60:5.2f} min  "
            f"load {load0:4.1f} -> {load1:4.1f}  ({summary})"
        )


if __name__ == "__main__":
    main()
