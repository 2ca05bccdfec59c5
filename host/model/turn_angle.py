"""A turn record's angle and its reference rate (method.md §4): the rate the hand turned,
read from the gyro about up with the statics' bias removed and scaled to the angle turned —
±360°·n when the turn starts and ends at rest, or, when it starts or ends in motion, the angle
the gyro read through its scale, the correction of which is an unknown of the fit
(:data:`host.model.catalogue.scale`'s own unknown of the record; its column
:func:`angle_free`). The gyro's scale on each axis before the fit, from the turns at rest."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from host.session.method import trapezoid_integral
from host.session.observations import Observation
from host.session.records import Record


def turn_reference(
    rec_gyro: np.ndarray, t_ms: np.ndarray, up: np.ndarray, bias_dps: np.ndarray, want_deg: float
) -> np.ndarray:
    """(N,3) reference rate of a turn: the measured rate about the up axis (static bias
    removed), scaled so that its trapezoid integral is exactly ``want_deg``."""
    raw = (rec_gyro - bias_dps) @ up
    total = float(trapezoid_integral(t_ms, raw))
    if abs(total) < 1e-6:
        return np.zeros((len(t_ms), 3))
    return (raw * (want_deg / total))[:, None] * up[None, :]


def angle_free(
    rec: Record,
    up: np.ndarray,
    bias_dps: np.ndarray,
    gyro_scale: np.ndarray | None,
    reads: np.ndarray,
) -> tuple[float, np.ndarray]:
    """A turn record in motion at an end: (the angle its reference rate turns, °: the measured
    integral about up, ``bias_dps`` (3,) removed, over 1 + the gyro's scale on that axis from
    the turns at rest, ``gyro_scale`` (3,), or 1 without them; (N, 3) what each gyro channel
    reads per degree of it, (°/s)/°, the column of its angle's unknown: the rate's profile
    about up, per degree, times ``reads`` (3,), what each channel reads of a turn about that
    axis per degree about up (:func:`turn_reads`), times that scale)."""
    raw = (rec.gyro - bias_dps) @ up
    k = int(np.argmax(np.abs(up)))
    scale = 1.0 if gyro_scale is None else float(gyro_scale[k])
    total = float(trapezoid_integral(rec.t_ms, raw))
    return total / scale, (raw / total)[:, None] * (scale * np.asarray(reads))[None, :]


def preliminary_gyro_scale(
    turns: Sequence[tuple[Record, Observation]], gyro_bias: np.ndarray
) -> np.ndarray | None:
    """(3,) 1 + each gyro's scale on its own axis from the turn records before the fit: the
    measured integral about up (static ``gyro_bias`` (4, 3) removed) over the known turn, the
    mean of the turns about each axis at rest at both ends (1 for an axis without turns);
    None without turns. It
    carries a face's lean into the gyro's columns (:data:`host.model.catalogue.face_error`)."""
    per: dict[int, list[float]] = {0: [], 1: [], 2: []}
    for rec, o in turns:
        if o.in_motion:  # its angle is not known: it reads nothing of the scale
            continue
        want = float(o.rate @ o.up)
        bias = gyro_bias[:3].T @ o.up + gyro_bias[3]
        total = float(trapezoid_integral(rec.t_ms, (rec.gyro - bias) @ o.up))
        if abs(want) > 1e-6 and abs(total) > 1e-6:
            per[int(np.argmax(np.abs(o.up)))].append(total / want)
    if not any(per.values()):
        return None
    return np.array([float(np.mean(v)) if v else 1.0 for v in per.values()])


def turn_reads(
    turns: Sequence[tuple[Record, Observation]], gyro_bias: np.ndarray
) -> dict[int, np.ndarray]:
    """up axis -> (3,) what each gyro channel reads of a turn about it per degree read about
    up: the mean over its turns (at rest or in motion, both ways) of their integrals, the
    static ``gyro_bias`` (4, 3) removed, over the integral about up. One vector per axis, so
    that the angles of the turns about an axis trade with its scale (and the cross-axis
    terms) alike."""
    per: dict[int, list[np.ndarray]] = {}
    for rec, o in turns:
        bias = gyro_bias[:3].T @ o.up + gyro_bias[3]
        total = trapezoid_integral(rec.t_ms, rec.gyro - bias)
        along = float(np.asarray(total) @ o.up)
        if abs(along) > 1e-6:
            per.setdefault(int(np.argmax(np.abs(o.up))), []).append(np.asarray(total) / along)
    return {k: np.mean(v, axis=0) for k, v in per.items()}
