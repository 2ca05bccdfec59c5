#!/usr/bin/env python3
"""Decoder throughput against pymavlink, measured in one run on the same number of samples.

    python benchmarks/decode_bench.py [--samples N] [--process [--process-samples N]]
                                       [--small-reads]

Prints frames/s for: our bulk path on a clean capture and with 1 % of frames corrupted, our
streaming path (4 KiB reads), and pymavlink parsing the same number of RAW_IMU messages with
its own parser; then the ratios, and the share of one core the streaming decoder needs to keep
up with a 1 Mbaud link. Targets (issue "The wire"): bulk >= 3 M frames/s clean, >= 1 M with
1 % corrupted, >= 30x pymavlink; streaming well under 5 % of a core at 1 Mbaud. With
``--process``, ``python3 -m host decode --stats`` as a whole process on a raw capture and on an
IMUCAP01 capture (the clock map too) of ``--process-samples`` frames, and its start-up alone
(issue 31: >= 3 M frames/s and >= 30x pymavlink as a whole process), as the best wall time,
the best CPU time and the median CPU time of the runs (on a loaded machine only the CPU time
means anything).

Measured (``--process --repeat 9``, one BLAS thread, ``nice -n 10`` on a shared 2-core machine,
CPU time, the median of the four process runs): IMUCAP01 capture 3.3 M frames/s (36-38x
pymavlink) at load 5-7, 2.5-3.1 M frames/s (29-35x) at load 8-9; raw capture 5.4-5.5 M
frames/s (59-63x); start-up alone 0.12-0.13 s; with ``--small-reads`` (1-2 frames a read)
2.3-2.4 M frames/s (27-28x) at load 6, the read headers walked block-wise (1.4 M frames/s,
16x, walked one Python step per read). Main at 5662e5a in the same conditions: IMUCAP01
2.2-2.5 M frames/s (28x). Before issue 31's work on it (main 0b0ec99, wall time at a lighter
load): 4.12 and 2.13 M frames/s (21.9x).
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from host.wire.bulk import decode_bulk  # noqa: E402
from host.wire.frames import encode_imu_samples  # noqa: E402
from host.wire.stream import StreamDecoder  # noqa: E402


def best_of(fn: Callable[[], int], repeat: int) -> tuple[float, int]:
    """Fastest wall time of ``repeat`` runs (s) and what the run returned (frame count)."""
    wall, _, out = timed(fn, repeat)
    return wall, out


def timed(fn: Callable[[], int], repeat: int) -> tuple[float, float, int]:
    """The least wall time and the least CPU time (this process's and its children's, user +
    system) of ``repeat`` runs (s), and what the run returned. On a loaded machine wall time
    counts the waits for a core; CPU time does not."""
    walls, cpus, out = timed_all(fn, repeat)
    return min(walls), min(cpus), out


def timed_all(fn: Callable[[], int], repeat: int) -> tuple[list[float], list[float], int]:
    """The wall and CPU times (s) of each of ``repeat`` runs, and what the last returned."""
    walls, cpus = [], []
    out = 0
    for _ in range(repeat):
        c0, t0 = _cpu_s(), time.perf_counter()
        out = fn()
        walls.append(time.perf_counter() - t0)
        cpus.append(_cpu_s() - c0)
    return walls, cpus, out


def _cpu_s() -> float:
    import resource

    own = resource.getrusage(resource.RUSAGE_SELF)
    kids = resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime


def our_capture(n: int, corrupt_fraction: float, seed: int = 1) -> bytes:
    rng = np.random.default_rng(seed)
    counts = rng.integers(-2000, 2000, size=(n, 7))
    counts[:, 2] += 16384
    data = bytearray(encode_imu_samples(0, np.arange(n) * 20000, counts))
    hit = rng.choice(n, size=int(n * corrupt_fraction), replace=False)
    for k in hit:
        data[27 * k + int(rng.integers(6, 25))] ^= 1 << int(rng.integers(8))
    return bytes(data)


def stream(data: bytes) -> int:
    d = StreamDecoder()
    n = 0
    for i in range(0, len(data), 4096):
        n += len(d.feed(data[i : i + 4096]))
    return n + len(d.flush())


def mavlink_capture(n: int):
    from pymavlink.dialects.v20 import common as mavlink2

    enc = mavlink2.MAVLink(None, srcSystem=1, srcComponent=1)
    rng = np.random.default_rng(1)
    vals = rng.integers(-2000, 2000, size=(n, 9)).tolist()
    parts = [enc.raw_imu_encode(20000 * i, *v).pack(enc) for i, v in enumerate(vals)]
    data = b"".join(parts)

    def parse() -> int:
        dec = mavlink2.MAVLink(None)
        dec.robust_parsing = True
        msgs = dec.parse_buffer(data) or []
        return sum(1 for m in msgs if m.get_type() == "RAW_IMU")

    return parse


def imucap(data: bytes, read_sizes: Callable[[int], int]) -> bytes:
    """``data`` as an IMUCAP01 capture of reads of ``read_sizes(i)`` bytes from byte i on,
    each stamped 2 ms after its last sample (frames every 20 ms)."""
    import struct

    from host.wire.capture import MAGIC

    parts = [MAGIC]
    i = 0
    while i < len(data):
        part = data[i : i + read_sizes(i)]
        t_ns = 10**12 + (i + len(part)) // 27 * 20_000_000 + 2_000_000
        parts.append(struct.pack("<QI", t_ns, len(part)) + part)
        i += len(part)
    return b"".join(parts)


def whole_process(data: bytes, n: int, repeat: int, small_reads: bool) -> dict[str, list[float]]:
    """``python3 -m host decode --stats`` as a user runs it, start-up included, on ``data``
    written as a raw capture and as an IMUCAP01 capture (4 KiB reads, host times 2 ms after
    each read's last sample), with ``small_reads`` also as the reads a board's link makes
    (``small``: 1 to 2 frames, 27-54 bytes), and on an empty file (the start-up alone): the
    wall times (``raw``, ``cap``, ``small``, ``start``; s) and CPU times (``raw_cpu``, ...)
    of ``repeat`` runs each. Bytecode is cached as an installed package has it (pip compiles
    it; this run does once, into a temporary directory, before timing)."""
    import os
    import subprocess
    import tempfile

    out: dict[str, list[float]] = {}
    with tempfile.TemporaryDirectory() as d:
        files = {name: Path(d) / f"{name}.bin" for name in ("raw", "cap", "small", "start")}
        files["raw"].write_bytes(data)
        files["start"].write_bytes(b"")
        files["cap"].write_bytes(imucap(data, lambda i: 4096))
        if small_reads:
            files["small"].write_bytes(imucap(data, lambda i: 27 + 27 * (i // 27 % 3 == 1)))
        else:
            del files["small"]
        root = Path(__file__).resolve().parent.parent
        env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
        env["PYTHONPYCACHEPREFIX"] = str(Path(d) / "pycache")
        for name, f in files.items():
            cmd = [sys.executable, "-m", "host", "decode", "--stats", str(f)]

            def run(c: list[str] = cmd) -> int:
                r = subprocess.run(c, cwd=root, env=env, check=True, capture_output=True)
                return r.returncode

            run()  # compiles and caches the bytecode, warms the file cache
            out[name], out[name + "_cpu"], _ = timed_all(run, repeat)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=300_000)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument(
        "--process", action="store_true",
        help="also time `python3 -m host decode --stats` as a whole process (start-up included)",
    )  # fmt: skip
    ap.add_argument(
        "--process-samples", type=int, default=1_500_000,
        help="frames in the capture the whole process decodes (8 h 20 min at 50 Hz)",
    )  # fmt: skip
    ap.add_argument(
        "--small-reads", action="store_true",
        help="with --process, also the capture as a board's link reads it (1-2 frames a read)",
    )  # fmt: skip
    args = ap.parse_args()
    n = args.samples
    clean = our_capture(n, 0.0)
    dirty = our_capture(n, 0.01)
    t_bulk, k_bulk = best_of(lambda: decode_bulk(clean).stats.frames, args.repeat)
    t_dirty, k_dirty = best_of(lambda: decode_bulk(dirty).stats.frames, args.repeat)
    t_stream, k_stream = best_of(lambda: stream(clean), max(1, args.repeat // 2))
    try:
        parse = mavlink_capture(n)
        w_mav, c_mav, k_mav = timed_all(parse, max(1, args.repeat // 3))
    except ImportError:
        w_mav, c_mav, k_mav = [float("nan")], [float("nan")], 0
    t_mav = min(w_mav)
    assert k_bulk == n and k_stream == n and (k_mav in (n, 0)), (k_bulk, k_stream, k_mav)
    r_bulk, r_dirty, r_stream, r_mav = n / t_bulk, k_dirty / t_dirty, n / t_stream, n / t_mav
    need = 1_000_000 / 10 / 27  # frames/s on a 1 Mbaud 8N1 link
    print(f"samples per run              {n}")
    print(f"bulk, clean                  {r_bulk / 1e6:8.2f} M frames/s")
    print(f"bulk, 1 % corrupted          {r_dirty / 1e6:8.2f} M frames/s ({k_dirty} recovered)")
    print(f"streaming, 4 KiB reads       {r_stream / 1e6:8.3f} M frames/s")
    print(f"pymavlink RAW_IMU            {r_mav / 1e6:8.3f} M frames/s")
    print(f"ratio bulk / pymavlink       {r_bulk / r_mav:8.1f} x")
    print(f"ratio streaming / pymavlink  {r_stream / r_mav:8.1f} x")
    print(f"streaming CPU at 1 Mbaud     {100 * need / r_stream:8.2f} % of one core")
    if args.process:
        big = args.process_samples
        data = our_capture(big, 0.0) if big != n else clean
        runs = max(1, args.repeat // 2)
        p = whole_process(data, big, runs, args.small_reads)
        # per column: the best wall time, the best CPU time, the median CPU time (s)
        mav = [n / min(w_mav), n / min(c_mav), n / statistics.median(c_mav)]
        print(f"process: {big} frames, `python3 -m host decode --stats FILE`, {runs} runs")
        print("                            wall (best)  CPU (best)  CPU (median)")
        cols = [min(p["start"]), min(p["start_cpu"]), statistics.median(p["start_cpu"])]
        print("start-up alone             " + "".join(f"{c:10.3f} s " for c in cols).rstrip())
        cases = [("raw", "raw capture"), ("cap", "IMUCAP01, 4 KiB reads")]
        cases += [("small", "IMUCAP01, 1-2 frames/read")] if "small" in p else []
        rates = {}
        for key, what in cases:
            times = [min(p[key]), min(p[key + "_cpu"]), statistics.median(p[key + "_cpu"])]
            rates[key] = [big / t for t in times]
            print(f"{what:27s}" + "".join(f"{r / 1e6:10.2f}   " for r in rates[key]) + "M/s")
        print("pymavlink RAW_IMU          " + "".join(f"{r / 1e6:10.3f}   " for r in mav) + "M/s")
        for key, _ in cases:
            ratio = "".join(f"{r / m:10.1f}   " for r, m in zip(rates[key], mav, strict=True))
            print(f"{'ratio ' + key + ' / pymavlink':27s}{ratio}x")


if __name__ == "__main__":
    main()
