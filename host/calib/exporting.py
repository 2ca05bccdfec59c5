"""Results out: the calibration in the parameters and files of the tools our users fly and code.

Our model (method.md §2, matrix form of :mod:`host.calib.calibration`), inverted by ``apply()``::

    a = Ka⁻¹ · (A − A0)                      Ka = I + Ma, A0 m/s², a m/s²
    ω = Kg⁻¹ · (G − G0 − GA · a / g)         Kg = I + Mg, G0 °/s, GA (°/s)/g, ω °/s

Every target has its own formula, units and frame; each exporter below is a small pure function
from :class:`LinearModel` to text, which states in its own comments the convention, the units
and — by name and size — what of our model the target cannot represent. The round-trip tests
apply the exported numbers with the target's formula and compare with ``apply()``.

- ``ardupilot``: ``INS_ACCOFFS_*`` (m/s²), ``INS_ACCSCAL_*``, ``INS_GYROFFS_*`` (rad/s);
  ArduPilot corrects ``a = (A − INS_ACCOFFS) ⊙ INS_ACCSCAL`` and ``ω = G − INS_GYROFFS`` in its
  sensor frame. No misalignment, no gyro scale, no g-sensitivity.
- ``px4``: ``CAL_ACC0_xOFF`` (m/s²), ``CAL_ACC0_xSCALE``, ``CAL_GYRO0_xOFF`` (rad/s) and
  ``CAL_GYRO0_xSCALE`` (read by PX4 versions whose gyro calibration has a scale); PX4 corrects
  ``R · ((data − thermal offset − offset) ⊙ scale)``, R its board rotation. No misalignment,
  no g-sensitivity.
- ``imucal``: imucal's Ferraris calibration JSON: ``a = R_a⁻¹ K_a⁻¹ (u − b_a)``,
  ``ω = R_g⁻¹ K_g⁻¹ (u_g − K_ga · a − b_g)`` with K diagonal, R with unit rows, K_ga in
  (°/s)/(m/s²): the whole linear model.
- ``c-header``: ``static const float`` matrices and biases for firmware that corrects samples
  itself, with the formula in a comment: the whole linear model.

The thermal calibration (:mod:`host.calib.thermal`, bias(T) − bias(T_ref) per channel) goes to
PX4's thermal compensation ``TC_A0_*``/``TC_G0_*`` (cubic, X0 = 0, clamped to the calibrated
range) and to ArduPilot's ``INS_TCAL1_*`` (:func:`ardupilot_thermal_params`: a cubic without
constant about ArduPilot's fixed 35 °C, its coefficients × 10⁶, clamped to TMIN/TMAX, and
``INS_ACC1_CALTEMP``/``INS_GYR1_CALTEMP``, the temperature the offsets hold at). Kalibr's IMU
YAML comes from a noise file (``noise --save``), not from the result
(:mod:`host.calib.kalibr`). A result whose exported constants are not all determined (NaN) is
refused with one line naming them: no format here can carry NaN.

An export cannot mislead: every format says, in a comment (or imucal's ``comment`` field),
when the records came from a simulated board (:attr:`LinearModel.marks`), and a result that
failed — any verdict that is not a pass: a value outside tolerance, undecided under the
decision rule or not determined, held-out records not predicted, a failed self-test — is
refused (:class:`host.errors.FailedResultError`, naming what failed) unless ``allow_fail``,
and then marked FAILED in the file.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from host.calib.result import CalibrationResult, carried_thermal
from host.calib.thermal import ThermalCalibration, change_from_reference, recentre_poly
from host.calib.verdict import reasons
from host.errors import FailedResultError, InputError
from host.session.inputs import written_serial
from host.session.method import (
    ACCEL_BIAS_NAMES,
    ACCEL_MIS_NAMES,
    ACCEL_SCALE_NAMES,
    GYRO_BIAS_NAMES,
    GYRO_GSENS_NAMES,
)

DEG = math.pi / 180.0


@dataclass(frozen=True)
class LinearModel:
    """The result's linear model (method.md §2) in one frame: ``ka`` = I + Ma, ``a0`` m/s²,
    ``kg`` = I + Mg, ``ga`` (°/s)/g, ``g0`` °/s, ``g`` local gravity m/s²; ``serial``;
    ``gyro_scale_measured`` False when no turn records gave Mg (then ``kg`` is I, as in
    ``apply()``); ``frame`` the axes (``x,y,z`` = our chip axes); ``further`` one sized line per
    parameter of the result's terms beyond the linear model, which no format here can hold."""

    serial: str
    ka: np.ndarray
    a0: np.ndarray
    kg: np.ndarray
    ga: np.ndarray
    g0: np.ndarray
    g: float
    gyro_scale_measured: bool
    frame: str = "x,y,z"
    axes: np.ndarray = field(default_factory=lambda: np.eye(3))
    further: tuple[str, ...] = ()
    #: what every file says first: SIMULATED BOARD …, FAILED calibration …
    marks: tuple[str, ...] = ()


def linear_model(result: CalibrationResult, with_thermal: bool = True) -> LinearModel:
    """The matrices of a result, as ``apply()`` uses them (unmeasured gyro terms nominal).
    ``with_thermal`` False: the carried bias(T) is exported on its own (not named as lost)."""
    mg = result.gyro_m()
    measured = bool(np.all(np.isfinite(mg)))
    return LinearModel(
        serial=result.serial,
        ka=np.eye(3) + result.accel_m(),
        a0=result.accel_bias(),
        kg=np.eye(3) + np.where(np.isfinite(mg), mg, 0.0),  # NaN or ±inf: not determined
        ga=result.gyro_gsens(),
        g0=result.gyro_bias(),
        g=float(result.g),
        gyro_scale_measured=measured,
        further=further_lines(result, with_thermal),
        marks=marks_of(result),
    )


def failures(result: CalibrationResult) -> list[str]:
    """What failed in ``result``, in words ('outside tolerance: Gxx, A0z'); [] when it
    passed: the verdict's own reasons (:func:`host.calib.verdict.reasons`), so an export
    is refused exactly when the verdict is not a pass."""
    return reasons(result)


def marks_of(result: CalibrationResult) -> tuple[str, ...]:
    """The lines every export of ``result`` starts with: that it is simulated, that it
    failed, that its PASS is conditional (the model does not fit its records)."""
    out = [result.simulated_line] if result.simulated else []
    if result.conditional:  # the report says what it means
        out.append(result.verdict())
    if bad := failures(result):
        out.append(f"FAILED calibration, exported with --allow-fail: {'; '.join(bad)}")
    return tuple(out)


def refuse_failed(result: CalibrationResult) -> None:
    """:class:`~host.errors.FailedResultError` naming what failed, if anything did."""
    if bad := failures(result):
        raise FailedResultError(
            f"result of {result.serial} FAILED ({'; '.join(bad)}): nothing exported; "
            "--allow-fail exports it anyway, marked FAILED"
        )


#: the §7 constants every format writes (the gyro's Mg, when not measured, goes out as nominal)
EXPORTED_NAMES = (
    ACCEL_SCALE_NAMES + ACCEL_MIS_NAMES + ACCEL_BIAS_NAMES + GYRO_BIAS_NAMES + GYRO_GSENS_NAMES
)


def refuse_undetermined(result: CalibrationResult) -> None:
    """UserError naming every exported constant that is not a finite number (NaN: not
    determined, or not in the result's model), and a non-finite g: no format may carry NaN."""
    consts = result.constants()
    bad = [n for n in EXPORTED_NAMES if not math.isfinite(consts[n])]
    if not math.isfinite(float(result.g)):
        bad.append("g")
    if bad:
        raise InputError(
            f"result of {result.serial}: {', '.join(bad)} not determined (NaN or infinite); "
            "nothing exported — measure the records the report asks for and calibrate again"
        )


def further_lines(result: CalibrationResult, with_thermal: bool = True) -> tuple[str, ...]:
    """One line per determined parameter of a term beyond method.md §2's linear model (e.g.
    ``temperature_bias gyro y = -0.0262 ± 0.0055 °/s/°C``): the exports carry only the linear
    model, so each of these is named as lost rather than dropped in silence."""
    return tuple(
        f"{p.term} {p.sensor} {p.axis} ({p.key}) = {p.value:.4g} ± {p.stderr:.2g} {p.unit}"
        for p in result.further
        if p.determined and (with_thermal or p.term != "thermal_bias")
    )


def in_frame(model: LinearModel, axes: np.ndarray, text: str) -> LinearModel:
    """The same model in the target's axes: ``axes`` the signed permutation P with
    target = P · ours (as ``--axes`` of import). Ka' = P Ka Pᵀ, A0' = P A0, likewise the gyro."""
    p = np.asarray(axes, dtype=np.float64)
    return LinearModel(
        serial=model.serial,
        ka=p @ model.ka @ p.T,
        a0=p @ model.a0,
        kg=p @ model.kg @ p.T,
        ga=p @ model.ga @ p.T,
        g0=p @ model.g0,
        g=model.g,
        gyro_scale_measured=model.gyro_scale_measured,
        frame=text,
        axes=p,
        further=model.further,
        marks=model.marks,
    )


# ---- what a diagonal target loses -----------------------------------------------------------
def _off_diagonal(m: np.ndarray) -> np.ndarray:
    return np.asarray(m - np.diag(np.diag(m)))


def _lost_lines(model: LinearModel, *, gyro_scale: bool, gyro_bias: bool = True) -> list[str]:
    """Named, sized statements of what a target with per-axis offset and scale cannot hold."""
    out = []
    mis_a = _off_diagonal(model.ka)
    out.append(
        f"accelerometer misalignment (off-diagonal of I+Ma, largest {np.abs(mis_a).max():.2e} "
        f"rad: up to {np.abs(mis_a).max() * model.g:.3f} m/s² at 1 g)"
    )
    mis_g = _off_diagonal(model.kg)
    if not gyro_scale:
        scale = np.abs(np.diag(model.kg) - 1).max()
        out.append(f"gyro scale error (largest {scale:.2e}, {100 * scale:.2f} % of the rate)")
    out.append(f"gyro misalignment (off-diagonal of I+Mg, largest {np.abs(mis_g).max():.2e} rad)")
    out.append(
        f"gyro g-sensitivity GA (largest {np.abs(model.ga).max():.3g} (°/s)/g: up to "
        f"{np.abs(model.ga).max():.3g} °/s of bias that changes with attitude)"
    )
    if not model.gyro_scale_measured:
        out.append("(gyro scale and misalignment were not measured: exported as nominal)")
    return out + [f"further term {x}" for x in model.further]


def _header(comment: str, title: str, model: LinearModel, convention: list[str]) -> list[str]:
    lines = [f"{comment} {title} for serial {written_serial(model.serial)} (imu-bench calibration)"]
    lines += [f"{comment} *** {m} ***" for m in model.marks]
    lines += [f"{comment} {c}" for c in convention]
    lines.append(f"{comment} frame: our chip axes mapped as {model.frame} (target = P · ours)")
    return lines


def _preamble(title: str, model: LinearModel, convention: list[str], gyro_scale: bool) -> list[str]:
    """'#' comment lines: title, convention, frame, and what the per-axis format loses."""
    lost = _lost_lines(model, gyro_scale=gyro_scale)
    lines = _header("#", title, model, convention)
    return lines + ["# NOT REPRESENTED by this format:"] + [f"#   - {x}" for x in lost]


# ---- ArduPilot ------------------------------------------------------------------------------
def ardupilot_params(model: LinearModel) -> dict[str, float]:
    """INS_ACCOFFS_* = A0 (m/s²), INS_ACCSCAL_* = 1/(1+Ma_ii), INS_GYROFFS_* = G0 (rad/s)."""
    out: dict[str, float] = {}
    for i, ax in enumerate("XYZ"):
        out[f"INS_ACCOFFS_{ax}"] = float(model.a0[i])
    for i, ax in enumerate("XYZ"):
        out[f"INS_ACCSCAL_{ax}"] = float(1.0 / model.ka[i, i])
    for i, ax in enumerate("XYZ"):
        out[f"INS_GYROFFS_{ax}"] = float(model.g0[i] * DEG)
    return out


#: ArduPilot's INS_TCAL polynomials are about this fixed temperature, °C, and stored × 10⁶
ARDUPILOT_TREF_C = 35.0
ARDUPILOT_TCAL_SCALE = 1.0e6


def ardupilot_thermal_params(
    model: LinearModel, thermal: ThermalCalibration
) -> tuple[dict[str, float], dict[str, np.ndarray]]:
    """ArduPilot's temperature calibration of our bias(T) − bias(T_ref) = q(T), and the shift
    of the offsets it needs: (parameters, {"ACC": m/s², "GYR": rad/s} per target axis).

    ArduPilot subtracts P(T − 35) − P(CALTEMP − 35) from the sample before its offsets, P a
    cubic without constant with coefficients INS_TCAL1_ACCk/GYRk × 10⁻⁶, T and CALTEMP
    clamped to [TMIN, TMAX]. With P the expansion of q about 35 °C (constant dropped) this is
    q(T) − q(CALTEMP); CALTEMP is T_ref clamped to the range, and the offsets are those at
    CALTEMP (A0 + q(CALTEMP): T_ref itself when it lies in the range)."""
    lo, hi = float(thermal.t_min_c), float(thermal.t_max_c)
    t_cal = min(max(float(thermal.t_ref_c), lo), hi)
    out: dict[str, float] = {"INS_TCAL1_ENABLE": 1.0, "INS_TCAL1_TMIN": lo, "INS_TCAL1_TMAX": hi}
    shift: dict[str, np.ndarray] = {}
    for sensor, names, unit in (("ACC", ("ax", "ay", "az"), 1.0), ("GYR", ("gx", "gy", "gz"), DEG)):
        coef = np.zeros((3, 3))  # [power - 1, our axis]
        at_cal = np.zeros(3)
        for i, name in enumerate(names):
            ch = thermal.channels[name]
            c = np.asarray(ch.coef[:3], dtype=np.float64)
            if c.size:
                zero = [[0.0] * c.size for _ in range(c.size)]  # covariance: not exported
                b, _ = recentre_poly(tuple(c), zero, thermal.t_ref_c, ARDUPILOT_TREF_C)
                coef[: b.size, i] = b * unit
                at_cal[i] = float(change_from_reference(tuple(c), np.array([t_cal]),
                                                        thermal.t_ref_c)[0]) * unit  # fmt: skip
        coef = coef @ np.asarray(model.axes).T  # to the target's axes
        for k in range(3):
            for i, ax in enumerate("XYZ"):
                out[f"INS_TCAL1_{sensor}{k + 1}_{ax}"] = float(coef[k, i] * ARDUPILOT_TCAL_SCALE)
        shift[sensor] = np.asarray(model.axes) @ at_cal
    out["INS_ACC1_CALTEMP"] = t_cal
    out["INS_GYR1_CALTEMP"] = t_cal
    return out, shift


def export_ardupilot(model: LinearModel, thermal: ThermalCalibration | None = None) -> str:
    """An ArduPilot parameter file (``NAME VALUE``, ``#`` comments; MAVProxy ``param load``,
    Mission Planner "Load from file"); with ``thermal`` its temperature calibration too."""
    conv = [
        "ArduPilot corrects in its sensor frame: a = (A - INS_ACCOFFS) * INS_ACCSCAL (per axis,",
        "m/s²); w = G - INS_GYROFFS (rad/s). INS_GYROFFS is re-measured at every boot unless",
        "INS_GYR_CAL = 0.",
    ]
    params = ardupilot_params(model)
    if thermal is None:
        conv.append("Temperature calibration (INS_TCAL1_*): the result carries no bias(T).")
    else:
        conv += [
            "Temperature calibration: before the offsets it subtracts P(T - 35) - P(CALTEMP - 35),",
            "P(d) = (ACC1 d + ACC2 d^2 + ACC3 d^3) * 1e-6 (GYRk likewise, rad/s), T and",
            "CALTEMP clamped to [INS_TCAL1_TMIN, INS_TCAL1_TMAX]; the offsets hold at CALTEMP.",
        ]
        tparams, shift = ardupilot_thermal_params(model, thermal)
        for i, ax in enumerate("XYZ"):
            params[f"INS_ACCOFFS_{ax}"] += float(shift["ACC"][i])
            params[f"INS_GYROFFS_{ax}"] += float(shift["GYR"][i])
        params.update(tparams)
    lines = _preamble("ArduPilot parameters", model, conv, gyro_scale=False)
    if thermal is not None:
        lines += [f"#   - {x}" for x in _thermal_lost(thermal, 3)]
        lines += [
            f"#   - {name} scale(T) (order {ch.scale_order}): ArduPilot has bias(T) only"
            for name, ch in thermal.channels.items()
            if ch.scale_order
        ]
    if bad := [k for k, v in params.items() if not math.isfinite(v)]:
        raise InputError(f"ardupilot: {', '.join(bad)} not finite; nothing exported")
    lines += [f"{k} {v:.9g}" for k, v in params.items()]
    return "\n".join(lines) + "\n"


# ---- PX4 ------------------------------------------------------------------------------------
def px4_params(model: LinearModel) -> dict[str, float]:
    """CAL_ACC0_xOFF = A0 (m/s²), CAL_ACC0_xSCALE = 1/(1+Ma_ii), CAL_GYRO0_xOFF = G0 (rad/s),
    CAL_GYRO0_xSCALE = 1/(1+Mg_ii)."""
    out: dict[str, float] = {}
    for i, ax in enumerate("XYZ"):
        out[f"CAL_ACC0_{ax}OFF"] = float(model.a0[i])
        out[f"CAL_ACC0_{ax}SCALE"] = float(1.0 / model.ka[i, i])
    for i, ax in enumerate("XYZ"):
        out[f"CAL_GYRO0_{ax}OFF"] = float(model.g0[i] * DEG)
        out[f"CAL_GYRO0_{ax}SCALE"] = float(1.0 / model.kg[i, i])
    return out


def px4_thermal_params(thermal: ThermalCalibration, axes: np.ndarray) -> dict[str, float]:
    """PX4 thermal compensation from our bias(T) − bias(T_ref) = Σ c_j (T − T_ref)^j:
    TC_A0_Xk_i / TC_G0_Xk_i = c_k of axis i (m/s², rad/s per °C^k; X0 = 0: the bias at T_ref
    is in CAL_*OFF), TREF = T_ref, TMIN/TMAX the calibrated range (PX4 clamps to it)."""
    out: dict[str, float] = {"TC_A_ENABLE": 1.0, "TC_G_ENABLE": 1.0}
    for sensor, names, unit in (("A", ("ax", "ay", "az"), 1.0), ("G", ("gx", "gy", "gz"), DEG)):
        coef = np.zeros((4, 3))  # [power, our axis]
        for i, name in enumerate(names):
            c = thermal.channels[name].coef[:3]
            coef[1 : 1 + len(c), i] = np.asarray(c) * unit
        coef = coef @ np.asarray(axes).T  # to the target's axes
        for k in range(4):
            for i in range(3):
                out[f"TC_{sensor}0_X{k}_{i}"] = float(coef[k, i])
        out[f"TC_{sensor}0_TREF"] = thermal.t_ref_c
        out[f"TC_{sensor}0_TMIN"] = thermal.t_min_c
        out[f"TC_{sensor}0_TMAX"] = thermal.t_max_c
    return out


def _thermal_lost(thermal: ThermalCalibration, max_order: int) -> list[str]:
    return [
        f"{name} bias(T) terms above order {max_order} (order {ch.order}: "
        f"c{ch.order} = {ch.coef[-1]:.3g} {ch.unit}/degC^{ch.order})"
        for name, ch in thermal.channels.items()
        if ch.order > max_order
    ]


def export_px4(model: LinearModel, thermal: ThermalCalibration | None = None) -> str:
    """A QGroundControl parameter file (``vehicle component NAME VALUE type``, tab separated;
    type 9 = float)."""
    conv = [
        "PX4 corrects in the sensor frame, then rotates to the body: R * ((data - thermal",
        "offset - CAL_*OFF) .* CAL_*SCALE); accel m/s², gyro rad/s. Set CAL_ACC0_ID and",
        "CAL_GYRO0_ID to your sensors' device ids (PX4 ignores a calibration for another id).",
        "CAL_GYRO0_xSCALE is read only by PX4 versions whose gyro calibration has a scale.",
    ]
    if thermal is None:
        conv.append("Thermal compensation (TC_A0_*, TC_G0_*): give --thermal SERIAL_thermal.json.")
    else:
        conv += [
            "Thermal compensation: thermal offset = X0 + X1 dT + X2 dT^2 + X3 dT^3, dT = T - TREF",
            "with T clamped to [TMIN, TMAX] (the calibrated range); set TC_A0_ID/TC_G0_ID too.",
        ]
    lines = _preamble("PX4 parameters", model, conv, gyro_scale=True)
    if thermal is not None:
        lines += [f"#   - {x}" for x in _thermal_lost(thermal, 3)]
    params = px4_params(model)
    if thermal is not None:
        params.update(px4_thermal_params(thermal, model.axes))
    if bad := [k for k, v in params.items() if not math.isfinite(v)]:
        raise InputError(f"px4: {', '.join(bad)} not finite; nothing exported (check the inputs)")
    lines.append("# Vehicle-Id\tComponent-Id\tName\tValue\tType")
    lines += [f"1\t1\t{k}\t{v:.9g}\t{6 if k.endswith('ENABLE') else 9}" for k, v in params.items()]
    return "\n".join(lines) + "\n"


# ---- imucal ---------------------------------------------------------------------------------
def _k_r(m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """m = K · R with K diagonal (row norms) and R with unit rows."""
    norms = np.linalg.norm(m, axis=1)
    return np.diag(norms), m / norms[:, None]


def imucal_info(model: LinearModel) -> dict[str, object]:
    """imucal's FerrarisCalibrationInfo fields: K_a R_a = I+Ma, b_a = A0 (m/s²),
    K_g R_g = I+Mg, K_ga = GA / g ((°/s)/(m/s²)), b_g = G0 (°/s)."""
    k_a, r_a = _k_r(model.ka)
    k_g, r_g = _k_r(model.kg)
    return {  # the comment first: a simulated or failed result says so at the top
        "comment": "".join(f"*** {m} *** " for m in model.marks)
        + f"imu-bench calibration of serial {written_serial(model.serial)}, frame {model.frame}; "
        "a = R_a^-1 K_a^-1 (u - b_a), w = R_g^-1 K_g^-1 (u_g - K_ga a - b_g)"
        + "".join(f"; NOT REPRESENTED: further term {x}" for x in model.further),
        "acc_unit": "m/s^2",
        "gyr_unit": "deg/s",
        "from_acc_unit": "m/s^2",
        "from_gyr_unit": "deg/s",
        "K_a": k_a.tolist(),
        "R_a": r_a.tolist(),
        "b_a": model.a0.tolist(),
        "K_g": k_g.tolist(),
        "R_g": r_g.tolist(),
        "K_ga": (model.ga / model.g).tolist(),
        "b_g": model.g0.tolist(),
        "cal_type": "Ferraris",
        "_format_version": "2.0.0",
    }


def export_imucal(model: LinearModel) -> str:
    """imucal's calibration JSON (``FerrarisCalibrationInfo.from_json`` reads it). JSON has no
    comments: the convention is in ``comment``; nothing of the linear model is lost."""
    return json.dumps(imucal_info(model), indent=4) + "\n"


# ---- C header -------------------------------------------------------------------------------
def c_arrays(model: LinearModel) -> dict[str, np.ndarray]:
    """The header's arrays: ACCEL_M_INV = (I+Ma)⁻¹, ACCEL_BIAS (m/s²), GYRO_M_INV = (I+Mg)⁻¹,
    GYRO_BIAS (°/s), GYRO_G_SENS = GA / g ((°/s)/(m/s²))."""
    return {
        "ACCEL_M_INV": np.linalg.inv(model.ka),
        "ACCEL_BIAS": model.a0,
        "GYRO_M_INV": np.linalg.inv(model.kg),
        "GYRO_BIAS": model.g0,
        "GYRO_G_SENS": model.ga / model.g,
    }


def _c_values(a: np.ndarray) -> str:
    if a.ndim == 1:
        return "{" + ", ".join(f"{v:.9g}f" for v in a) + "}"
    return "{\n" + ",\n".join("    " + _c_values(row) for row in a) + "\n}"


#: the characters a C macro name may hold
_C_NAME = frozenset("ABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789_")


def export_c_header(model: LinearModel) -> str:
    """A C header with ``static const float`` arrays and the correction in a comment."""
    serial = written_serial(model.serial)
    guard = "IMU_CALIBRATION_" + "".join(c if c in _C_NAME else "_" for c in serial.upper())
    lines = [
        f"/* IMU calibration of serial {serial}, generated by imu-bench (python3 -m host",
        " * export).",
        *(f" * *** {m} ***" for m in model.marks),
        " * The whole linear model of method.md §2; apply per sample, in this order:",
        " *",
        " *   a[i] = sum_k ACCEL_M_INV[i][k] * (A[k] - ACCEL_BIAS[k])         A, a in m/s^2",
        " *   c[i] = G[i] - GYRO_BIAS[i] - sum_k GYRO_G_SENS[i][k] * a[k]     G in deg/s",
        " *   w[i] = sum_k GYRO_M_INV[i][k] * c[k]                             w in deg/s",
        " *",
        " * The accelerometer is corrected first: the gyro's g-sensitivity uses the corrected a.",
        f" * Frame: our chip axes mapped as {model.frame}.",
    ]
    if not model.gyro_scale_measured:
        lines.append(" * Gyro scale and misalignment were not measured: GYRO_M_INV is identity.")
    lines += [f" * NOT REPRESENTED: further term {x}" for x in model.further]
    lines += [" */", f"#ifndef {guard}_H", f"#define {guard}_H", ""]
    for name, arr in c_arrays(model).items():
        dims = "".join(f"[{d}]" for d in arr.shape)
        lines.append(f"static const float {name}{dims} = {_c_values(np.asarray(arr))};")
    lines += ["", f"#endif /* {guard}_H */"]
    return "\n".join(lines) + "\n"


# ---- registry -------------------------------------------------------------------------------
FORMATS: dict[str, tuple[Callable[[LinearModel], str], str]] = {
    "ardupilot": (export_ardupilot, ".parm"),
    "px4": (export_px4, ".params"),
    "imucal": (export_imucal, ".json"),
    "c-header": (export_c_header, ".h"),
}
#: formats made from another input than the result (``export`` says which option gives it)
PENDING = {
    "kalibr": "Kalibr's IMU YAML is made from noise figures, not from a calibration: give the "
    "noise file of a long static recording (python3 -m host noise FILE --save NOISE.json) with "
    "--noise NOISE.json",
}


def export(
    result: CalibrationResult,
    fmt: str,
    axes: np.ndarray | None = None,
    axes_text: str = "x,y,z",
    thermal: ThermalCalibration | None = None,
    *,
    allow_fail: bool = False,
) -> str:
    """The text of ``result`` in format ``fmt`` (see :data:`FORMATS`), optionally in the
    target's axes (signed permutation ``axes``: target = P · ours) and with the thermal
    calibration ``thermal`` (bias(T); PX4 only). A failed result raises
    :class:`~host.errors.FailedResultError` unless ``allow_fail`` (then the file says FAILED)."""
    key = fmt.strip().lower()
    if key == "c":
        key = "c-header"
    if key in PENDING:
        raise InputError(f"--to {fmt}: {PENDING[key]}")
    if key not in FORMATS:
        raise InputError(f"--to {fmt}: unknown format; choose one of {', '.join(FORMATS)}")
    if not allow_fail:
        refuse_failed(result)
    refuse_undetermined(result)
    if thermal is None and key in ("px4", "ardupilot"):  # the result's own bias(T), if any
        thermal = carried_thermal(result)
    model = linear_model(result, with_thermal=thermal is None)
    if axes is not None:
        model = in_frame(model, axes, axes_text)
    if thermal is not None:
        if key == "ardupilot":
            return export_ardupilot(model, thermal)
        if key != "px4":
            raise InputError(
                f"--thermal: {key} has no place for bias(T) in this export; px4 writes it "
                "(TC_A0_*, TC_G0_*), ardupilot too (INS_TCAL1_*)"
            )
        return export_px4(model, thermal)
    return FORMATS[key][0](model)
