"""The engine's public prediction (host/model/fit.py: ``predict``, ``predict_session``): what
the calibration's held-out ``verify`` calls instead of rebuilding the design itself."""

from __future__ import annotations

import numpy as np

from host.calib.applying import verify
from host.calib.calibration import CalibrationOptions, calibrate_from_records
from host.model.dataset import build_dataset, session_from_records
from host.model.fit import fit_model, predict, predict_session
from host.model.spec import parse_model
from host.workbench.scenarios import hidden_effect_case

#: shared terms (one parameter set for all channels) and a per-channel one beside base
MODEL = "base,plate_tilt:accel,lever_arm:accel,temperature_bias:gyro"


def _values(fit: object) -> dict[tuple[str, str, str, str], float]:
    return {
        (p.term_name, p.sensor, p.axis, p.key): p.value
        for p in fit.parameters  # type: ignore[attr-defined]
    }


def test_predict_with_the_fitted_values_gives_the_fits_own_prediction() -> None:
    session = session_from_records(hidden_effect_case("lever_arm", seed=2).records)
    ds = build_dataset(session)
    model = parse_model(MODEL)
    fit = fit_model(ds, model)
    assert not fit.undetermined
    got = predict(ds, model, _values(fit))
    assert np.allclose(got, fit.predicted, rtol=0, atol=1e-9 * float(np.max(np.abs(ds.y))))
    # a parameter left out counts as 0: the prediction moves by exactly its columns
    values = _values(fit)
    values[("lever_arm", "accel", "", "x")] = 0.0
    moved = predict(ds, model, values)
    assert not np.allclose(moved, got)


def test_predict_session_tables_match_the_fit_on_the_same_records() -> None:
    session = session_from_records(hidden_effect_case("none", seed=5).records)
    model = parse_model(MODEL)
    fit = fit_model(build_dataset(session), model)
    held = predict_session(session, model, _values(fit))
    assert [(g.record, g.channel) for g in held.groups] == [
        (g.record, g.channel) for g in fit.groups
    ]
    for h, f in zip(held.groups, fit.groups, strict=True):
        assert h.measured == f.measured
        assert abs(h.model - f.model) <= 1e-9 * max(1.0, abs(f.model))
        # nothing fitted to these rows: z against the measurement's σ alone (never NaN)
        assert np.isfinite(h.z)


def test_verify_a_result_with_shared_terms_on_other_records() -> None:
    """A result whose model has a shared term (one plate tilt for every channel) verifies on
    records it was not fitted to (the design of a shared term has one column set, not one per
    axis)."""
    fitted = session_from_records(hidden_effect_case("none", seed=6).records)
    other = session_from_records(hidden_effect_case("none", seed=6, static_s=12.0).records)
    result = calibrate_from_records(fitted, CalibrationOptions(model="base,plate_tilt:accel"))
    v = verify(result, other, source="other")
    assert v.values and v.passed
    assert 0.3 < v.rms_z < 3.0
