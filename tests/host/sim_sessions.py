"""Simulated record files for tests that need a whole session on disk (one helper instead of
the same four lines in every fixture). The truth is ``SensorTruth.random`` from the seed, so
each test file keeps its own unit by choosing its own seed."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from host.bench.plan import Plan, simulate_session, write_session
from host.bench.truth import SensorTruth


def write_sim_session(
    d: Path, serial: str, seed: int, *, static_s: float = 5.0, turns: int = 1
) -> Path:
    """Write the records of one simulated session (no warm-up) into ``d``; return ``d``.

    ``static_s`` is each static record's length in seconds, ``turns`` the turns per direction.
    """
    truth = SensorTruth.random(np.random.default_rng(seed))
    recs = simulate_session(truth, Plan(static_s=static_s, turns=turns, warmup_s=0), seed)
    write_session(d, serial, recs)
    return d
