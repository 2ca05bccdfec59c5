"""The calibration result a user ships, and :func:`apply`, which corrects raw samples with it.

A result is the model the user chose (a spec of named terms, :mod:`host.modelling.model`) with every
parameter of every term: value, 1-σ standard error, unit, and — for the §2 constants that the
report of method.md §7 tolerances — the tolerance and the pass flag. Format v2
(``SERIAL_result.json``, ``format_version: 2``) also carries the noise model of the fit and the
fit quality (χ², dof, RMS z, p, verdict). Format v1 files (the §7 constants only) still load:
they become the ``base`` model.

A parameter whose value is NaN was **not determined** by the records; ``needs`` says what
would determine it. :func:`apply` refuses such a result unless asked to take them as nominal.

Length (over 600 lines): one versioned object — its v2 file, loading v1 and v2, ``apply`` and
held-out ``verify`` — must agree on every parameter's meaning; they change together.
"""

from __future__ import annotations

import dataclasses
import json
import math
import warnings
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from host.calib.thermal import CHANNELS as THERMAL_CHANNELS
from host.calib.thermal import (
    ThermalCalibration,
    ThermalRangeWarning,
    recentre_poly,
    recentred,
)
from host.errors import UserError
from host.model.catalogue import BASE, CARRIED, CATALOGUE
from host.model.fit import predict_session
from host.model.loader import load_term_file
from host.model.noise import NoiseModel
from host.model.signals import AXES, TEMP_REF_C, RecordSignals
from host.model.spec import parse_model
from host.model.stats import chi2_sf
from host.model.terms import Term
from host.session.directory import Session, read_session
from host.session.method import (
    ACCEL_BIAS_NAMES,
    CONSTANT_NAMES,
    GYRO_BIAS_NAMES,
    NOISE_NAMES,
    TOLERANCES,
    UNITS,
    names_to_gsens,
    names_to_matrix,
)

FORMAT = "imu-bench calibration result"


# ---- small JSON helpers -------------------------------------------------------------------
def _num(v: Any) -> float:
    return float("nan") if v is None else float(v)


def _jsonable(v: Any) -> Any:
    if isinstance(v, float | np.floating):
        f = float(v)
        return None if not math.isfinite(f) else f
    if isinstance(v, tuple | list | np.ndarray):
        return [_jsonable(x) for x in v]
    if isinstance(v, dict):
        return {str(k): _jsonable(x) for k, x in v.items()}
    return v


# ---- the parts of a result ----------------------------------------------------------------
@dataclass(frozen=True)
class ParameterResult:
    """One parameter of one term on one output channel.

    ``term`` catalogue name ('temperature_bias'), ``sensor`` accel/gyro, ``axis`` x/y/z (the
    output channel), ``key`` the term's parameter ('per_C'), ``name`` its report name ('A0x';
    'temperature_bias.gyro.y' for further terms). ``value``/``stderr`` in ``unit``; NaN value:
    not determined by the records, ``needs`` says what would determine it. ``tolerance`` and
    ``passed`` where method.md §7 defines a tolerance (None otherwise).
    """

    term: str
    sensor: str
    axis: str
    key: str
    name: str
    value: float
    stderr: float
    unit: str
    tolerance: float | None = None
    passed: bool | None = None
    needs: str = ""

    @property
    def determined(self) -> bool:
        return math.isfinite(self.value)

    @property
    def base(self) -> bool:
        """A parameter of the linear model of method.md §2 (reported in the §7 layout)."""
        return self.term in BASE

    def to_dict(self) -> dict[str, Any]:
        return {f.name: _jsonable(getattr(self, f.name)) for f in dataclasses.fields(self)}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> ParameterResult:
        tol = d.get("tolerance")
        return cls(
            term=str(d["term"]), sensor=str(d["sensor"]), axis=str(d["axis"]), key=str(d["key"]),
            name=str(d["name"]), value=_num(d["value"]), stderr=_num(d["stderr"]),
            unit=str(d["unit"]), tolerance=None if tol is None else float(tol),
            passed=None if d.get("passed") is None else bool(d["passed"]),
            needs=str(d.get("needs", "")),
        )  # fmt: skip


@dataclass(frozen=True)
class FitQuality:
    """How well the model explains the records: χ² on ``dof`` degrees of freedom, RMS of the
    record/channel z values, p = P(χ² this large | model right), ``verdict`` adequate /
    inadequate (p < 0.01: the model misses something) / untestable (some channel has no
    degrees of freedom: ``untestable`` lists them). ``stderr_note``: how the standard errors
    were treated (the uncertainty policy, :func:`host.modelling.model.stderr_scale`)."""

    chi2: float
    dof: int
    rms_z: float
    p: float
    verdict: str
    untestable: tuple[str, ...] = ()
    stderr_note: str = ""

    def line(self) -> str:
        """The report's one fit-quality line."""
        s = (
            f"Fit quality: χ² = {self.chi2:.1f} on {self.dof} dof, RMS z = {self.rms_z:.2f}, "
            f"p = {self.p:.3g}: {self.verdict}"
        )
        if self.untestable:
            s += f" (no degrees of freedom on {', '.join(self.untestable)})"
        return s

    def to_dict(self) -> dict[str, Any]:
        return {
            "chi2": _jsonable(self.chi2), "dof": self.dof, "rms_z": _jsonable(self.rms_z),
            "p": _jsonable(self.p), "verdict": self.verdict, "untestable": list(self.untestable),
            "stderr_note": self.stderr_note,
        }  # fmt: skip

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> FitQuality:
        return cls(
            float(_num(d["chi2"])), int(d["dof"]), _num(d["rms_z"]), _num(d["p"]),
            str(d["verdict"]), tuple(str(x) for x in d.get("untestable", ())),
            str(d.get("stderr_note", "")),
        )  # fmt: skip


@dataclass(frozen=True, eq=False)
class RecordResidual:
    """Residual of one record after the fit.

    static/rate: ``accel_mean``/``gyro_mean`` = mean residual (m/s², °/s), ``*_std`` = std of the
    samples. turn: ``gyro_mean`` = integral residual / T (°/s equivalent), ``angle_deg`` =
    integral residual (°), stds NaN.
    """

    record: str
    kind: str
    n: int
    duration_s: float
    accel_mean: tuple[float, float, float]
    accel_std: tuple[float, float, float]
    gyro_mean: tuple[float, float, float]
    gyro_std: tuple[float, float, float]
    angle_deg: tuple[float, float, float] | None = None

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict (NaN -> None)."""
        return {f.name: _jsonable(getattr(self, f.name)) for f in dataclasses.fields(self)}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> RecordResidual:
        """Inverse of :meth:`to_dict`."""

        def t3(v: Any) -> tuple[float, float, float]:
            a, b, c = (_num(x) for x in v)
            return (a, b, c)

        return cls(
            record=str(d["record"]), kind=str(d["kind"]), n=int(d["n"]),
            duration_s=float(d["duration_s"]), accel_mean=t3(d["accel_mean"]),
            accel_std=t3(d["accel_std"]), gyro_mean=t3(d["gyro_mean"]),
            gyro_std=t3(d["gyro_std"]),
            angle_deg=None if d.get("angle_deg") is None else t3(d["angle_deg"]),
        )  # fmt: skip


def tolerance_of(name: str) -> float | None:
    """The §7 tolerance of a report name (None: the method defines none)."""
    return TOLERANCES.get(name)


def within(name: str, value: float) -> bool | None:
    """§7 pass flag: True within tolerance, False outside or not determined, None no tolerance."""
    tol = tolerance_of(name)
    if tol is None:
        return None
    if not math.isfinite(value):
        return False
    return value <= tol if name in NOISE_NAMES else abs(value) <= tol


# ---- the result ---------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class CalibrationResult:
    """One unit's calibration: the model ``model`` (spec,
    :func:`host.modelling.model.parse_model`) and every parameter of it
    (:class:`ParameterResult`), the §3 noise levels ``noise_std``
    (Astdx … Gstdz: m/s², °/s), local ``g`` m/s² at ``latitude_deg``/``height_m``, ``turns``
    (n of the turn records, None: none or mixed), the noise model and the fit quality.

    ``temp_mean_c``: the session's mean chip temperature, °C (the reference of
    ``temperature_bias_quadratic``). ``time_known``: the records carried the time since
    power-on (else time terms were fitted on time within each record). ``term_files``: the
    Python files of custom terms (needed again by :func:`apply`).

    The §7 constants are attributes too (``result.Axx``, NaN when not determined or not in the
    model), as in format v1.
    """

    FORMAT_VERSION: ClassVar[int] = 2

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
    #: ``thermal_bias``, from ``python -m host thermal``) holds; None: no thermal calibration
    thermal_range_c: tuple[float, float] | None = None
    #: where the bias(T) came from (the SERIAL_thermal.json file)
    thermal_source: str = ""
    #: format version of the file this was loaded from
    loaded_version: int = 2

    # ---- views ---------------------------------------------------------------------------
    def __getattr__(self, name: str) -> float:
        # the §7 constants by name, as in format v1 (result.Axx)
        if name in CONSTANT_NAMES:
            return self.constants()[name]
        raise AttributeError(name)

    def parameter(self, name: str) -> ParameterResult:
        """The parameter called ``name`` (KeyError if the model has none)."""
        for p in self.parameters:
            if p.name == name:
                return p
        raise KeyError(name)

    def constants(self) -> dict[str, float]:
        """§7 name -> value in report order (NaN: not determined, or not in the model)."""
        by = {p.name: p.value for p in self.parameters}
        by.update(self.noise_std)
        return {n: float(by.get(n, math.nan)) for n in CONSTANT_NAMES}

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
        return tuple(p for p in self.parameters if not p.determined)

    def passed(self) -> dict[str, bool | None]:
        """§7 name -> True within tolerance, False outside or not determined, None no
        tolerance (or not in the model)."""
        in_model = {p.name for p in self.parameters} | set(self.noise_std)
        return {n: within(n, v) if n in in_model else None for n, v in self.constants().items()}

    @property
    def all_passed(self) -> bool:
        """Every toleranced value within tolerance, every parameter determined, and the
        held-out records (if verified) predicted within the §8 accuracy."""
        ok = all(p is not False for p in self.passed().values()) and not self.undetermined
        return ok and (self.verification is None or self.verification.passed)

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

    # ---- JSON ----------------------------------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict (format v2)."""
        return {
            "format": FORMAT,
            "format_version": self.FORMAT_VERSION,
            "serial": self.serial,
            "created": self.created,
            "model": self.model,
            "term_files": list(self.term_files),
            "parameters": [p.to_dict() for p in self.parameters],
            # the §7 view, for readers: value and pass flag by report name (not read back)
            "constants": _jsonable(self.constants()),
            "pass": self.passed(),
            "noise_std": {
                n: {
                    "value": _jsonable(v),
                    "unit": UNITS[n],
                    "tolerance": tolerance_of(n),
                    "passed": within(n, v),
                }
                for n, v in self.noise_std.items()
            },  # fmt: skip
            "all_passed": self.all_passed,
            "fit": None if self.fit is None else self.fit.to_dict(),
            "noise_model": _jsonable(dict(self.noise_model)),
            "g": self.g,
            "g_unit": "m/s²",
            "latitude_deg": self.latitude_deg,
            "height_m": self.height_m,
            "turns": self.turns,
            "temp_mean_c": self.temp_mean_c,
            "time_known": self.time_known,
            "earth_rate": self.earth_rate,
            "method": self.method,
            "records": list(self.records),
            "bias_estimates": _jsonable(dict(self.bias_estimates)),
            "closed_form": _jsonable(dict(self.closed_form)),
            "combinations": list(self.combinations),
            "residuals": [r.to_dict() for r in self.residuals],
            "notes": list(self.notes),
            "verification": None if self.verification is None else self.verification.to_dict(),
            "thermal": None
            if self.thermal_range_c is None
            else {
                "valid_range_c": list(self.thermal_range_c),
                "source": self.thermal_source,
                "model": "thermal_bias: sum_j c_j (T - temp_mean_c)^j, T chip degC",
            },
        }

    def to_json(self) -> str:
        """The JSON text of :meth:`to_dict` (UTF-8, indented)."""
        return json.dumps(self.to_dict(), indent=2, ensure_ascii=False) + "\n"

    @classmethod
    def from_json(cls, text: str | bytes) -> CalibrationResult:
        """Parse a result file, format v2 or v1; UserError on bad JSON, an unknown version or
        a missing field."""
        try:
            d = json.loads(text)
        except (ValueError, UnicodeDecodeError) as exc:
            raise UserError(f"calibration result: not valid JSON ({exc})") from exc
        if not isinstance(d, dict) or "format_version" not in d:
            raise UserError("calibration result: not an imu-bench result (no format_version)")
        version = d["format_version"]
        if version not in (1, 2):
            raise UserError(
                f"calibration result format v{version} but this program reads v1 and "
                f"v{cls.FORMAT_VERSION}; recompute it with 'python -m host calibrate --from-dir'"
            )
        try:
            return _from_v1(d) if version == 1 else _from_v2(d)
        except (KeyError, TypeError, ValueError, IndexError, AttributeError) as exc:
            raise UserError(f"calibration result: missing or bad field ({exc})") from exc

    @classmethod
    def load(cls, path: str | Path) -> CalibrationResult:
        """Read ``SERIAL_result.json`` (v1 or v2)."""
        try:
            text = Path(path).read_text(encoding="utf-8")
        except OSError as exc:
            raise UserError(f"{path}: cannot read the result ({exc.strerror})") from exc
        return cls.from_json(text)


def _common(d: Mapping[str, Any]) -> dict[str, Any]:
    return {
        "serial": str(d["serial"]),
        "created": str(d["created"]),
        "g": float(d["g"]),
        "latitude_deg": float(d["latitude_deg"]),
        "height_m": float(d["height_m"]),
        "turns": None if d.get("turns") is None else int(d["turns"]),
        "earth_rate": bool(d.get("earth_rate", False)),
        "method": str(d.get("method", "")),
        "records": tuple(str(x) for x in d.get("records", ())),
        "bias_estimates": {
            k: (_num(v[0]), _num(v[1]), _num(v[2])) for k, v in d.get("bias_estimates", {}).items()
        },
        "closed_form": {k: _num(v) for k, v in d.get("closed_form", {}).items()},
        "residuals": tuple(RecordResidual.from_dict(r) for r in d.get("residuals", [])),
        "notes": tuple(str(x) for x in d.get("notes", [])),
    }


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
                v = _num(values[name])
                out.append(
                    ParameterResult(
                        mt.term.name, mt.sensor, AXES[ax], mt.term.params[q], name, v,
                        _num(se.get(name)), units[q], tolerance_of(name), within(name, v),
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
                f"{len(t.params)}: refit with python -m host thermal --max-order {len(t.params)}"
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


def _from_v1(d: Mapping[str, Any]) -> CalibrationResult:
    consts = {n: _num(d["constants"][n]) for n in CONSTANT_NAMES}
    params = base_parameters(consts, {k: _num(v) for k, v in d.get("std_errors", {}).items()})
    params = tuple(
        dataclasses.replace(p, needs="a turn about that axis (format v1: not measured)")
        if not p.determined
        else p
        for p in params
    )
    return CalibrationResult(
        model="base",
        parameters=params,
        noise_std={n: consts[n] for n in NOISE_NAMES},
        loaded_version=1,
        **_common(d),
    )


def _from_v2(d: Mapping[str, Any]) -> CalibrationResult:
    fit = d.get("fit")
    th = d.get("thermal")
    return CalibrationResult(
        model=str(d["model"]),
        parameters=tuple(ParameterResult.from_dict(p) for p in d["parameters"]),
        noise_std={str(k): _num(v["value"]) for k, v in d["noise_std"].items()},
        fit=None if fit is None else FitQuality.from_dict(fit),
        noise_model=dict(d.get("noise_model", {})),
        term_files=tuple(str(x) for x in d.get("term_files", ())),
        temp_mean_c=float(d.get("temp_mean_c", TEMP_REF_C)),
        time_known=bool(d.get("time_known", True)),
        combinations=tuple(str(x) for x in d.get("combinations", ())),
        verification=(
            None if d.get("verification") is None else Verification.from_dict(d["verification"])
        ),
        thermal_range_c=None
        if th is None
        else (float(th["valid_range_c"][0]), float(th["valid_range_c"][1])),
        thermal_source="" if th is None else str(th.get("source", "")),
        **_common(d),
    )


# ---- applying a result --------------------------------------------------------------------
class _MissingInput(Exception):
    """A term asked for an input that :func:`apply` was not given."""

    def __init__(self, what: str) -> None:
        super().__init__(what)
        self.what = what


class _Missing:
    """Stands in for an input not given to :func:`apply`: has a length (so terms can size
    their columns) but any arithmetic with it raises :class:`_MissingInput`."""

    def __init__(self, what: str, n: int) -> None:
        self.what = what
        self.n = n

    def __len__(self) -> int:
        return self.n

    def _raise(self, *_a: Any, **_k: Any) -> Any:
        raise _MissingInput(self.what)

    __array__ = __add__ = __radd__ = __sub__ = __rsub__ = __mul__ = __rmul__ = _raise
    __truediv__ = __rtruediv__ = __pow__ = __neg__ = __getitem__ = __iter__ = _raise
    __float__ = __lt__ = __gt__ = __le__ = __ge__ = _raise


_NEEDS_ARG = {
    "temp_c": "the chip temperature: pass temp_c=(N,) °C",
    "t_s": "the time since power-on: pass t_s=(N,) s",
}


def _catalogue_for(result: CalibrationResult, catalogue: Mapping[str, Term] | None) -> dict[
    str, Term
]:  # fmt: skip
    cat = {**CATALOGUE, **CARRIED}
    for f in result.term_files:
        if Path(f).is_file():
            cat = load_term_file(f, cat)
    if catalogue:
        cat.update(catalogue)
    return cat


def _per_sample(x: Any, n: int, what: str, unit: str) -> np.ndarray:
    a = np.asarray(x, dtype=np.float64)
    if a.ndim == 0:
        return np.full(n, float(a))
    if a.shape != (n,):
        raise UserError(f"apply(): {what} has shape {a.shape}, expected ({n},) in {unit}")
    return a


def apply(
    result: CalibrationResult,
    accel: np.ndarray,
    gyro: np.ndarray,
    temp_c: np.ndarray | float | None = None,
    t_s: np.ndarray | float | None = None,
    *,
    catalogue: Mapping[str, Term] | None = None,
    allow_undetermined: bool = False,
) -> tuple[np.ndarray, np.ndarray]:
    """Invert the whole model of ``result``: raw outputs -> calibrated specific force and rate.

    ``accel`` m/s² and ``gyro`` °/s, (N,3) or (3,); ``temp_c`` chip temperature °C and ``t_s``
    time since power-on s, (N,) or scalars — needed only by the terms that use them (a clear
    UserError names the term and the input otherwise). Returns (specific force m/s², rate °/s)
    of the same shape as the inputs.

    Every term is evaluated with its own column function (method.md §2 for the base terms,
    the catalogue's docstrings for the others, custom terms from the result's term files or
    ``catalogue``); the model output = input + Σ terms is inverted by fixed-point iteration on
    (I+M)⁻¹ (exact for the linear model: a = (I+Ma)⁻¹(A − A0), ω = (I+Mg)⁻¹(G − G0 − GA·a/g)).
    Parameters the records did not determine raise UserError unless ``allow_undetermined``
    (then they are taken as nominal, 0). A result carrying a thermal calibration (bias(T),
    term ``thermal_bias``) needs ``temp_c`` and warns
    (:class:`host.calib.thermal.ThermalRangeWarning`) for temperatures outside the range over
    which it holds, where its polynomial is extrapolated.
    """
    a_raw = np.asarray(accel, dtype=np.float64)
    g_raw = np.asarray(gyro, dtype=np.float64)
    single = a_raw.ndim == 1
    a2, g2 = np.atleast_2d(a_raw), np.atleast_2d(g_raw)
    if a2.shape[1:] != (3,) or g2.shape != a2.shape:
        raise UserError(
            f"apply(): accel {a_raw.shape} and gyro {g_raw.shape} must both be (N,3) or (3,)"
        )
    n = len(a2)
    und = [p.name for p in result.undetermined]
    if und and not allow_undetermined:
        raise UserError(
            f"the result of {result.serial} does not determine {', '.join(und)}; recalibrate "
            "with the records it needs, or pass allow_undetermined=True to take them as 0"
        )
    cat = _catalogue_for(result, catalogue)
    model = parse_model(result.model, cat)
    theta: dict[tuple[str, str, str], dict[str, float]] = {}
    for p in result.parameters:
        v = p.value if p.determined else 0.0
        theta.setdefault((p.term, p.sensor, p.axis), {})[p.key] = v
    temp: Any = _Missing("temp_c", n) if temp_c is None else _per_sample(temp_c, n, "temp_c", "°C")
    time: Any = _Missing("t_s", n) if t_s is None else _per_sample(t_s, n, "t_s", "s")
    if result.thermal_range_c is not None and temp_c is not None:
        lo, hi = result.thermal_range_c
        outside = (temp < lo) | (temp > hi)
        if np.any(outside):
            warnings.warn(
                f"{int(np.count_nonzero(outside))} samples at {float(temp.min()):.1f} to "
                f"{float(temp.max()):.1f} degC lie outside the thermal calibration's range "
                f"{lo:.1f} to {hi:.1f} degC: the bias(T) polynomial is extrapolated there",
                ThermalRangeWarning,
                stacklevel=2,
            )
    inv_a = np.linalg.inv(np.eye(3) + np.nan_to_num(result.accel_m()))
    inv_g = np.linalg.inv(np.eye(3) + np.nan_to_num(result.gyro_m()))

    def predict(force: np.ndarray, rate: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        sig = RecordSignals(
            name="apply", kind="apply", t_s=time, temp_c=temp, force=force, rate=rate,
            accel=a2, gyro=g2, g=result.g, up=np.zeros(3), temp_mean_c=result.temp_mean_c,
        )  # fmt: skip
        out = {"accel": force.copy(), "gyro": rate.copy()}
        for mt in model:
            for ax in mt.axes:
                vals = theta.get((mt.term.name, mt.sensor, AXES[ax]), {})
                th = np.array([vals.get(k, 0.0) for k in mt.term.params])
                try:
                    if mt.term.value is not None:
                        c = np.asarray(mt.term.value(sig, mt.sensor, ax, th), dtype=np.float64)
                    else:
                        assert mt.term.columns is not None
                        x = np.asarray(mt.term.columns(sig, mt.sensor, ax), dtype=np.float64)
                        c = (x.reshape(n, -1) @ th) if th.size else np.zeros(n)
                except _MissingInput as exc:
                    raise UserError(
                        f"term {mt.label} of this result needs {_NEEDS_ARG[exc.what]} to apply()"
                    ) from None
                out[mt.sensor][:, ax] += c
        return out["accel"], out["gyro"]

    force = (a2 - np.nan_to_num(result.accel_bias())) @ inv_a.T
    rate = np.zeros_like(g2)
    for _ in range(50):
        pa, pg = predict(force, rate)
        da = (a2 - pa) @ inv_a.T
        dg = (g2 - pg) @ inv_g.T
        force, rate = force + da, rate + dg
        if max(float(np.max(np.abs(da), initial=0.0)), float(np.max(np.abs(dg), initial=0.0))) < (
            1e-12 * max(1.0, float(np.max(np.abs(a2), initial=0.0)))
        ):
            break
    return (force[0], rate[0]) if single else (force, rate)


# ---- held-out verification ------------------------------------------------------------------
#: method.md §8: compensated error on attitudes/rates not used in the fit, ≤ 0.01 g and ≤ 0.5 °/s
VERIFY_ACCEL_G = 0.01
VERIFY_GYRO_DPS = 0.5


@dataclass(frozen=True)
class VerifiedValue:
    """One record and channel of another session, predicted by the result: ``measured``,
    ``predicted``, ``residual`` (measured − predicted) and ``sigma`` in ``unit`` (the channel's
    unit; ° for turn integrals), ``z`` = residual/σ, ``limit`` the §8 accuracy limit in the same
    unit and ``passed`` |residual| ≤ limit."""

    record: str
    kind: str
    channel: str
    measured: float
    predicted: float
    residual: float
    sigma: float
    z: float
    unit: str
    limit: float
    passed: bool

    def to_dict(self) -> dict[str, Any]:
        return {f.name: _jsonable(getattr(self, f.name)) for f in dataclasses.fields(self)}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> VerifiedValue:
        return cls(
            str(d["record"]), str(d["kind"]), str(d["channel"]), _num(d["measured"]),
            _num(d["predicted"]), _num(d["residual"]), _num(d["sigma"]), _num(d["z"]),
            str(d["unit"]), _num(d["limit"]), bool(d["passed"]),
        )  # fmt: skip


@dataclass(frozen=True)
class Verification:
    """Held-out verification: the records of ``source`` (not used in the fit) predicted by the
    result. ``rms_z`` and ``chi2`` over the values (``p`` = P(χ²_n this large | the result
    is right)); ``passed``: every value within the §8 accuracy limits."""

    source: str
    values: tuple[VerifiedValue, ...]
    rms_z: float
    chi2: float
    p: float

    @property
    def passed(self) -> bool:
        return all(v.passed for v in self.values)

    def to_dict(self) -> dict[str, Any]:
        return {
            "source": self.source, "values": [v.to_dict() for v in self.values],
            "rms_z": _jsonable(self.rms_z), "chi2": _jsonable(self.chi2), "p": _jsonable(self.p),
            "passed": self.passed,
        }  # fmt: skip

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> Verification:
        return cls(
            str(d["source"]), tuple(VerifiedValue.from_dict(v) for v in d["values"]),
            _num(d["rms_z"]), _num(d["chi2"]), _num(d["p"]),
        )  # fmt: skip


def verify(
    result: CalibrationResult,
    session: Session,
    *,
    source: str = "",
    catalogue: Mapping[str, Term] | None = None,
) -> Verification:
    """Predict every record of ``session`` (another session, extra attitudes: records the fit
    did not use) with the whole model of ``result`` and its noise model; measured − predicted
    per record and channel (static: record mean; turn: integral), against the accuracy limits
    of method.md §8 (0.01 g, 0.5 °/s; a turn's limit is 0.5 °/s × its duration, in °).
    UserError when the result does not determine a parameter the prediction needs."""
    und = [p.name for p in result.undetermined]
    if und:
        raise UserError(
            f"--verify: the result does not determine {', '.join(und)}: nothing to predict with"
        )
    nm = NoiseModel()
    if result.noise_model:
        known = {f.name for f in dataclasses.fields(NoiseModel)}
        nm = dataclasses.replace(nm, **{k: v for k, v in result.noise_model.items() if k in known})
    model = parse_model(result.model, _catalogue_for(result, catalogue))
    values = {(p.term, p.sensor, p.axis, p.key): p.value for p in result.parameters}
    held_out = predict_session(
        session, model, values, noise=nm, latitude_deg=result.latitude_deg,
        height_m=result.height_m, earth_rate=result.earth_rate,
    )  # fmt: skip
    ds, groups = held_out.dataset, held_out.groups
    out: list[VerifiedValue] = []
    duration = {s.name: float(s.t_s[-1] - s.t_s[0]) if len(s.t_s) > 1 else 0.0 for s in ds.signals}
    for g in groups:
        if g.sensor == "accel":
            limit = VERIFY_ACCEL_G * result.g
        else:
            limit = VERIFY_GYRO_DPS * (duration[g.record] if g.kind == "turn" else 1.0)
        out.append(VerifiedValue(
            g.record, g.kind, g.channel, g.measured, g.model, g.residual, g.sigma, g.z, g.unit,
            limit, abs(g.residual) <= limit,
        ))  # fmt: skip
    z = np.array([v.z for v in out])
    chi2 = float(z @ z)
    return Verification(
        source, tuple(out), float(np.sqrt(np.mean(z**2))) if len(z) else math.nan, chi2,
        chi2_sf(chi2, len(z)),
    )  # fmt: skip


def verify_directory(result: CalibrationResult, directory: str, serial: str | None = None) -> (
    CalibrationResult
):  # fmt: skip
    """``result`` with :func:`verify` on the records in ``directory`` attached."""
    session = read_session(directory, serial)
    return dataclasses.replace(result, verification=verify(result, session, source=directory))
