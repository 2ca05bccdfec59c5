"""One archived calibration: what the archive keeps of a result and the files it came from.

:func:`entry_from_directory` reads what ``calibrate`` wrote — ``SERIAL_result.json`` (through
:func:`~host.calib.codec.read_result`), the report ``SERIAL_result.txt`` and the
record files the result names — and returns an :class:`Entry`: the identity of the session
(serial, bench, operator, lot, firmware and sensor revision, the time of the first record, the
chip temperatures), the model, every parameter with its σ and the covariance, the fit quality,
the verdict and the SHA-256 of every file. The result file's own hash is the entry's identity:
adding the same file twice is the same entry.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path

import numpy as np

from host.calib.codec import read_result
from host.calib.result import CalibrationResult
from host.errors import UserError
from host.session.directory import read_record
from host.session.records import name_problem
from host.wire.selftest import OUTCOMES

#: environment variables naming the bench and the operator when neither the records' headers
#: nor the command line do
BENCH_ENV = "IMU_BENCH_NAME"
OPERATOR_ENV = "IMU_BENCH_OPERATOR"


@dataclass(frozen=True)
class Parameter:
    """One fitted parameter as archived: report ``name`` ('A0x', 'temperature_bias.gyro.y'),
    the term/sensor/axis it belongs to, ``value`` and 1-σ ``stderr`` in ``unit`` (NaN: not
    determined), the §7 ``tolerance`` and ``passed`` flag where the method has one, ``dof``
    the degrees of freedom of ``stderr`` (inf: from the noise model alone)."""

    name: str
    term: str
    sensor: str
    axis: str
    unit: str
    value: float
    stderr: float
    tolerance: float | None = None
    passed: bool | None = None
    dof: float = math.inf


@dataclass(frozen=True)
class Entry:
    """One calibration of one unit, as the archive keeps it.

    ``measured_at``: UTC time of the session's first record (ISO 8601, ``Z``);
    ``temp_*_c``: the chip temperature over the records, °C; ``covariance``: the parameters'
    covariance in the order of ``parameters`` (``covariance_kind`` 'full' when the result file
    carries it, 'diagonal' when only the σ were there); ``verdict``: 'pass' or 'fail' (the
    report's verdict, and a failed self-test fails it); ``self_test``: 'pass', 'fail',
    'not run' (``--no-self-test``) or '' (no verdict, or records without a self-test);
    ``result_hash``/``report_hash``/``records_hash``: SHA-256 (hex) of the result file, the
    report and the records (the hash of the sorted 'name sha256' lines of ``record_hashes``);
    ``result_json``: the result file's text, kept whole; ``simulated``: its records came
    from a virtual or emulated board (kept, but not in the lot, control and drift statistics).
    """

    serial: str
    measured_at: str
    model: str
    parameters: tuple[Parameter, ...]
    result_hash: str
    bench: str = ""
    operator: str = ""
    lot: str = ""
    firmware: str = ""
    sensor_revision: str = ""
    temp_min_c: float = math.nan
    temp_mean_c: float = math.nan
    temp_max_c: float = math.nan
    covariance: tuple[tuple[float, ...], ...] = ()
    covariance_kind: str = "diagonal"
    chi2: float = math.nan
    dof: int = 0
    rms_z: float = math.nan
    p: float = math.nan
    fit_verdict: str = ""
    verdict: str = "fail"
    self_test: str = ""
    report_hash: str = ""
    records_hash: str = ""
    record_hashes: tuple[tuple[str, str], ...] = ()
    result_json: str = ""
    simulated: bool = False

    def parameter(self, name: str) -> Parameter:
        """The parameter called ``name`` (KeyError if the entry has none)."""
        for p in self.parameters:
            if p.name == name:
                return p
        raise KeyError(name)


def sha256_bytes(data: bytes) -> str:
    """SHA-256 of ``data``, hex."""
    return hashlib.sha256(data).hexdigest()


def records_digest(record_hashes: Sequence[tuple[str, str]]) -> str:
    """One hash for a set of record files: SHA-256 of the sorted 'name sha256' lines."""
    lines = "".join(f"{n} {h}\n" for n, h in sorted(record_hashes))
    return sha256_bytes(lines.encode())


def utc_iso(text: str) -> str:
    """An ISO 8601 time (with an offset; naive = UTC) as UTC ``YYYY-MM-DDTHH:MM:SS.ffffffZ``
    (sorts as text). UserError for text that is no time."""
    try:
        t = datetime.fromisoformat(text.strip().replace("Z", "+00:00"))
    except ValueError:
        raise UserError(
            f"not an ISO 8601 time: {text!r} (e.g. 2026-05-04T09:30:00+02:00)"
        ) from None
    if t.tzinfo is None:
        t = t.replace(tzinfo=UTC)
    return t.astimezone(UTC).strftime("%Y-%m-%dT%H:%M:%S.%fZ")


def diagonal_covariance(stderr: Sequence[float]) -> tuple[tuple[float, ...], ...]:
    """The covariance when only the σ are known: diag(σ²) (NaN σ -> NaN)."""
    s = np.asarray(stderr, dtype=np.float64)
    return tuple(tuple(float(x) for x in row) for row in np.diag(s * s))


def result_covariance(
    doc: Mapping[str, object], names: Sequence[str]
) -> tuple[tuple[float, ...], ...] | None:
    """The full covariance a result file carries (``covariance: {names, matrix}``), reordered
    to ``names``; None when the file has none or it does not cover every name."""
    cov = doc.get("covariance")
    if not isinstance(cov, Mapping):
        return None
    cnames = cov.get("names")
    matrix = cov.get("matrix")
    if not isinstance(cnames, list) or not isinstance(matrix, list):
        return None
    pos = {str(n): i for i, n in enumerate(cnames)}
    if any(n not in pos for n in names):
        return None
    try:
        m = np.array([[math.nan if x is None else float(x) for x in row] for row in matrix])
    except (TypeError, ValueError):  # not a matrix of numbers
        return None
    if m.shape != (len(cnames), len(cnames)):
        return None
    idx = [pos[n] for n in names]
    sub = m[np.ix_(idx, idx)]
    return tuple(tuple(float(x) for x in row) for row in sub)


def _find_result(directory: Path, serial: str | None) -> Path:
    if directory.is_file():
        return directory
    if not directory.is_dir():
        raise UserError(f"{directory}: no such directory (give the directory calibrate wrote)")
    if serial is not None:
        path = directory / f"{serial}_result.json"
        if not path.is_file():
            raise UserError(f"{path}: no such file (run calibrate --from-dir {directory} first)")
        return path
    found = sorted(directory.glob("*_result.json"))
    if not found:
        raise UserError(f"{directory}: no SERIAL_result.json (run calibrate --from-dir first)")
    if len(found) > 1:
        names = ", ".join(p.name for p in found)
        raise UserError(f"{directory}: several results ({names}); say which with --serial")
    return found[0]


def _first(metas: Sequence[Mapping[str, str]], key: str) -> str:
    for m in metas:
        v = m.get(key, "").strip()
        if v:
            return v
    return ""


def _named(
    option: str, given: str | None, metas: Sequence[Mapping[str, str]], key: str, env: str | None
) -> str:
    """A name for the archive: the option's value, else the records' header, else $``env``;
    UserError, naming where it came from, when it is not printable text (an escape sequence
    in the archive garbles every listing of the lot)."""
    value, source = given, option
    if not value:
        value, source = _first(metas, key), f"the records' '{key}' header line"
    if not value and env is not None:
        value, source = os.environ.get(env, ""), f"${env}"
    problem = name_problem(value) if value else None
    if problem is not None:
        raise UserError(f"{source}: {problem}")
    return value or ""


def self_test_outcome(metas: Sequence[Mapping[str, str]], where: object) -> str:
    """The session's self-test as its records' headers say it (``self_test`` line, written by
    :meth:`host.wire.selftest.SelfTest.meta`): 'pass', 'fail', 'not run' or '' (no verdict).
    UserError naming ``where`` for any other text."""
    outcome = _first(metas, "self_test").lower()
    if outcome not in OUTCOMES:
        raise UserError(
            f"{where}: records say self_test: {outcome!r} (expected pass, fail or not run)"
        )
    return outcome


def archived_verdict(all_passed: bool, self_test: str) -> str:
    """'pass' or 'fail' as archived: the report's verdict, failed by a failed self-test."""
    return "pass" if all_passed and self_test != "fail" else "fail"


def conditional_pass(verdict: str, fit_verdict: str) -> bool:
    """An archived 'pass' whose fit's verdict is 'inadequate': the result's conditional PASS
    (every value within tolerance as fitted, on a model that does not fit the records), not a
    clean pass."""
    return verdict == "pass" and fit_verdict == "inadequate"


def _report_beside(path: Path, serial: str) -> Path:
    """The report written with the result file ``path``; UserError when it is missing."""
    report = path.with_name(f"{serial}_result.txt")
    if not report.is_file():
        raise UserError(f"{report}: no such file (the report written with {path.name})")
    return report


def _fitted_records(
    result: CalibrationResult, rdir: Path
) -> tuple[list[tuple[str, str]], list[dict[str, str]], list[np.ndarray]]:
    """Each record the result was fitted on, from ``rdir``: (name, SHA-256), its header and
    its chip temperatures, °C. UserError for one missing, or not the one fitted (its
    SHA-256 differs from the one the result names)."""
    hashes: list[tuple[str, str]] = []
    metas: list[dict[str, str]] = []
    temps: list[np.ndarray] = []
    for name in result.records:
        rpath = rdir / f"{result.serial}_{name}.txt"
        if not rpath.is_file():
            raise UserError(
                f"{rpath}: no such file — the result was fitted on it; give the records' "
                "directory with --records"
            )
        digest = sha256_bytes(rpath.read_bytes())
        fitted = None if result.provenance is None else result.provenance.record_sha256.get(name)
        if fitted is not None and fitted != digest:  # was: archived with another sitting's
            raise UserError(
                f"{rpath}: not the record the result was fitted on (its SHA-256 differs from "
                "the one the result names); give the directory of those records with --records"
            )
        hashes.append((name, digest))
        rec = read_record(rpath)
        metas.append(rec.meta)
        temps.append(rec.temp)
    return hashes, metas, temps


def _temperature_range(temps: list[np.ndarray]) -> tuple[float, float, float]:
    """The lowest, mean and highest chip temperature of the records, °C (NaN: none)."""
    t = np.concatenate(temps) if temps else np.array([])
    t = t[np.isfinite(t)]
    if not t.size:
        return math.nan, math.nan, math.nan
    return float(t.min()), float(t.mean()), float(t.max())


def _measured_at(metas: list[dict[str, str]], created: str) -> str:
    """When the session was measured: its first record's start (UTC ISO), else when the
    result was computed."""
    starts = [utc_iso(m["start_time"]) for m in metas if m.get("start_time")]
    return min(starts) if starts else utc_iso(created)


def entry_from_directory(
    directory: str | os.PathLike[str],
    *,
    serial: str | None = None,
    records_dir: str | os.PathLike[str] | None = None,
    bench: str | None = None,
    operator: str | None = None,
    lot: str | None = None,
) -> Entry:
    """The :class:`Entry` of the result in ``directory`` (or the result file itself): the
    result, its report beside it and its records (in ``records_dir``, default the same
    directory). ``bench``/``operator``/``lot`` override the records' header lines of those
    names; bench and operator fall back to $IMU_BENCH_NAME / $IMU_BENCH_OPERATOR. UserError
    naming the missing or bad file."""
    path = _find_result(Path(directory), serial)
    raw = path.read_bytes()
    result, doc = read_result(path), json.loads(raw)
    report = _report_beside(path, result.serial)
    rdir = Path(records_dir) if records_dir is not None else path.parent
    hashes, metas, temps = _fitted_records(result, rdir)
    t_min, t_mean, t_max = _temperature_range(temps)
    measured_at = _measured_at(metas, result.created)
    self_test = self_test_outcome(metas, path)
    params = tuple(
        Parameter(p.name, p.term, p.sensor, p.axis, p.unit, p.value, p.stderr, p.tolerance,
                  p.passed, p.dof)
        for p in result.parameters
    )  # fmt: skip
    full = result_covariance(doc, [p.name for p in params])
    fit = result.fit
    return Entry(
        serial=result.serial,
        measured_at=measured_at,
        model=result.model,
        parameters=params,
        result_hash=sha256_bytes(raw),
        bench=_named("--bench", bench, metas, "bench", BENCH_ENV),
        operator=_named("--operator", operator, metas, "operator", OPERATOR_ENV),
        lot=_named("--lot", lot, metas, "lot", None),
        firmware=_first(metas, "firmware"),
        sensor_revision=_first(metas, "sensor_revision"),
        temp_min_c=t_min,
        temp_mean_c=t_mean,
        temp_max_c=t_max,
        covariance=full if full is not None else diagonal_covariance([p.stderr for p in params]),
        covariance_kind="full" if full is not None else "diagonal",
        chi2=fit.chi2 if fit else math.nan,
        dof=fit.dof if fit else 0,
        rms_z=fit.rms_z if fit else math.nan,
        p=fit.p if fit else math.nan,
        fit_verdict=fit.verdict if fit else "",
        verdict=archived_verdict(result.all_passed, self_test),
        self_test=self_test,
        report_hash=sha256_bytes(report.read_bytes()),
        records_hash=records_digest(hashes),
        record_hashes=tuple(hashes),
        result_json=raw.decode("utf-8"),
        simulated=result.simulated,
    )
