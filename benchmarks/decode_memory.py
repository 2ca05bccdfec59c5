#!/usr/bin/env python3
"""Peak memory of ``python3 -m host decode`` on big inputs, against a small capture decoded in
the same run (issue 17, item 4: decoding reads in chunks, in bounded memory).

    python benchmarks/decode_memory.py [--mib 1024] [--dense-mib 128] [--keep DIR]

Each case runs the whole command in a fresh process and reads its peak resident set size
(``resource.getrusage(RUSAGE_CHILDREN).ru_maxrss`` of a wrapper that waits for it):

- ``small``: a 60 s IMUCAP01 capture (the baseline);
- ``sparse raw``: a raw capture of ``--mib`` MiB, zeros (a sparse file: no disk used) with 60 s
  of frames every 64 MiB, decoded to CSV;
- ``sparse cap``: an IMUCAP01 capture of ``--mib`` MiB whose 64 MiB zero reads alternate with
  60 s of frames with arrival times (the clock map streams across them), to CSV;
- ``fifo``: the same capture through a FIFO fed by ``cat``, to CSV;
- ``dense``: ``--dense-mib`` MiB of back-to-back IMU frames (written to disk), ``--stats``.

Prints input size, peak RSS, the ratio to the baseline, rows out and wall time. Before issue
17's item 4, ``decode`` read the whole input (then refused anything above 512 MiB).
"""

from __future__ import annotations

import argparse
import os
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
from host.bench.linksim import LinkParams, simulate_link  # noqa: E402
from host.wire.capture import MAGIC, MAX_READ  # noqa: E402
from host.wire.frames import encode_imu_samples  # noqa: E402

BLOCK = 64 << 20
WRAPPER = (
    "import resource, subprocess, sys\n"
    "with open(sys.argv[1], 'wb') as out:\n"
    "    rc = subprocess.call(sys.argv[2:], stdout=out)\n"
    "kb = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss\n"
    "print(rc, kb)\n"
)


def peak_rss(cmd: list[str], out: Path) -> tuple[int, float, float]:
    """Run ``cmd`` (stdout to ``out``); exit code, its peak RSS in MiB, wall time in s."""
    t0 = time.perf_counter()
    r = subprocess.run(
        [sys.executable, "-c", WRAPPER, str(out), *cmd],
        capture_output=True, text=True, cwd=ROOT, check=True,
    )  # fmt: skip
    rc, kb = r.stdout.split()
    return int(rc), int(kb) / 1024, time.perf_counter() - t0


def board_minutes(k: int) -> list[list[tuple[int, bytes]]]:
    """``k`` minutes of one board's stream, as (host ns, bytes) reads grouped by minute."""
    lc = simulate_link(LinkParams(seconds=60.0 * k, seed=1))
    t0 = lc.chunks[0][0]
    out: list[list[tuple[int, bytes]]] = [[] for _ in range(k)]
    for t, b in lc.chunks:
        out[min(int((t - t0) // 60e9), k - 1)].append((t, bytes(b)))
    return out


def write_sparse_raw(path: Path, mib: int) -> None:
    with open(path, "wb") as f:
        for k, reads in enumerate(board_minutes(max(mib * (1 << 20) // BLOCK, 1))):
            f.seek(k * BLOCK)
            f.write(b"".join(b for _, b in reads))
        f.truncate(mib << 20)


def write_sparse_cap(path: Path, mib: int) -> None:
    with open(path, "wb") as f:
        f.write(MAGIC)
        for reads in board_minutes(max(mib * (1 << 20) // BLOCK, 1)):
            for t, b in reads:
                f.write(struct.pack("<QI", t, len(b)) + b)
            for k in range(BLOCK // MAX_READ):  # 64 MiB of zeros in the largest reads there are
                f.write(struct.pack("<QI", reads[-1][0] + 1000 * (k + 1), MAX_READ))
                f.seek(MAX_READ, os.SEEK_CUR)  # not written: sparse
        f.truncate()


def write_dense(path: Path, mib: int) -> None:
    n_per = 1 << 16
    rng = np.random.default_rng(1)
    with open(path, "wb") as f:
        t0 = 0
        while f.tell() < mib << 20:
            t = t0 + 20_000 * np.arange(n_per)
            f.write(encode_imu_samples(t0 // 20_000, t, rng.integers(-999, 999, (n_per, 7))))
            t0 += 20_000 * n_per


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--mib", type=int, default=1024, help="size of the sparse inputs (MiB)")
    ap.add_argument("--dense-mib", type=int, default=128, help="size of the dense input (MiB)")
    ap.add_argument("--keep", type=Path, help="make the inputs in this directory and keep them")
    args = ap.parse_args()
    tmp = args.keep or Path(tempfile.mkdtemp(prefix="decode_memory."))
    tmp.mkdir(parents=True, exist_ok=True)
    try:
        small = tmp / "small.cap"
        small.write_bytes(simulate_link(LinkParams(seconds=60, seed=1)).to_imucap())
        raw, cap, dense = tmp / "sparse.bin", tmp / "sparse.cap", tmp / "dense.bin"
        write_sparse_raw(raw, args.mib)
        write_sparse_cap(cap, args.mib)
        write_dense(dense, args.dense_mib)
        fifo = tmp / "pipe.cap"
        if not fifo.exists():
            os.mkfifo(fifo)
        host = [sys.executable, "-m", "host", "decode"]
        out = tmp / "out.txt"
        cases: list[tuple[str, Path, list[str]]] = [
            ("small (baseline)", small, [*host, "--csv", str(small)]),
            ("sparse raw, --csv", raw, [*host, "--csv", str(raw)]),
            ("sparse cap, --csv", cap, [*host, "--csv", str(cap)]),
            ("FIFO (cat), --csv", cap, [*host, "--csv", str(fifo)]),
            ("dense raw, --stats", dense, [*host, "--stats", str(dense)]),
        ]
        print(f"{'case':<20} {'input MiB':>10} {'peak RSS MiB':>13} {'x baseline':>11} "
              f"{'rows out':>10} {'wall s':>7}")  # fmt: skip
        base = None
        for name, src, cmd in cases:
            feeder = None
            if "FIFO" in name:
                feeder = subprocess.Popen(
                    ["sh", "-c", 'cat "$1" > "$2"', "sh", str(src), str(fifo)]
                )
            rc, rss, wall = peak_rss(cmd, out)
            if feeder is not None:
                feeder.wait()
            if rc != 0:
                raise SystemExit(f"{name}: exit {rc}")
            base = base or rss
            with open(out, "rb") as f:
                rows = sum(chunk.count(b"\n") for chunk in iter(lambda: f.read(1 << 20), b""))
            size = src.stat().st_size / 2**20
            print(f"{name:<20} {size:>10.1f} {rss:>13.1f} {rss / base:>11.2f} {rows:>10} "
                  f"{wall:>7.1f}")  # fmt: skip
    finally:
        if args.keep is None:
            shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
