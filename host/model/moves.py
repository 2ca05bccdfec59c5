"""The moves' rows in a dataset (:func:`add_moves`): each move between two poses gives two rows
on the gyro (:func:`host.model.poses.move_rows`: the calibrated rate, integrated exactly, carries
gravity from the rest before to the rest after), each its own group with its own white noise,
read by every gyro channel's terms and by both poses' attitudes (:data:`RecordLinks`)."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np

from host.model.poses import RecordLinks, move_rows
from host.model.rows import RowTable
from host.model.signals import RecordSignals
from host.model.whitening import Group, Whitener
from host.session.records import Record

#: the term whose records' own unknowns are the poses' attitudes
ATTITUDE_TERM = "misalignment"


def add_moves(
    table: RowTable,
    signals: Sequence[RecordSignals],
    records: Sequence[Record],
    white_level: Mapping[tuple[str, int], float],
    whiten: Whitener,
    groups: list[Group],
    floor: float = 0.0,
) -> tuple[Whitener, dict[tuple[int, str, int], np.ndarray], dict[tuple[int, str, int], np.ndarray],
           RecordLinks]:  # fmt: skip
    """Add every move's rows to ``table`` (after the other rows were whitened: ``whiten``,
    ``groups``, extended here), with the gyro's white noise ``white_level`` ((sensor, axis) ->
    variance·τ of one sample) and its noise floor ``floor`` (°/s). Returns (the whitener of all
    rows, the moves' rows per gyro channel, their weights per gyro channel (2, N) s, the rows
    that read each pose's attitude)."""
    index = {s.name: i for i, s in enumerate(signals)}
    white = np.array([white_level.get(("gyro", a), 0.0) for a in range(3)])
    blocks = list(whiten.blocks)
    rows_of: dict[tuple[int, str, int], np.ndarray] = {}
    weights: dict[tuple[int, str, int], np.ndarray] = {}
    links: RecordLinks = {}
    for ri, (sig, rec) in enumerate(zip(signals, records, strict=True)):
        if sig.kind != "move":
            continue
        first, last = signals[index[rec.move_from]], signals[index[rec.move_to]]
        t_rel = sig.t_s - sig.t_s[0]
        mv = move_rows(t_rel, sig.gyro, sig.rate, first.up, last.up, white, floor)
        span = [(0.0, float(t_rel[-1]))]
        rows = []
        for k in range(2):
            (row,) = table.add_values(ri, "gyro", k, [float(mv.y[k])], [float(mv.nominal[k])],
                                      span, integral=True)  # fmt: skip
            rows.append(row)
            groups.append(Group(ri, "gyro", k, np.array([row]), float(mv.sigma[k]), math.nan))
            blocks.append((np.array([row]), np.array([[1.0 / float(mv.sigma[k])]])))
            links.setdefault((ATTITUDE_TERM, first.name), []).append((row, mv.from_coef[k]))
            links.setdefault((ATTITUDE_TERM, last.name), []).append((row, mv.to_coef[k]))
        for a in range(3):
            rows_of[(ri, "gyro", a)] = np.array(rows)
            weights[(ri, "gyro", a)] = mv.weights[:, a, :]
    return Whitener(len(table.y), tuple(blocks)), rows_of, weights, links
