"""Held-out prediction: each record predicted by the model fitted to the others
(:func:`leave_one_out`, method.md §8: accuracy on attitudes not used in the fit)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from host.model.dataset import Dataset
from host.model.design import design, select_columns
from host.model.fit import Fit
from host.model.stats import right_singular


# ---- held-out prediction ----------------------------------------------------------------------
@dataclass(frozen=True)
class Prediction:
    """Leave-one-record-out prediction error of a model (:func:`leave_one_out`): each record
    is predicted by the model fitted to all the others; ``rms_z`` = RMS over the predicted
    record/channel values of (measured − predicted)/σ, σ² = the measurement's variance + the
    prediction's; ``n`` values predicted, ``skipped`` records none of whose values the others
    can predict (a value needing a parameter only its own record determines is left out)."""

    rms_z: float
    n: int
    skipped: tuple[str, ...]


def _thetas_of(fit: Fit) -> list[np.ndarray | None]:
    """Per model term, its fitted parameters (for nonlinear terms; None for linear ones)."""
    out: list[np.ndarray | None] = []
    for mt in fit.model:
        if not mt.term.nonlinear:
            out.append(None)
            continue
        vals = [p.value for p in fit.parameters if p.term == mt.label]
        out.append(np.nan_to_num(np.array(vals, dtype=np.float64)))
    return out


def _stack_r(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The triangular factor R of the rows of ``a`` and ``b`` stacked (k, c), k ≤ c."""
    both = np.vstack([a, b])
    return np.asarray(np.linalg.qr(both, mode="r")) if len(both) else both


def _others_reduced(ds: Dataset, z: np.ndarray) -> list[np.ndarray]:
    """Per record, the whitened rows of all the other records, reduced to their R factor
    (≤ c rows): ``z`` (n_rows, c) the unwhitened columns. R keeps every column's length and
    every angle between columns (R = QᵀZ, Q orthonormal), so the least squares, the column
    choice and the null space of the others' rows read the same from it. From running R
    factors over the records before and after each one: memory and time linear in the rows
    (W is block-diagonal within records, so the others' whitened rows are rows of W·z)."""
    zw = ds.whiten.apply(z)
    c = zw.shape[1]
    own = [zw[ds.row_record == ri] for ri in range(len(ds.signals))]
    before = [np.zeros((0, c))]
    for part in own:
        before.append(_stack_r(before[-1], part))
    after = [np.zeros((0, c))]
    for part in reversed(own):
        after.append(_stack_r(after[-1], part))
    after.reverse()  # after[ri]: the records from ri on
    return [_stack_r(before[ri], after[ri + 1]) for ri in range(len(own))]


def leave_one_out(ds: Dataset, fit: Fit) -> Prediction:
    """Predict every record from the fit of ``fit.model`` to the other records (the design is
    linearised at ``fit``'s parameters for nonlinear terms). A term that only fits noise makes
    this prediction error larger, where χ² always falls (method.md §8: accuracy on attitudes
    not used in the fit)."""
    x, offset, _ = design(ds, fit.model, _thetas_of(fit))
    y = ds.y - ds.nominal - offset
    others = _others_reduced(ds, np.column_stack([x, y]))
    zs: list[float] = []
    skipped: list[str] = []
    for ri, sig in enumerate(ds.signals):
        xw, yw = others[ri][:, :-1], others[ri][:, -1]
        keep, _ = select_columns(xw)
        cols = np.flatnonzero(keep)
        norms = np.linalg.norm(xw, axis=0)
        live = norms > 0
        if not len(cols):
            skipped.append(sig.name)
            continue
        sol, *_ = np.linalg.lstsq(xw[:, cols], yw, rcond=None)
        cov = np.linalg.pinv(xw[:, cols].T @ xw[:, cols])
        sv, vt = right_singular(xw[:, live] / norms[live])
        rank = int(np.sum(sv > 1e-9 * sv[0])) if len(sv) else 0
        null = vt[rank:].T  # null space of the others' design, normalised coordinates
        theta = np.zeros(x.shape[1])
        theta[cols] = sol
        rows_z: list[float] = []
        for gr in ds.groups:
            if gr.record != ri or gr.free_level:
                continue  # (a free level predicts nothing: it is a value of its own)
            a = x[gr.rows].mean(axis=0)
            an = a[live] / norms[live]
            if np.any(a[~live] != 0.0) or float(np.linalg.norm(an @ null)) > 1e-6 * max(
                float(np.linalg.norm(an)), 1e-300
            ):
                continue  # the others do not determine what this value needs
            r = float(np.mean(y[gr.rows]) - a @ theta)
            var = gr.sigma**2 + float(a[cols] @ cov @ a[cols])
            rows_z.append(r / math.sqrt(var))
        if rows_z:
            zs.extend(rows_z)
        else:
            skipped.append(sig.name)
    z = np.array(zs)
    return Prediction(float(np.sqrt(np.mean(z**2))) if len(z) else math.nan, len(z),
                      tuple(skipped))  # fmt: skip
