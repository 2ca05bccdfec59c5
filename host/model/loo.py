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


def leave_one_out(ds: Dataset, fit: Fit) -> Prediction:
    """Predict every record from the fit of ``fit.model`` to the other records (the design is
    linearised at ``fit``'s parameters for nonlinear terms). A term that only fits noise makes
    this prediction error larger, where χ² always falls (method.md §8: accuracy on attitudes
    not used in the fit)."""
    x, offset, _ = design(ds, fit.model, _thetas_of(fit))
    # W is block-diagonal within records: the others' whitened rows are rows of W·x
    xw_all = ds.whiten.apply(x)
    yw_all = ds.whiten.apply(ds.y - ds.nominal - offset)
    y = ds.y - ds.nominal - offset
    zs: list[float] = []
    skipped: list[str] = []
    for ri, sig in enumerate(ds.signals):
        out_rows = ds.row_record == ri
        keep_rows = ~out_rows
        xw = xw_all[keep_rows]
        yw = yw_all[keep_rows]
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
            if gr.record != ri:
                continue
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
