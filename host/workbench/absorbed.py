"""A yardstick that does not contain the candidate's own signal (issue 24).

The turn-angle variance component (:func:`host.model.variance.turn_angle_sigma`) is measured
from the closures of the turns made both ways about an axis (each ccw + cw pair less the static
reading).
A term that is nothing at rest and even in the turn's direction (a gyro scale asymmetry,
½·asym·|ω|; a quadratic scale, k2·ω²) moves that closure exactly as a hand's angle error does,
so a yardstick measured with it absorbs the very signal the term would explain, and the
candidate looks insignificant. Such a candidate is tested instead against the turn-angle σ
estimated jointly with it: from the closures of the axes it does not touch (its own parameter
takes up the closure of its axis), 0 when none is left.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from host.model.dataset import Dataset
from host.model.design import BuiltColumns, term_columns
from host.model.spec import ModelTerm
from host.model.variance import turn_angle_sigma, turn_pairs

#: a candidate's part even in the turn direction, relative to its largest turn integral, below
#: which it does not move a closure (float round-off of an odd term)
EVEN_TOL = 1e-6


def _turn_pairs(ds: Dataset) -> list[tuple[int, int, int]]:
    """(up axis, row of the ccw turn's integral on that axis, row of the cw one) for each pair
    of turns made both ways about an axis, paired as the closures are
    (:func:`host.model.variance.turn_pairs`)."""
    out: list[tuple[int, int, int]] = []
    for k, ccw, cw in turn_pairs(ds.signals, ds.time_known):
        a, b = ds.rows_of.get((ccw, "gyro", k)), ds.rows_of.get((cw, "gyro", k))
        if a is not None and b is not None and len(a) == len(b) == 1:
            out.append((k, int(a[0]), int(b[0])))
    return out


def closure_axes(ds: Dataset, mt: ModelTerm, built: BuiltColumns | None = None) -> frozenset[int]:
    """The axes whose turn closure the candidate ``mt`` moves as an angle error does: its
    columns are (near) nothing on the static rows of that gyro channel and the same sign in
    both turn directions. Empty for a term odd in the direction (a scale factor cancels) or
    one that acts at rest too (a bias: the closure takes off the static reading). ``built``:
    the columns already built on these rows (:class:`~host.model.design.BuiltColumns`)."""
    if mt.sensor != "gyro" or not ds.closures:
        return frozenset()
    x, _ = built.of(ds, mt) if built is not None else term_columns(ds, mt)
    out = set()
    for k, ccw, cw in _turn_pairs(ds):
        ends = np.abs(x[[ccw, cw]]).max()
        if not ends > 0:
            continue
        even = np.abs(x[ccw] + x[cw]).max()
        static = [
            rows
            for (r, s, a), rows in ds.rows_of.items()
            if s == "gyro" and a == k and ds.signals[r].kind != "turn"
        ]
        at_rest = max((float(np.abs(x[rows]).max()) for rows in static), default=0.0)
        # at rest the term reads like a bias over a turn's duration: compare per second
        duration = max(float(ds.aggregators[int(ds.row_record[ccw])][0].sum()), 1e-9)
        if even > EVEN_TOL * ends and at_rest * duration < 0.01 * even:
            out.add(k)
    return frozenset(out)


def without_turn_angle(ds: Dataset, axes: frozenset[int]) -> Dataset:
    """``ds`` with the turn-angle σ re-estimated from the closures of the other axes
    (:func:`host.model.variance.turn_angle_sigma`) and the up-channel turn integrals
    re-weighed with it: the yardstick for a candidate that explains the closures of ``axes``.
    ``ds`` itself when the σ does not change."""
    old = ds.turn_angle_sigma_deg
    new = turn_angle_sigma([c for c in ds.closures if c.axis not in axes]).value
    if math.isclose(new, old):
        return ds
    whiten = ds.whiten
    groups = list(ds.groups)
    for i, gr in enumerate(groups):
        sig = ds.signals[gr.record]
        if sig.kind != "turn" or gr.sensor != "gyro" or abs(float(sig.up[gr.axis])) <= 0.5:
            continue
        var = max(gr.sigma**2 - old**2, 0.0) + new**2
        whiten = whiten.with_block(gr.rows, np.array([[1.0 / math.sqrt(var)]]))
        groups[i] = dataclasses.replace(gr, sigma=math.sqrt(var))
    note = (
        f"turn angle for a candidate that moves the closures of the turns about "
        f"{', '.join('xyz'[a] for a in sorted(axes))}: {new:.2g}° from the other axes "
        f"(was {old:.2g}°)"
    )
    return dataclasses.replace(
        ds, whiten=whiten, groups=tuple(groups), turn_angle_sigma_deg=new,
        notes=(*ds.notes, note),
    )  # fmt: skip
