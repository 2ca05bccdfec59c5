"""Eight processes archiving at once into one archive (SQLite file, PostgreSQL database) lose
nothing and duplicate nothing: every entry is there once, counted by rows and by hashes,
while each process also re-adds entries the others add (the idempotent path under a race)."""

from __future__ import annotations

import multiprocessing as mp

import numpy as np
import pytest

from host.archive.store import Archive
from tests.host.archive.lot_sim import simulate_lot

PROCESSES = 8
PER_PROCESS = 25


def _entries() -> list:
    lot = simulate_lot(np.random.default_rng(99), units=70, sessions=3, plant=False)
    return lot.entries[: PROCESSES * PER_PROCESS]


def _worker(url: str, part: int, out: mp.Queue) -> None:
    entries = _entries()
    mine = entries[part * PER_PROCESS : (part + 1) * PER_PROCESS]
    shared = entries[:10]  # every process adds these too: a race on the same hashes
    added = 0
    with Archive(url) as a:
        for e in [*shared, *mine]:
            added += a.add(e)[1]
    out.put(added)


@pytest.mark.slow
@pytest.mark.timeout(300)
def test_eight_processes_lose_and_duplicate_nothing(archive_url: str) -> None:
    ctx = mp.get_context("fork")  # the children open their own archive
    out: mp.Queue = ctx.Queue()
    procs = [ctx.Process(target=_worker, args=(archive_url, i, out)) for i in range(PROCESSES)]
    for p in procs:
        p.start()
    for p in procs:
        p.join(240)
        assert p.exitcode == 0
    added = sum(out.get(timeout=5) for _ in procs)
    entries = _entries()
    want = {e.result_hash for e in entries}
    with Archive(archive_url) as a:
        hashes = a.result_hashes()
        n, m = a.count()
    assert added == len(want) == PROCESSES * PER_PROCESS  # each new entry added exactly once
    assert sorted(hashes) == sorted(want)  # none lost, none twice
    assert n == len(want) and m == sum(len(e.parameters) for e in entries)
