"""Held-out prediction (host/model/loo.py): each record predicted by the model fitted to the
others, checked against a dense refit without that record's rows."""

from __future__ import annotations

import math

import numpy as np
import pytest

from host.bench.plan import Plan, simulate_session, tilted_45
from host.bench.truth import SensorTruth
from host.model.dataset import build_dataset, session_from_records
from host.model.design import design
from host.model.fit import fit_model
from host.model.loo import leave_one_out
from host.model.spec import parse_model


def test_each_record_is_predicted_by_a_refit_of_the_others() -> None:
    truth = SensorTruth.random(np.random.default_rng(4))
    recs = simulate_session(truth, Plan(static_s=10.0, tilted=tilted_45()), 4)
    ds = build_dataset(session_from_records(recs), moving=False)
    model = parse_model("bias,scale")
    fit = fit_model(ds, model)
    got = leave_one_out(ds, fit)
    # the dense way: the others' rows whitened with the whole W, one least squares each
    w = ds.whiten.dense()
    x, offset, _ = design(ds, model)
    y = ds.y - ds.nominal - offset
    zs = []
    for ri in range(len(ds.signals)):
        keep = ds.row_record != ri
        xw = w[np.ix_(keep, keep)] @ x[keep]
        yw = w[np.ix_(keep, keep)] @ y[keep]
        theta, *_ = np.linalg.lstsq(xw, yw, rcond=None)
        cov = np.linalg.inv(xw.T @ xw)
        for g in ds.groups:
            if g.record == ri:
                a = x[g.rows].mean(axis=0)
                r = float(np.mean(y[g.rows]) - a @ theta)
                zs.append(r / math.sqrt(g.sigma**2 + float(a @ cov @ a)))
    assert got.skipped == () and got.n == len(zs) == len(ds.groups)
    assert got.rms_z == pytest.approx(float(np.sqrt(np.mean(np.square(zs)))), rel=1e-9)
