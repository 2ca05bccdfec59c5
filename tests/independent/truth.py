"""The truth of an independent session: the base error model (method.md §2) with a different
value on every axis, and the bench's geometry (all zero unless an effect sets it).

Names are method.md's: A0x…, Axx…, Axz… (accelerometer, m/s² and rad), G0x… (°/s), Gxx…,
Gxz…, GAxx… ((°/s)/g). Nothing is imported from the project's simulator.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from tests.independent.physics import AXES, error_matrix

#: misalignment keys in method.md's order (the row's channel, then the axis it leans toward)
MIS_KEYS = ("xz", "xy", "yz", "yx", "zy", "zx")


def distinct(rng: np.random.Generator, k: int, half_range: float) -> np.ndarray:
    """``k`` values in ±``half_range``, each in its own 1/k slice of the range (shuffled), none
    within 10 % of a slice of zero or of another: a different value on every axis."""
    slots = rng.permutation(k)
    u = rng.uniform(0.15, 0.85, k)
    v = half_range * (2.0 * (slots + u) / k - 1.0)
    v[np.abs(v) < 0.05 * half_range] += 0.1 * half_range
    return v


@dataclass
class BaseTruth:
    """The §2 error model of one unit."""

    accel_bias: np.ndarray  # (3,) m/s²
    accel_scale: np.ndarray  # (3,)
    accel_mis: dict[str, float]  # rad
    gyro_bias: np.ndarray  # (3,) °/s
    gyro_scale: np.ndarray  # (3,)
    gyro_mis: dict[str, float]  # rad
    g_sens: np.ndarray  # (3, 3) (°/s)/g, row = gyro channel, column = force axis

    @property
    def accel_matrix(self) -> np.ndarray:
        return error_matrix(self.accel_scale, self.accel_mis, "accel")

    @property
    def gyro_matrix(self) -> np.ndarray:
        return error_matrix(self.gyro_scale, self.gyro_mis, "gyro")

    def constants(self) -> dict[str, float]:
        """method.md's names -> values."""
        out: dict[str, float] = {}
        for i, a in enumerate(AXES):
            out[f"A0{a}"] = float(self.accel_bias[i])
            out[f"A{a}{a}"] = float(self.accel_scale[i])
            out[f"G0{a}"] = float(self.gyro_bias[i])
            out[f"G{a}{a}"] = float(self.gyro_scale[i])
            for j, b in enumerate(AXES):
                out[f"GA{a}{b}"] = float(self.g_sens[i, j])
        for k in MIS_KEYS:
            out[f"A{k}"] = float(self.accel_mis[k])
            out[f"G{k}"] = float(self.gyro_mis[k])
        return out


def random_base(rng: np.random.Generator) -> BaseTruth:
    """A plausible MPU-6000 (method.md §7's magnitudes), every axis different."""
    am = distinct(rng, 6, 0.01)
    gm = distinct(rng, 6, 0.01)
    return BaseTruth(
        accel_bias=distinct(rng, 3, 0.3),
        accel_scale=distinct(rng, 3, 0.015),
        accel_mis=dict(zip(MIS_KEYS, am.tolist(), strict=True)),
        gyro_bias=distinct(rng, 3, 2.5),
        gyro_scale=distinct(rng, 3, 0.02),
        gyro_mis=dict(zip(MIS_KEYS, gm.tolist(), strict=True)),
        g_sens=distinct(rng, 9, 0.06).reshape(3, 3),
    )


@dataclass
class Geometry:
    """The bench: a plate tilt, face leans, a tilted seat during the turns of one axis, the
    sensor's offset from the cube's centre. All zero on a perfect bench."""

    plate_tilt_rad: float = 0.0
    #: room azimuth the plate's normal leans toward, counter-clockwise from east (the fence)
    plate_azimuth_rad: float = 0.0
    #: per resting face ('+x' … '-z'): (3,) lean, rad; horizontal accel i reads +g·lean[i]
    face_lean: dict[str, np.ndarray] = field(default_factory=dict)
    #: per up axis ('x'|'y'|'z'): (3,) lean of the seat during that axis's turn records only
    turn_lean: dict[str, np.ndarray] = field(default_factory=dict)
    #: per turn record ('y_ccw' …): (3,) lean of the seat during that one record only
    record_lean: dict[str, np.ndarray] = field(default_factory=dict)
    #: sensor offset from the cube's centre (the turn's pivot), body axes, m
    lever_arm_m: np.ndarray = field(default_factory=lambda: np.zeros(3))

    def lean(self, face: str, kind: str, record: str = "") -> np.ndarray:
        """Lean of the seat of ``face`` in a record of ``kind`` ('static'|'turn') named
        ``record``, rad."""
        out = np.array(self.face_lean.get(face, np.zeros(3)), dtype=float)
        if kind == "turn":
            out = out + np.array(self.turn_lean.get(face[-1], np.zeros(3)), dtype=float)
            out = out + np.array(self.record_lean.get(record, np.zeros(3)), dtype=float)
        return out
