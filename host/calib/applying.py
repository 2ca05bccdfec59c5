"""Use a calibration result: :func:`apply` corrects raw samples with it, :func:`verify`
predicts held-out records with it (method.md §8).

Both evaluate the whole model of the result (:mod:`host.calib.result`) with each term's own
column function. A result is data: custom terms come only from the term files the caller
passes, checked against the SHA-256 the result stored; nothing a result file names is run.
:func:`apply` refuses a result with undetermined parameters unless asked to take them as
nominal.
"""

from __future__ import annotations

import dataclasses
import math
import warnings
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any, cast

import numpy as np

from host.calib.result import CalibrationResult
from host.calib.thermal import ThermalRangeWarning
from host.calib.values import VERIFY_ACCEL_G, VERIFY_GYRO_DPS, Verification, VerifiedValue
from host.errors import InputError, NotDeterminedError, TermFileMismatch
from host.model.catalogue import CARRIED, CATALOGUE
from host.model.fit import predict_session
from host.model.loader import load_term_file
from host.model.noise import NoiseModel
from host.model.signals import AXES, RecordSignals
from host.model.spec import ModelTerm, parse_model
from host.model.stats import chi2_sf
from host.model.terms import Term
from host.session.directory import Session, read_session


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


def _catalogue_for(
    result: CalibrationResult,
    term_files: Iterable[str | Path],
    catalogue: Mapping[str, Term] | None,
) -> dict[str, Term]:
    """The terms to evaluate ``result`` with: the built-in ones, the custom terms of the term
    files the caller passed (each checked against the digests the result stored before it
    runs) and ``catalogue``. A result is data: the files it names are never run on its word."""
    cat = {**CATALOGUE, **CARRIED}
    stored = set(result.term_sha256.values())
    for f in term_files:  # a result without digests (older files): the caller's word alone
        cat = load_term_file(f, cat, sha256=stored if stored else None)
    if catalogue:
        cat.update(catalogue)
    known = {"base", *cat}
    missing = sorted({item.split(":")[0].strip() for item in result.model.split(",")} - known)
    if missing:
        named = [f"{f} (sha256 {result.term_sha256.get(f, '?')[:12]}…)" for f in result.term_files]
        raise TermFileMismatch(
            f"the model of {result.serial} uses the custom term(s) {', '.join(missing)}; a "
            "result file's term files are never run on its word: pass the file you trust as "
            f"term_files=[...] (it was calibrated with {', '.join(named) or 'no term file'})"
        )
    return cat


def _per_sample(x: Any, n: int, what: str, unit: str) -> np.ndarray:
    a = np.asarray(x, dtype=np.float64)
    if a.ndim == 0:
        return np.full(n, float(a))
    if a.shape != (n,):
        raise InputError(f"apply(): {what} has shape {a.shape}, expected ({n},) in {unit}")
    return a


def apply(
    result: CalibrationResult,
    accel: np.ndarray,
    gyro: np.ndarray,
    temp_c: np.ndarray | float | None = None,
    t_s: np.ndarray | float | None = None,
    *,
    term_files: Iterable[str | Path] = (),
    catalogue: Mapping[str, Term] | None = None,
    allow_undetermined: bool = False,
) -> tuple[np.ndarray, np.ndarray]:
    """Correct raw samples with a calibration: invert the whole model of ``result``.

    Parameters
    ----------
    result : CalibrationResult
        The calibration (:func:`host.load_result`, :func:`host.calibrate`).
    accel, gyro : array_like
        Raw accelerometer m/s² and gyro °/s, (N, 3) or (3,).
    temp_c, t_s : array_like or float, optional
        Chip temperature °C and time since power-on s, (N,) or scalars: needed only by the
        terms that use them (an :class:`~host.errors.InputError` names the term otherwise).
    term_files : iterable of path-like
        The Python files of the result's custom terms. A result is data: the files it names
        are never run; a file passed here is run only if its SHA-256 is one the result stored
        (else :class:`~host.errors.TermFileMismatch`).
    catalogue : mapping, optional
        Further terms by name (:class:`~host.model.terms.Term`), instead of files.
    allow_undetermined : bool
        Take parameters the records did not determine as nominal (0); by default they raise
        :class:`~host.errors.NotDeterminedError`.

    Returns
    -------
    tuple of ndarray
        (specific force m/s², rate °/s), each of the shape of the inputs.

    Notes
    -----
    Every term is evaluated with its own column function (method.md §2 for the base terms,
    the catalogue's docstrings for the others); the model output = input + Σ terms is
    inverted by fixed-point iteration on (I+M)⁻¹ (exact for the linear model:
    a = (I+Ma)⁻¹(A − A0), ω = (I+Mg)⁻¹(G − G0 − GA·a/g)). A result carrying a thermal
    calibration (term ``thermal_bias``) needs ``temp_c`` and warns
    (:class:`host.calib.thermal.ThermalRangeWarning`) outside the range where it holds.

    Examples
    --------
    >>> result = host.calibrate(directory)
    >>> rec = host.read_session(directory).records["x_up"]
    >>> accel, gyro = host.apply(result, rec.accel, rec.gyro)
    >>> accel.shape == rec.accel.shape, round(float(accel[:, 0].mean()), 1)  # x up: +1 g on x
    (True, 9.8)
    """
    a2, g2, single = _samples(accel, gyro)
    _refuse_undetermined(result, allow_undetermined)
    model = parse_model(result.model, _catalogue_for(result, term_files, catalogue))
    temp, time = _inputs(result, temp_c, t_s, len(a2))
    force, rate = _invert(_Forward(result, model, a2, g2, temp, time), result, a2, g2)
    return (force[0], rate[0]) if single else (force, rate)


def _refuse_undetermined(result: CalibrationResult, allowed: bool) -> None:
    """NotDeterminedError for a result with parameters the records did not determine, unless
    ``allowed`` (they are taken as nominal, 0)."""
    und = [p.name for p in result.undetermined]
    if und and not allowed:
        raise NotDeterminedError(
            f"the result of {result.serial} does not determine {', '.join(und)}; recalibrate "
            "with the records it needs, or pass allow_undetermined=True to take them as 0"
        )


def _inputs(
    result: CalibrationResult,
    temp_c: np.ndarray | float | None,
    t_s: np.ndarray | float | None,
    n: int,
) -> tuple[np.ndarray, np.ndarray]:
    """The chip temperature and the time per sample (stand-ins for those not given), with a
    warning for temperatures outside the carried bias(T)'s range."""
    temp = _optional_input(temp_c, n, "temp_c", "°C")
    time = _optional_input(t_s, n, "t_s", "s")
    if result.thermal_range_c is not None and temp_c is not None:
        _warn_outside_thermal_range(temp, result.thermal_range_c)
    return temp, time


def _samples(accel: np.ndarray, gyro: np.ndarray) -> tuple[np.ndarray, np.ndarray, bool]:
    """The raw samples as (N, 3) float arrays, and whether they came as one sample (3,)."""
    a_raw = np.asarray(accel, dtype=np.float64)
    g_raw = np.asarray(gyro, dtype=np.float64)
    a2, g2 = np.atleast_2d(a_raw), np.atleast_2d(g_raw)
    if a2.shape[1:] != (3,) or g2.shape != a2.shape:
        raise InputError(
            f"apply(): accel {a_raw.shape} and gyro {g_raw.shape} must both be (N,3) or (3,)"
        )
    return a2, g2, a_raw.ndim == 1


def _optional_input(x: np.ndarray | float | None, n: int, what: str, unit: str) -> np.ndarray:
    """An input per sample, or for one not given a stand-in that raises when a term uses it
    (an array to the terms, :class:`_Missing` underneath)."""
    if x is None:
        return cast(np.ndarray, _Missing(what, n))
    return _per_sample(x, n, what, unit)


def _warn_outside_thermal_range(temp: np.ndarray, valid: tuple[float, float]) -> None:
    """:class:`host.calib.thermal.ThermalRangeWarning` for samples outside the chip
    temperatures (°C) where the carried bias(T) holds (attributed to apply()'s caller)."""
    lo, hi = valid
    outside = (temp < lo) | (temp > hi)
    if np.any(outside):
        warnings.warn(
            f"{int(np.count_nonzero(outside))} samples at {float(temp.min()):.1f} to "
            f"{float(temp.max()):.1f} °C lie outside the thermal calibration's range "
            f"{lo:.1f} to {hi:.1f} °C: the bias(T) polynomial is extrapolated there",
            ThermalRangeWarning,
            stacklevel=4,
        )


class _Forward:
    """The model of a result from the true specific force and rate to what the sensor reads:
    input + Σ terms, each with its own column (or value) function and the result's values
    (undetermined ones as 0)."""

    def __init__(
        self,
        result: CalibrationResult,
        model: list[ModelTerm],
        accel: np.ndarray,
        gyro: np.ndarray,
        temp: np.ndarray,
        time: np.ndarray,
    ) -> None:
        self.result, self.model = result, model
        self.accel, self.gyro, self.temp, self.time = accel, gyro, temp, time
        self.theta: dict[tuple[str, str, str], dict[str, float]] = {}
        for p in result.parameters:
            v = p.value if p.determined else 0.0
            self.theta.setdefault((p.term, p.sensor, p.axis), {})[p.key] = v

    def __call__(self, force: np.ndarray, rate: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(accel, gyro) the sensor reads for ``force`` m/s² and ``rate`` °/s, (N, 3) each."""
        r = self.result
        sig = RecordSignals(
            name="apply", kind="apply", t_s=self.time, temp_c=self.temp, force=force,
            rate=rate, accel=self.accel, gyro=self.gyro, g=r.g, up=np.zeros(3),
            temp_mean_c=r.temp_mean_c,
        )  # fmt: skip
        out = {"accel": force.copy(), "gyro": rate.copy()}
        for mt in self.model:
            for ax in mt.axes:
                out[mt.sensor][:, ax] += self._term(mt, ax, sig)
        return out["accel"], out["gyro"]

    def _term(self, mt: ModelTerm, ax: int, sig: RecordSignals) -> np.ndarray:
        """One term's contribution to channel ``ax`` of its sensor, (N,)."""
        n = len(self.accel)
        vals = self.theta.get((mt.term.name, mt.sensor, AXES[ax]), {})
        th = np.array([vals.get(k, 0.0) for k in mt.term.params])
        try:
            if mt.term.value is not None:
                return np.asarray(mt.term.value(sig, mt.sensor, ax, th), dtype=np.float64)
            assert mt.term.columns is not None
            x = np.asarray(mt.term.columns(sig, mt.sensor, ax), dtype=np.float64)
            return (x.reshape(n, -1) @ th) if th.size else np.zeros(n)
        except _MissingInput as exc:
            raise InputError(
                f"term {mt.label} of this result needs {_NEEDS_ARG[exc.what]} to apply()"
            ) from None


def _invert(
    forward: _Forward, result: CalibrationResult, a2: np.ndarray, g2: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The specific force and rate whose readings are ``a2``, ``g2``: fixed-point iteration
    on (I+M)⁻¹ from the linear model's inverse (exact for the linear model)."""
    inv_a = np.linalg.inv(np.eye(3) + np.nan_to_num(result.accel_m()))
    inv_g = np.linalg.inv(np.eye(3) + np.nan_to_num(result.gyro_m()))
    force = (a2 - np.nan_to_num(result.accel_bias())) @ inv_a.T
    rate = np.zeros_like(g2)
    for _ in range(50):
        pa, pg = forward(force, rate)
        da = (a2 - pa) @ inv_a.T
        dg = (g2 - pg) @ inv_g.T
        force, rate = force + da, rate + dg
        if max(float(np.max(np.abs(da), initial=0.0)), float(np.max(np.abs(dg), initial=0.0))) < (
            1e-12 * max(1.0, float(np.max(np.abs(a2), initial=0.0)))
        ):
            break
    return force, rate


# ---- held-out verification ------------------------------------------------------------------
def verify(
    result: CalibrationResult,
    session: Session,
    *,
    source: str = "",
    term_files: Iterable[str | Path] = (),
    catalogue: Mapping[str, Term] | None = None,
) -> Verification:
    """Predict every record of ``session`` (another session, extra attitudes: records the fit
    did not use) with the whole model of ``result`` and its noise model; measured − predicted
    per record and channel (static: record mean; turn: integral), against the accuracy limits
    of method.md §8 (0.01 g, 0.5 °/s; a turn's limit is 0.5 °/s × its duration, in °).
    UserError when the result does not determine a parameter the prediction needs. Custom
    terms: from ``term_files`` or ``catalogue`` only, as in :func:`apply`."""
    und = [p.name for p in result.undetermined]
    if und:
        raise NotDeterminedError(
            f"--verify: the result does not determine {', '.join(und)}: nothing to predict with"
        )
    nm = NoiseModel()
    if result.noise_model:
        known = {f.name for f in dataclasses.fields(NoiseModel)}
        nm = dataclasses.replace(nm, **{k: v for k, v in result.noise_model.items() if k in known})
    model = parse_model(result.model, _catalogue_for(result, term_files, catalogue))
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


def verify_directory(
    result: CalibrationResult,
    directory: str,
    serial: str | None = None,
    term_files: Iterable[str | Path] = (),
) -> CalibrationResult:
    """``result`` with :func:`verify` on the records in ``directory`` attached (custom terms
    from ``term_files``)."""
    session = read_session(directory, serial)
    v = verify(result, session, source=directory, term_files=term_files)
    return dataclasses.replace(result, verification=v)
