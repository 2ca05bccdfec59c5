"""The axis each turn was made about (issue 25): where gravity sits in the body while the cube
turns, from the centre of the circle its rests or its motion draw
(:func:`host.model.plate.turn_circles`) against the static record of the same face.

A turn made with the cube seated off its face (a few degrees) is named, and its reference rate
taken along the measured axis, so that the gyro cross-axis values it would fake are corrected
(:func:`resolve_turn_axes`).

Units: rad for leans, m/s² for specific force.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np

from host.model.geometry import plate_axes
from host.model.plate import PlateTilt
from host.model.signals import RecordSignals

#: a turn whose axis sits further than this from the static seat on the same face is named
#: tilted (and beyond what the plate's tilt and the noise allow), rad: 5 mrad (0.3°), above a
#: hand re-seating a cube on a clean plate
SEAT_TOL_RAD = 0.005


@dataclass(frozen=True)
class TurnAxis:
    """Where one turn record's axis sits in the body against the static record(s) of the same
    face: ``lean`` (3,) rad, the axis's unit vector minus the nominal up (zero along up);
    ``sd`` rad its noise σ per component; ``bound`` rad how far the plate's tilt at the
    statics' unknown heading can move it (0 when their heading is recorded)."""

    record: str
    up: np.ndarray
    statics: tuple[str, ...]
    lean: np.ndarray
    sd: float
    bound: float

    @property
    def size(self) -> float:
        """|lean|, rad."""
        return float(np.linalg.norm(self.lean))

    @property
    def tilted(self) -> bool:
        """The turn was made about an axis off the static seat beyond what the plate allows
        (:attr:`bound`) plus a re-seating (:data:`SEAT_TOL_RAD`) or the noise (3σ), whichever
        is larger."""
        return self.size > self.bound + max(SEAT_TOL_RAD, 3.0 * self.sd)

    @property
    def axis(self) -> np.ndarray:
        """(3,) the turn axis in the body, a unit vector (the nominal up leaned): the lean is
        what the horizontal accelerometers read of g, so its components are the unit axis's own
        (sines), and along up it keeps √(1 − |lean|²). Normalising up + lean instead takes them
        for tangents: the axis falls short across by |lean|²/2 of itself (0.15 mrad at 5°,
        the gyro cross-axis pulls' sd 1.7 there) and long along up by |lean|⁴/2 (its scale)."""
        along = math.sqrt(max(1.0 - float(self.lean @ self.lean), 0.0))
        return np.asarray(self.lean + along * self.up)

    def line(self) -> str:
        """The reader's sentence: the tilt, the gyro cross-axis it would fake, the correction."""
        k = int(np.argmax(np.abs(self.up)))
        up = ("+" if self.up[k] > 0 else "-") + "xyz"[k]
        fake = ", ".join(
            f"gyro {'xyz'[i]} {self.lean[i] * 360.0:+.2f}°/turn ({self.lean[i]:+.4f} of the rate)"
            for i in range(3) if i != k
        )  # fmt: skip
        out = (
            f"{self.record}: turned about an axis {1e3 * self.size:.1f} mrad "
            f"({math.degrees(self.size):.2f}°) off {up} — the accelerometer during the turn puts "
            f"gravity that far from where {' and '.join(self.statics)} has it (the cube was not "
            f"seated flat while it turned). A tilted turn puts part of its rate on the other "
            f"gyros ({fake}), which a fit would take for cross-axis sensitivity: the turn's "
            "reference rate is taken along the measured axis instead, and the turn's "
            f"cross-axis integrals carry that measurement's σ (± {1e3 * self.sd:.2f} mrad of "
            "the rate), so the fitted cross-axis values' σ include the geometry"
        )
        if self.bound > 0:
            out += (
                f"; the axis is uncertain by up to {1e3 * self.bound:.1f} mrad (the plate's "
                "tilt at the statics' unknown heading), and so are the gyro cross-axis values "
                "of this axis — record placement_heading_deg or level the plate"
            )
        return out


def turn_axes(signals: Sequence[RecordSignals], plate: PlateTilt | None) -> list[TurnAxis]:
    """Each turn record's axis against the static records of the same face (the circle's
    centre of :func:`turn_circle` against their mean horizontal readings: a bias, a
    misalignment and a face error are the same in both and cancel; the plate's tilt at the
    statics' heading is removed when it is recorded in the plate's frame, else bounds the
    result)."""
    if plate is None:
        return []
    cal = _accel_calibration(signals)
    out = []
    # a circle read from a turn's motion places its centre only when the turn rests at its
    # ends too (a turn without a rest is a planner's ideal record, not a cube on a face)
    for c in (c for c in plate.circles if c.n_rests > 0):
        sig = next(s for s in signals if s.name == c.record)
        same = [s for s in signals if s.kind == "static" and _close(s.up, sig.up)]
        if not same:
            continue
        k = int(np.argmax(np.abs(sig.up)))
        hor = [i for i in range(3) if i != k]
        reads, var = [], []
        known = plate.frame == "the fence" and all(s.placement_deg is not None for s in same)
        for st in same:
            m = st.accel[:, hor].mean(axis=0)
            if known:
                east, north = plate_axes(st.up, np.array([math.radians(st.placement_deg or 0.0)]))
                m = m - st.g * (plate.vector[0] * east[0, hor] + plate.vector[1] * north[0, hor])
            reads.append(m)
            var.append(st.accel[:, hor].var(axis=0) / len(st.t_s))
        static = np.zeros(3)
        static[hor] = np.mean(reads, axis=0)
        static[k] = float(np.mean([st.accel[:, k].mean() for st in same]))
        turn = static.copy()
        turn[hor] = c.centre
        sd = math.sqrt(float(np.max(c.centre_var + np.mean(var, axis=0) / len(same)))) / sig.g
        lean = np.zeros(3)
        lean[hor] = (cal(turn) - cal(static))[hor] / sig.g
        bound = 0.0 if known else plate.size + 2.0 * plate.size_sd
        out.append(TurnAxis(c.record, np.asarray(sig.up, dtype=float),
                            tuple(s.name for s in same), lean, sd, bound))  # fmt: skip
    return out


def _close(a: np.ndarray, b: np.ndarray) -> bool:
    """``np.allclose(a, b)`` of two finite up vectors (3,), in plain arithmetic: it is asked
    for every static record against every turn."""
    return all(
        abs(x - y) <= 1e-8 + 1e-5 * abs(y) for x, y in zip(a.tolist(), b.tolist(), strict=True)
    )


def _accel_calibration(
    signals: Sequence[RecordSignals],
) -> Callable[[np.ndarray], np.ndarray]:
    """The accelerometer's bias and scale-and-misalignment matrix from the static records'
    means (f = b + C·g·up, least squares), as the map from a reading (3,) m/s² to the specific
    force; the identity when the statics do not determine them. A lean read through it is
    free of the scale factors and cross-axis terms (a few % of it otherwise)."""
    st = [s for s in signals if s.kind == "static"]
    a = np.array([np.concatenate([s.g * s.up, [1.0]]) for s in st]) if st else np.zeros((0, 4))
    if len(st) < 4 or np.linalg.matrix_rank(a) < 4:
        return lambda f: np.asarray(f, dtype=float)
    y = np.array([s.accel.mean(axis=0) for s in st])
    coef, *_ = np.linalg.lstsq(a, y, rcond=None)
    c_inv, b = np.linalg.inv(coef[:3].T), coef[3]
    return lambda f: np.asarray(c_inv @ (np.asarray(f, dtype=float) - b))


def resolve_turn_axes(
    signals: Sequence[RecordSignals], axes: Sequence[TurnAxis]
) -> tuple[list[RecordSignals], list[TurnAxis]]:
    """The records with each tilted turn's reference rate and specific force along its
    measured axis (``axes``: :func:`turn_axes`, :attr:`TurnAxis.tilted`): the gyro cross-axis
    values such a turn would fake are corrected by the tilt the accelerometer shows. Returns
    the records and the tilted turns (their :meth:`TurnAxis.line` tells the reader)."""
    out = list(signals)
    tilted = [a for a in axes if a.tilted]
    for a in tilted:
        i = next(j for j, s in enumerate(out) if s.name == a.record)
        s = out[i]
        w = s.rate @ s.up
        out[i] = replace(s, rate=w[:, None] * a.axis[None, :],
                         force=np.tile(s.g * a.axis, (len(s.t_s), 1)))  # fmt: skip
    return out, tilted
