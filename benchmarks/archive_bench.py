#!/usr/bin/env python3
"""The archive's speed on both back ends: archiving 1 000 sessions, and the ``trend`` and
``lot`` queries over 10 000 sessions.

    OPENBLAS_NUM_THREADS=1 python benchmarks/archive_bench.py [--postgres URL] [--sessions 10000]

Each session is a real result (a simulated session through ``calibrate``: 33 parameters, the
whole result file, 12 record hashes) with its serial, values and hashes varied. SQLite is a
file in a temporary directory; PostgreSQL is ``--postgres URL`` or, when the Debian binaries
are there, a throwaway cluster started here (fsync off: the figure is the archive's work, not
the disk's). The baseline, in the same process, is the folder-of-JSON way (one result file
per calibration, imucal's): writing 1 000 files, and reading 10 000 to find one serial's
trend. Targets: 1 000 sessions in < 5 s, each query < 100 ms.
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import hashlib
import json
import os
import sys
import tempfile
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np
from sqlalchemy import text

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
from host.archive import checks  # noqa: E402
from host.archive.entry import Entry, entry_from_directory  # noqa: E402
from host.archive.store import Archive  # noqa: E402
from host.calib.publish import ComputeSettings, compute_and_write  # noqa: E402
from host.session.directory import read_session  # noqa: E402


def template(tmp: Path) -> Entry:
    from tests.host.sim_sessions import write_sim_session

    d = write_sim_session(tmp / "T1", "T1", seed=5)
    compute_and_write(read_session(d, None), d, ComputeSettings())
    return entry_from_directory(d, bench="B1")


def variants(t: Entry, n: int, units: int, seed: int) -> list[Entry]:
    rng = np.random.default_rng(seed)
    out = []
    for i in range(n):
        serial = f"S{i % units:05d}"
        params = tuple(
            dataclasses.replace(p, value=p.value + rng.normal(0, p.stderr or 1e-3))
            for p in t.parameters
        )
        h = hashlib.sha256(f"{seed}-{i}".encode()).hexdigest()
        out.append(
            dataclasses.replace(
                t, serial=serial, parameters=params, result_hash=h, records_hash=h[::-1],
                bench=f"B{1 + i % 4}", measured_at=f"2026-{1 + (i // units) % 12:02d}-01T08:00:"
                f"{i % 60:02d}.000000Z",
            )
        )  # fmt: skip
    return out


def json_baseline(entries: list[Entry], d: Path) -> float:
    t0 = time.perf_counter()
    for e in entries:
        (d / f"{e.serial}_{e.result_hash[:12]}.json").write_text(e.result_json)
    return time.perf_counter() - t0


def json_trend_baseline(d: Path, serial: str) -> float:
    t0 = time.perf_counter()
    found = [json.loads(p.read_text()) for p in d.glob("*.json") if p.name.startswith(serial)]
    assert found
    return time.perf_counter() - t0


@contextlib.contextmanager
def postgres(url: str | None) -> Iterator[str | None]:
    if url:
        yield url
        return
    from tests.host.archive.pg_cluster import cluster, why_no_postgres

    why = why_no_postgres()
    if why:
        print(f"PostgreSQL skipped: {why}")
        yield None
        return
    with cluster() as c:
        yield c.new_database()


def best(f: object, repeat: int = 5) -> float:
    """The best wall time of ``repeat`` calls, s."""
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        f()  # type: ignore[operator]
        times.append(time.perf_counter() - t0)
    return min(times)


def cpu(f: object, repeat: int = 5) -> float:
    """The best CPU time of this process over ``repeat`` calls, s (on a loaded machine the
    wall time measures the others too; for SQLite the whole query runs in this process)."""
    times = []
    for _ in range(repeat):
        t0 = time.process_time()
        f()  # type: ignore[operator]
        times.append(time.process_time() - t0)
    return min(times)


def server_cpu(a: Archive) -> Callable[[], float]:
    """The CPU time (s) used so far by the server process of the archive's pooled connection,
    when it is PostgreSQL on this machine (0 otherwise): on a shared machine the wall time
    measures the other processes too, client + server CPU does not."""
    if a.backend != "postgresql":
        return lambda: 0.0
    with a.engine.connect() as conn:
        pid = conn.execute(text("SELECT pg_backend_pid()")).scalar_one()
    stat = Path(f"/proc/{pid}/stat")

    def read() -> float:
        try:
            f = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:  # not on this machine
            return 0.0
        return (int(f[11]) + int(f[12])) / os.sysconf("SC_CLK_TCK")

    return read


def run(name: str, url: str, t: Entry, sessions: int, tmp: Path) -> None:
    add = variants(t, 1000, 250, seed=1)
    base_dir = tmp / f"json-{name}"
    base_dir.mkdir()
    base = json_baseline(add, base_dir)
    with Archive(url) as a:
        server = server_cpu(a)
        t0, c0, s0 = time.perf_counter(), time.process_time(), server()
        for e in add:
            a.add(e)
        one_by_one = time.perf_counter() - t0
        one_cpu = time.process_time() - c0
        one_server = server() - s0
        rest = variants(t, sessions - 1000, sessions // 3, seed=2)
        t0 = time.perf_counter()
        a.add_many(rest)
        batch = time.perf_counter() - t0
        n, m = a.count()
        assert n == sessions, (n, sessions)
        tr = best(lambda: checks.trend(a, "S00007"))
        tr1 = best(lambda: checks.trend(a, "S00007", ["G0z"]))
        lot = best(lambda: a.values(["A0x", "G0z"], latest_per_unit=True))
        tr_cpu = cpu(lambda: checks.trend(a, "S00007"))
        lot_cpu = cpu(lambda: a.values(["A0x", "G0z"], latest_per_unit=True))
        lot_all = best(lambda: checks.lot_report(a), repeat=2)
    for e in rest[:9000]:
        (base_dir / f"{e.serial}_{e.result_hash[:12]}.json").write_text(e.result_json)
    jt = json_trend_baseline(base_dir, "S00007")
    print(f"\n{name}: {n} sessions, {m} parameter rows (load average now "
          f"{os.getloadavg()[0]:.1f})")  # fmt: skip
    ratio = one_by_one / base
    print(f"  archive 1000 sessions one by one: {one_by_one:6.2f} s, CPU here {one_cpu:.2f} s "
          f"(target < 5 s; {ratio:5.1f}× writing 1000 JSON files, {base:.3f} s)")  # fmt: skip
    if one_server:
        print(f"    CPU of the server for them: {one_server:.2f} s; client + server "
              f"{one_cpu + one_server:.2f} s")  # fmt: skip
    print(f"  archive {len(rest)} sessions in one batch: {batch:6.2f} s "
          f"({1000 * batch / len(rest):.2f} ms per session)")  # fmt: skip
    print(
        f"  trend of one unit, every parameter: {1000 * tr:6.1f} ms  (target < 100 ms; "
        f"reading {sessions} JSON files for it: {1000 * jt:.0f} ms, ratio {tr / jt:.3f})"
    )
    print(f"  trend of one unit, one parameter:   {1000 * tr1:6.1f} ms")
    print(f"  CPU time here: trend {1000 * tr_cpu:.1f} ms, lot query {1000 * lot_cpu:.1f} ms")
    print(f"  lot query, 2 parameters, latest session per unit: {1000 * lot:6.1f} ms "
          "(target < 100 ms)")  # fmt: skip
    print(f"  lot report, every parameter with outliers:        {1000 * lot_all:6.1f} ms")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--postgres", metavar="URL", help="an empty PostgreSQL database")
    ap.add_argument("--sessions", type=int, default=10000)
    args = ap.parse_args()
    print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    with tempfile.TemporaryDirectory() as tmpdir:
        tmp = Path(tmpdir)
        t = template(tmp)
        size = len(t.result_json) / 1024
        print(f"each session: {len(t.parameters)} parameters, result file {size:.0f} KiB, "
              f"{len(t.record_hashes)} record hashes")  # fmt: skip
        run("SQLite", str(tmp / "bench.sqlite"), t, args.sessions, tmp)
        with postgres(args.postgres) as url:
            if url:
                run("PostgreSQL", url, t, args.sessions, tmp)


if __name__ == "__main__":
    main()
