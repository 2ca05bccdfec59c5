"""The weighted least squares of a model over a dataset's rows (:func:`solve`): the design
whitened, its independent columns chosen, the parameters solved for (Gauss-Newton over terms
nonlinear in theirs), the residuals and χ²; and χ² alone of one model fitted to several sets
of rows (:func:`fitted_chi2`). The fit's results and tables: :mod:`host.model.fit`."""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from host.model.dataset import Dataset
from host.model.design import BuiltColumns, design, select_columns
from host.model.spec import ModelTerm


@dataclass(frozen=True, eq=False)
class Solution:
    """The least-squares solution of one model over one dataset's rows (:func:`solve`)."""

    x: np.ndarray  # (n_rows, P) the design
    offset: np.ndarray  # (n_rows,)
    xw: np.ndarray  # W·x
    keep: np.ndarray  # (P,) columns independent of the earlier ones
    basis: np.ndarray  # orthonormal basis of their whitened span
    theta: np.ndarray  # (P,) NaN where not kept
    cov: np.ndarray  # (P, P) (zeros unless asked for)
    predicted: np.ndarray
    resid: np.ndarray
    wres: np.ndarray  # W·resid
    chi2: float


def solve(
    ds: Dataset,
    model: tuple[ModelTerm, ...],
    max_iter: int,
    built: BuiltColumns | None,
    covariance: bool,
) -> Solution:
    """Weighted least squares of ``model`` over the rows of ``ds`` (Gauss-Newton over the
    nonlinear terms), the parameters' covariance only when asked for."""
    thetas: list[np.ndarray | None] = [
        np.tile(np.array(mt.term.initial), len(mt.axes)) if mt.term.nonlinear else None
        for mt in model
    ]
    iters = max_iter if any(mt.term.nonlinear for mt in model) else 1
    for _ in range(iters):
        x, offset, spans = design(ds, model, thetas, built)
        xw = ds.whiten.apply(x)
        keep, basis = select_columns(xw)
        theta, cov = weighted_lstsq(ds, offset, xw, keep, ds.y, covariance)
        moved = 0.0
        for i, mt in enumerate(model):
            if mt.term.nonlinear:
                a, b = spans[i]
                old = thetas[i]
                assert old is not None
                new = np.where(np.isfinite(theta[a:b]), theta[a:b], old)
                moved = max(moved, float(np.max(np.abs(new - old) / (1e-12 + np.abs(new)))))
                thetas[i] = new
        if moved < 1e-8:
            break
    predicted, resid, wres = residual(ds, x, offset, theta, ds.y)
    return Solution(x, offset, xw, keep, basis, theta, cov, predicted, resid, wres,
                   float(wres @ wres))  # fmt: skip


def weighted_lstsq(
    ds: Dataset,
    offset: np.ndarray,
    xw: np.ndarray,
    keep: np.ndarray,
    y: np.ndarray,
    covariance: bool,
) -> tuple[np.ndarray, np.ndarray]:
    """(θ (P,), NaN where not kept; its covariance (P, P), zeros unless asked for) of the
    whitened design ``xw``'s ``keep`` columns fitted to the rows ``y`` less the ideal
    sensor's value and the design's ``offset``."""
    yw = ds.whiten.apply(y - ds.nominal - offset)
    theta = np.full(xw.shape[1], np.nan)
    cov = np.zeros((xw.shape[1], xw.shape[1]))
    if keep.any():
        sol, *_ = np.linalg.lstsq(xw[:, keep], yw, rcond=None)
        theta[keep] = sol
        if covariance:
            cov[np.ix_(keep, keep)] = np.linalg.pinv(xw[:, keep].T @ xw[:, keep])
    return theta, cov


def residual(
    ds: Dataset, x: np.ndarray, offset: np.ndarray, theta: np.ndarray, y: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(predicted, residual y − predicted, whitened residual), (n_rows,) each, of the design
    ``x`` with ``offset`` at ``theta`` (NaN: 0)."""
    predicted = ds.nominal + offset + x @ np.nan_to_num(theta)
    resid = y - predicted
    return predicted, resid, ds.whiten.apply(resid)


def fitted_chi2(
    ds: Dataset,
    model: Sequence[ModelTerm],
    ys: Sequence[np.ndarray],
    built: BuiltColumns | None = None,
    max_iter: int = 20,
) -> list[float]:
    """χ² of ``model`` fitted to each of ``ys`` (n_rows,) in place of the measured rows of
    ``ds``: :func:`host.model.fit.fit_model`'s, without the tables, the standard errors and
    the channels' statistics; a linear model's design is whitened and its columns chosen once
    for all of them (``built``: the columns already built on these rows,
    :class:`~host.model.design.BuiltColumns`)."""
    model = tuple(model)
    if any(mt.term.nonlinear for mt in model):
        return [solve(dataclasses.replace(ds, y=y), model, max_iter, built, False).chi2
                for y in ys]  # fmt: skip
    x, offset, _ = design(ds, model, (), built)
    xw = ds.whiten.apply(x)
    keep, _ = select_columns(xw)
    out = []
    for y in ys:
        theta, _ = weighted_lstsq(ds, offset, xw, keep, y, False)
        wres = residual(ds, x, offset, theta, y)[2]
        out.append(float(wres @ wres))
    return out
