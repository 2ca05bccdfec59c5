"""The fit (:func:`fit_model`) is ONE weighted linear least-squares problem over every record of a
:class:`~host.model.dataset.Dataset`:

* static (and rate-table) records are cut into blocks of ``NoiseModel.block_s`` seconds; each
  block mean of each channel is a row, so temperature and time terms see within-record variation
  as well as the differences between records;
* each turn record gives one row per gyro channel, the trapezoid integral (method.md §4), in °;
* accelerometer rows of a turn record: one per still moment (gravity at another heading) and, on
  the horizontal channels, one per moving block (:mod:`host.model.turning`: the lever arm's
  centripetal and tangential acceleration, with the hand's scatter measured from the blocks).

The rows are whitened exactly (record mean + orthonormal within-record contrasts,
:mod:`host.model.noise`); χ² is then honest under the null and needs no inflation. Terms
nonlinear in their parameters are linearised around the current estimate and the fit iterated
(Gauss-Newton). The results: :class:`Fit` with its :class:`Parameter` values, per-channel
statistics (:class:`ChannelFit`) and residual tables (:func:`residual_tables`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from host.model.dataset import Dataset, build_dataset
from host.model.design import BuiltColumns, design
from host.model.noise import NoiseModel
from host.model.poses import FRAME_FIXED
from host.model.signals import AXES, SENSORS, UNIT
from host.model.solve import solve
from host.model.spec import ModelTerm
from host.model.stats import ALPHA_FIT, chi2_sf, right_singular, rref, stderr_scale
from host.model.whitening import Group, group_means
from host.session.directory import Session
from host.session.method import DEFAULT_HEIGHT_M, DEFAULT_LATITUDE_DEG


# ---- the fit --------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class Parameter:
    """One fitted parameter: §2-style ``name``, owning model-term label, value, 1-σ std error
    (NaN value: the records do not determine it), unit; ``sensor``, ``axis`` (x/y/z, the output
    channel) and ``key`` (the term's own parameter name, e.g. ``per_C``)."""

    name: str
    term: str
    value: float
    stderr: float
    unit: str
    sensor: str = ""
    axis: str = ""
    key: str = ""

    @property
    def term_name(self) -> str:
        """The catalogue name of the owning term ('temperature_bias')."""
        return self.term.split(":")[0]


@dataclass(frozen=True, eq=False)
class Combination:
    """A combination of undetermined parameters that the records DO determine:
    Σ coefficient·parameter = value ± stderr (unit of the first parameter)."""

    terms: tuple[tuple[float, str], ...]  # (coefficient, parameter name)
    value: float
    stderr: float
    unit: str

    def describe(self) -> str:
        """'A0x + 9.815·Axx = 0.6021 ± 0.0003 m/s²'."""
        parts: list[str] = []
        for i, (c, n) in enumerate(self.terms):
            sign = "−" if c < 0 else "+"
            mag = abs(c)
            coef = "" if abs(mag - 1.0) < 1e-9 else f"{mag:.4g}·"
            parts.append((("−" if c < 0 else "") if i == 0 else f" {sign} ") + coef + n)
        return f"{''.join(parts)} = {self.value:.6g} ± {self.stderr:.2g} {self.unit}".strip()


@dataclass(frozen=True, eq=False)
class ChannelFit:
    """Fit statistics of one output channel (the channels are independent problems).

    ``dof`` = rows − determined parameters; ``dof_records`` = record/channel values −
    parameters (the between-record test: 0 means the model is not tested at all, verdict
    ``untestable``); ``se_scale``: :func:`stderr_scale`; ``combinations``: what the records
    determine of the undetermined parameters."""

    sensor: str
    axis: str
    chi2: float
    dof: int
    dof_records: int
    se_scale: float
    combinations: tuple[Combination, ...] = ()

    @property
    def channel(self) -> str:
        return f"{self.sensor} {self.axis}"

    @property
    def testable(self) -> bool:
        return self.dof_records > 0


@dataclass(frozen=True, eq=False)
class GroupResidual:
    """Measured vs model for one record and channel (mean over the record, or turn integral).

    ``measured``/``model``/``residual`` in the channel's unit (°/s, m/s²) or ° for turn
    integrals; ``sigma`` the standard error of the measurement; ``z`` = residual / its own
    standard deviation under the model (:func:`residual_sigmas`: the measurement's σ less what
    the fit absorbed), so that z is N(0, 1) when the model is right; NaN when the model fits
    this value exactly (a parameter of its own: nothing is left to test)."""

    record: str
    kind: str
    sensor: str
    axis: str
    measured: float
    model: float
    residual: float
    sigma: float
    z: float
    unit: str

    @property
    def channel(self) -> str:
        return f"{self.sensor} {self.axis}"


@dataclass(frozen=True, eq=False)
class SpanResidual:
    """A block of a static record that departs from its own record's mean residual."""

    record: str
    sensor: str
    axis: str
    t0_s: float
    t1_s: float
    residual: float
    z: float
    unit: str


@dataclass(frozen=True, eq=False)
class Fit:
    """Result of :func:`fit_model` (see :class:`Dataset` for the rows)."""

    model: tuple[ModelTerm, ...]
    parameters: tuple[Parameter, ...]
    predicted: np.ndarray  # (n_rows,)
    residual: np.ndarray  # (n_rows,)
    white_residual: np.ndarray  # W·residual
    basis: np.ndarray  # orthonormal basis of the whitened determined columns
    chi2: float
    dof: int
    n_params: int
    groups: tuple[GroupResidual, ...]
    spans: tuple[SpanResidual, ...]
    undetermined: tuple[str, ...]
    channels: tuple[ChannelFit, ...] = ()
    #: the parameters' covariance (order of ``parameters``, the standard errors' scaling
    #: applied, so its diagonal is stderr²); NaN rows and columns for undetermined ones
    covariance: np.ndarray | None = None

    @property
    def untestable(self) -> tuple[str, ...]:
        """Channels whose record values leave no degrees of freedom ('accel x', …)."""
        return tuple(c.channel for c in self.channels if not c.testable)

    @property
    def scaled(self) -> tuple[ChannelFit, ...]:
        """Channels whose standard errors were scaled (:func:`stderr_scale`)."""
        return tuple(c for c in self.channels if c.se_scale != 1.0)

    def uncertainty_note(self) -> str:
        """The one sentence saying how the standard errors were treated ('' if unscaled)."""
        if not self.scaled:
            return ""
        parts = ", ".join(f"{c.channel} ×{c.se_scale:.2g}" for c in self.scaled)
        return (
            f"poor fit (χ² p < {ALPHA_FIT:g}): standard errors scaled by √(χ²/dof) on {parts}; "
            "the model does not explain these channels"
        )

    @property
    def rms_z(self) -> float:
        """RMS of the record/channel z values (the compare table; values the model fits
        exactly are left out): ≈ 1 when the model explains the data to the noise."""
        z = np.array([g.z for g in self.groups if math.isfinite(g.z)])
        return float(np.sqrt(np.mean(z**2))) if len(z) else float("nan")

    @property
    def chi2_p(self) -> float:
        """P(χ² this large | the model and the noise model are right)."""
        return chi2_sf(self.chi2, self.dof)

    @property
    def bic(self) -> float:
        """χ² + p·ln(n) (known noise variance)."""
        return self.chi2 + self.n_params * math.log(max(len(self.residual), 2))

    def parameter(self, name: str) -> Parameter:
        for p in self.parameters:
            if p.name == name:
                return p
        raise KeyError(name)


def fit_model(
    ds: Dataset, model: Sequence[ModelTerm], max_iter: int = 20, built: BuiltColumns | None = None
) -> Fit:
    """Weighted least squares of ``model`` over all rows of ``ds`` (one problem, all channels).

    Parameters the records cannot determine are reported NaN (and listed in ``undetermined``).
    Nonlinear terms: Gauss-Newton iterations until the parameters settle. ``built``: the
    columns already built on these rows (:class:`~host.model.design.BuiltColumns`).
    """
    model = tuple(model)
    sol = solve(ds, model, max_iter, built, covariance=True)
    x, xw, keep, basis, theta, cov = sol.x, sol.xw, sol.keep, sol.basis, sol.theta, sol.cov
    th0 = np.nan_to_num(theta)
    predicted, resid, wres, chi2 = sol.predicted, sol.resid, sol.wres, sol.chi2
    n_par = int(keep.sum())
    # who owns each column: (name, unit, channel, term label, sensor, axis, key)
    # (axis -1: a shared parameter of all the sensor's channels)
    owners: list[tuple[str, str, tuple[str, int], str, str]] = []
    for mt in model:
        for ax, name, key in mt.slots(ds.signals):
            ch = (mt.sensor, -1 if ax is None else ax)
            owners.append((name, mt.unit(key), ch, mt.label, key))
    channels, estimable = _channel_fits(ds, x, xw, wres, th0, cov, owners)
    if any(mt.term.twin_columns is not None for mt in model):
        # a term read by both sensors couples their channels: what all rows determine
        estimable = _estimable(xw)
    scale_of = {(c.sensor, AXES.index(c.axis)): c.se_scale for c in channels}
    for chf in channels:  # a shared parameter: the largest scale of its sensor's channels
        scale_of[(chf.sensor, -1)] = max(scale_of.get((chf.sensor, -1), 1.0), chf.se_scale)
    params: list[Parameter] = []
    undetermined: list[str] = []
    fixed = _by_convention(ds)
    for c, (name, unit, ch, label, key) in enumerate(owners):
        ok = bool(keep[c] and estimable[c]) or name in fixed
        se = math.sqrt(max(float(cov[c, c]), 0.0)) * scale_of.get(ch, 1.0) if ok else math.nan
        value = (0.0 if name in fixed else float(theta[c])) if ok else math.nan
        params.append(
            Parameter(name, label, value, 0.0 if name in fixed else se, unit, ch[0],
                      AXES[ch[1]] if ch[1] >= 0 else "", key)
        )  # fmt: skip
        if not ok:
            undetermined.append(name)
    groups, spans_out = residual_tables(ds, predicted, resid, basis)
    scale = np.array([scale_of.get(ch, 1.0) for (_, _, ch, _, _) in owners])
    pcov = cov * np.outer(scale, scale)
    bad = ~(keep & estimable)
    pcov[bad, :] = np.nan
    pcov[:, bad] = np.nan
    conv = np.array([o[0] in fixed for o in owners], dtype=bool)
    pcov[conv, :] = 0.0
    pcov[:, conv] = 0.0
    return Fit(
        model=model, parameters=tuple(params), predicted=predicted, residual=resid,
        white_residual=wres, basis=basis, chi2=chi2, dof=ds.n_rows - n_par - _free(ds.groups),
        n_params=n_par,
        groups=groups, spans=spans_out, undetermined=tuple(undetermined),
        channels=tuple(channels), covariance=pcov,
    )  # fmt: skip


def _by_convention(ds: Dataset) -> set[str]:
    """The parameters fixed at 0 by the frame's convention: without a record of a set attitude
    (poses only), :data:`host.model.poses.FRAME_FIXED`; else none."""
    return set(FRAME_FIXED) if any(s.pose_frame for s in ds.signals) else set()


def residual_sigmas(ds: Dataset, basis: np.ndarray) -> np.ndarray:
    """Standard deviation of each group's mean residual (ds.groups order) when the model is
    right: the measurement's σ less what the fit absorbed. Cov(r) = W⁻¹(I − QQᵀ)W⁻ᵀ with Q the
    orthonormal basis of the whitened design, so var(aᵀr) = ‖W⁻ᵀa‖² − ‖QᵀW⁻ᵀa‖²; 0 where the
    model has a parameter for that value alone (it is fitted exactly), and where the group's
    level is an unknown of its own (:attr:`~host.model.whitening.Group.free_level`). W⁻ᵀa lies
    on the group's own rows: each sum runs over them (memory linear in the rows)."""
    v = ds.group_means_whitened
    g = ds.row_group
    var = np.bincount(g, weights=v * v, minlength=len(ds.groups))
    if basis.shape[1]:
        qv = np.zeros((len(ds.groups), basis.shape[1]))
        np.add.at(qv, g, basis * v[:, None])
        var = var - np.sum(qv**2, axis=1)
    var[[k for k, gr in enumerate(ds.groups) if gr.free_level]] = 0.0
    return np.sqrt(np.maximum(var, 0.0))


def _channel_fits(
    ds: Dataset,
    x: np.ndarray,
    xw: np.ndarray,
    wres: np.ndarray,
    theta: np.ndarray,
    cov: np.ndarray,
    owners: Sequence[tuple[str, str, tuple[str, int], str, str]],
) -> tuple[list[ChannelFit], np.ndarray]:
    """Per output channel: χ², dof, record-level dof, the standard-error scale, which columns
    the records determine individually (a parameter is determined when its unit vector lies in
    the row space of the channel's design) and the combinations they do determine."""
    estimable = np.zeros(len(owners), dtype=bool)
    out: list[ChannelFit] = []
    joint = _pose_record_dof(ds, x, owners)  # with poses: over a sensor's channels together
    for s_i, sensor in enumerate(SENSORS):
        for ax in range(3):
            rows = np.flatnonzero((ds.row_sensor == s_i) & (ds.row_axis == ax))
            grs = [g for g in ds.groups if g.sensor == sensor and g.axis == ax]
            if not len(rows):
                continue
            cols = np.array(
                [c for c, o in enumerate(owners) if o[2] in ((sensor, ax), (sensor, -1))],
                dtype=int,
            )
            xc = xw[np.ix_(rows, cols)] if len(cols) else np.zeros((len(rows), 0))
            norms = np.linalg.norm(xc, axis=0)
            live = norms > 0
            rank, null = 0, np.zeros((len(cols), 0))
            if live.any():
                xn = xc[:, live] / norms[live]
                sv, vt = right_singular(xn)
                rank = int(np.sum(sv > 1e-9 * sv[0])) if len(sv) else 0
                null = np.zeros((len(cols), vt.shape[0] - rank))
                null[live] = vt[rank:].T / norms[live, None]  # back to parameter units
            for j, c in enumerate(cols):
                estimable[c] = (
                    estimable[c]
                    or bool(live[j])
                    and (null.shape[1] == 0 or float(np.linalg.norm(null[j] * norms[j])) < 1e-6)
                )
            # record-level design: one row per record/channel value (mean of its rows; not a
            # free level's, which is a value of its own)
            tested = [g for g in grs if not g.free_level]
            rank_g = _record_rank(x, tested, cols)
            chi2 = float(wres[rows] @ wres[rows])
            dof = len(rows) - rank - _free(grs)
            scale = stderr_scale(chi2, dof)
            combos = (
                _combinations(cols, estimable, null, norms, theta, cov * scale**2, owners)
                if null.shape[1]
                else ()
            )
            dof_g = joint.get(sensor, len(tested) - rank_g)
            out.append(ChannelFit(sensor, AXES[ax], chi2, dof, dof_g, scale, combos))
    if any(o[2][1] < 0 for o in owners):
        # shared parameters couple the channels: what all rows together determine
        estimable = _estimable(xw)
    return out, estimable


def _pose_record_dof(
    ds: Dataset, x: np.ndarray, owners: Sequence[tuple[str, str, tuple[str, int], str, str]]
) -> dict[str, int]:
    """sensor -> its record-level dof counted over its three channels together, in a session
    with poses: a pose's attitude (two unknowns shared by the accelerometer's channels) is
    tested by the three values it explains, which no channel alone shows. {} without poses."""
    if not any(sig.kind == "pose" for sig in ds.signals):
        return {}
    out: dict[str, int] = {}
    for sensor in SENSORS:
        tested = [g for g in ds.groups if g.sensor == sensor and not g.free_level]
        cols = np.array([c for c, o in enumerate(owners) if o[2][0] == sensor], dtype=int)
        if tested and len(cols):
            out[sensor] = len(tested) - _record_rank(x, tested, cols)
    return out


def _record_rank(x: np.ndarray, tested: Sequence[Group], cols: np.ndarray) -> int:
    """The rank of the record-level design: one row per record/channel value of ``tested``
    (the mean of its rows of the design ``x``), on the columns ``cols``."""
    if not len(cols) or not tested:
        return 0
    xg = np.array([x[np.ix_(g.rows, cols)].mean(axis=0) for g in tested])
    gn = np.linalg.norm(xg, axis=0)
    return int(np.linalg.matrix_rank(xg[:, gn > 0] / gn[gn > 0], tol=1e-9))


def _free(groups: Sequence[Group]) -> int:
    """How many of ``groups`` have a level of their own (each takes one degree of freedom as
    a parameter would: its rows' mean is weighed out,
    :data:`host.model.whitening.FREE_LEVEL_RAD`)."""
    return sum(gr.free_level for gr in groups)


def _estimable(xw: np.ndarray) -> np.ndarray:
    """(P,) which columns of the whitened design ``xw`` (n, P) the rows determine: the
    parameter's unit vector lies in the row space (it has no part in the null space)."""
    norms = np.linalg.norm(xw, axis=0)
    live = norms > 0
    out = np.zeros(xw.shape[1], dtype=bool)
    if not live.any():
        return out
    sv, vt = right_singular(xw[:, live] / norms[live])
    rank = int(np.sum(sv > 1e-9 * sv[0])) if len(sv) else 0
    null = vt[rank:].T
    idx = np.flatnonzero(live)
    for j, c in enumerate(idx):
        out[c] = null.shape[1] == 0 or float(np.linalg.norm(null[j])) < 1e-6
    return out


def _combinations(
    cols: np.ndarray,
    estimable: np.ndarray,
    null: np.ndarray,
    norms: np.ndarray,
    theta: np.ndarray,
    cov: np.ndarray,
    owners: Sequence[tuple[str, str, tuple[str, int], str, str]],
) -> tuple[Combination, ...]:
    """Combinations c·θ of the undetermined parameters of one channel that the records
    determine: c supported on them with cᵀ·N = 0 (N the null space of the design)."""
    und = [j for j, c in enumerate(cols) if not estimable[c] and norms[j] > 0]
    if not und:
        return ()
    # in normalised coordinates (columns of unit norm) for a well-scaled null space
    ns = null[und] * norms[und, None]
    _, sv, vt = np.linalg.svd(ns.T, full_matrices=True)
    r = int(np.sum(sv > 1e-9 * max(float(sv[0]), 1e-300))) if len(sv) else 0
    basis = vt[r:]
    if not len(basis):
        return ()
    out: list[Combination] = []
    for row in rref(basis * norms[und][None, :]):
        coef = row / row[np.flatnonzero(np.abs(row) > 1e-12)[0]]
        idx = [cols[und[k]] for k in range(len(und))]
        terms = tuple((float(coef[k]), owners[idx[k]][0]) for k in range(len(und))
                      if abs(coef[k]) > 1e-9)  # fmt: skip
        full = np.zeros(len(theta))
        for k in range(len(und)):
            full[idx[k]] = coef[k]
        value = float(full @ theta)
        se = math.sqrt(max(float(full @ cov @ full), 0.0))
        unit = owners[idx[next(k for k in range(len(und)) if abs(coef[k]) > 1e-9)]][1]
        out.append(Combination(terms, value, se, unit))
    return tuple(out)


def residual_tables(
    ds: Dataset, predicted: np.ndarray, resid: np.ndarray, basis: np.ndarray
) -> tuple[tuple[GroupResidual, ...], tuple[SpanResidual, ...]]:
    """Measured vs model per record and channel, and per block of a static record: from the
    rows' ``predicted`` values and residuals ``resid`` (n_rows,), with ``basis`` the
    orthonormal basis of the whitened design that was fitted to these rows (n_rows, r; r = 0
    for rows the model was not fitted to: z against the measurement's σ alone)."""
    out: list[GroupResidual] = []
    spans: list[SpanResidual] = []
    sd_res = residual_sigmas(ds, basis).tolist()
    # each group's mean residual, measured and model value, the groups of one length at once
    means = np.column_stack([group_means(v, ds.groups_by_size) for v in (resid, ds.y, predicted)])
    for k, gr in enumerate(ds.groups):
        sig = ds.signals[gr.record]
        turn = sig.kind == "turn" and gr.sensor == "gyro"  # an integral, °
        unit = "°" if turn else UNIT[gr.sensor]
        r, measured, model = means[k].tolist()
        sd = sd_res[k]
        out.append(
            GroupResidual(
                record=sig.name, kind=sig.kind, sensor=gr.sensor, axis=AXES[gr.axis],
                measured=measured, model=model, residual=r, sigma=gr.sigma,
                z=r / sd if sd > 1e-3 * gr.sigma else math.nan, unit=unit,
            )
        )  # fmt: skip
        b = len(gr.rows)
        if b >= 2 and math.isfinite(gr.contrast_var):
            sd = math.sqrt(gr.contrast_var * (1.0 - 1.0 / b))
            for res, (t0, t1) in zip(resid[gr.rows].tolist(), ds.span[gr.rows].tolist(),
                                     strict=True):  # fmt: skip
                d = res - r
                spans.append(SpanResidual(sig.name, gr.sensor, AXES[gr.axis], t0, t1, d, d / sd,
                                          unit))  # fmt: skip
    return tuple(out), tuple(spans)


#: a parameter's value by (term name, sensor, axis 'x'/'y'/'z' or '' for a shared parameter,
#: the term's own parameter key), as :class:`Parameter` names them
Values = Mapping[tuple[str, str, str, str], float]


def predict(
    ds: Dataset, model: Sequence[ModelTerm], values: Values, built: BuiltColumns | None = None
) -> np.ndarray:
    """(n_rows,) the rows of ``ds`` as ``model`` predicts them with the parameter ``values``
    (nothing fitted; a parameter not given is 0): the ideal sensor's value plus every term's
    contribution, in the rows' units (``built``: the columns already built on these rows)."""
    per_term: list[np.ndarray] = []
    for mt in model:
        per_term.append(np.array([
            values.get((mt.term.name, mt.sensor, "" if ax is None else AXES[ax], key), 0.0)
            for ax, _, key in mt.slots(ds.signals)
        ]))  # fmt: skip
    thetas: list[np.ndarray | None] = [
        th if mt.term.nonlinear else None for mt, th in zip(model, per_term, strict=True)
    ]
    x, offset, _ = design(ds, model, thetas, built)
    theta = np.concatenate(per_term) if per_term else np.zeros(0)
    return np.asarray(ds.nominal + offset + x @ theta)


@dataclass(frozen=True, eq=False)
class Predicted:
    """Records predicted by a model with given parameter values, none fitted to them
    (:func:`predict_session`): ``dataset`` their rows, ``predicted`` (n_rows,) the model's
    values, ``groups`` measured vs predicted per record and channel (z against the
    measurement's σ alone)."""

    dataset: Dataset
    predicted: np.ndarray
    groups: tuple[GroupResidual, ...]


def predict_session(
    session: Session,
    model: Sequence[ModelTerm],
    values: Values,
    *,
    noise: NoiseModel | None = None,
    latitude_deg: float = DEFAULT_LATITUDE_DEG,
    height_m: float = DEFAULT_HEIGHT_M,
    earth_rate: bool = False,
) -> Predicted:
    """Build the dataset of ``session`` (records the model was not fitted to; the same checks
    and noise model as a fit, :func:`~host.model.dataset.build_dataset`) and predict it with
    ``model`` and the parameter ``values`` (:func:`predict`)."""
    ds = build_dataset(
        session, noise=noise, latitude_deg=latitude_deg, height_m=height_m,
        earth_rate=earth_rate,
    )  # fmt: skip
    predicted = predict(ds, model, values)
    groups, _ = residual_tables(ds, predicted, ds.y - predicted, np.zeros((ds.n_rows, 0)))
    return Predicted(ds, predicted, groups)
