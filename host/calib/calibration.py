"""Calibration of the accelerometer and gyro triads from records (method.md §2-§4, §7).

The linear model of method.md §2 in matrix form: :mod:`host.session.method`.

One engine: every number the project reports comes from the workbench's weighted
least-squares fit (:func:`host.model.fit.fit_model`, its noise model) of the chosen
model (default ``base`` = the linear model above) — :func:`calibrate_from_records`. It
accepts other plans: turns without their opposite partner (the bias then comes from the
statics), extra static attitudes (meta ``up``), several turns per axis, rate-table records
(meta ``rate_dps``, ``rate_axis``). The closed form of the method — stage 1 (§3, six
statics) and stage 2 (§4, CW/CCW turn pairs integrated by the trapezoid rule over the
recorded sample times), :func:`stage1`, :func:`stage2` — is computed beside it and printed
as a check.

The method's constants and sign layout (§2, §7), local gravity (§3) and the per-record
quantities are in :mod:`host.session.method`, the record checks in :mod:`host.session.checks`,
the result in :mod:`host.calib.result` and ``apply`` in :mod:`host.calib.applying`.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from host.calib.provenance import provenance_of
from host.calib.result import CalibrationResult, thermal_parameters
from host.calib.thermal import CHANNELS, ThermalCalibration, corrected_records
from host.calib.values import FitQuality, ParameterResult, RecordResidual, within
from host.errors import UserError
from host.model.catalogue import BASE, CATALOGUE
from host.model.components import fit_with_components
from host.model.dataset import Dataset, build_dataset
from host.model.fit import Fit, fit_model
from host.model.loader import load_term_file, term_file_sha256
from host.model.noise import NoiseModel
from host.model.plate import bias_note
from host.model.poses import frame_note
from host.model.spec import ModelTerm, parse_model, short_spec
from host.model.stats import ALPHA_FIT
from host.session.checks import check_record_lengths
from host.session.directory import Session
from host.session.method import (
    ACCEL_BIAS_NAMES,
    ACCEL_NOISE_NAMES,
    DEFAULT_HEIGHT_M,
    DEFAULT_LATITUDE_DEG,
    GYRO_BIAS_NAMES,
    GYRO_NOISE_NAMES,
    TOLERANCES,
    RecordStats,
    gsens_to_names,
    local_gravity,
    matrix_to_names,
    record_stats,
    trapezoid_integral,
)
from host.session.records import STATIC_NAMES, TURN_NAMES, Record
from host.version import __version__


# ---- closed form, method.md §3 and §4 -----------------------------------------------------
@dataclass(frozen=True, eq=False)
class Stage1:
    """Closed-form stage 1 (§3). Matrices are (3×3) with row = channel."""

    accel_m: np.ndarray  # Ma (scale errors on the diagonal, misalignments off it)
    accel_bias_estimates: np.ndarray  # [channel, pair x/y/z], m/s²
    gyro_gsens: np.ndarray  # GA, (°/s)/g
    gyro_bias_estimates: np.ndarray  # [channel, pair], °/s
    accel_noise: np.ndarray  # largest std over the six orientations, m/s²
    gyro_noise: np.ndarray  # °/s

    @property
    def accel_bias(self) -> np.ndarray:
        """Mean of the three estimates, m/s²."""
        return np.asarray(self.accel_bias_estimates.mean(axis=1))

    @property
    def gyro_bias(self) -> np.ndarray:
        """Mean of the three estimates, °/s."""
        return np.asarray(self.gyro_bias_estimates.mean(axis=1))

    def constants(self) -> dict[str, float]:
        """The stage-1 constants under the report's names."""
        out = {k: v for k, v in matrix_to_names("A", self.accel_m).items()}
        out.update(zip(ACCEL_BIAS_NAMES, map(float, self.accel_bias), strict=True))
        out.update(gsens_to_names(self.gyro_gsens))
        out.update(zip(GYRO_BIAS_NAMES, map(float, self.gyro_bias), strict=True))
        out.update(zip(ACCEL_NOISE_NAMES, map(float, self.accel_noise), strict=True))
        out.update(zip(GYRO_NOISE_NAMES, map(float, self.gyro_noise), strict=True))
        return out


def stage1(stats: Mapping[str, RecordStats], g: float) -> Stage1:
    """Method.md §3 closed form from the six statics x_up … z_dn (orientations 1 … 6).

    Column k of (I + Ma) is (A_k,up − A_k,dn)/(2g); the bias estimate from pair k is
    (A_k,up + A_k,dn)/2; GA column k is (G_k,up − G_k,dn)/2 and the gyro bias estimate
    (G_k,up + G_k,dn)/2. Noise = largest std over the six orientations per channel.
    """
    missing = [n for n in STATIC_NAMES if n not in stats]
    if missing:
        raise UserError(f"stage 1 needs the six static records; missing: {', '.join(missing)}")
    a_up = np.column_stack([stats[f"{ax}_up"].accel_mean for ax in "xyz"])  # [channel, k]
    a_dn = np.column_stack([stats[f"{ax}_dn"].accel_mean for ax in "xyz"])
    g_up = np.column_stack([stats[f"{ax}_up"].gyro_mean for ax in "xyz"])
    g_dn = np.column_stack([stats[f"{ax}_dn"].gyro_mean for ax in "xyz"])
    return Stage1(
        accel_m=(a_up - a_dn) / (2.0 * g) - np.eye(3),
        accel_bias_estimates=(a_up + a_dn) / 2.0,
        gyro_gsens=(g_up - g_dn) / 2.0,
        gyro_bias_estimates=(g_up + g_dn) / 2.0,
        accel_noise=np.max([stats[n].accel_std for n in STATIC_NAMES], axis=0),
        gyro_noise=np.max([stats[n].gyro_std for n in STATIC_NAMES], axis=0),
    )


def stage2(stats: Mapping[str, RecordStats], turns: int) -> np.ndarray:
    """Method.md §4 closed form: Mg (3×3) from the six turn integrals, n = ``turns``.

    Column k of (I + Mg) is (I_{K+} − I_{K−})/(720·n): the fixed recording window makes
    bias·T (and g-sensitivity·T) cancel between the CCW and CW turns about the same axis.
    """
    missing = [n for n in TURN_NAMES if n not in stats]
    if missing:
        raise UserError(f"stage 2 needs the six turn records; missing: {', '.join(missing)}")
    cols = [
        (stats[f"{ax}_ccw"].gyro_integral - stats[f"{ax}_cw"].gyro_integral) / (720.0 * turns)
        for ax in "xyz"
    ]
    return np.column_stack(cols) - np.eye(3)


# ---- the whole computation: the one engine ------------------------------------------------
def _synthetic_record(
    name: str, g: float, turns: int, temp_c: float, meta: Mapping[str, str]
) -> Record:
    """An ideal record of the standard plan (statics and turns of method.md §3, §4), used only
    to ask whether adding it would determine a parameter (the values do not matter)."""
    from host.session.records import turn_window_s

    rng = np.random.default_rng(abs(hash(name)) % 2**32)
    up = np.zeros(3)
    up["xyz".index(name[0])] = -1.0 if name.endswith("_dn") else 1.0
    turn = name.endswith(("_ccw", "_cw"))
    seconds = turn_window_s(turns) if turn else 10.0
    t_ms = np.arange(0.0, seconds * 1000.0, 20.0)
    n = len(t_ms)
    gyro = rng.normal(0.0, 0.02, (n, 3))
    if turn:
        sign = 1.0 if name.endswith("_ccw") else -1.0
        profile = 1.0 - np.cos(2 * np.pi * t_ms / t_ms[-1])
        profile *= sign * 360.0 * turns / float(trapezoid_integral(t_ms, profile))
        gyro += profile[:, None] * up[None, :]
    accel = g * up + rng.normal(0.0, 0.01, (n, 3))
    return Record(name, t_ms, accel, gyro, np.full(n, temp_c), dict(meta))


def _missing_records(
    session: Session, g: float, turns: int | None
) -> tuple[dict[str, Record], int]:
    """Synthetic records of the standard plan that ``session`` lacks, by name, made like its
    own (its mean chip temperature, its turns' n, a power-on time after its last record), and
    that n."""
    recs = list(session.records.values())
    temp = float(np.mean([float(np.mean(r.temp)) for r in recs])) if recs else 25.0
    ns = [int(r.meta["turns"]) for r in recs if r.meta.get("turns", "").isdigit()]
    n_turns = turns or (ns[0] if ns else 1)
    meta: dict[str, str] = {}
    if recs and all("power_on_s" in r.meta for r in recs):
        last = max(float(r.meta["power_on_s"]) + r.duration_s for r in recs)
        meta["power_on_s"] = f"{last + 60.0:.3f}"
    missing = [n for n in STATIC_NAMES + TURN_NAMES if n not in session.records]
    return {c: _synthetic_record(c, g, n_turns, temp, meta) for c in missing}, n_turns


def what_would_determine(
    session: Session,
    model: list[ModelTerm],
    names: Iterable[str],
    *,
    latitude_deg: float = DEFAULT_LATITUDE_DEG,
    height_m: float = DEFAULT_HEIGHT_M,
    turns: int | None = None,
    again: Iterable[str] = (),
) -> dict[str, str]:
    """For each parameter in ``names`` that the records of ``session`` do not determine under
    ``model`` (model terms of :mod:`host.model`): which records of the standard plan
    (method.md §3, §4) would determine it — 'add any one of: x_dn, y_dn' or 'add all of:
    x_ccw, x_cw' — else the term's own ``needs`` text. ``again``: turn records in motion at an
    end, each a candidate measured again at rest ("x_ccw again (at rest at both ends)")."""
    wanted = list(names)
    if not wanted:
        return {}
    synth, n_turns = _missing_records(session, local_gravity(latitude_deg, height_m), turns)
    redo = [n for n in again if n in session.records and n not in synth]
    g = local_gravity(latitude_deg, height_m)
    temp = float(np.mean([float(np.mean(r.temp)) for r in session.records.values()]))
    for n in redo:
        synth[n] = _synthetic_record(n, g, n_turns, temp, session.records[n].meta)
    candidates = list(synth)
    label = {c: f"{c} again (at rest at both ends)" if c in redo else c for c in candidates}

    def determined(extra: Iterable[str]) -> set[str]:
        records = dict(session.records)
        records.update({c: synth[c] for c in extra})
        try:
            ds = build_dataset(
                Session(session.serial, records), latitude_deg=latitude_deg, height_m=height_m,
                turns=n_turns,
            )  # fmt: skip
        except UserError:
            return set()
        return set(wanted) - set(fit_model(ds, model).undetermined)

    singles = {c: determined([c]) for c in candidates}
    everything = determined(candidates) if candidates else set()
    needs_of = {
        p: mt.term.needs for mt in model for ax in mt.axes for p in mt.term.param_labels(
            mt.sensor, ax)
    }  # fmt: skip
    out: dict[str, str] = {}
    for name in wanted:
        alone = [c for c in candidates if name in singles[c]]
        if alone:
            out[name] = f"add any one of: {', '.join(label[c] for c in alone)}"
        elif name in everything:
            need = list(candidates)
            for c in candidates:  # greedy: drop what is not needed
                rest = [x for x in need if x != c]
                if rest and name in determined(rest):
                    need = rest
            out[name] = f"add all of: {', '.join(label[c] for c in need)}"
        else:
            out[name] = needs_of.get(name, "") or "records that excite it"
    return out


@dataclass(frozen=True)
class CalibrationOptions:
    """How :func:`calibrate_from_records` calibrates a session: ``model`` the model spec
    (default ``base``, method.md §2) over the catalogue and the custom terms of the Python
    files ``term_files``; ``noise`` the noise model (None: :class:`host.model.noise.NoiseModel`'s
    defaults); ``turns`` n for turn records without meta ``turns`` (None: inferred per record);
    the site (``latitude_deg``, ``height_m``: local gravity); ``earth_rate``: the reference
    rate includes the vertical Earth rate; ``thermal`` the unit's bias(T)
    (:mod:`host.calib.thermal`, from ``thermal_source``); ``created`` the date/time for the
    report header (None: now, local time, ISO)."""

    model: str = "base"
    term_files: Sequence[str] = ()
    noise: NoiseModel | None = None
    turns: int | None = None
    latitude_deg: float = DEFAULT_LATITUDE_DEG
    height_m: float = DEFAULT_HEIGHT_M
    earth_rate: bool = False
    thermal: ThermalCalibration | None = None
    thermal_source: str = ""
    created: str | None = None


def calibrate_from_records(
    session: Session, options: CalibrationOptions | None = None
) -> CalibrationResult:
    """Check the records of ``session``, fit the model of ``options`` (default
    :class:`CalibrationOptions`) with the workbench's weighted least squares
    (:func:`host.model.fit.fit_model`, its noise model), return every parameter.

    The closed form of §3/§4 is computed beside it where the plan has it (``closed_form``).
    Parameters the records do not determine are NaN with what would determine them; they make
    ``all_passed`` False.

    With a ``thermal`` calibration the records are first corrected to the session's mean chip
    temperature T̄ with it, so the model's biases are those at T̄; the result then carries the
    bias change as the term ``thermal_bias`` about T̄ with the range over which it holds
    (``thermal_range_c``).
    """
    o = options if options is not None else CalibrationOptions()
    check_record_lengths(session)
    t_guess = float(np.mean([float(np.mean(r.temp)) for r in session.records.values()]))
    if o.thermal is not None:
        session = _thermally_corrected(session, o.thermal, o.thermal_source, t_guess)
    mts, digests = _model_with_term_files(o.model, tuple(str(f) for f in o.term_files))
    nm = o.noise if o.noise is not None else NoiseModel()
    ds = build_dataset(
        session, noise=nm, latitude_deg=o.latitude_deg, height_m=o.height_m, turns=o.turns,
        earth_rate=o.earth_rate,
    )  # fmt: skip
    # the turn-angle and wobble components estimated jointly with the model: a term that
    # explains the turn closures (an asymmetry) takes their scatter from the yardstick
    joint = fit_with_components(ds, mts)
    fitted = _Fitted(session, mts, digests, nm, joint.fit, joint.dataset, o)
    return _result(fitted, t_guess)


@dataclass(frozen=True, eq=False)
class _Fitted:
    """A session's fit as :func:`calibrate_from_records` made it, and what it was made with."""

    session: Session
    model: list[ModelTerm]
    digests: dict[str, str]  # term file (resolved path) -> SHA-256
    noise: NoiseModel
    fit: Fit
    dataset: Dataset
    options: CalibrationOptions


def _result(f: _Fitted, t_corrected: float) -> CalibrationResult:
    """The result of a fit: its parameters with what would determine the others, the closed
    form beside it, residuals, notes and where the records came from; the bias(T) the
    records were corrected with (to ``t_corrected``, °C) carried as ``thermal_bias``."""
    from datetime import datetime

    session, fit, ds, nm, o = f.session, f.fit, f.dataset, f.noise, f.options
    thermal, thermal_source = o.thermal, o.thermal_source
    stats = {n: record_stats(r) for n, r in session.records.items()}
    g = local_gravity(o.latitude_deg, o.height_m)
    closed, bias_est, n_turns = _closed_form(session, stats, g, ds)
    params, spec = _parameters(f), short_spec(f.model)
    t_mean = float(ds.signals[0].temp_mean_c) if ds.signals else 25.0
    if thermal is not None:
        params, spec = _with_thermal(params, spec, thermal, t_corrected, t_mean)
    th_note = None if thermal is None else _thermal_note(session, thermal, thermal_source)
    notes = _notes(session, ds, fit, f.model, th_note)
    prov = provenance_of(session, software=f"imu-bench {__version__}")
    if prov.simulated:  # never let a virtual board pass for a unit (first note, as in v2 files)
        notes.insert(0, prov.simulated_line)
    metas = [rec.meta for rec in session.records.values()]
    return CalibrationResult(
        covariance=_covariance(fit.covariance, params),
        serial=session.serial,
        created=o.created or datetime.now().astimezone().isoformat(timespec="seconds"),
        g=g, latitude_deg=o.latitude_deg, height_m=o.height_m, turns=n_turns,
        model=spec,
        parameters=params,
        noise_std=_noise_levels(stats, ds),
        fit=_fit_quality(fit),
        noise_model={"block_s": nm.block_s, "max_blocks": nm.max_blocks,
                     "floor": dict(ds.floor), "turn_angle_sigma_deg": nm.turn_angle_sigma_deg},
        term_files=tuple(f.digests),
        term_sha256=f.digests,
        temp_mean_c=t_mean,
        time_known=ds.time_known,
        earth_rate=o.earth_rate,
        records=tuple(s.name for s in ds.signals),
        bias_estimates=bias_est,
        closed_form=closed,
        combinations=tuple(c.describe() for ch in fit.channels for c in ch.combinations),
        residuals=_residuals(ds, fit, stats),
        notes=tuple(notes),
        thermal_range_c=None if thermal is None else (thermal.t_min_c, thermal.t_max_c),
        thermal_source=thermal_source,
        provenance=prov,
        self_test=next((m["self_test"] for m in metas if m.get("self_test")), ""),
    )  # fmt: skip


def _thermally_corrected(
    session: Session, thermal: ThermalCalibration, source: str, t_c: float
) -> Session:
    """The records of ``session`` corrected to ``t_c`` (°C) with the unit's bias(T); a thermal
    calibration of another serial is refused."""
    if thermal.serial and session.serial and thermal.serial != session.serial:
        raise UserError(
            f"{source or 'the thermal calibration'} is of serial {thermal.serial}, "
            f"the records of {session.serial}: give the unit's own SERIAL_thermal.json"
        )
    return dataclasses.replace(session, records=corrected_records(session.records, thermal, t_c))


def _model_with_term_files(
    model: str, files: tuple[str, ...]
) -> tuple[list[ModelTerm], dict[str, str]]:
    """The model spec parsed over the catalogue and the users' term files, and each file's
    SHA-256 by its resolved path (the bytes hashed are the bytes run)."""
    digests = {str(Path(f).resolve()): term_file_sha256(f) for f in files}
    cat = dict(CATALOGUE)
    for f in files:
        cat = load_term_file(f, cat, sha256=(digests[str(Path(f).resolve())],))
    return parse_model(model, cat), digests


def _noise_levels(stats: Mapping[str, RecordStats], ds: Dataset) -> dict[str, float]:
    """§3 noise: the largest sample std over the static records, per channel (Gstd…, Astd…)."""
    statics = [s.name for s in ds.signals if s.kind in ("static", "pose")]
    anoise = np.max([stats[n].accel_std for n in statics], axis=0)
    gnoise = np.max([stats[n].gyro_std for n in statics], axis=0)
    out = dict(zip(GYRO_NOISE_NAMES, map(float, gnoise), strict=True))
    out.update(zip(ACCEL_NOISE_NAMES, map(float, anoise), strict=True))
    return out


def _parameters(f: _Fitted) -> tuple[ParameterResult, ...]:
    """The fit's parameters with their §7 tolerance and pass flag, and what would determine
    the undetermined ones (:func:`what_would_determine`)."""
    needs = what_would_determine(
        f.session, f.model, f.fit.undetermined, latitude_deg=f.options.latitude_deg,
        height_m=f.options.height_m, turns=f.options.turns,
        again=[s.name for s in f.dataset.signals if s.angle_column is not None],
    )  # fmt: skip
    return tuple(
        ParameterResult(
            p.term_name,
            p.sensor,
            p.axis,
            p.key,
            p.name,
            p.value,
            p.stderr,
            p.unit,
            TOLERANCES.get(p.name),
            within(p.name, p.value),
            needs.get(p.name, ""),
            p.dof,
        )  # fmt: skip
        for p in f.fit.parameters
    )


def _closed_form(
    session: Session, stats: Mapping[str, RecordStats], g: float, ds: Dataset
) -> tuple[dict[str, float], dict[str, tuple[float, float, float]], int | None]:
    """The closed form where the plan has it (the check printed beside the fit): §3's values
    and bias estimates from the six faces, §4's gyro matrix from the six turns (none of them
    in motion at an end: its angle is not 360°·n); and the turns' n (None: none, or mixed)."""
    closed: dict[str, float] = {}
    bias_est: dict[str, tuple[float, float, float]] = {}
    if all(n in stats and session.records[n].kind == "static" for n in STATIC_NAMES):
        s1 = stage1(stats, g)
        closed.update(s1.constants())
        for i in range(3):
            a, b, c = (float(x) for x in s1.accel_bias_estimates[i])
            bias_est[ACCEL_BIAS_NAMES[i]] = (a, b, c)
            a, b, c = (float(x) for x in s1.gyro_bias_estimates[i])
            bias_est[GYRO_BIAS_NAMES[i]] = (a, b, c)
    ns = set(ds.turns_of.values())
    n_turns = next(iter(ns)) if len(ns) == 1 else None
    at_rest = not any(sig.angle_column is not None for sig in ds.signals)
    if all(n in ds.turns_of for n in TURN_NAMES) and n_turns is not None and at_rest:
        closed.update(matrix_to_names("G", stage2(stats, n_turns)))
    return closed, bias_est, n_turns


def _t3(v: Iterable[float]) -> tuple[float, float, float]:
    a, b, c = (float(x) for x in v)
    return (a, b, c)


def _residuals(
    ds: Dataset, fit: Fit, stats: Mapping[str, RecordStats]
) -> tuple[RecordResidual, ...]:
    """Residuals per record, from the fit's record/channel values: a static's or rate's mean
    (and its samples' std), a turn's integral residual (and as °/s over its duration)."""
    by = {(gr.record, gr.sensor, gr.axis): gr.residual for gr in fit.groups}
    nan3 = (math.nan, math.nan, math.nan)
    out: list[RecordResidual] = []
    for sig in ds.signals:
        st = stats[sig.name]
        gr = _t3(by.get((sig.name, "gyro", ax), math.nan) for ax in "xyz")
        if sig.kind in ("turn", "move"):
            out.append(RecordResidual(
                sig.name, sig.kind, st.n, st.duration_s, nan3, nan3,
                _t3(x / st.duration_s for x in gr), nan3, gr,
            ))  # fmt: skip
            continue
        ar = _t3(by.get((sig.name, "accel", ax), math.nan) for ax in "xyz")
        out.append(RecordResidual(
            sig.name, sig.kind, st.n, st.duration_s, ar, _t3(st.accel_std), gr,
            _t3(st.gyro_std),
        ))  # fmt: skip
    return tuple(out)


def _notes(
    session: Session, ds: Dataset, fit: Fit, mts: list[ModelTerm], thermal: str | None
) -> list[str]:
    """The result's notes, in the report's order: the dataset's (the power-on-time note only
    for a model with time terms), the bias(T) used (``thermal``), records kept despite a
    warning, mixed turn counts, the uncertainty policy, the plate's tilt, what is not
    determined."""
    # the power-on-time note matters only to time terms, which base does not have
    only_base = all(mt.term.name in BASE for mt in mts)
    notes = [n for n in ds.notes if not (only_base and "power_on_s" in n)]
    if thermal is not None:
        notes.append(thermal)
    for name, rec in session.records.items():  # kept by the operator despite a warning
        if rec.meta.get("warning"):
            notes.append(f"{name} kept despite a warning: {rec.meta['warning']}")
    ns = set(ds.turns_of.values())
    if len(ns) > 1:
        notes.append(f"turn records with different numbers of turns: {sorted(ns)}")
    if fit.uncertainty_note():
        notes.append(fit.uncertainty_note())
    tilt = bias_note(ds.signals, {p.name: p.stderr for p in fit.parameters}, ds.g)
    if tilt:
        notes.append(tilt)
    if any(s.pose_frame for s in ds.signals):
        notes.append(frame_note())
    if fit.undetermined:
        notes.append(
            f"not determined by these records: {', '.join(fit.undetermined)} (nothing is fixed "
            "at zero; see what would determine each)"
        )
    return notes


def _fit_quality(fit: Fit) -> FitQuality:
    """The result's fit quality: inadequate when the standard errors were widened or p is
    below :data:`host.model.stats.ALPHA_FIT`, untestable when a channel has no dof."""
    verdict = (
        "inadequate"
        if fit.scaled or fit.chi2_p < ALPHA_FIT
        else ("untestable" if fit.untestable else "adequate")
    )
    return FitQuality(
        fit.chi2, fit.dof, fit.rms_z, fit.chi2_p, verdict, fit.untestable, fit.uncertainty_note()
    )


def _covariance(
    fit_cov: np.ndarray | None, params: tuple[ParameterResult, ...]
) -> tuple[tuple[float, ...], ...]:
    """The result's covariance: the fit's over its parameters (the first ones), the carried
    bias(T) terms after them with their own variances (another fit: no cross terms), NaN
    for what is not determined."""
    n = len(params)
    out = np.diag([p.stderr**2 for p in params]).astype(np.float64)
    if fit_cov is not None:
        k = min(len(fit_cov), n)
        out[:k, :k] = fit_cov[:k, :k]
    bad = np.array([not math.isfinite(p.stderr) for p in params], dtype=bool)
    out[bad, :] = np.nan
    out[:, bad] = np.nan
    return tuple(tuple(float(x) for x in row) for row in out)


def _with_thermal(
    params: tuple[ParameterResult, ...],
    spec: str,
    thermal: ThermalCalibration,
    t_corrected: float,
    t_mean: float,
) -> tuple[tuple[ParameterResult, ...], str]:
    """The fitted parameters plus bias(T) as ``thermal_bias`` about ``t_mean`` (°C). The
    records were corrected to ``t_corrected``: were the fit's mean temperature another (a
    record left out), the biases move by the bias change between the two."""
    if t_corrected != t_mean:
        shift = {}
        for j, name in enumerate(CHANNELS):
            ch = thermal.channels[name]
            d = ch.delta(np.array([t_mean, t_corrected]), thermal.t_ref_c)
            shift[("accel" if j < 3 else "gyro", "xyz"[j % 3])] = float(d[0] - d[1])
        params = tuple(
            dataclasses.replace(p, value=p.value + shift[(p.sensor, p.axis)])
            if p.term == "bias"
            else p
            for p in params
        )
    carried = thermal_parameters(thermal, t_mean)
    terms = [t for t in ("thermal_bias", "thermal_scale") if any(p.term == t for p in carried)]
    return params + carried, ",".join([spec, *terms])


def _thermal_note(session: Session, thermal: ThermalCalibration, source: str) -> str:
    """The report's line on the bias(T) used, and records outside its range."""
    orders = ", ".join(
        f"{n} {ch.order}" + (f" (scale {ch.scale_order})" if ch.scale_order else "")
        for n, ch in thermal.channels.items()
    )
    note = (
        f"bias(T) from {source or 'a thermal calibration'} (orders {orders}; valid "
        f"{thermal.t_min_c:.1f} to {thermal.t_max_c:.1f} °C) removed from the records "
        "before the fit, carried as thermal_bias"
    )
    temps = np.concatenate([r.temp for r in session.records.values()])
    lo, hi = float(temps.min()), float(temps.max())
    if lo < thermal.t_min_c or hi > thermal.t_max_c:
        note += (
            f"; the records ({lo:.1f} to {hi:.1f} °C) reach outside that range, where it is "
            "extrapolated"
        )
    return note
