"""A calibration result's files: ``SERIAL_result.json``, format v3 written, v1–v3 read.

Format v2 carries the model (a spec of named terms) with every parameter, the noise model of
the fit and the fit quality (χ², dof, RMS z, p, verdict); v3 adds where the records came from
(:class:`host.calib.provenance.Provenance`) and, later, where the floor of a record mean came
from (``floor_source``; absent in files written before it, which load as measured) and the
decision rule its marks follow (``decision_rule``, :mod:`host.calib.decision`; absent in files
written before it, which load as ``simple``, the rule they were judged by). v1 and v2
files still load: a v1 file's §7 names (``constants``, ``std_errors``) become the parameters of
the ``base`` model here, and a v1/v2 file is simulated when its notes say ``SIMULATED BOARD``.
Beside the values a file carries derived views for its readers, not read back: the §7 values
by report name, their marks and pass flags and the verdict line (:mod:`host.calib.verdict`,
:mod:`host.calib.result_text`). A result file is data: loading one runs nothing.
"""

from __future__ import annotations

import dataclasses
import json
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from host.calib.decision import LEGACY_RULE
from host.calib.provenance import Provenance
from host.calib.result import CalibrationResult, base_parameters
from host.calib.result_text import verdict_line
from host.calib.values import (
    FitQuality,
    ParameterResult,
    RecordResidual,
    Verification,
    as_float,
    jsonable,
    tolerance_of,
)
from host.calib.verdict import all_passed, conditional, marks, passed
from host.errors import InputError, ResultFileError
from host.model.signals import TEMP_REF_C
from host.session.inputs import check_serial, load_json
from host.session.method import CONSTANT_NAMES, NOISE_NAMES, UNITS

FORMAT = "imu-bench calibration result"
#: the format version this program writes
FORMAT_VERSION = 3
#: the format versions :func:`result_from_json` reads
READS = (1, 2, 3)
#: the keys of a result's ``floor_source``: the options whose values it keeps
FLOOR_SOURCES = ("noise", "floor")


# ---- writing ------------------------------------------------------------------------------
def result_to_dict(r: CalibrationResult) -> dict[str, Any]:
    """JSON-ready dict (format v3): the result's values, then views for readers."""
    return {**_head(r), **_verdict_views(r), **_fit_and_site(r), **_records_part(r)}


def _head(r: CalibrationResult) -> dict[str, Any]:
    """Who and what: the format, the unit, where the records came from, the model."""
    prov = r.provenance
    return {
        "format": FORMAT,
        "format_version": FORMAT_VERSION,
        "serial": r.serial,
        "created": r.created,
        "simulated": r.simulated,
        "simulated_by": [] if prov is None else list(prov.simulated_by),
        "provenance": None if prov is None else prov.to_dict(),
        "self_test": r.self_test,
        "decision_rule": r.decision_rule,
        "model": r.model,
        "term_files": list(r.term_files),
        "term_sha256": dict(r.term_sha256),
        "parameters": [p.to_dict() for p in r.parameters],
    }


def _verdict_views(r: CalibrationResult) -> dict[str, Any]:
    """The §7 view (value and pass flag by report name), the noise levels, and the verdict
    line and whether a PASS rests on a model that does not fit (derived, not read back).
    ``marks``: ``+``, ``−``, ``?`` by the decision rule; ``pass`` is true for ``+`` only."""
    flags = passed(r)
    return {
        "constants": jsonable(r.constants()),
        "marks": marks(r),
        "pass": flags,
        "noise_std": {
            n: {
                "value": jsonable(v),
                "unit": UNITS[n],
                "tolerance": tolerance_of(n),
                "passed": flags.get(n),
            }
            for n, v in r.noise_std.items()
        },  # fmt: skip
        "all_passed": all_passed(r),
        "verdict": verdict_line(r),
        "conditional": conditional(r),
    }


def _fit_and_site(r: CalibrationResult) -> dict[str, Any]:
    """The fit quality, its noise model and floor, the site and the session's conditions."""
    return {
        "fit": None if r.fit is None else r.fit.to_dict(),
        "noise_model": jsonable(dict(r.noise_model)),
        "floor_source": dict(r.floor_source),
        "g": r.g,
        "g_unit": "m/s²",
        "latitude_deg": r.latitude_deg,
        "height_m": r.height_m,
        "turns": r.turns,
        "temp_mean_c": r.temp_mean_c,
        "time_known": r.time_known,
        "earth_rate": r.earth_rate,
        "method": r.method,
    }


def _records_part(r: CalibrationResult) -> dict[str, Any]:
    """The records, the checks beside the fit, residuals, covariance, notes, verification
    and the carried bias(T)."""
    return {
        "records": list(r.records),
        "bias_estimates": jsonable(dict(r.bias_estimates)),
        "closed_form": jsonable(dict(r.closed_form)),
        "combinations": list(r.combinations),
        "residuals": [x.to_dict() for x in r.residuals],
        "covariance": None
        if not r.covariance
        else {
            "names": [p.name for p in r.parameters],
            "matrix": jsonable(r.covariance),
            "units": "the product of the two parameters' units",
        },
        "notes": list(r.notes),
        "verification": None if r.verification is None else r.verification.to_dict(),
        "thermal": None
        if r.thermal_range_c is None
        else {
            "valid_range_c": list(r.thermal_range_c),
            "source": r.thermal_source,
            "model": "thermal_bias: sum_j c_j (T - temp_mean_c)^j, T chip degC",
        },
    }


def result_to_json(r: CalibrationResult) -> str:
    """The JSON text of :func:`result_to_dict` (UTF-8, indented)."""
    return json.dumps(result_to_dict(r), indent=2, ensure_ascii=False) + "\n"


# ---- reading ------------------------------------------------------------------------------
def result_from_json(text: str | bytes) -> CalibrationResult:
    """Parse a result file, format v3, v2 or v1; ResultFileError (a UserError) on bad JSON,
    an unknown version or a missing field."""
    try:
        d = load_json(text, "calibration result")
    except InputError as exc:  # too large or too deep: one line, not the parser's recursion
        raise ResultFileError(str(exc)) from None
    except (ValueError, UnicodeDecodeError) as exc:
        raise ResultFileError(f"calibration result: not valid JSON ({exc})") from exc
    if not isinstance(d, dict) or "format_version" not in d:
        raise ResultFileError("calibration result: not an imu-bench result (no format_version)")
    version = d["format_version"]
    if type(version) is not int or version not in READS:  # JSON true is not v1
        raise ResultFileError(
            f"calibration result format v{version} but this program reads "
            f"{', '.join(f'v{v}' for v in READS)}; recompute it with "
            "'python3 -m host calibrate --from-dir'"
        )
    try:
        result = _from_v1(d) if version == 1 else _from_v2(d, version)
    except (KeyError, TypeError, ValueError, IndexError, AttributeError) as exc:
        raise ResultFileError(f"calibration result: missing or bad field ({exc})") from exc
    try:  # it names the report and the records beside it: one line of every file it is in
        check_serial(result.serial, "its serial")
    except ValueError as exc:
        raise ResultFileError(
            f"calibration result: not a result this program wrote ({exc})"
        ) from None
    return result


def read_result(path: str | os.PathLike[str]) -> CalibrationResult:
    """Read ``SERIAL_result.json`` (v3, v2 or v1)."""
    try:
        text = Path(path).read_text(encoding="utf-8")
    except OSError as exc:
        raise ResultFileError(f"{path}: cannot read the result ({exc.strerror})") from exc
    except UnicodeDecodeError:
        raise ResultFileError(
            f"{path}: not a calibration result (not UTF-8 text); give the "
            "SERIAL_result.json that calibrate wrote"
        ) from None
    try:
        return result_from_json(text)
    except ResultFileError as exc:  # which file
        raise ResultFileError(f"{path}: {exc}") from None


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
        "decision_rule": str(d.get("decision_rule", LEGACY_RULE)),
    }


def _from_v1(d: Mapping[str, Any]) -> CalibrationResult:
    """Format v1: the §7 constants by report name, the ``base`` model's parameters."""
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
    ver = d.get("verification")
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
        verification=None if ver is None else Verification.from_dict(ver),
        thermal_range_c=None
        if th is None
        else (float(th["valid_range_c"][0]), float(th["valid_range_c"][1])),
        thermal_source="" if th is None else str(th.get("source", "")),
        **_common(d),
    )
