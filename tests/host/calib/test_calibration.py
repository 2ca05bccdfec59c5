"""Calibration: closed form (§3, §4), least-squares fit, checks, result JSON, apply."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from host.calib.applying import apply
from host.calib.calibration import CalibrationOptions, calibrate_from_records, stage1, stage2
from host.calib.codec import FORMAT_VERSION, result_from_json, result_to_json
from host.calib.result import CalibrationResult
from host.calib.verdict import passed
from host.errors import RecordCheckError, UserError
from host.session.directory import Session, read_session
from host.session.method import (
    ACCEL_BIAS_NAMES,
    ACCEL_MIS_NAMES,
    ACCEL_SCALE_NAMES,
    CONSTANT_NAMES,
    GYRO_BIAS_NAMES,
    GYRO_GSENS_NAMES,
    GYRO_MIS_NAMES,
    GYRO_SCALE_NAMES,
    NOISE_NAMES,
    local_gravity,
    matrix_to_names,
    names_to_matrix,
    record_stats,
    trapezoid_integral,
)
from host.session.records import STATIC_NAMES, TURN_NAMES, Record

try:
    from calib_truth import TRUTH, make_record, make_records
except ImportError:  # tests/ imported as a package
    from tests.host.calib_truth import TRUTH, make_record, make_records

# shared/ sits beside the checkout (as in CI)
REAL = Path(__file__).resolve().parents[4] / "shared" / "data" / "imucal-example"
G = local_gravity()
SCALE_MIS = ACCEL_SCALE_NAMES + ACCEL_MIS_NAMES + GYRO_SCALE_NAMES + GYRO_MIS_NAMES


def _session(records: dict[str, Record], serial: str = "SIM1") -> Session:
    return Session(serial, records)


@pytest.fixture(scope="module")
def standard() -> CalibrationResult:
    return calibrate_from_records(_session(make_records(seed=11)))


def _assert_recovers(res: CalibrationResult, gyro_scale: bool = True) -> dict[str, float]:
    """Acceptance of the brief; returns the absolute errors."""
    c = res.constants()
    err = {k: abs(c[k] - v) for k, v in TRUTH.items()}
    names = SCALE_MIS if gyro_scale else ACCEL_SCALE_NAMES + ACCEL_MIS_NAMES
    for k in names:
        assert err[k] < 1e-3, (k, c[k], TRUTH[k])
    for k in ACCEL_BIAS_NAMES:
        assert err[k] < 3e-3, (k, c[k], TRUTH[k])
    for k in GYRO_BIAS_NAMES:
        assert err[k] < 0.01, (k, c[k], TRUTH[k])
    for k in GYRO_GSENS_NAMES:
        assert err[k] < 0.005, (k, c[k], TRUTH[k])
    return err


# ---- basics -------------------------------------------------------------------------------
def test_local_gravity() -> None:
    assert local_gravity(0.0, 0.0) == pytest.approx(9.78030)
    assert local_gravity(90.0, 0.0) == pytest.approx(9.78030 * 1.005302)
    phi = math.radians(55.75)
    want = 9.78030 * (1 + 0.005302 * math.sin(phi) ** 2 - 0.000007 * math.sin(2 * phi) ** 2)
    assert local_gravity() == pytest.approx(want - 0.000003086 * 150)
    assert 9.814 < local_gravity() < 9.816
    with pytest.raises(UserError, match="latitude"):
        local_gravity(91.0, 0.0)


def test_matrix_names_round_trip() -> None:
    m = names_to_matrix("A", TRUTH)
    assert m[0, 2] == -TRUTH["Axy"] and m[1, 0] == -TRUTH["Ayz"] and m[2, 1] == -TRUTH["Azx"]
    assert m[0, 1] == TRUTH["Axz"] and m[1, 2] == TRUTH["Ayx"] and m[2, 0] == TRUTH["Azy"]
    assert matrix_to_names("A", m) == {k: TRUTH[k] for k in matrix_to_names("A", m)}


def test_trapezoid_uses_sample_times() -> None:
    t = np.array([0.0, 10.0, 30.0, 60.0])  # ms, uneven
    y = np.column_stack([np.ones(4), t / 1000.0])
    assert trapezoid_integral(t, y) == pytest.approx([0.06, 0.5 * 0.06**2])


# ---- closed form --------------------------------------------------------------------------
def test_stage1_and_stage2_noise_free() -> None:
    recs = make_records(seed=2, accel_noise=0.0, gyro_noise=0.0, angle_error_deg=0.0)
    stats = {n: record_stats(r) for n, r in recs.items()}
    s1 = stage1(stats, G).constants()
    for k in ACCEL_SCALE_NAMES + ACCEL_MIS_NAMES:
        assert s1[k] == pytest.approx(TRUTH[k], abs=2e-5), k
    for k in GYRO_GSENS_NAMES + ACCEL_BIAS_NAMES:
        assert s1[k] == pytest.approx(TRUTH[k], abs=2e-4), k
    for k in GYRO_BIAS_NAMES:
        assert s1[k] == pytest.approx(TRUTH[k], abs=1e-3), k
    # equal windows: bias·T and g-sensitivity·T cancel in the CCW − CW difference
    m2 = matrix_to_names("G", stage2(stats, 2))
    for k in GYRO_SCALE_NAMES + GYRO_MIS_NAMES:
        assert m2[k] == pytest.approx(TRUTH[k], abs=2e-5), k
    with pytest.raises(UserError, match="missing: x_dn"):
        stage1({k: v for k, v in stats.items() if k != "x_dn"}, G)


# ---- least squares ------------------------------------------------------------------------
def test_standard_session_recovers_truth(standard: CalibrationResult) -> None:
    err = _assert_recovers(standard)
    # with this noise the errors are far inside the acceptance, and within ~4 std errors
    for k in SCALE_MIS + ACCEL_BIAS_NAMES + GYRO_BIAS_NAMES + GYRO_GSENS_NAMES:
        assert err[k] < 4.5 * standard.std_errors[k] + 1e-5, (k, err[k], standard.std_errors[k])
    assert standard.turns == 2
    # nothing to note but how the noise floor, the seating at still moments and the hand while
    # the cube turns (the moving blocks) were measured
    assert all(
        n.startswith(
            (
                "noise floor of a record mean",
                "seating of the cube",
                "the hand while the cube",
                "a named variance component",
            )
        )
        for n in standard.notes
    ), standard.notes


def test_closed_form_agrees_with_lsq(standard: CalibrationResult) -> None:
    c = standard.constants()
    assert set(standard.closed_form) == set(CONSTANT_NAMES)
    for k, v in standard.closed_form.items():
        if k in NOISE_NAMES:
            assert v == c[k]
        elif k.startswith("A"):
            # the fit also reads the accelerometer at the still moments inside the turns,
            # which the closed form (statics only) does not: the two differ by that extra
            # data, within the standard error
            assert abs(v - c[k]) < 1.0 * standard.std_errors[k], (k, v, c[k])
        else:
            # the gyro: the fit also reads bias and g-sensitivity in the turn integrals
            # (gravity along the turn axis for their whole duration) and weighs the turns by
            # their measured scatter, not the closed form's assumed 0.5°: extra data, within
            # the standard error
            assert abs(v - c[k]) < 1.5 * standard.std_errors[k], (k, v, c[k])


def test_noise_is_largest_static_std(standard: CalibrationResult) -> None:
    # truth noise: 0.01 m/s², 0.025 °/s per sample
    for k in NOISE_NAMES[:3]:
        assert 0.024 < standard.constants()[k] < 0.0275
    for k in NOISE_NAMES[3:]:
        assert 0.0095 < standard.constants()[k] < 0.011


def test_residuals(standard: CalibrationResult) -> None:
    assert [r.record for r in standard.residuals] == list(STATIC_NAMES + TURN_NAMES)
    for r in standard.residuals:
        if r.kind == "static":
            assert max(abs(x) for x in r.accel_mean) < 1e-3
            assert max(abs(x) for x in r.gyro_mean) < 3e-3
            assert all(0.008 < x < 0.012 for x in r.accel_std)
        else:
            assert r.angle_deg is not None and max(abs(x) for x in r.angle_deg) < 0.5


def test_one_way_turns_bias_from_statics() -> None:
    # a one-way turn puts the whole hand angle error (0.2° std) into the scale: 0.2/(360·n),
    # so n = 3 turns to stay inside 1e-3 with margin
    recs = make_records(STATIC_NAMES + ("x_cw", "y_ccw", "z_cw"), seed=5, turns=3)
    res = calibrate_from_records(_session(recs))
    _assert_recovers(res)
    assert any("only CW" in n for n in res.notes) and any("only CCW" in n for n in res.notes)
    assert res.turns == 3
    # the closed form of stage 2 needs pairs: only stage-1 closed-form values
    assert "Gxx" not in res.closed_form and "Axx" in res.closed_form


def test_uneven_durations_and_several_turns_per_axis() -> None:
    rng = np.random.default_rng(8)
    recs = make_records(seed=8)
    # statics of different lengths, a second pair about x, extra tilted attitudes
    recs["z_dn"] = make_record("z_dn", rng, seconds=12.0)
    recs["x_ccw_2"] = make_record("x_ccw_2", rng, sign=1, turns=2, up=np.array([1.0, 0, 0]))
    recs["x_cw_2"] = make_record("x_cw_2", rng, sign=-1, turns=2, up=np.array([1.0, 0, 0]))
    for i, up in enumerate(([0, 1, 1], [1, 0, -1], [-1, -1, 1])):
        nm = f"tilt_{i}"
        recs[nm] = make_record(nm, rng, up=np.array(up, float), meta={"up": str(up)})
    res = calibrate_from_records(_session(recs))
    _assert_recovers(res)
    assert len(res.residuals) == 17


def test_rate_table_plan() -> None:
    rng = np.random.default_rng(4)
    recs = make_records(STATIC_NAMES, seed=4)
    for ax in "xyz":
        up = np.zeros(3)
        up["xyz".index(ax)] = 1.0
        for rate in (-100.0, -50.0, 50.0, 100.0):
            nm = f"rate_{ax}_{rate:+.0f}"
            meta = {"rate_dps": f"{rate}", "rate_axis": f"+{ax}", "up": f"+{ax}"}
            recs[nm] = make_record(nm, rng, up=up, rate_dps=rate, seconds=10.0, meta=meta)
    res = calibrate_from_records(_session(recs))
    _assert_recovers(res)


def test_statics_only_gyro_scale_not_measured() -> None:
    res = calibrate_from_records(_session(make_records(STATIC_NAMES, seed=6)))
    _assert_recovers(res, gyro_scale=False)
    for k in GYRO_SCALE_NAMES + GYRO_MIS_NAMES:
        assert math.isnan(res.constants()[k])
    assert passed(res)["Gxx"] is False and not res.all_passed
    assert any("not determined" in n and "Gxx" in n for n in res.notes)
    # what would determine it: a turn about that axis, either way (the bias is from statics)
    assert res.parameter("Gxx").needs == "add any one of: x_ccw, x_cw"
    assert res.parameter("Gzx").needs == "add any one of: y_ccw, y_cw"
    back = result_from_json(result_to_json(res))
    assert math.isnan(back.constants()["Gxx"])
    assert json.loads(result_to_json(res))["constants"]["Gxx"] is None
    assert back.parameter("Gxx").needs == res.parameter("Gxx").needs


def test_turns_about_x_only() -> None:
    res = calibrate_from_records(_session(make_records(STATIC_NAMES + ("x_ccw", "x_cw"))))
    m = res.gyro_m()
    assert np.all(np.isfinite(m[:, 0])) and np.all(np.isnan(m[:, 1:]))
    c = res.constants()
    assert abs(c["Gxx"] - TRUTH["Gxx"]) < 1e-3 and abs(c["Gzy"] - TRUTH["Gzy"]) < 1e-3


def test_unknown_record_is_ignored_with_a_note() -> None:
    recs = make_records(seed=14)
    r = recs["x_up"]
    recs["notes"] = Record("notes", r.t_ms, r.accel, r.gyro, r.temp, {})
    res = calibrate_from_records(_session(recs))
    assert "SIM1_notes.txt: not a static, turn or rate record; ignored" in res.notes
    assert "notes" not in [x.record for x in res.residuals]


def test_turn_that_did_not_happen() -> None:
    recs = make_records(seed=14)
    still = make_records(("x_up",), seed=15)["x_up"]
    recs["x_ccw"] = Record("x_ccw", still.t_ms, still.accel, still.gyro, still.temp, {})
    with pytest.raises(
        UserError,
        match=r"SIM1_x_ccw.txt: the cube turned [+-]0° about \+X, "
        r"expected \+720°",
    ):
        calibrate_from_records(_session(recs), CalibrationOptions(turns=2))


def test_no_statics_is_an_error() -> None:
    with pytest.raises(UserError, match="no static or pose records"):
        calibrate_from_records(_session(make_records(TURN_NAMES)))


# ---- checks -------------------------------------------------------------------------------
def test_wrong_face_is_named() -> None:
    recs = make_records(seed=3)
    wrong = make_records(("z_up",), seed=3)["z_up"]
    recs["x_up"] = Record("x_up", wrong.t_ms, wrong.accel, wrong.gyro, wrong.temp, {})
    with pytest.raises(UserError) as ei:
        calibrate_from_records(_session(recs))
    assert str(ei.value) == (
        "SIM1_x_up.txt: gravity is on +Z, expected +X: the cube was on the wrong face; "
        "re-measure x_up"
    )
    # the record is named by the error's type and attribute, not only by its text
    assert isinstance(ei.value, RecordCheckError) and ei.value.file_name == "SIM1_x_up.txt"


def test_wrong_face_of_a_turn() -> None:
    recs = make_records(seed=3)
    wrong = make_records(("y_cw",), seed=3)["y_cw"]
    recs["x_cw"] = Record("x_cw", wrong.t_ms, wrong.accel, wrong.gyro, wrong.temp, {})
    with pytest.raises(UserError, match=r"SIM1_x_cw.txt: gravity is on \+Y, expected \+X"):
        calibrate_from_records(_session(recs))


def test_incomplete_turn_is_named() -> None:
    recs = make_records(seed=3)
    rng = np.random.default_rng(0)
    short = make_record("z_ccw", rng, sign=1, turns=1)  # 360° where 720° are expected
    recs["z_ccw"] = Record("z_ccw", short.t_ms, short.accel, short.gyro, short.temp, {})
    with pytest.raises(
        UserError,
        match=r"SIM1_z_ccw.txt: the cube turned \+3[56]\d° about \+Z, "
        r"expected \+720° \(2 turns\)",
    ):
        calibrate_from_records(_session(recs), CalibrationOptions(turns=2))
    # the number of turns is inferred when not given: then it is the odd one out
    res = calibrate_from_records(_session(recs))
    assert res.turns is None and any("different numbers of turns" in n for n in res.notes)


def test_wrong_direction_is_named() -> None:
    recs = make_records(seed=3)
    cw = recs["y_cw"]
    recs["y_ccw"] = Record("y_ccw", cw.t_ms, cw.accel, cw.gyro, cw.temp, {})
    with pytest.raises(
        UserError,
        match=r"SIM1_y_ccw.txt: .* the wrong way \(expected "
        r"counter-clockwise\)",
    ):
        calibrate_from_records(_session(recs))


def test_gyro_range_alarm() -> None:
    recs = make_records(seed=3)
    r = recs["x_cw"]
    recs["x_cw"] = Record("x_cw", r.t_ms, r.accel, r.gyro, r.temp, {"gyro_range_dps": "100"})
    with pytest.raises(UserError, match=r"SIM1_x_cw.txt: the rate reached .* ±100 °/s"):
        calibrate_from_records(_session(recs))


def test_moving_static_is_named() -> None:
    recs = make_records(seed=3)
    r = recs["y_dn"]
    gyro = r.gyro + np.where(np.arange(len(r)) % 50 < 5, 30.0, 0.0)[:, None]
    recs["y_dn"] = Record("y_dn", r.t_ms, r.accel, gyro, r.temp, {})
    with pytest.raises(RecordCheckError, match="SIM1_y_dn.txt: the cube moved") as ei:
        calibrate_from_records(_session(recs))
    assert ei.value.file_name == "SIM1_y_dn.txt"


# ---- result and apply ---------------------------------------------------------------------
def test_json_round_trip_and_version(standard: CalibrationResult) -> None:
    text = result_to_json(standard)
    d = json.loads(text)
    assert d["format_version"] == FORMAT_VERSION == 3
    assert list(d["constants"]) == list(CONSTANT_NAMES)
    par = {p["name"]: p for p in d["parameters"]}
    assert par["G0x"]["unit"] == "°/s" and par["A0z"]["tolerance"] == 0.8
    assert par["G0x"]["term"] == "bias" and par["G0x"]["sensor"] == "gyro"
    assert par["Gzy"]["term"] == "misalignment" and par["Gzy"]["axis"] == "z"
    assert par["GAyz"]["stderr"] == pytest.approx(standard.std_errors["GAyz"])
    assert d["noise_std"]["Astdx"]["tolerance"] is None and d["pass"]["Astdx"] is None
    assert d["pass"]["Gxx"] is True and d["g"] == pytest.approx(G)
    assert d["model"] == "base" and d["fit"]["verdict"] == "adequate" and d["fit"]["dof"] > 0
    assert set(d["noise_model"]) >= {"floor", "block_s", "turn_angle_sigma_deg"}
    assert d["latitude_deg"] == 55.75 and d["height_m"] == 150.0 and d["turns"] == 2
    back = result_from_json(text)
    assert back.constants() == standard.constants()
    assert result_to_json(back) == text
    d["format_version"] = 4
    with pytest.raises(UserError, match="format v4 but this program reads v1, v2, v3"):
        result_from_json(json.dumps(d))
    with pytest.raises(UserError, match="not valid JSON"):
        result_from_json("{")
    del d["parameters"][3]["value"]
    d["format_version"] = 3
    with pytest.raises(UserError, match="missing or bad field"):
        result_from_json(json.dumps(d))


def test_pass_flags() -> None:
    truth = dict(TRUTH, A0x=0.7, GAyz=-0.2)
    recs = make_records(seed=9, truth=truth)
    res = calibrate_from_records(_session(recs))
    p = passed(res)
    assert p["A0x"] is False and p["GAyz"] is False and p["A0y"] is True
    assert not res.all_passed


def test_apply_gives_g_and_zero_rate(standard: CalibrationResult) -> None:
    recs = make_records(seed=21)  # fresh data, same unit
    for name in STATIC_NAMES:
        r = recs[name]
        a, w = apply(standard, r.accel, r.gyro)
        mean_a = a.mean(axis=0)
        assert np.linalg.norm(mean_a) == pytest.approx(G, abs=3e-3)
        assert mean_a @ r.up == pytest.approx(G, abs=3e-3)
        assert np.abs(w.mean(axis=0)).max() < 0.01
        raw_err = np.abs(r.gyro.mean(axis=0)).max()
        assert raw_err > 0.5  # the raw gyro was visibly biased
    r = recs["y_ccw"]
    _, w = apply(standard, r.accel, r.gyro)
    ang = trapezoid_integral(r.t_ms, w)
    assert ang == pytest.approx([0.0, 720.0, 0.0], abs=1.0)
    a1, w1 = apply(standard, r.accel[0], r.gyro[0])
    assert a1.shape == (3,) and w1.shape == (3,)


def test_earth_rate_option() -> None:
    recs = make_records(seed=12)
    a = calibrate_from_records(_session(recs))
    b = calibrate_from_records(_session(recs), CalibrationOptions(earth_rate=True))
    # the vertical Earth rate (0.0035 °/s at 55.75°) moves the g-sensitivity, not the scale
    assert abs(b.constants()["GAzz"] - a.constants()["GAzz"]) == pytest.approx(
        15.041067 / 3600 * math.sin(math.radians(55.75)), rel=0.05
    )
    assert abs(b.constants()["Gzz"] - a.constants()["Gzz"]) < 1e-6 and b.earth_rate


# ---- real data ----------------------------------------------------------------------------
@pytest.fixture(scope="module")
def real() -> tuple[CalibrationResult, dict[str, np.ndarray]]:
    res = calibrate_from_records(read_session(REAL))
    imucal = json.loads((REAL / "imucal_result.json").read_text())
    return res, {k: np.array(v) for k, v in imucal.items() if isinstance(v, list)}


def test_real_data_scale_matches_imucal(
    real: tuple[CalibrationResult, dict[str, np.ndarray]],
) -> None:
    res, im = real
    # imucal: u = K·R·a + b; for small errors K·R − I is our M (§2 signs via names_to_matrix)
    for pre, k, r in (("A", "K_a", "R_a"), ("G", "K_g", "R_g")):
        theirs = im[k] @ im[r] - np.eye(3)
        ours = names_to_matrix(pre, res.constants())
        closed = names_to_matrix(pre, {**res.constants(), **res.closed_form})
        if pre == "A":  # imucal divides by 9.81, we by the local g
            closed = (np.eye(3) + closed) * (res.g / 9.81) - np.eye(3)
        assert np.abs(np.diag(ours - theirs)).max() < 2e-3  # scale errors, brief: ~2e-3
        assert np.abs(ours - theirs).max() < 2e-3  # misalignments too
        # the closed form is the same estimator as imucal's (different g, trapezoid rule)
        assert np.abs(closed - theirs).max() < 3e-4, pre
    assert np.abs(res.gyro_bias() - im["b_g"]).max() < 2e-3
    assert np.abs(res.gyro_gsens() - im["K_ga"] * 9.81).max() < 1e-3


def test_real_data_accel_bias_inconsistency(
    real: tuple[CalibrationResult, dict[str, np.ndarray]],
) -> None:
    res, im = real
    # imucal's b_a is the estimate from the channel's own axis pair; ours is the mean of three
    own = [res.bias_estimates[n][i] for i, n in enumerate(ACCEL_BIAS_NAMES)]
    assert np.abs(np.array(own) - im["b_a"]).max() < 1e-3
    spreads = [max(e) - min(e) for n, e in res.bias_estimates.items() if n.startswith("A0")]
    assert min(spreads) > 0.015  # README: the three estimates disagree by 0.02-0.04 m/s²
    assert np.abs(res.accel_bias() - im["b_a"]).max() < 0.03
    # and the model misfit shows in the static residuals (≫ noise of a mean, ~1e-3)
    worst = max(max(abs(x) for x in r.accel_mean) for r in res.residuals if r.kind == "static")
    assert worst > 0.01


def test_real_data_plan(real: tuple[CalibrationResult, dict[str, np.ndarray]]) -> None:
    res, _ = real
    assert res.turns == 1 and res.serial == "REAL"
    assert sum("only CW" in n for n in res.notes) == 3
    turn_res = [r for r in res.residuals if r.kind == "turn"]
    assert len(turn_res) == 3  # one-way turns: exactly determined, residual ~0
    assert all(max(abs(x) for x in (r.angle_deg or ())) < 1e-6 for r in turn_res)


def test_a_failed_check_names_its_bench_record() -> None:
    from host.errors import RecordCheckError
    from host.session.checks import failed_record

    def err(f: str) -> RecordCheckError:
        return RecordCheckError(f"{f}: bad", file_name=f)

    assert failed_record(err("U7_y_cw.txt"), "U7") == "y_cw"
    assert failed_record(err("U7_z_dn.txt"), "U7") == "z_dn"
    assert failed_record(err("U8_z_dn.txt"), "U7") is None  # another unit's file
    # the closing check and the repeats of a session (--redo measures them again by name)
    assert failed_record(err("U7_x_up_2.txt"), "U7") == "x_up_2"
    assert failed_record(err("U7_x_ccw_2.txt"), "U7") == "x_ccw_2"
    assert failed_record(err("U_7_y_up_3.txt"), "U_7") == "y_up_3"
    assert failed_record(err("U7_tilt_45_1.txt"), "U7") is None  # not a record the bench measures
    assert failed_record(err("U7_result.txt"), "U7") is None
