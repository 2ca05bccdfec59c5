"""Memory that grows with the data (issue 31): the fit, the residual tables and the held-out
prediction of k sessions' records take memory about k times one session's, not k² times (a
dense n × n matrix anywhere would)."""

from __future__ import annotations

import tracemalloc
from dataclasses import replace

import numpy as np
import pytest

from host.bench.plan import Plan, simulate_session
from host.bench.truth import SensorTruth
from host.model.dataset import Dataset, build_dataset, session_from_records
from host.model.fit import fit_model
from host.model.loo import leave_one_out
from host.model.spec import parse_model


def _dataset(copies: int) -> Dataset:
    truth = SensorTruth.random(np.random.default_rng(2)).only("linear", "noise")
    one = simulate_session(truth, Plan(static_s=10.0), 2)
    recs = {}
    for k in range(copies):
        for name, r in one.items():
            new = name if k == 0 else f"{name}_{k + 1}"
            recs[new] = replace(r, name=new)
    return build_dataset(session_from_records(recs))


def _peak_bytes(ds: Dataset) -> int:
    model = parse_model("base")
    tracemalloc.start()
    try:
        fit = fit_model(ds, model)
        leave_one_out(ds, fit)
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


@pytest.mark.slow
def test_fit_and_held_out_prediction_memory_grows_linearly_with_the_records() -> None:
    small, large = _dataset(1), _dataset(8)
    assert large.n_rows >= 7 * small.n_rows
    ratio = _peak_bytes(large) / _peak_bytes(small)
    # linear: about 8; a dense n × n matrix makes it 64 once it dominates (it does by 8×)
    assert ratio < 16, ratio
