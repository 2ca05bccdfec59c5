"""The calibration result a user ships, and its files.

A result is the model the user chose (a spec of named terms, :mod:`host.model.spec`) with every
parameter of every term (:mod:`host.calib.values`): value, 1-σ standard error, unit, and — for
the §2 constants that the report of method.md §7 tolerances — the tolerance and the pass flag.
Format v2 (``SERIAL_result.json``, ``format_version: 2``) also carries the noise model of the fit
and the fit quality (χ², dof, RMS z, p, verdict); format v3 adds where the records came from
(:class:`host.calib.provenance.Provenance`: ``simulated`` and by what, the equipment, when
measured) and, later, where the floor of a record mean came from (``floor_source``: the
``--noise``/``--floor`` to repeat; absent in files written before it, which load as measured).
Format v1 and v2 files still load: v1 becomes the ``base`` model, and a v1/v2 file is
simulated when its notes say ``SIMULATED BOARD``. A thermal calibration travels in a result as
the term ``thermal_bias`` (:func:`thermal_parameters`, :func:`carried_thermal`).

A parameter whose value is NaN was **not determined** by the records; ``needs`` says what
would determine it. Applying a result to raw samples and verifying it on held-out records:
:mod:`host.calib.applying`.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from host.calib.provenance import Provenance
from host.calib.thermal import CHANNELS as THERMAL_CHANNELS
from host.calib.thermal import ThermalCalibration, recentre_poly, recentred
from host.calib.values import (
    FitQuality,
    ParameterResult,
    RecordResidual,
    Verification,
    as_float,
    jsonable,
    tolerance_of,
    within,
)
from host.errors import ResultFileError, UserError
from host.model.catalogue import CARRIED
from host.model.signals import AXES, TEMP_REF_C
from host.model.spec import parse_model
from host.model.terms import Term
from host.session.directory import SIMULATED_BOARD
from host.session.method import (
    ACCEL_BIAS_NAMES,
    CONSTANT_NAMES,
    GYRO_BIAS_NAMES,
    NOISE_NAMES,
    UNITS,
    names_to_gsens,
    names_to_matrix,
)

FORMAT = "imu-bench calibration result"


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

    The §7 constants are attributes too (``result.Axx``, NaN when not determined or not in the
    model), as in format v1.
    """

    FORMAT_VERSION: ClassVar[int] = 3
    #: the format versions :meth:`from_json` reads
    READS: ClassVar[tuple[int, ...]] = (1, 2, 3)

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
    #: ``thermal_bias``, from ``python -m host thermal``) holds; None: no thermal calibration
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
    #: format version of the file this was loaded from
    loaded_version: int = 3

    def __repr__(self) -> str:
        """One line: serial, model, size, verdict, and SIMULATED for simulated records."""
        verdict = "PASS" if self.all_passed else "FAIL"
        fit = f", fit {self.fit.verdict}" if self.fit is not None else ""
        sim = ", SIMULATED" if self.simulated else ""
        return (
            f"<CalibrationResult {self.serial}: model {self.model}, "
            f"{len(self.parameters)} parameters, {verdict}{fit}{sim}>"
        )

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
        """Every toleranced value within tolerance, every parameter determined, the
        held-out records (if verified) predicted within the §8 accuracy, and no failed
        self-test of the sensor."""
        ok = all(p is not False for p in self.passed().values()) and not self.undetermined
        ok = ok and self.self_test != "fail"
        return ok and (self.verification is None or self.verification.passed)

    @property
    def conditional(self) -> bool:
        """A PASS that rests on a model that does not fit these records (the fit's verdict is
        ``inadequate``): every value is within tolerance as fitted, but it holds only if the
        effect the model lacks does not bias the values. It does not change
        :attr:`all_passed` (nor the exit status 0)."""
        return self.all_passed and self.fit is not None and self.fit.verdict == "inadequate"

    def failed_values(self) -> list[str]:
        """Names of the §7 values outside tolerance, then of the parameters not determined."""
        bad = [n for n, ok in self.passed().items() if ok is False]
        return bad + [p.name for p in self.undetermined if p.name not in bad]

    def verdict(self) -> str:
        """PASS or FAIL and why, in one line: the report's header and conclusion, the last
        line on screen and the result file's ``verdict`` say it alike. ``PASS (conditional:
        the model does not fit, RMS z 8.35)`` when :attr:`conditional`; a FAIL on a model
        that does not fit says so as its last reason."""
        fit = self.fit
        misfit = fit is not None and fit.verdict == "inadequate"
        skipped = " — self-test not run" if self.self_test == "not run" else ""
        if self.all_passed and fit is not None and misfit:
            return f"PASS (conditional: the model does not fit, RMS z {fit.rms_z:.2f}){skipped}"
        if self.all_passed:
            return "PASS: every value within tolerance" + skipped
        bad = self.failed_values()
        why = [f"{len(bad)} value(s) outside tolerance or not determined"] if bad else []
        if self.verification is not None and not self.verification.passed:
            why.append("held-out records not predicted within the limits")
        if self.self_test == "fail":
            why.append("the sensor failed its self-test")
        if misfit:
            why.append("the model does not fit")
        return f"FAIL: {'; '.join(why)}{skipped}"

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
            "simulated": self.simulated,
            "simulated_by": [] if self.provenance is None else list(self.provenance.simulated_by),
            "provenance": None if self.provenance is None else self.provenance.to_dict(),
            "self_test": self.self_test,
            "model": self.model,
            "term_files": list(self.term_files),
            "term_sha256": dict(self.term_sha256),
            "parameters": [p.to_dict() for p in self.parameters],
            # the §7 view, for readers: value and pass flag by report name (not read back)
            "constants": jsonable(self.constants()),
            "pass": self.passed(),
            "noise_std": {
                n: {
                    "value": jsonable(v),
                    "unit": UNITS[n],
                    "tolerance": tolerance_of(n),
                    "passed": within(n, v),
                }
                for n, v in self.noise_std.items()
            },  # fmt: skip
            "all_passed": self.all_passed,
            # derived, not read back: the verdict line the report and the screen print, and
            # whether a PASS rests on a model that does not fit (exit status 0 either way)
            "verdict": self.verdict(),
            "conditional": self.conditional,
            "fit": None if self.fit is None else self.fit.to_dict(),
            "noise_model": jsonable(dict(self.noise_model)),
            "floor_source": dict(self.floor_source),
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
            "bias_estimates": jsonable(dict(self.bias_estimates)),
            "closed_form": jsonable(dict(self.closed_form)),
            "combinations": list(self.combinations),
            "residuals": [r.to_dict() for r in self.residuals],
            "covariance": None
            if not self.covariance
            else {
                "names": [p.name for p in self.parameters],
                "matrix": jsonable(self.covariance),
                "units": "the product of the two parameters' units",
            },
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
            raise ResultFileError(f"calibration result: not valid JSON ({exc})") from exc
        if not isinstance(d, dict) or "format_version" not in d:
            raise ResultFileError("calibration result: not an imu-bench result (no format_version)")
        version = d["format_version"]
        if type(version) is not int or version not in cls.READS:  # JSON true is not v1
            raise ResultFileError(
                f"calibration result format v{version} but this program reads "
                f"{', '.join(f'v{v}' for v in cls.READS)}; recompute it with "
                "'python3 -m host calibrate --from-dir'"
            )
        try:
            return _from_v1(d) if version == 1 else _from_v2(d, version)
        except (KeyError, TypeError, ValueError, IndexError, AttributeError) as exc:
            raise ResultFileError(f"calibration result: missing or bad field ({exc})") from exc

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> CalibrationResult:
        """Read ``SERIAL_result.json`` (v1 or v2)."""
        try:
            text = Path(path).read_text(encoding="utf-8")
        except OSError as exc:
            raise ResultFileError(f"{path}: cannot read the result ({exc.strerror})") from exc
        except UnicodeDecodeError:
            raise ResultFileError(
                f"{path}: not a calibration result (not UTF-8 text); give the "
                "SERIAL_result.json that calibrate wrote"
            ) from None
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
            k: (as_float(v[0]), as_float(v[1]), as_float(v[2]))
            for k, v in d.get("bias_estimates", {}).items()
        },
        "closed_form": {k: as_float(v) for k, v in d.get("closed_form", {}).items()},
        "residuals": tuple(RecordResidual.from_dict(r) for r in d.get("residuals", [])),
        "notes": tuple(str(x) for x in d.get("notes", [])),
        "self_test": str(d.get("self_test", "")),
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


def _from_v1(d: Mapping[str, Any]) -> CalibrationResult:
    consts = {n: as_float(d["constants"][n]) for n in CONSTANT_NAMES}
    params = base_parameters(consts, {k: as_float(v) for k, v in d.get("std_errors", {}).items()})
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


def _covariance(doc: Any, names: list[str]) -> tuple[tuple[float, ...], ...]:
    """A file's ``covariance`` ({names, matrix}) over ``names``, in their order (names it has
    beyond them are left out: their marginal); () for none. ValueError when it does not cover
    every parameter or is not a square matrix."""
    if doc is None:
        return ()
    cnames = [str(n) for n in doc["names"]]
    m = np.array([[as_float(x) for x in row] for row in doc["matrix"]], dtype=np.float64)
    if m.shape != (len(cnames), len(cnames)) or not set(names) <= set(cnames):
        raise ValueError("covariance: not a square matrix over every parameter")
    idx = [cnames.index(n) for n in names]
    return tuple(tuple(float(x) for x in row) for row in m[np.ix_(idx, idx)])


#: the keys of a result's ``floor_source``: the options whose values it keeps
FLOOR_SOURCES = ("noise", "floor")


def _floor_source(doc: Any) -> dict[str, str]:
    """A file's ``floor_source``: text values under the known keys only (it is data that a
    command line repeats, quoted; nothing in it is run). ValueError for anything else."""
    if not isinstance(doc, dict) or not set(doc) <= set(FLOOR_SOURCES):
        raise ValueError(f"floor_source: expected keys among {', '.join(FLOOR_SOURCES)}")
    if not all(isinstance(v, str) and v for v in doc.values()):
        raise ValueError("floor_source: each value is the text of an option")
    return {k: doc[k] for k in FLOOR_SOURCES if k in doc}


def _from_v2(d: Mapping[str, Any], version: int) -> CalibrationResult:
    """Format v2, and v3 with its ``provenance``."""
    fit = d.get("fit")
    th = d.get("thermal")
    prov = d.get("provenance") if version >= 3 else None
    if version >= 3 and bool(d.get("simulated")) != bool(prov and prov.get("simulated")):
        raise ValueError("'simulated' and provenance.simulated disagree")
    return CalibrationResult(
        loaded_version=version,
        provenance=None if prov is None else Provenance.from_dict(prov),
        covariance=_covariance(d.get("covariance"), [str(p["name"]) for p in d["parameters"]]),
        model=str(d["model"]),
        parameters=tuple(ParameterResult.from_dict(p) for p in d["parameters"]),
        noise_std={str(k): as_float(v["value"]) for k, v in d["noise_std"].items()},
        fit=None if fit is None else FitQuality.from_dict(fit),
        noise_model=dict(d.get("noise_model", {})),
        floor_source=_floor_source(d.get("floor_source", {})),
        term_files=tuple(str(x) for x in d.get("term_files", ())),
        term_sha256={str(k): str(v) for k, v in d.get("term_sha256", {}).items()},
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
