#!/usr/bin/env python3
"""Peak memory and time of ``python3 -m host calibrate --from-dir`` against the number of records
(issue 31, item 3: memory that grows with the data, not with its square).

    python benchmarks/fit_memory.py [--sizes 1,10,100] [--keep DIR]

One simulated session (6 statics of 30 s and 6 turns: 12 records) is the 1× baseline; k× is k
such sessions of the same unit (other seeds) in one directory, the repeats named ``x_up_2``, ….
Each size runs the whole command in a fresh process; its peak resident set size is read with
``resource.getrusage(RUSAGE_CHILDREN).ru_maxrss`` by a wrapper that waits for it. Prints the
records, peak RSS and CPU time, each also as a ratio to the 1× run of the same invocation
(linear: the CPU time and the memory above the interpreter's own grow like the records).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
from host.bench.plan import Plan, simulate_session, write_session  # noqa: E402
from host.bench.truth import SensorTruth  # noqa: E402

WRAPPER = (
    "import resource, subprocess, sys\n"
    "rc = subprocess.call(sys.argv[1:], stdout=subprocess.DEVNULL)\n"
    "ru = resource.getrusage(resource.RUSAGE_CHILDREN)\n"
    "print(rc, ru.ru_maxrss, ru.ru_utime + ru.ru_stime)\n"
)
#: the interpreter with numpy and the package imported, no records: what does not grow
IDLE = [sys.executable, "-c", "import host.calib.publish, host.model.fit"]


def peak_rss(cmd: list[str]) -> tuple[int, float, float]:
    """Run ``cmd``; its exit code, peak RSS in MiB and CPU time in s (user + system: on a
    shared machine the wall time mostly measures the others' load)."""
    env = dict(os.environ, PYTHONPATH=str(ROOT), OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1")
    r = subprocess.run(
        [sys.executable, "-c", WRAPPER, *cmd],
        capture_output=True, text=True, cwd=ROOT, check=True, env=env,
    )  # fmt: skip
    rc, kb, cpu = r.stdout.split()
    return int(rc), int(kb) / 1024, float(cpu)


def write_sessions(out: Path, copies: int) -> int:
    """``copies`` simulated sessions of one unit into ``out``; -> the number of records."""
    truth = SensorTruth.random(np.random.default_rng(0)).only("linear", "noise")
    n = 0
    for k in range(copies):
        recs = simulate_session(truth, Plan(static_s=30.0), seed=k)
        if k:
            recs = {f"{n}_{k + 1}": replace(r, name=f"{n}_{k + 1}") for n, r in recs.items()}
        write_session(out, "MEM", recs)
        n += len(recs)
    return n


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", default="1,10,100", help="multiples of the 12-record session")
    ap.add_argument("--keep", type=Path, help="write the sessions here and keep them")
    args = ap.parse_args()
    sizes = [int(s) for s in args.sizes.split(",")]
    base = args.keep or Path(tempfile.mkdtemp(prefix="fit_memory_"))
    _, idle, _ = peak_rss(IDLE)
    print(f"interpreter with the package imported: {idle:.0f} MiB")
    print(f"{'size':>5} {'records':>8} {'peak MiB':>9} {'× 1×':>6} {'above idle':>11} "
          f"{'× 1×':>6} {'CPU s':>7} {'× 1×':>6}")  # fmt: skip
    first: tuple[float, float, float] | None = None
    for k in sizes:
        d = base / f"x{k}"
        d.mkdir(parents=True, exist_ok=True)
        n = write_sessions(d, k)
        (d / "out").mkdir(exist_ok=True)
        cmd = [sys.executable, "-m", "host", "calibrate", "--from-dir", str(d),
               "--out", str(d / "out"), "--no-archive"]  # fmt: skip
        rc, mib, secs = peak_rss(cmd)
        if rc not in (0, 1):  # 1: out of tolerance, still a result
            raise SystemExit(f"calibrate on {k}× exited {rc}")
        above = max(mib - idle, 1e-9)
        first = first or (mib, above, secs)
        print(f"{k:>4}× {n:>8} {mib:>9.0f} {mib / first[0]:>6.2f} {above:>11.0f} "
              f"{above / first[1]:>6.1f} {secs:>7.1f} {secs / first[2]:>6.1f}")  # fmt: skip
    if not args.keep:
        for p in sorted(base.rglob("*"), reverse=True):
            p.unlink() if p.is_file() else p.rmdir()
        base.rmdir()


if __name__ == "__main__":
    main()
