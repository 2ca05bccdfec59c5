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
statistics (:class:`~host.model.channels.ChannelFit`) and residual tables (:func:`residual_tables`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from host.model.channels import (
    MOVE_ROWS,
    ChannelFit,
    channel_fits,
    estimable_columns,
    free_levels,
    parameter_scales,
)
from host.model.dataset import Dataset, build_dataset
from host.model.design import BuiltColumns, design
from host.model.noise import NoiseModel
from host.model.poses import FRAME_FIXED
from host.model.signals import AXES, UNIT
from host.model.solve import solve
from host.model.spec import ModelTerm
from host.model.stats import ALPHA_FIT, chi2_sf
from host.model.whitening import group_means
from host.session.directory import Session
from host.session.method import DEFAULT_HEIGHT_M, DEFAULT_LATITUDE_DEG


# ---- the fit --------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class Parameter:
    """One fitted parameter: §2-style ``name``, owning model-term label, value, 1-σ std error
    (NaN value: the records do not determine it), unit; ``sensor``, ``axis`` (x/y/z, the output
    channel) and ``key`` (the term's own parameter name, e.g. ``per_C``). ``dof``: the degrees
    of freedom the standard error is read on (inf: from the noise model alone; finite where
    an estimated variance component carries part of it,
    :func:`host.model.components.fit_with_components`)."""

    name: str
    term: str
    value: float
    stderr: float
    unit: str
    sensor: str = ""
    axis: str = ""
    key: str = ""
    dof: float = math.inf

    @property
    def term_name(self) -> str:
        """The catalogue name of the owning term ('temperature_bias')."""
        return self.term.split(":")[0]


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
    #: parameter name -> the factor its standard error was widened by (:func:`stderr_scale`
    #: of its channel; a parameter the moves' rows read: at least the moves' factor)
    se_scales: Mapping[str, float] = field(default_factory=dict)
    #: (len(influence_rows), n_params) ∂θ/∂(whitened row) of the rows asked for
    #: (:func:`fit_model`'s ``influence_rows``; the order of ``parameters``, unscaled): a
    #: parameter's variance is the sum of its column's squares over every row
    influence: np.ndarray | None = None

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
    ds: Dataset,
    model: Sequence[ModelTerm],
    max_iter: int = 20,
    built: BuiltColumns | None = None,
    influence_rows: np.ndarray | None = None,
) -> Fit:
    """Weighted least squares of ``model`` over all rows of ``ds`` (one problem, all channels).

    Parameters the records cannot determine are reported NaN (and listed in ``undetermined``).
    Nonlinear terms: Gauss-Newton iterations until the parameters settle. ``built``: the
    columns already built on these rows (:class:`~host.model.design.BuiltColumns`);
    ``influence_rows``: the whitened rows whose influence :attr:`Fit.influence` keeps."""
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
    channels, estimable = channel_fits(ds, x, xw, wres, th0, cov, owners, basis)
    if any(mt.term.twin_columns is not None for mt in model):
        # a term read by both sensors couples their channels: what all rows determine
        estimable = estimable_columns(xw)
    scale = parameter_scales(ds, channels, owners, x)
    params: list[Parameter] = []
    undetermined: list[str] = []
    fixed = _by_convention(ds)
    for c, (name, unit, ch, label, key) in enumerate(owners):
        ok = bool(keep[c] and estimable[c]) or name in fixed
        se = math.sqrt(max(float(cov[c, c]), 0.0)) * float(scale[c]) if ok else math.nan
        value = (0.0 if name in fixed else float(theta[c])) if ok else math.nan
        params.append(
            Parameter(name, label, value, 0.0 if name in fixed else se, unit, ch[0],
                      AXES[ch[1]] if ch[1] >= 0 else "", key)
        )  # fmt: skip
        if not ok:
            undetermined.append(name)
    groups, spans_out = residual_tables(ds, predicted, resid, basis)
    conv = np.array([o[0] in fixed for o in owners], dtype=bool)
    pcov = _scaled_covariance(cov, scale, ~(keep & estimable), conv)
    return Fit(
        model=model, parameters=tuple(params), predicted=predicted, residual=resid,
        white_residual=wres, basis=basis, chi2=chi2, dof=ds.n_rows - n_par - free_levels(ds.groups),
        n_params=n_par,
        groups=groups, spans=spans_out, undetermined=tuple(undetermined),
        channels=tuple(channels), covariance=pcov,
        se_scales={o[0]: float(k) for o, k in zip(owners, scale, strict=True)},
        influence=None if influence_rows is None else xw[influence_rows] @ cov,
    )  # fmt: skip


def _scaled_covariance(
    cov: np.ndarray, scale: np.ndarray, bad: np.ndarray, conv: np.ndarray
) -> np.ndarray:
    """The parameters' covariance with their standard errors' ``scale``: NaN rows and
    columns where ``bad`` (undetermined), 0 where ``conv`` (fixed by convention)."""
    pcov = cov * np.outer(scale, scale)
    pcov[bad, :] = np.nan
    pcov[:, bad] = np.nan
    pcov[conv, :] = 0.0
    pcov[:, conv] = 0.0
    return pcov


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
        move = sig.kind == "move"  # a miss of the gyro's rotation, °
        turn = move or sig.kind == "turn" and gr.sensor == "gyro"  # an integral, °
        unit = "°" if turn else UNIT[gr.sensor]
        axis = MOVE_ROWS[gr.axis] if move else AXES[gr.axis]
        r, measured, model = means[k].tolist()
        sd = sd_res[k]
        out.append(
            GroupResidual(
                record=sig.name, kind=sig.kind, sensor=gr.sensor, axis=axis,
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
