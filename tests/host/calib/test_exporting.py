"""``python3 -m host export``: every format round-trips through the target's own formula.

For each target, the exported numbers are read back from the exported text and applied with
the formula the target uses; on synthetic raw samples that must reproduce ``apply()`` to 1e-6
relative for the part of the model the target can represent (and visibly not for the rest).
"""

from __future__ import annotations

import contextlib
import dataclasses
import io
import json
import math
import re
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from host.__main__ import main
from host.calib.applying import apply
from host.calib.codec import result_from_json, result_to_json
from host.calib.exporting import FORMATS, export
from host.calib.result import CalibrationResult, base_parameters
from host.errors import FailedResultError, UserError
from host.ingest.importing import parse_axes
from host.session.method import (
    CONSTANT_NAMES,
    GYRO_GSENS_NAMES,
    GYRO_MIS_NAMES,
    GYRO_SCALE_NAMES,
    NOISE_NAMES,
    local_gravity,
)

try:
    from calib_truth import TRUTH
except ImportError:  # tests/ imported as a package
    from tests.host.calib_truth import TRUTH

DEG = math.pi / 180.0
RTOL = 1e-6


def _result(**override: float) -> CalibrationResult:
    consts = {n: 0.0 for n in CONSTANT_NAMES}
    consts.update(TRUTH)
    consts.update({"Gstdx": 0.021, "Gstdy": 0.023, "Gstdz": 0.026})
    consts.update({"Astdx": 0.008, "Astdy": 0.009, "Astdz": 0.011})
    consts.update(override)
    return CalibrationResult(
        serial="EXP1", created="2026-11-23T12:00:00+00:00", g=local_gravity(),
        latitude_deg=55.75, height_m=150.0, turns=2, model="base",
        parameters=base_parameters(consts), noise_std={n: consts[n] for n in NOISE_NAMES},
    )  # fmt: skip


#: only what a per-axis offset + scale target holds (misalignment, GA zero)
DIAGONAL = {n: 0.0 for n in ("Axz", "Axy", "Ayz", "Ayx", "Azy", "Azx")} | {
    n: 0.0 for n in ("Gxz", "Gxy", "Gyz", "Gyx", "Gzy", "Gzx")
} | {n: 0.0 for n in GYRO_GSENS_NAMES}  # fmt: skip


def _samples(n: int = 300) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(42)
    accel = rng.normal([0.3, -0.5, 0.8], [6.0, 7.0, 8.0], (n, 3))
    gyro = rng.normal([5.0, -7.0, 3.0], [90.0, 110.0, 130.0], (n, 3))
    return accel, gyro


def _params(text: str) -> dict[str, float]:
    """NAME VALUE lines (ArduPilot) or QGC rows 'vehicle comp NAME VALUE type' (PX4)."""
    out = {}
    for line in text.splitlines():
        if not line.strip() or line.startswith("#"):
            continue
        f = line.split()
        if len(f) == 2:
            out[f[0]] = float(f[1])
        else:
            assert len(f) == 5 and f[4] == ("6" if f[2].endswith("ENABLE") else "9"), line
            out[f[2]] = float(f[3])
    return out


def _close(got: np.ndarray, want: np.ndarray) -> None:
    np.testing.assert_allclose(got, want, rtol=RTOL, atol=RTOL * float(np.abs(want).max()))


# ---- ArduPilot ----------------------------------------------------------------------------
def _ardupilot_apply(p: dict[str, float], a: np.ndarray, g: np.ndarray) -> tuple:
    off = np.array([p[f"INS_ACCOFFS_{x}"] for x in "XYZ"])
    scal = np.array([p[f"INS_ACCSCAL_{x}"] for x in "XYZ"])
    goff = np.array([p[f"INS_GYROFFS_{x}"] for x in "XYZ"])  # rad/s
    return (a - off) * scal, (g * DEG - goff) / DEG


def test_ardupilot_round_trip_on_its_representable_part() -> None:
    accel, gyro = _samples()
    res = _result(**DIAGONAL, Gxx=0.0, Gyy=0.0, Gzz=0.0)
    text = export(res, "ardupilot")
    a_t, g_t = _ardupilot_apply(_params(text), accel, gyro)
    a_ref, g_ref = apply(res, accel, gyro)
    _close(a_t, a_ref)
    _close(g_t, g_ref)


def test_ardupilot_names_what_it_loses_and_really_loses_it() -> None:
    accel, gyro = _samples()
    res = _result()
    text = export(res, "ardupilot")
    for what in ("accelerometer misalignment", "gyro scale error", "gyro misalignment",
                 "g-sensitivity"):  # fmt: skip
        assert what in text
    a_t, _ = _ardupilot_apply(_params(text), accel, gyro)
    a_ref, _ = apply(res, accel, gyro)
    assert np.abs(a_t - a_ref).max() > 1e-3  # the misalignment is really not in there


# ---- PX4 ----------------------------------------------------------------------------------
def _px4_apply(p: dict[str, float], a: np.ndarray, g: np.ndarray) -> tuple:
    aoff = np.array([p[f"CAL_ACC0_{x}OFF"] for x in "XYZ"])
    ascale = np.array([p[f"CAL_ACC0_{x}SCALE"] for x in "XYZ"])
    goff = np.array([p[f"CAL_GYRO0_{x}OFF"] for x in "XYZ"])
    gscale = np.array([p[f"CAL_GYRO0_{x}SCALE"] for x in "XYZ"])
    return (a - aoff) * ascale, ((g * DEG - goff) * gscale) / DEG


def test_px4_round_trip_on_its_representable_part() -> None:
    accel, gyro = _samples()
    res = _result(**DIAGONAL)  # PX4 keeps the gyro scale
    text = export(res, "px4")
    assert "gyro scale error" not in text and "accelerometer misalignment" in text
    a_t, g_t = _px4_apply(_params(text), accel, gyro)
    a_ref, g_ref = apply(res, accel, gyro)
    _close(a_t, a_ref)
    _close(g_t, g_ref)


# ---- imucal -------------------------------------------------------------------------------
def _imucal_apply(d: dict, a: np.ndarray, g: np.ndarray) -> tuple:
    """imucal's Ferraris correction, written from its documented model."""
    ka, ra, ba = (np.array(d[k]) for k in ("K_a", "R_a", "b_a"))
    kg, rg, bg, kga = (np.array(d[k]) for k in ("K_g", "R_g", "b_g", "K_ga"))
    acc = (np.linalg.inv(ra) @ np.linalg.inv(ka) @ (a - ba).T).T
    gyr = (np.linalg.inv(rg) @ np.linalg.inv(kg) @ (g - (kga @ acc.T).T - bg).T).T
    return acc, gyr


def test_imucal_round_trip_of_the_whole_model() -> None:
    accel, gyro = _samples()
    res = _result()
    d = json.loads(export(res, "imucal"))
    assert d["cal_type"] == "Ferraris" and d["_format_version"] == "2.0.0"
    assert np.allclose(np.linalg.norm(np.array(d["R_a"]), axis=1), 1.0)
    assert np.count_nonzero(np.array(d["K_g"]) - np.diag(np.diag(np.array(d["K_g"])))) == 0
    a_t, g_t = _imucal_apply(d, accel, gyro)
    a_ref, g_ref = apply(res, accel, gyro)
    _close(a_t, a_ref)
    _close(g_t, g_ref)


# ---- C header -----------------------------------------------------------------------------
_ARRAY_RE = re.compile(r"static const float (\w+)((?:\[\d\])+) = (\{.*?\});", re.S)


def _c_arrays(text: str) -> dict[str, np.ndarray]:
    out = {}
    for name, dims, body in _ARRAY_RE.findall(text):
        vals = [float(v) for v in re.findall(r"([-+0-9.eE]+)f", body)]
        shape = tuple(int(d) for d in re.findall(r"\[(\d)\]", dims))
        out[name] = np.array(vals, dtype=np.float32).astype(np.float64).reshape(shape)
    return out


def test_c_header_round_trip_with_the_formula_in_its_comment() -> None:
    accel, gyro = _samples()
    res = _result()
    text = export(res, "c-header")
    c = _c_arrays(text)
    assert set(c) == {"ACCEL_M_INV", "ACCEL_BIAS", "GYRO_M_INV", "GYRO_BIAS", "GYRO_G_SENS"}
    a_t = (c["ACCEL_M_INV"] @ (accel - c["ACCEL_BIAS"]).T).T  # the comment's three lines
    corr = gyro - c["GYRO_BIAS"] - (c["GYRO_G_SENS"] @ a_t.T).T
    g_t = (c["GYRO_M_INV"] @ corr.T).T
    a_ref, g_ref = apply(res, accel, gyro)
    _close(a_t, a_ref)
    _close(g_t, g_ref)
    assert "#ifndef IMU_CALIBRATION_EXP1_H" in text


# ---- frames, CLI --------------------------------------------------------------------------
def test_target_axes_map_every_axis() -> None:
    """--axes y,x,-z: the target's raw samples are P·ours; its corrected output is P·apply()."""
    accel, gyro = _samples()
    res = _result()
    p = parse_axes("y,x,-z")
    d = json.loads(export(res, "imucal", p, "y,x,-z"))
    a_t, g_t = _imucal_apply(d, accel @ p.T, gyro @ p.T)
    a_ref, g_ref = apply(res, accel, gyro)
    _close(a_t, a_ref @ p.T)
    _close(g_t, g_ref @ p.T)


def test_unmeasured_gyro_scale_exports_as_nominal_and_says_so() -> None:
    nan = {n: math.nan for n in ("Gxx", "Gyy", "Gzz", "Gxz", "Gxy", "Gyz", "Gyx", "Gzy", "Gzx")}
    res = _result(**nan)
    with pytest.raises(FailedResultError, match=r"not determined: Gxx, Gyy, Gzz, Gxz"):
        export(res, "px4")  # a result that does not determine Mg failed: not without asking
    text = export(res, "px4", allow_fail=True)
    assert "not measured" in text
    assert "# *** FAILED calibration, exported with --allow-fail: not determined: Gxx" in text
    assert _params(text)["CAL_GYRO0_YSCALE"] == 1.0


def test_cli_writes_each_format_and_refuses_unknown_ones(tmp_path: Path, capsys) -> None:
    res = _result()
    rj = tmp_path / "EXP1_result.json"
    rj.write_text(result_to_json(res))
    for fmt, (_, ext) in FORMATS.items():
        out = tmp_path / f"cal{ext}"
        assert main(["export", str(tmp_path), "--to", fmt, "--out", str(out)]) == 0
        assert out.read_text() == export(res, fmt)
    assert main(["export", str(rj), "--to", "kalibr"]) == 2
    assert "--noise NOISE.json" in capsys.readouterr().err
    assert main(["export", str(rj), "--to", "betaflight"]) == 2
    err = capsys.readouterr().err
    assert "unknown format" in err and err.count("\n") == 1
    assert main(["export", str(tmp_path / "nope.json"), "--to", "px4"]) == 2


def test_an_earlier_export_is_replaced_and_any_other_file_kept(tmp_path: Path, capsys) -> None:
    """Was: --out over a vehicle's parameter file replaced it whole, silently; --out DIR said
    'permission denied'; --axes '' (an unset variable) exported in our axes."""
    (tmp_path / "EXP1_result.json").write_text(result_to_json(_result()))
    for fmt, (_, ext) in FORMATS.items():
        out = tmp_path / f"cal{ext}"
        for again in (False, True):
            assert main(["export", str(tmp_path), "--to", fmt, "--out", str(out)]) == 0
            said = capsys.readouterr().err
            assert said.startswith(f"written: {out}") and ("replaced" in said) == again
    vehicle = tmp_path / "vehicle.parm"
    vehicle.write_text("INS_ACCOFFS_X 0.1\nSERIAL0_BAUD 115\n")
    for argv, words in (
        (["--out", str(vehicle)], "exists and is no export of this program; it is kept"),
        (["--out", str(tmp_path)], f"is a directory; give a file name, e.g. {tmp_path}/U17.parm"),
        (["--axes", ""], "--axes '': an empty value (an unset variable?)"),
    ):
        assert main(["export", str(tmp_path), "--to", "ardupilot", *argv]) == 2
        err = capsys.readouterr().err
        assert words in err and err.count("\n") == 1, err
    assert vehicle.read_text() == "INS_ACCOFFS_X 0.1\nSERIAL0_BAUD 115\n"


@settings(
    max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(st.binary(max_size=200).filter(lambda b: b"imu-bench" not in b))
def test_no_other_file_is_ever_replaced(tmp_path: Path, body: bytes) -> None:
    (tmp_path / "EXP1_result.json").write_text(result_to_json(_result()))
    out = tmp_path / "any.params"
    out.write_bytes(body)
    with contextlib.redirect_stderr(io.StringIO()) as err:
        assert main(["export", str(tmp_path), "--to", "px4", "--out", str(out)]) == 2
    assert out.read_bytes() == body and "it is kept" in err.getvalue()


REAL = Path(__file__).resolve().parents[4] / "shared" / "data" / "imucal-example"


def test_imucal_export_of_the_real_session_agrees_with_imucals_own_result() -> None:
    """Real data, imucal's own numbers: our K·R split, K_ga per m/s² and signs match imucal's
    convention (a transposed R or K_ga per g would miss by 10-100× these tolerances). imucal
    uses g = 9.81 and its own bias estimator: K_a and b_a agree less closely."""
    from host.calib.calibration import calibrate_from_records
    from host.session.directory import read_session

    real = calibrate_from_records(read_session(REAL))  # outside the MPU-6000's tolerances
    ours = json.loads(export(real, "imucal", allow_fail=True))
    theirs = json.loads((REAL / "imucal_result.json").read_text())
    tol = {"K_g": 2e-4, "R_g": 1e-4, "K_ga": 1e-4, "b_g": 2e-3, "K_a": 2e-3, "R_a": 1e-3,
           "b_a": 0.03}  # fmt: skip
    for key, t in tol.items():
        diff = np.abs(np.array(ours[key]) - np.array(theirs[key])).max()
        assert diff < t, (key, diff)


# ---- thermal (PX4 thermal compensation) ---------------------------------------------------
def _thermal(orders: dict[str, tuple[float, ...]]):
    from host.calib.thermal import CHANNELS, UNITS, ChannelThermal, ThermalCalibration

    chans = {}
    for j, name in enumerate(CHANNELS):
        c = orders[name]
        cov = tuple(tuple(0.0 for _ in c) for _ in c)
        chans[name] = ChannelThermal(name, UNITS[j], len(c), c, cov, 0.001, (), ())
    return ThermalCalibration("EXP1", 31.5, 22.0, 48.0, chans)


THERMAL = {
    "ax": (2.1e-3, -3e-5), "ay": (-1.3e-3, 2e-5, 1e-7), "az": (4.4e-3,),
    "gx": (0.011, -2e-4), "gy": (-0.007,), "gz": (0.004, 1e-4, -3e-6),
}  # fmt: skip


def _px4_thermal_apply(p: dict[str, float], a: np.ndarray, g: np.ndarray, t: np.ndarray):
    out = []
    for sensor, raw, unit in (("A", a, 1.0), ("G", g * DEG, DEG)):
        dt = np.clip(t, p[f"TC_{sensor}0_TMIN"], p[f"TC_{sensor}0_TMAX"]) - p[f"TC_{sensor}0_TREF"]
        x = np.array([[p[f"TC_{sensor}0_X{k}_{i}"] for i in range(3)] for k in range(4)])
        offset = x[0] + np.outer(dt, x[1]) + np.outer(dt**2, x[2]) + np.outer(dt**3, x[3])
        off = "ACC0" if sensor == "A" else "GYRO0"
        o = np.array([p[f"CAL_{off}_{ax}OFF"] for ax in "XYZ"])
        sc = np.array([p[f"CAL_{off}_{ax}SCALE"] for ax in "XYZ"])
        out.append((raw - offset - o) * sc / unit)
    return out[0], out[1]


def test_px4_thermal_compensation_round_trip() -> None:
    from host.calib.thermal import apply_thermal

    accel, gyro = _samples()
    temp = np.random.default_rng(5).uniform(22.0, 48.0, len(accel))
    res = _result(**DIAGONAL)
    th = _thermal(THERMAL)
    text = export(res, "px4", thermal=th)
    assert (
        "order" not in text.split("# Vehicle-Id")[0].split("NOT REPRESENTED")[1].split("g-sens")[1]
    )
    a_t, g_t = _px4_thermal_apply(_params(text), accel, gyro, temp)
    a_ref, g_ref = apply(res, *apply_thermal(th, accel, gyro, temp))
    _close(a_t, a_ref)
    _close(g_t, g_ref)


def test_px4_thermal_names_a_fourth_order_it_cannot_hold() -> None:
    th = _thermal({**THERMAL, "gy": (-0.007, 1e-4, 2e-6, -4e-8)})
    text = export(_result(), "px4", thermal=th)
    assert "gy bias(T) terms above order 3 (order 4" in text


def test_thermal_for_a_format_without_it_is_refused(tmp_path: Path, capsys) -> None:
    rj = tmp_path / "EXP1_result.json"
    rj.write_text(result_to_json(_result()))
    tj = tmp_path / "EXP1_thermal.json"
    tj.write_text(_thermal(THERMAL).to_json())
    assert main(["export", str(rj), "--to", "px4", "--thermal", str(tj)]) == 0
    assert "TC_G0_X1_0" in capsys.readouterr().out
    assert main(["export", str(rj), "--to", "imucal", "--thermal", str(tj)]) == 2
    assert "no place for bias(T)" in capsys.readouterr().err


def test_every_format_names_a_further_term_it_cannot_hold() -> None:
    # A result of model base,temperature_bias:gyro:y: no export target has a place for the
    # temperature term, so each must name it with its value, never drop it in silence.
    from host.calib.values import ParameterResult

    base = _result()
    extra = ParameterResult(
        term="temperature_bias", sensor="gyro", axis="y", key="per_C",
        name="temperature_bias.gyro.y", value=-0.02624, stderr=0.0055, unit="°/s/°C",
    )  # fmt: skip
    result = dataclasses.replace(
        base, model="base,temperature_bias:gyro:y", parameters=(*base.parameters, extra)
    )
    for fmt in FORMATS:
        text = export(result, fmt)
        assert "temperature_bias gyro y" in text and "-0.02624" in text, fmt
        assert "temperature_bias" not in export(base, fmt), fmt


def _noise_doc() -> dict:
    """A noise file (``noise --save``) with a different figure on every axis; gy's random
    walk unresolved (value None, upper bound only)."""
    figs = {}
    for k, ch in enumerate(("ax", "ay", "az", "gx", "gy", "gz")):
        n = (3.1e-3, 2.9e-3, 3.6e-3, 5.0e-3, 5.4e-3, 4.7e-3)[k]
        rrw = (2.0e-4, 2.6e-4, 2.2e-4, 3.0e-4, None, 2.5e-4)[k]
        figs[ch] = {
            "white_noise_density": {"value": n, "ci": [0.9 * n, 1.1 * n]},
            "bias_instability": {"value": 10 * n, "ci": [5 * n, 20 * n]},
            "rate_random_walk": {"value": rrw, "ci": [None if rrw is None else rrw / 2, 7e-4]},
        }
    return {"format": "imu-bench noise", "format_version": 1, "duration_s": 14400.0,
            "rate_hz": 50.0, "channels": figs}  # fmt: skip


def _yaml_values(text: str) -> dict[str, str]:
    return dict(
        (k.strip(), v.strip())
        for k, v in (line.split(":", 1) for line in text.splitlines() if not line.startswith("#"))
    )


def test_kalibr_yaml_round_trip_through_kalibrs_discrete_noise(tmp_path: Path, capsys) -> None:
    # Kalibr turns a continuous density into a per-sample std as sigma_d = density * sqrt(rate);
    # on our Allan model that is the deviation at tau = one sample period (N / sqrt(tau0)),
    # in SI units (gyro in rad), for the worst axis of each sensor.
    doc = _noise_doc()
    nf = tmp_path / "n.json"
    nf.write_text(json.dumps(doc))
    out = tmp_path / "imu.yaml"
    assert main(["export", "--to", "kalibr", "--noise", str(nf), "--out", str(out)]) == 0
    text = out.read_text()
    y = _yaml_values(text)
    rate = float(y["update_rate"])
    assert rate == 50.0 and y["rostopic"] == "/imu0"
    tau0 = 1.0 / rate
    ch = doc["channels"]
    for key, names, fig, unit in (
        ("accelerometer_noise_density", ("ax", "ay", "az"), "white_noise_density", 1.0),
        ("gyroscope_noise_density", ("gx", "gy", "gz"), "white_noise_density", DEG),
        ("accelerometer_random_walk", ("ax", "ay", "az"), "rate_random_walk", 1.0),
    ):
        ours = max(ch[n][fig]["value"] / math.sqrt(tau0) for n in names) * unit
        assert math.isclose(float(y[key]) * math.sqrt(rate), ours, rel_tol=RTOL), key
    # gy's rate random walk is unresolved: its upper bound (7e-4 °/s²/√Hz) is the worst axis
    assert math.isclose(float(y["gyroscope_random_walk"]), 7e-4 * DEG, rel_tol=RTOL)
    assert "gy rate_random_walk not resolved" in text and "bias instability" in text
    # a noise file is for kalibr only; kalibr needs one
    rj = tmp_path / "EXP1_result.json"
    rj.write_text(result_to_json(_result()))
    assert main(["export", str(rj), "--to", "px4", "--noise", str(nf)]) == 2
    assert main(["export", "--to", "px4"]) == 2
    assert "give the result" in capsys.readouterr().err


# ---- no format ever writes NaN ----------------------------------------------------------------
#: a number token a target would choke on: nan/NaN/nanf, inf/Infinity
_NOT_A_NUMBER = re.compile(r"(?<![A-Za-z])(nan|inf(inity)?)f?(?![A-Za-z])", re.IGNORECASE)
_LINEAR = [n for n in CONSTANT_NAMES if n not in NOISE_NAMES]


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    st.dictionaries(
        st.sampled_from(_LINEAR),
        st.one_of(
            st.floats(-0.2, 0.2),
            st.sampled_from([math.nan, math.inf, -math.inf]),
        ),
        max_size=6,
    ),
    st.sampled_from(sorted(FORMATS)),
)
def test_no_export_writes_nan_or_inf(values: dict[str, float], fmt: str) -> None:
    """Any constant the exports carry that is NaN or infinite refuses the export, naming it;
    otherwise the text holds numbers only (the gyro's unmeasured Mg goes out as nominal)."""
    res = _result(**values)
    gyro_m = GYRO_SCALE_NAMES + GYRO_MIS_NAMES
    bad = [n for n, v in values.items() if not math.isfinite(v) and n not in gyro_m]
    if bad:
        with pytest.raises(UserError) as exc:
            export(res, fmt, allow_fail=True)  # refused even when a failed result is allowed
        msg = str(exc.value)
        assert "\n" not in msg and all(n in msg for n in bad)
    else:
        text = export(res, fmt, allow_fail=True)
        assert not _NOT_A_NUMBER.search(text), text
        if fmt == "imucal":
            json.loads(text, parse_constant=lambda c: pytest.fail(f"imucal JSON holds {c}"))


def test_cli_refuses_to_export_an_undetermined_result(tmp_path: Path, capsys) -> None:
    rj = tmp_path / "EXP1_result.json"
    rj.write_text(result_to_json(_result(A0y=math.nan, GAxz=math.nan)))
    for fmt, (_, ext) in FORMATS.items():
        out = tmp_path / f"cal{ext}"
        assert main(["export", str(rj), "--to", fmt, "--out", str(out)]) == 1  # FAILED
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "not determined: A0y, GAxz" in err, err
        assert "--allow-fail" in err and not out.exists()
        argv = ["export", str(rj), "--to", fmt, "--out", str(out), "--allow-fail"]
        assert main(argv) == 2  # allowed to fail, but no format can carry NaN
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "A0y" in err and "GAxz" in err, err
        assert not out.exists()


# ---- thermal (ArduPilot's INS_TCAL) ---------------------------------------------------------
def _ardupilot_tcal_apply(p: dict[str, float], a: np.ndarray, g: np.ndarray, t: np.ndarray):
    """ArduPilot's correction as its parameter documentation and AP_InertialSensor describe
    it, written here on its own: before the offsets subtract P(T − 35) − P(CALTEMP − 35),
    P(d) = (C1·d + C2·d² + C3·d³)·1e-6 per axis, T and CALTEMP clamped to [TMIN, TMAX];
    accel m/s², gyro rad/s."""
    lo, hi = p["INS_TCAL1_TMIN"], p["INS_TCAL1_TMAX"]
    assert p["INS_TCAL1_ENABLE"] == 1.0
    out = []
    for sensor, raw, unit, cal in (("ACC", a, 1.0, "INS_ACC1_CALTEMP"),
                                   ("GYR", g * DEG, DEG, "INS_GYR1_CALTEMP")):  # fmt: skip
        c = np.array([[p[f"INS_TCAL1_{sensor}{k}_{x}"] for x in "XYZ"] for k in (1, 2, 3)])

        def poly(d: np.ndarray, c: np.ndarray = c) -> np.ndarray:
            d = np.asarray(d, dtype=np.float64).reshape(-1, 1)
            return (d * c[0] + d**2 * c[1] + d**3 * c[2]) * 1e-6

        corr = poly(np.clip(t, lo, hi) - 35.0) - poly(np.clip(p[cal], lo, hi) - 35.0)
        if sensor == "ACC":
            off = np.array([p[f"INS_ACCOFFS_{x}"] for x in "XYZ"])
            scal = np.array([p[f"INS_ACCSCAL_{x}"] for x in "XYZ"])
            out.append((raw - corr - off) * scal)
        else:
            off = np.array([p[f"INS_GYROFFS_{x}"] for x in "XYZ"])
            out.append((raw - corr - off) / unit)
    return out[0], out[1]


@pytest.mark.parametrize("t_ref", [31.5, 18.0])  # T_ref inside the range, and below it
def test_ardupilot_thermal_round_trip(t_ref: float) -> None:
    """The exported INS_TCAL1_*, CALTEMP and offsets, run through ArduPilot's formula, give
    what apply() gives over the calibrated range, to 1e-6 (a wrong scale, reference or sign
    misses by far more: the bias(T) changes reach 0.1 m/s² and 0.5 °/s here)."""
    import dataclasses as dc

    from host.calib.thermal import apply_thermal

    accel, gyro = _samples()
    temp = np.random.default_rng(6).uniform(22.0, 48.0, len(accel))
    res = _result(**DIAGONAL, Gxx=0.0, Gyy=0.0, Gzz=0.0)
    th = dc.replace(_thermal(THERMAL), t_ref_c=t_ref)
    text = export(res, "ardupilot", thermal=th)
    p = _params(text)
    assert p["INS_ACC1_CALTEMP"] == p["INS_GYR1_CALTEMP"] == min(max(t_ref, 22.0), 48.0)
    assert (p["INS_TCAL1_TMIN"], p["INS_TCAL1_TMAX"]) == (22.0, 48.0)
    a_t, g_t = _ardupilot_tcal_apply(p, accel, gyro, temp)
    a_ref, g_ref = apply(res, *apply_thermal(th, accel, gyro, temp))
    _close(a_t, a_ref)
    _close(g_t, g_ref)
    # the thermal part matters at this tolerance: without it the answers differ
    a_0, _ = _ardupilot_apply(p, accel, gyro)
    assert np.abs(a_0 - a_ref).max() > 1e3 * RTOL * np.abs(a_ref).max()


def test_ardupilot_thermal_from_the_result_itself(tmp_path: Path, capsys) -> None:
    """A result calibrated with --thermal carries bias(T): export --to ardupilot --thermal
    writes it, and ArduPilot's formula reproduces apply() with temperatures."""
    import dataclasses as dc

    from host.calib.result import thermal_parameters

    base = _result(**DIAGONAL, Gxx=0.0, Gyy=0.0, Gzz=0.0)
    th = _thermal(THERMAL)
    res = dc.replace(
        base, model="base,thermal_bias", temp_mean_c=29.0, thermal_range_c=(22.0, 48.0),
        parameters=(*base.parameters, *thermal_parameters(th, 29.0)),
    )  # fmt: skip
    rj = tmp_path / "EXP1_result.json"
    rj.write_text(result_to_json(res))
    assert main(["export", str(rj), "--to", "ardupilot", "--thermal"]) == 0
    p = _params(capsys.readouterr().out)
    accel, gyro = _samples()
    temp = np.random.default_rng(7).uniform(22.0, 48.0, len(accel))
    a_t, g_t = _ardupilot_tcal_apply(p, accel, gyro, temp)
    a_ref, g_ref = apply(result_from_json(rj.read_text()), accel, gyro, temp_c=temp)
    _close(a_t, a_ref)
    _close(g_t, g_ref)
    # --thermal alone on a result without bias(T) says what to give
    rj.write_text(result_to_json(base))
    assert main(["export", str(rj), "--to", "ardupilot", "--thermal"]) == 2
    assert "carries no bias(T)" in capsys.readouterr().err


def test_ardupilot_thermal_names_what_it_cannot_hold() -> None:
    th = _thermal({**THERMAL, "gy": (-0.007, 1e-4, 2e-6, -4e-8)})
    text = export(_result(), "ardupilot", thermal=th)
    assert "gy bias(T) terms above order 3 (order 4" in text
    assert "INS_TCAL1_GYR3_Y" in text


def test_a_unit_that_failed_its_self_test_is_not_exported(tmp_path: Path, capsys) -> None:
    """Every value within tolerance, but the sensor failed its self-test (issue 43): every
    format refuses it with exit 1 naming the self-test; --allow-fail writes it marked FAILED."""
    failed = dataclasses.replace(_result(), self_test="fail")
    rj = tmp_path / "EXP1_result.json"
    rj.write_text(result_to_json(failed))
    assert result_from_json(rj.read_text()).self_test == "fail"
    for fmt, (_, ext) in FORMATS.items():
        out = tmp_path / f"cal{ext}"
        assert main(["export", str(rj), "--to", fmt, "--out", str(out)]) == 1, fmt
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "failed its self-test" in err, err
        assert not out.exists()
        assert main(["export", str(rj), "--to", fmt, "--out", str(out), "--allow-fail"]) == 0
        assert "FAILED calibration, exported with --allow-fail" in out.read_text()
        assert "the sensor failed its self-test" in out.read_text()
        capsys.readouterr()
    passing = dataclasses.replace(_result(), self_test="pass")  # the same values, passed
    assert "FAILED" not in export(passing, "px4")
