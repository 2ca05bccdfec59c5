"""The method's constants, names and sign layout (method.md §2, §3, §7), local gravity (§3)
and the per-record quantities every estimator starts from (means, stds, §4 trapezoid
integrals).

Model (method.md §2), in matrix form with chip axes x, y, z::

    A = (I + Ma)·a + A0                     a: true specific force, m/s²
    G = (I + Mg)·ω + GA·(a/g) + G0          ω: true rate, °/s; a/g in units of local g

    Ma = [[ Axx,  Axz, -Axy],     Mg = [[ Gxx,  Gxz, -Gxy],     GA = [[GAxx, GAxy, GAxz],
          [-Ayz,  Ayy,  Ayx],           [-Gyz,  Gyy,  Gyx],           [GAyx, GAyy, GAyz],
          [ Azy, -Azx,  Azz]]           [ Gzy, -Gzx,  Gzz]]           [GAzx, GAzy, GAzz]]
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from host.errors import UserError
from host.session.records import Record
from host.session.spacing import trapezoid

# ---- constants ----------------------------------------------------------------------------
#: default site: Moscow (the source documents' bench), latitude in degrees, height in metres
DEFAULT_LATITUDE_DEG = 55.75
DEFAULT_HEIGHT_M = 150.0
#: Earth's rotation rate (sidereal), °/s
EARTH_RATE_DPS = 15.041067 / 3600.0
#: uncertainty of the angle of one hand turn (return against the ruler), degrees
TURN_ANGLE_SIGMA_DEG = 0.5
#: a hand turn must reach sign·360·n within this many degrees (+5 % of 360·n)
TURN_ANGLE_TOL_DEG = 15.0
#: static records: gravity may be at most this far (degrees) from the expected up direction
ORIENTATION_TOL_DEG = 25.0
#: static records: above these sample std the cube was moving (m/s², °/s)
STATIC_MAX_ACCEL_STD = 0.3
STATIC_MAX_GYRO_STD = 1.0

ACCEL_SCALE_NAMES = ("Axx", "Ayy", "Azz")
ACCEL_MIS_NAMES = ("Axz", "Axy", "Ayz", "Ayx", "Azy", "Azx")
ACCEL_BIAS_NAMES = ("A0x", "A0y", "A0z")
ACCEL_NOISE_NAMES = ("Astdx", "Astdy", "Astdz")
GYRO_SCALE_NAMES = ("Gxx", "Gyy", "Gzz")
GYRO_MIS_NAMES = ("Gxz", "Gxy", "Gyz", "Gyx", "Gzy", "Gzx")
GYRO_BIAS_NAMES = ("G0x", "G0y", "G0z")
GYRO_GSENS_NAMES = tuple(f"GA{i}{k}" for i in "xyz" for k in "xyz")
GYRO_NOISE_NAMES = ("Gstdx", "Gstdy", "Gstdz")

#: report groups (method.md §7) in report order: (title, names, unit, tolerance or None)
GROUPS: tuple[tuple[str, tuple[str, ...], str, float | None], ...] = (
    ("gyro relative scale error", GYRO_SCALE_NAMES, "", 0.03),
    ("gyro misalignment", GYRO_MIS_NAMES, "rad", 0.02),
    ("gyro bias", GYRO_BIAS_NAMES, "°/s", 20.0),
    ("gyro g-sensitivity", GYRO_GSENS_NAMES, "(°/s)/g", 0.1),
    ("gyro noise (std)", GYRO_NOISE_NAMES, "°/s", 0.05),
    ("accel relative scale error", ACCEL_SCALE_NAMES, "", 0.03),
    ("accel misalignment", ACCEL_MIS_NAMES, "rad", 0.02),
    ("accel bias", ("A0x", "A0y"), "m/s²", 0.5),
    ("accel bias", ("A0z",), "m/s²", 0.8),
    ("accel noise (std)", ACCEL_NOISE_NAMES, "m/s²", None),
)
CONSTANT_NAMES: tuple[str, ...] = tuple(n for _, names, _, _ in GROUPS for n in names)
UNITS: dict[str, str] = {n: u for _, names, u, _ in GROUPS for n in names}
TOLERANCES: dict[str, float | None] = {n: t for _, names, _, t in GROUPS for n in names}
NOISE_NAMES = GYRO_NOISE_NAMES + ACCEL_NOISE_NAMES

#: position of each scale/misalignment name in the matrix M (row = output channel,
#: column = input axis) and its sign, method.md §2
_LAYOUT: dict[str, tuple[int, int, int]] = {
    "xx": (0, 0, 1), "xz": (0, 1, 1), "xy": (0, 2, -1),
    "yz": (1, 0, -1), "yy": (1, 1, 1), "yx": (1, 2, 1),
    "zy": (2, 0, 1), "zx": (2, 1, -1), "zz": (2, 2, 1),
}  # fmt: skip


def matrix_to_names(prefix: str, m: np.ndarray) -> dict[str, float]:
    """M (3×3, I excluded) -> {'Axx': .., 'Axz': .., ...} with the §2 signs."""
    return {prefix + s: float(sign * m[i, k]) for s, (i, k, sign) in _LAYOUT.items()}


def names_to_matrix(prefix: str, values: Mapping[str, float]) -> np.ndarray:
    """{'Axx': .., ...} -> M (3×3, I excluded), the inverse of :func:`matrix_to_names`."""
    m = np.zeros((3, 3))
    for s, (i, k, sign) in _LAYOUT.items():
        m[i, k] = sign * float(values[prefix + s])
    return m


def gsens_to_names(ga: np.ndarray) -> dict[str, float]:
    """GA (3×3, (°/s)/g) -> {'GAxx': .., 'GAxy': .., ...}."""
    return {f"GA{a}{b}": float(ga[i, k]) for i, a in enumerate("xyz") for k, b in enumerate("xyz")}


def names_to_gsens(values: Mapping[str, float]) -> np.ndarray:
    """{'GAxx': ..} -> GA (3×3)."""
    return np.array([[float(values[f"GA{a}{b}"]) for b in "xyz"] for a in "xyz"])


# ---- gravity ------------------------------------------------------------------------------
def local_gravity(
    latitude_deg: float = DEFAULT_LATITUDE_DEG, height_m: float = DEFAULT_HEIGHT_M
) -> float:
    """Local gravity in m/s², Helmert's normal-gravity formula with height correction (§3):
    g = 9.78030·(1 + 0.005302·sin²φ − 0.000007·sin²2φ) − 0.000003086·h."""
    if not -90.0 <= latitude_deg <= 90.0 or not math.isfinite(latitude_deg):
        raise UserError(f"latitude {latitude_deg} is not within -90..90 degrees")
    if not -500.0 <= height_m <= 9000.0 or not math.isfinite(height_m):
        raise UserError(f"height {height_m} m is not plausible (-500..9000 m)")
    phi = math.radians(latitude_deg)
    return (
        9.78030 * (1 + 0.005302 * math.sin(phi) ** 2 - 0.000007 * math.sin(2 * phi) ** 2)
        - 0.000003086 * height_m
    )


# ---- per-record quantities ----------------------------------------------------------------
def trapezoid_integral(t_ms: np.ndarray, values: np.ndarray) -> np.ndarray:
    """∫ values dt over the sample times by the trapezoid rule (§4); t in ms, result in
    (unit of values)·s, e.g. ° for °/s. ``values`` (N,) or (N,k)."""
    return trapezoid(np.asarray(t_ms, dtype=np.float64) / 1000.0, values)


@dataclass(frozen=True, eq=False)
class RecordStats:
    """Means, stds (ddof=1) and gyro integrals of one record."""

    name: str
    kind: str
    n: int
    duration_s: float
    dt_s: float
    accel_mean: np.ndarray
    accel_std: np.ndarray
    gyro_mean: np.ndarray
    gyro_std: np.ndarray
    gyro_integral: np.ndarray  # °, trapezoid over t_ms


def record_stats(record: Record) -> RecordStats:
    """Channel means/stds and trapezoid gyro integrals of ``record``."""
    n = len(record)
    ddof = 1 if n > 1 else 0
    return RecordStats(
        name=record.name,
        kind=record.kind,
        n=n,
        duration_s=record.duration_s,
        dt_s=record.duration_s / max(n - 1, 1),
        accel_mean=record.accel.mean(axis=0),
        accel_std=record.accel.std(axis=0, ddof=ddof),
        gyro_mean=record.gyro.mean(axis=0),
        gyro_std=record.gyro.std(axis=0, ddof=ddof),
        gyro_integral=trapezoid_integral(record.t_ms, record.gyro),
    )
