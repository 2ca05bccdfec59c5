"""The parts of a calibration result: small value types with their JSON.

Each parameter of the model (value, 1-σ standard error, unit, and for the §2 constants the
method.md §7 tolerance and pass flag), the fit quality, one record's residuals, and the held-out
verification's values (method.md §8 limits). The result object that holds them and its files are
:mod:`host.calib.result`.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from host.model.catalogue import BASE
from host.session.method import CONSTANT_NAMES, NOISE_NAMES, TOLERANCES


# ---- small JSON helpers -------------------------------------------------------------------
def as_float(v: Any) -> float:
    """A JSON number as a float; null (None) is NaN."""
    return float("nan") if v is None else float(v)


def jsonable(v: Any) -> Any:
    """``v`` ready for JSON: floats (numpy's too) with NaN/inf as null, tuples and arrays as
    lists, dict keys as strings."""
    if isinstance(v, float | np.floating):
        f = float(v)
        return None if not math.isfinite(f) else f
    if isinstance(v, tuple | list | np.ndarray):
        return [jsonable(x) for x in v]
    if isinstance(v, dict):
        return {str(k): jsonable(x) for k, x in v.items()}
    return v


# ---- the parts of a result ----------------------------------------------------------------
def _dof(v: Any) -> float:
    """A parameter's ``dof`` from a file: null is inf; ValueError unless a positive number."""
    if v is None:
        return math.inf
    if isinstance(v, bool) or not isinstance(v, int | float) or not (v > 0):
        raise ValueError(f"a parameter's dof is {v!r}: expected a positive number or null")
    return float(v)


@dataclass(frozen=True)
class ParameterResult:
    """One parameter of one term on one output channel.

    ``term`` catalogue name ('temperature_bias'), ``sensor`` accel/gyro, ``axis`` x/y/z (the
    output channel), ``key`` the term's parameter ('per_C'), ``name`` its report name ('A0x';
    'temperature_bias.gyro.y' for further terms). ``value``/``stderr`` in ``unit``; NaN value:
    not determined by the records, ``needs`` says what would determine it. ``tolerance`` and
    ``passed`` where method.md §7 defines a tolerance (None otherwise). ``dof``: the degrees
    of freedom ``stderr`` is read on (inf, null in the file: from the noise model alone; finite
    where an estimated variance component carries part of it — its U takes Student's t).
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
    dof: float = math.inf

    @property
    def determined(self) -> bool:
        return math.isfinite(self.value)

    @property
    def base(self) -> bool:
        """A parameter of the linear model of method.md §2 (reported in the §7 layout)."""
        return self.term in BASE

    def to_dict(self) -> dict[str, Any]:
        return {f.name: jsonable(getattr(self, f.name)) for f in dataclasses.fields(self)}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> ParameterResult:
        tol = d.get("tolerance")
        return cls(
            term=str(d["term"]), sensor=str(d["sensor"]), axis=str(d["axis"]), key=str(d["key"]),
            name=str(d["name"]), value=as_float(d["value"]), stderr=as_float(d["stderr"]),
            unit=str(d["unit"]), tolerance=None if tol is None else float(tol),
            passed=None if d.get("passed") is None else bool(d["passed"]),
            needs=str(d.get("needs", "")), dof=_dof(d.get("dof")),
        )  # fmt: skip


@dataclass(frozen=True)
class FitQuality:
    """How well the model explains the records: χ² on ``dof`` degrees of freedom, RMS of the
    record/channel z values, p = P(χ² this large | model right), ``verdict`` adequate /
    inadequate (p < 0.01: the model misses something) / untestable (some channel has no
    degrees of freedom: ``untestable`` lists them). ``stderr_note``: how the standard errors
    were treated (the uncertainty policy, :func:`host.model.stats.stderr_scale`)."""

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
            "chi2": jsonable(self.chi2), "dof": self.dof, "rms_z": jsonable(self.rms_z),
            "p": jsonable(self.p), "verdict": self.verdict, "untestable": list(self.untestable),
            "stderr_note": self.stderr_note,
        }  # fmt: skip

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> FitQuality:
        return cls(
            float(as_float(d["chi2"])), int(d["dof"]), as_float(d["rms_z"]), as_float(d["p"]),
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
        return {f.name: jsonable(getattr(self, f.name)) for f in dataclasses.fields(self)}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> RecordResidual:
        """Inverse of :meth:`to_dict`."""

        def t3(v: Any) -> tuple[float, float, float]:
            a, b, c = (as_float(x) for x in v)
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


def constants_of(
    parameters: tuple[ParameterResult, ...], noise_std: Mapping[str, float]
) -> dict[str, float]:
    """§7 name -> value in report order, from a result's parameters and noise levels (NaN:
    not determined, or not in the model)."""
    by = {p.name: p.value for p in parameters}
    by.update(noise_std)
    return {n: float(by.get(n, math.nan)) for n in CONSTANT_NAMES}


def undetermined_of(parameters: tuple[ParameterResult, ...]) -> tuple[ParameterResult, ...]:
    """The parameters the records did not determine (NaN value)."""
    return tuple(p for p in parameters if not p.determined)


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
        return {f.name: jsonable(getattr(self, f.name)) for f in dataclasses.fields(self)}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> VerifiedValue:
        return cls(
            str(d["record"]), str(d["kind"]), str(d["channel"]), as_float(d["measured"]),
            as_float(d["predicted"]), as_float(d["residual"]), as_float(d["sigma"]),
            as_float(d["z"]), str(d["unit"]), as_float(d["limit"]), bool(d["passed"]),
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
            "rms_z": jsonable(self.rms_z), "chi2": jsonable(self.chi2), "p": jsonable(self.p),
            "passed": self.passed,
        }  # fmt: skip

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> Verification:
        return cls(
            str(d["source"]), tuple(VerifiedValue.from_dict(v) for v in d["values"]),
            as_float(d["rms_z"]), as_float(d["chi2"]), as_float(d["p"]),
        )  # fmt: skip


def target_line(parameters: Sequence[ParameterResult], target: float) -> str:
    """Whether the adaptive plan's ``target`` (the worst σ/tolerance, ``calibrate --plan
    adaptive --target``) was met by these values (their σ as stated, widened where the model
    does not fit): one line for the report and the dialogue's last screen."""
    worst, whose = 0.0, ""
    for p in parameters:
        r = p.stderr / p.tolerance if p.tolerance else 0.0
        if not math.isfinite(r) or r > worst:
            worst, whose = (r if math.isfinite(r) else math.inf), p.name
    met = "met" if worst <= target else "NOT met"
    return (
        f"Target of the adaptive plan, worst σ/tolerance ≤ {target:g}: {met} ({worst:.3g}, "
        f"{whose})."
    )
