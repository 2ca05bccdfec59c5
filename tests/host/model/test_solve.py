"""The weighted least squares over a dataset's rows (host/model/solve.py) and the columns built
once per dataset (host/model/design.py ``BuiltColumns``): χ² of one model fitted to several
sets of rows is each fit's own, and columns built on one dataset never serve another."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from host.model.catalogue import CATALOGUE
from host.model.dataset import build_dataset, session_from_records
from host.model.design import BuiltColumns, design
from host.model.fit import fit_model, predict
from host.model.signals import RecordSignals
from host.model.solve import fitted_chi2
from host.model.spec import parse_model
from host.model.terms import nonlinear_term
from host.workbench.scenarios import hidden_effect_case

MODEL = "base,plate_tilt:accel,lever_arm:accel,temperature_bias:gyro"


@nonlinear_term(sensors=("gyro",), params={"c": "(°/s/°C)^(1/3)"}, initial=[0.5])
def cube_temp(sig: RecordSignals, sensor: str, axis: int, theta: np.ndarray) -> np.ndarray:
    """Temperature bias parametrised by its cube root (a nonlinear test term)."""
    return np.asarray(theta[0] ** 3 * sig.d_temp)


def _dataset(effect: str, seed: int):  # type: ignore[no-untyped-def]
    return build_dataset(session_from_records(hidden_effect_case(effect, seed=seed).records))


@pytest.mark.slow
def test_chi2_of_several_rows_is_each_fits_own() -> None:
    """One whitened design fitted to several sets of rows gives, for each, the χ² of the whole
    fit on a copy of the dataset holding those rows (a linear and a nonlinear model)."""
    ds = _dataset("lever_arm", 2)
    rng = np.random.default_rng(7)
    nonlinear = [*parse_model("base"), *parse_model("cube_temp:gyro:z", {"cube_temp": cube_temp})]
    for model in (parse_model(MODEL), nonlinear):
        fit = fit_model(ds, model)
        values = {(p.term_name, p.sensor, p.axis, p.key): p.value for p in fit.parameters}
        ys = [ds.y, predict(ds, model, values), ds.y + 1e-3 * rng.standard_normal(ds.n_rows)]
        got = fitted_chi2(ds, model, ys, BuiltColumns(ds))
        want = [fit_model(dataclasses.replace(ds, y=y), model).chi2 for y in ys]
        assert got == want
        assert got[1] < 1e-6 * got[0]  # its own noise-free prediction: fitted exactly


def test_columns_built_on_one_dataset_never_serve_another() -> None:
    """A copy with other measured values shares the columns; another session's dataset (other
    records, other rows) gets its own, whatever was built before."""
    model = parse_model(MODEL, CATALOGUE)
    one, other = _dataset("lever_arm", 2), _dataset("temperature", 3)
    built = BuiltColumns(one)
    x1, off1, spans1 = design(one, model, (), built)
    copy = dataclasses.replace(one, y=one.y + 1.0)
    assert np.array_equal(design(copy, model, (), built)[0], x1)
    x2, off2, spans2 = design(other, model, (), built)
    ref2 = design(other, model)
    assert np.array_equal(x2, ref2[0]) and np.array_equal(off2, ref2[1]) and spans2 == ref2[2]
    assert np.array_equal(x1, design(one, model)[0]) and spans1 == design(one, model)[2]
