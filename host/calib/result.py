"""The calibration result a user ships: a frozen record of values.

A result is the model the user chose (a spec of named terms, :mod:`host.model.spec`) with every
parameter of every term (:mod:`host.calib.values`): value, 1-σ standard error, unit, and — for
the §2 constants that the report of method.md §7 tolerances — the tolerance and the pass flag
(as the result's decision rule gives it, :mod:`host.calib.decision`);
the noise model of the fit and the fit quality, where the records came from
(:class:`host.calib.provenance.Provenance`) and where the floor of a record mean came from. A
thermal calibration travels in a result as the term ``thermal_bias`` (:func:`thermal_parameters`,
:func:`carried_thermal`).

The rest is elsewhere: the verdict policy in :mod:`host.calib.verdict`, its words in
:mod:`host.calib.result_text`, the files (JSON v1–v3 both ways, the old names of v1 among them)
in :mod:`host.calib.codec`.

A parameter whose value is NaN was **not determined** by the records; ``needs`` says what
would determine it. Applying a result to raw samples and verifying it on held-out records:
:mod:`host.calib.applying`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from host.calib.decision import DEFAULT_RULE, check_rule
from host.calib.provenance import Provenance
from host.calib.result_text import summary, verdict_line
from host.calib.thermal import CHANNELS as THERMAL_CHANNELS
from host.calib.thermal import ThermalCalibration, recentre_poly, recentred
from host.calib.values import (
    FitQuality,
    ParameterResult,
    RecordResidual,
    Verification,
    as_float,
    constants_of,
    tolerance_of,
    undetermined_of,
    within,
)
from host.calib.verdict import all_passed, conditional, judged_parameters
from host.errors import UserError
from host.model.catalogue import CARRIED
from host.model.signals import AXES, TEMP_REF_C
from host.model.spec import parse_model
from host.model.terms import Term
from host.session.directory import SIMULATED_BOARD
from host.session.method import (
    ACCEL_BIAS_NAMES,
    GYRO_BIAS_NAMES,
    names_to_gsens,
    names_to_matrix,
)


# ---- the result ---------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class CalibrationResult:
    """One unit's calibration: the model ``model`` (spec,
    :func:`host.model.spec.parse_model`) and every parameter of it
    (:class:`ParameterResult`), the §3 noise levels ``noise_std``
    (Astdx … Gstdz: m/s², °/s), local ``g`` m/s² at ``latitude_deg``/``height_m``, ``turns``
    (n of the turn records, None: none or mixed), the noise model and the fit quality.

    ``temp_mean_c``: the session's mean chip temperature, °C (the reference of
    ``temperature_bias_quadratic``). ``time_known``: the records carried the time since
    power-on (else time terms were fitted on time within each record). ``term_files``: the
    Python files of custom terms, ``term_sha256`` each one's SHA-256 (path -> hex): a result
    is data, :func:`host.calib.applying.apply` never runs a file it names, only the files its
    caller passes, and only when one of these digests matches.

    The §7 constants by report name: :meth:`constants` (``result.constants()["Axx"]``, NaN
    when not determined or not in the model). Files: :mod:`host.calib.codec`.
    """

    serial: str
    created: str
    g: float
    latitude_deg: float
    height_m: float
    turns: int | None
    model: str
    parameters: tuple[ParameterResult, ...]
    noise_std: Mapping[str, float]
    fit: FitQuality | None = None
    noise_model: Mapping[str, Any] = field(default_factory=dict)
    term_files: tuple[str, ...] = ()
    term_sha256: Mapping[str, str] = field(default_factory=dict)
    temp_mean_c: float = TEMP_REF_C
    time_known: bool = True
    earth_rate: bool = False
    method: str = "weighted least squares over all records (method.md §2)"
    records: tuple[str, ...] = ()
    #: the three closed-form bias estimates (§3, from the x, y, z pairs) per A0./G0. name
    bias_estimates: Mapping[str, tuple[float, float, float]] = field(default_factory=dict)
    #: closed-form values (§3, §4) where the plan has them: the check printed beside the fit
    closed_form: Mapping[str, float] = field(default_factory=dict)
    #: combinations of undetermined parameters the records do determine ('A0x − 9.8·Axy = …')
    combinations: tuple[str, ...] = ()
    residuals: tuple[RecordResidual, ...] = ()
    notes: tuple[str, ...] = ()
    #: held-out verification on records not used in the fit (``calibrate --verify DIR2``)
    verification: Verification | None = None
    #: the chip temperatures (°C, low, high) over which the carried bias(T) (term
    #: ``thermal_bias``, from ``python3 -m host thermal``) holds; None: no thermal calibration
    thermal_range_c: tuple[float, float] | None = None
    #: where the bias(T) came from (the SERIAL_thermal.json file)
    thermal_source: str = ""
    #: where the records came from (format v3; None: an older file, or made without records)
    provenance: Provenance | None = None
    #: the parameters' full covariance, in the order of ``parameters`` (diagonal: stderr²;
    #: NaN rows for undetermined ones); () when the file carried none (v1, v2)
    covariance: tuple[tuple[float, ...], ...] = ()
    #: the MPU-6000's self-test of the sitting, from the records' ``self_test`` header:
    #: 'pass', 'fail' (the calibration fails), 'not run' (``--no-self-test``: the verdict
    #: says so) or '' (no verdict, or an older file)
    self_test: str = ""
    #: where the fit's floor of a record mean came from, as the options that give the same
    #: yardstick again: ``noise`` the ``--noise`` file, ``floor`` the ``--floor`` text, each as
    #: the user gave it; {} when it was measured from the records (or an older file)
    floor_source: Mapping[str, str] = field(default_factory=dict)
    #: how each value's mark was decided (:mod:`host.calib.decision`): 'guarded' (value ± U
    #: within the tolerance) or 'simple' (the value within it, U not used)
    decision_rule: str = DEFAULT_RULE
    #: format version of the file this was loaded from
    loaded_version: int = 3

    def __post_init__(self) -> None:
        """The rule checked, and each §7 parameter's ``passed`` flag set by it."""
        check_rule(self.decision_rule)
        object.__setattr__(self, "parameters", judged_parameters(self))

    def __repr__(self) -> str:
        """One line: serial, model, size, verdict, and SIMULATED for simulated records."""
        return summary(self)

    # ---- views ---------------------------------------------------------------------------
    @property
    def simulated(self) -> bool:
        """The records came from a virtual or emulated board or the simulator, not a unit."""
        return bool(self.simulated_line)

    @property
    def simulated_line(self) -> str:
        """``SIMULATED BOARD <by>: not a measurement of a unit``, or '' for a unit (older
        files: their note that says so)."""
        if self.provenance is not None:
            return self.provenance.simulated_line
        return next((n for n in self.notes if n.startswith(SIMULATED_BOARD)), "")

    def parameter(self, name: str) -> ParameterResult:
        """The parameter called ``name`` (KeyError if the model has none)."""
        for p in self.parameters:
            if p.name == name:
                return p
        raise KeyError(name)

    def constants(self) -> dict[str, float]:
        """§7 name -> value in report order (NaN: not determined, or not in the model)."""
        return constants_of(self.parameters, self.noise_std)

    @property
    def further(self) -> tuple[ParameterResult, ...]:
        """Parameters of the terms beyond the §2 linear model."""
        return tuple(p for p in self.parameters if not p.base)

    @property
    def std_errors(self) -> dict[str, float]:
        """name -> 1-σ standard error of every fitted parameter."""
        return {p.name: p.stderr for p in self.parameters}

    @property
    def undetermined(self) -> tuple[ParameterResult, ...]:
        """The parameters the records did not determine."""
        return undetermined_of(self.parameters)

    @property
    def all_passed(self) -> bool:
        """The result passes (:func:`host.calib.verdict.all_passed`)."""
        return all_passed(self)

    @property
    def conditional(self) -> bool:
        """A PASS that rests on a model that does not fit these records
        (:func:`host.calib.verdict.conditional`); :attr:`all_passed` stays True."""
        return conditional(self)

    def verdict(self) -> str:
        """PASS or FAIL and why, in one line (:func:`host.calib.result_text.verdict_line`)."""
        return verdict_line(self)

    def accel_m(self) -> np.ndarray:
        """Ma (3×3, method.md §2), NaN where not determined."""
        return names_to_matrix("A", self.constants())

    def accel_bias(self) -> np.ndarray:
        """A0 (3,), m/s²."""
        c = self.constants()
        return np.array([c[n] for n in ACCEL_BIAS_NAMES], dtype=np.float64)

    def gyro_m(self) -> np.ndarray:
        """Mg (3×3), NaN where not determined."""
        return names_to_matrix("G", self.constants())

    def gyro_gsens(self) -> np.ndarray:
        """GA (3×3), (°/s)/g."""
        return names_to_gsens(self.constants())

    def gyro_bias(self) -> np.ndarray:
        """G0 (3,), °/s."""
        c = self.constants()
        return np.array([c[n] for n in GYRO_BIAS_NAMES], dtype=np.float64)


def base_parameters(
    values: Mapping[str, float], stderrs: Mapping[str, float] | None = None
) -> tuple[ParameterResult, ...]:
    """The parameters of the ``base`` model from §7 names (``values``: name -> value)."""
    out: list[ParameterResult] = []
    se = stderrs or {}
    for mt in parse_model("base"):
        units = mt.term.param_units(mt.sensor)
        for ax in mt.axes:
            for q, name in enumerate(mt.term.param_labels(mt.sensor, ax)):
                v = as_float(values[name])
                out.append(
                    ParameterResult(
                        mt.term.name, mt.sensor, AXES[ax], mt.term.params[q], name, v,
                        as_float(se.get(name)), units[q], tolerance_of(name), within(name, v),
                    )
                )  # fmt: skip
    return tuple(out)


def _poly_parameters(
    term: Term, sensor: str, ax: int, coef: np.ndarray, cov: np.ndarray
) -> list[ParameterResult]:
    """c_1 … c_k of one channel's polynomial in temperature as parameters of ``term``, each
    with its 1-σ error from the diagonal of ``cov``."""
    labels, units = term.param_labels(sensor, ax), term.param_units(sensor)
    return [
        ParameterResult(
            term.name,
            sensor,
            AXES[ax],
            term.params[i],
            labels[i],
            float(coef[i]),
            math.sqrt(max(float(cov[i, i]), 0.0)),
            units[i],
        )  # fmt: skip
        for i in range(len(coef))
    ]


def thermal_parameters(cal: ThermalCalibration, t_ref_c: float) -> tuple[ParameterResult, ...]:
    """The bias(T) of a thermal calibration as parameters of the term ``thermal_bias`` about
    ``t_ref_c`` (°C, the result's ``temp_mean_c``): c_1 … c_k of each channel with order k ≥ 1
    (:func:`host.calib.thermal.recentred`), 1-σ errors from the fit's covariance."""
    t = CARRIED["thermal_bias"]
    ts = CARRIED["thermal_scale"]
    out: list[ParameterResult] = []
    for j, name in enumerate(THERMAL_CHANNELS):
        ch = cal.channels[name]
        sensor, ax = ("accel" if j < 3 else "gyro"), j % 3
        if ch.scale_order:
            if ch.scale_order > len(ts.params):
                raise UserError(f"{name}: scale(T) of order {ch.scale_order} is not carried")
            c, cov = recentre_poly(ch.scale_coef, ch.scale_cov, cal.t_ref_c, t_ref_c)
            out += _poly_parameters(ts, sensor, ax, c[: ch.scale_order], cov)
        if not ch.order:
            continue
        if ch.order > len(t.params):
            raise UserError(
                f"{name}: bias(T) of order {ch.order}; a result carries up to order "
                f"{len(t.params)}: refit with python3 -m host thermal --max-order {len(t.params)}"
            )
        c, cov = recentred(ch, cal.t_ref_c, t_ref_c)
        out += _poly_parameters(t, sensor, ax, c[: ch.order], cov)
    return tuple(out)


def carried_thermal(result: CalibrationResult) -> ThermalCalibration | None:
    """The bias(T) a result carries (term ``thermal_bias`` about ``temp_mean_c``) as a
    :class:`~host.calib.thermal.ThermalCalibration` (diagonal covariance, no selection table),
    for the exports that write thermal compensation; None when it carries none."""
    if result.thermal_range_c is None:
        return None
    from host.calib.thermal import UNITS as THERMAL_UNITS
    from host.calib.thermal import ChannelThermal

    def carried(term: str, sensor: str, axis: str) -> list[ParameterResult]:
        t = CARRIED[term]
        got = {
            p.key: p for p in result.parameters
            if p.term == t.name and p.sensor == sensor and p.axis == axis
        }  # fmt: skip
        return [got[k] for k in t.params[: len(got)] if k in got]

    def diag(ps: list[ParameterResult]) -> tuple[tuple[float, ...], ...]:
        return tuple(tuple(p.stderr**2 if q is p else 0.0 for q in ps) for p in ps)

    chans = {}
    for j, name in enumerate(THERMAL_CHANNELS):
        sensor, axis = ("accel" if j < 3 else "gyro"), AXES[j % 3]
        ps = carried("thermal_bias", sensor, axis)
        ss = carried("thermal_scale", sensor, axis) if sensor == "accel" else []
        chans[name] = ChannelThermal(
            name, THERMAL_UNITS[j], len(ps), tuple(p.value for p in ps), diag(ps),
            math.nan, (), (), len(ss), tuple(p.value for p in ss), diag(ss),
        )  # fmt: skip
    lo, hi = result.thermal_range_c
    return ThermalCalibration(result.serial, result.temp_mean_c, lo, hi, chans)
