#!/usr/bin/env python3
"""Peak memory and time of ``python3 -m host noise`` on static captures of 1×, 10× and 100× a
base length (issue 31, item 3: ``noise`` streams its capture).

    python benchmarks/noise_memory.py [--hours 0.9] [--scales 1,10,100] [--keep DIR]

Each capture is an IMUCAP01 file of the board's 50 Hz stream at rest (white noise and a slow
random walk on every channel, one read per second), written in pieces so the writer's own
memory stays small; 0.9 h is ≈ 4.8 MB, so 100× is ≈ 480 MB, the capture the issue measured
(4.8 GB peak). Each case runs the whole command in a fresh process and reads its peak
resident set size (``RUSAGE_CHILDREN`` of a wrapper that waits for it). Prints samples,
input size, peak RSS and its ratio to the 1× case, wall time and time per million samples
(the 1× case is mostly start-up): memory stays nearly flat and time near linear (the Allan
deviation's τ grid grows with the log of the length).
"""

from __future__ import annotations

import argparse
import shutil
import struct
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
from host.wire.capture import MAGIC  # noqa: E402
from host.wire.frames import encode_imu_samples  # noqa: E402

RATE = 50
WRAPPER = (
    "import resource, subprocess, sys\n"
    "rc = subprocess.call(sys.argv[1:], stdout=subprocess.DEVNULL)\n"
    "kb = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss\n"
    "print(rc, kb)\n"
)


def write_static(path: Path, seconds: int, seed: int = 1) -> int:
    """A static capture of ``seconds`` s at 50 Hz, written an hour at a time; samples."""
    rng = np.random.default_rng(seed)
    rest = np.array([0, 0, 16384, 0, 0, 0, 0], np.float64)  # z up at ±2 g; temp 0 counts
    walk = np.zeros(7)
    n_total = seconds * RATE
    with open(path, "wb") as f:
        f.write(MAGIC)
        for s0 in range(0, n_total, 3600 * RATE):
            n = min(3600 * RATE, n_total - s0)
            white = rng.normal(0.0, 6.0, (n, 7))
            steps = np.cumsum(rng.normal(0.0, 0.01, (n, 7)), axis=0) + walk
            walk = steps[-1]
            counts = np.rint(rest + white + steps).astype(np.int16)
            counts[:, 3] = -521  # 35 °C, constant
            t_us = (s0 + np.arange(n, dtype=np.int64)) * (1_000_000 // RATE)
            frames = encode_imu_samples(s0 & 0xFFFF, t_us, counts)
            size = len(frames) // n
            parts = []
            for k in range(0, n, RATE):
                j = min(k + RATE, n)
                host_ns = int(t_us[j - 1]) * 1000 + 2_000_000
                parts.append(struct.pack("<QI", host_ns, (j - k) * size))
                parts.append(frames[k * size : j * size])
            f.write(b"".join(parts))
    return n_total


def peak(cmd: list[str]) -> tuple[int, float, float]:
    """Run ``cmd``; its exit code, peak RSS in MiB and wall time in s."""
    t0 = time.perf_counter()
    r = subprocess.run([sys.executable, "-c", WRAPPER, *cmd], capture_output=True, text=True,
                       cwd=ROOT, check=True)  # fmt: skip
    rc, kb = r.stdout.split()
    return int(rc), int(kb) / 1024, time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--hours", type=float, default=0.9, help="the 1× length, h")
    ap.add_argument("--scales", default="1,10,100", help="lengths to run, × the base")
    ap.add_argument("--keep", metavar="DIR", help="write the captures here and keep them")
    a = ap.parse_args()
    work = Path(a.keep) if a.keep else Path(tempfile.mkdtemp(prefix="noise-memory-"))
    work.mkdir(parents=True, exist_ok=True)
    print(f"{'case':>5} {'samples':>10} {'MB':>8} {'peak RSS MiB':>13} {'RSS/1x':>7} "
          f"{'s':>7} {'s per M samples':>16}")  # fmt: skip
    base: float | None = None
    try:
        for k in (int(x) for x in a.scales.split(",")):
            path = work / f"static_{k}x.cap"
            seconds = int(round(a.hours * 3600 * k))
            n = seconds * RATE
            if not path.exists():
                write_static(path, seconds)
            rc, rss, wall = peak([sys.executable, "-m", "host", "noise", str(path)])
            base = base or rss
            print(f"{k:>4}x {n:>10} {path.stat().st_size / 1e6:>8.1f} {rss:>13.1f} "
                  f"{rss / base:>7.2f} {wall:>7.1f} {wall / n * 1e6:>16.2f}"
                  + ("" if rc == 0 else f"  exit {rc}"), flush=True)  # fmt: skip
    finally:
        if not a.keep:
            shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
