#!/usr/bin/env python3
"""How long the test suite takes: the quick loop (``-m "not slow"``) and, with ``--full``, the
whole suite (issue 31, item 8: quick loop under 2 minutes on 2 cores, full suite under 8 on
an idle 2-core machine).

    python benchmarks/suite_times.py [--full | --only-full] [--workers 1,2] [--top N]
                                     [--marker EXPR] [--save FILE] [PATH ...]

Each run is ``python3 -m pytest -q`` in a fresh process, as CI runs it, over PATH (default: the
whole ``tests`` tree); ``--workers 1,2`` runs the same tests once per worker count, one after
the other, so that their wall times are compared under the same load (``-n N`` of
pytest-xdist, ``--dist loadfile`` as CI runs it). Prints per run its wall time, the CPU time
of pytest and every process it started (``getrusage(RUSAGE_CHILDREN)``), the sum over the
tests of each test's own CPU time (``benchmarks/suite_cpu.py``: what the tests cost whatever
the load or the worker count), the tests counted, the load average before and after, and with
``--top N`` the N tests of most CPU time. On a shared machine the wall time is the load's as
much as the suite's, the CPU time is not: on an idle 2-core machine the wall time of one worker
is about the CPU time, of two workers about half of it, plus the tests that wait on a clock
(live sessions, emulated boards in real time).
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import re
import resource
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def run_suite(
    marker: str | None, workers: int, paths: list[str]
) -> tuple[float, float, str, list[dict]]:
    """Wall time (s), CPU time (s), pytest's summary line (and its FAILED lines) and each
    test's own times (``{"test", "cpu", "wall"}``) of one run of the suite."""
    cmd = [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-p",
           "benchmarks.suite_cpu"]  # fmt: skip
    if marker:
        cmd += ["-m", marker]
    if workers > 1:
        cmd += ["-n", str(workers), "--dist", "loadfile"]
    cmd += paths
    env = dict(os.environ)
    for name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        env.setdefault(name, "1")
    env["PYTHONPATH"] = os.pathsep.join(p for p in (str(ROOT), env.get("PYTHONPATH")) if p)
    with tempfile.TemporaryDirectory(prefix="suite-times-") as tmp:
        env["SUITE_CPU_OUT"] = str(Path(tmp) / "tests.jsonl")
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        t0 = time.perf_counter()
        # Ctrl+C as a terminal has it: a background job starts with SIGINT ignored, and the
        # tests of Ctrl+C then fail (Python installs its handler only where SIGINT is not
        # ignored)
        r = subprocess.run(
            cmd, cwd=ROOT, env=env, capture_output=True, text=True,
            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
        )  # fmt: skip
        wall = time.perf_counter() - t0
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        out_file = Path(env["SUITE_CPU_OUT"])
        tests = [json.loads(ln) for ln in out_file.read_text().splitlines()] if (
            out_file.exists()) else []  # fmt: skip
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    out = r.stdout.splitlines()
    lines = [ln for ln in out if re.search(r"\d+ (passed|failed)", ln)]
    summary = lines[-1].strip("= ") if lines else f"exit {r.returncode}"
    failed = [ln for ln in out if ln.startswith(("FAILED ", "ERROR "))]
    return wall, cpu, "\n  ".join([summary, *failed]), tests


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("paths", nargs="*", help="test files or folders (default: tests)")
    ap.add_argument("--full", action="store_true", help="also time the whole suite")
    ap.add_argument("--only-full", action="store_true", help="time the whole suite only")
    ap.add_argument(
        "--marker", help="time the tests of this -m expression only (instead of the quick loop)"
    )
    ap.add_argument(
        "--workers", default="1",
        help="pytest-xdist workers, a comma list run one after the other (default 1: one "
             "process; CI runs 2)",
    )  # fmt: skip
    ap.add_argument("--top", type=int, default=0, help="print the N tests of most CPU time")
    ap.add_argument("--save", help="append each test's times to this file (JSON lines)")
    args = ap.parse_args()
    try:
        workers = [int(w) for w in args.workers.split(",")]
    except ValueError:
        ap.error(f"--workers {args.workers!r}: give counts like 1 or 1,2")
    if max(workers) > 1 and importlib.util.find_spec("xdist") is None:
        ap.error("--workers above 1 needs pytest-xdist (pip install -e '.[test]')")
    if args.marker is not None:
        runs = [(f"-m '{args.marker}'", args.marker)]
    else:
        runs = [] if args.only_full else [("quick loop (-m 'not slow')", "not slow")]
        if args.full or args.only_full:
            runs.append(("full suite", None))
    print(f"{os.cpu_count()} cores; {' '.join(args.paths) or 'tests'}")
    for name, marker in runs:
        for n in workers:
            load0 = os.getloadavg()[0]
            wall, cpu, summary, tests = run_suite(marker, n, args.paths)
            load1 = os.getloadavg()[0]
            per_test = sum(t["cpu"] for t in tests)
            print(
                f"{name} -n {n}: wall {wall / 60:5.2f} min  CPU {cpu / 60:5.2f} min  "
                f"sum of tests' CPU {per_test / 60:5.2f} min  load {load0:4.1f} -> "
                f"{load1:4.1f}\n  {summary}"
            )
            if args.save:
                with open(args.save, "a") as f:
                    f.writelines(json.dumps({**t, "workers": n}) + "\n" for t in tests)
            for t in sorted(tests, key=lambda t: -t["cpu"])[: args.top]:
                print(f"  {t['cpu']:6.1f} s CPU {t['wall']:6.1f} s wall  {t['test']}")


if __name__ == "__main__":
    main()
