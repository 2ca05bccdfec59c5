"""Time the simulator: a 12-record session (6 × 30 s statics + 6 turns of 2) simulated and
written to record files. Budget: < 1 s. Run: ``python benchmarks/sim_bench.py``."""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from host.bench.plan import Plan, simulate_session, write_session
from host.bench.truth import SensorTruth


def main(repeats: int = 5) -> None:
    truth = SensorTruth.random(np.random.default_rng(0))
    plan = Plan(static_s=30.0, turns=2)
    sim_t, write_t = [], []
    for k in range(repeats):
        t0 = time.perf_counter()
        records = simulate_session(truth, plan, seed=k)
        t1 = time.perf_counter()
        with tempfile.TemporaryDirectory() as d:
            write_session(d, "BENCH", records)
        t2 = time.perf_counter()
        sim_t.append(t1 - t0)
        write_t.append(t2 - t1)
    n = sum(len(r) for r in records.values())
    total = [a + b for a, b in zip(sim_t, write_t, strict=True)]
    print(
        f"12-record session, {n} samples: simulate {min(sim_t) * 1e3:.0f} ms, "
        f"write {min(write_t) * 1e3:.0f} ms, total {min(total) * 1e3:.0f} ms "
        f"(best of {repeats}; median total {np.median(total) * 1e3:.0f} ms; budget 1000 ms)"
    )


if __name__ == "__main__":
    main()
