"""Calibration of the accelerometer and gyro triads from records (method.md §2-§4, §7).

Model (method.md §2), in matrix form with chip axes x, y, z::

    A = (I + Ma)·a + A0                     a: true specific force, m/s²
    G = (I + Mg)·ω + GA·(a/g) + G0          ω: true rate, °/s; a/g in units of local g

    Ma = [[ Axx,  Axz, -Axy],     Mg = [[ Gxx,  Gxz, -Gxy],     GA = [[GAxx, GAxy, GAxz],
          [-Ayz,  Ayy,  Ayx],           [-Gyz,  Gyy,  Gyx],           [GAyx, GAyy, GAyz],
          [ Azy, -Azx,  Azz]]           [ Gzy, -Gzx,  Gzz]]           [GAzx, GAzy, GAzz]]

Two estimators:

* the closed form of the method: stage 1 (§3, six statics) and stage 2 (§4, CW/CCW turn pairs
  integrated by the trapezoid rule over the recorded sample times) — :func:`stage1`,
  :func:`stage2`;
* a weighted linear least-squares fit of the same model to every record
  (:func:`build_observations` + :func:`fit_linear`) which accepts other plans: turns without
  their opposite partner (the bias then comes from the statics), extra static attitudes
  (meta ``up``), several turns per axis, rate-table records (meta ``rate_dps``, ``rate_axis``).
  Each record contributes one :class:`Observation` (static/rate: channel means; turn: channel
  integrals, with the bias and g-sensitivity terms multiplied by the duration T). For the
  standard 12-record session the two agree well below the noise. The report uses the fit.
"""

from __future__ import annotations

import dataclasses
import json
import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

from host.calib.records import MIN_RECORD_ROWS, STATIC_NAMES, TURN_NAMES, Record, Session
from host.errors import UserError

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
    t = np.asarray(t_ms, dtype=np.float64) / 1000.0
    v = np.asarray(values, dtype=np.float64)
    if len(t) < 2:
        return np.zeros(v.shape[1:])
    dt = np.diff(t)
    mid = 0.5 * (v[1:] + v[:-1])
    return np.asarray(np.tensordot(dt, mid, axes=(0, 0)))


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


# ---- closed form, method.md §3 and §4 -----------------------------------------------------
@dataclass(frozen=True, eq=False)
class Stage1:
    """Closed-form stage 1 (§3). Matrices are (3×3) with row = channel."""

    accel_m: np.ndarray  # Ma (scale errors on the diagonal, misalignments off it)
    accel_bias_estimates: np.ndarray  # [channel, pair x/y/z], m/s²
    gyro_gsens: np.ndarray  # GA, (°/s)/g
    gyro_bias_estimates: np.ndarray  # [channel, pair], °/s
    accel_noise: np.ndarray  # largest std over the six orientations, m/s²
    gyro_noise: np.ndarray  # °/s

    @property
    def accel_bias(self) -> np.ndarray:
        """Mean of the three estimates, m/s²."""
        return np.asarray(self.accel_bias_estimates.mean(axis=1))

    @property
    def gyro_bias(self) -> np.ndarray:
        """Mean of the three estimates, °/s."""
        return np.asarray(self.gyro_bias_estimates.mean(axis=1))

    def constants(self) -> dict[str, float]:
        """The stage-1 constants under the report's names."""
        out = {k: v for k, v in matrix_to_names("A", self.accel_m).items()}
        out.update(zip(ACCEL_BIAS_NAMES, map(float, self.accel_bias), strict=True))
        out.update(gsens_to_names(self.gyro_gsens))
        out.update(zip(GYRO_BIAS_NAMES, map(float, self.gyro_bias), strict=True))
        out.update(zip(ACCEL_NOISE_NAMES, map(float, self.accel_noise), strict=True))
        out.update(zip(GYRO_NOISE_NAMES, map(float, self.gyro_noise), strict=True))
        return out


def stage1(stats: Mapping[str, RecordStats], g: float) -> Stage1:
    """Method.md §3 closed form from the six statics x_up … z_dn (orientations 1 … 6).

    Column k of (I + Ma) is (A_k,up − A_k,dn)/(2g); the bias estimate from pair k is
    (A_k,up + A_k,dn)/2; GA column k is (G_k,up − G_k,dn)/2 and the gyro bias estimate
    (G_k,up + G_k,dn)/2. Noise = largest std over the six orientations per channel.
    """
    missing = [n for n in STATIC_NAMES if n not in stats]
    if missing:
        raise UserError(f"stage 1 needs the six static records; missing: {', '.join(missing)}")
    a_up = np.column_stack([stats[f"{ax}_up"].accel_mean for ax in "xyz"])  # [channel, k]
    a_dn = np.column_stack([stats[f"{ax}_dn"].accel_mean for ax in "xyz"])
    g_up = np.column_stack([stats[f"{ax}_up"].gyro_mean for ax in "xyz"])
    g_dn = np.column_stack([stats[f"{ax}_dn"].gyro_mean for ax in "xyz"])
    return Stage1(
        accel_m=(a_up - a_dn) / (2.0 * g) - np.eye(3),
        accel_bias_estimates=(a_up + a_dn) / 2.0,
        gyro_gsens=(g_up - g_dn) / 2.0,
        gyro_bias_estimates=(g_up + g_dn) / 2.0,
        accel_noise=np.max([stats[n].accel_std for n in STATIC_NAMES], axis=0),
        gyro_noise=np.max([stats[n].gyro_std for n in STATIC_NAMES], axis=0),
    )


def stage2(stats: Mapping[str, RecordStats], turns: int) -> np.ndarray:
    """Method.md §4 closed form: Mg (3×3) from the six turn integrals, n = ``turns``.

    Column k of (I + Mg) is (I_{K+} − I_{K−})/(720·n): the fixed recording window makes
    bias·T (and g-sensitivity·T) cancel between the CCW and CW turns about the same axis.
    """
    missing = [n for n in TURN_NAMES if n not in stats]
    if missing:
        raise UserError(f"stage 2 needs the six turn records; missing: {', '.join(missing)}")
    cols = [
        (stats[f"{ax}_ccw"].gyro_integral - stats[f"{ax}_cw"].gyro_integral) / (720.0 * turns)
        for ax in "xyz"
    ]
    return np.column_stack(cols) - np.eye(3)


# ---- least squares ------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class Observation:
    """One record's contribution to the linear fit.

    Per gyro channel i the model is ``gyro[i] = (I+Mg)[i]·rate + GA[i]·force + G0[i]·tau``;
    per accel channel ``accel[i] = (I+Ma)[i]·(g·up) + A0[i]`` (means only).

    static / rate: ``gyro`` = channel means (°/s), ``rate`` = reference rate (°/s),
    ``force`` = up direction (g), ``tau`` = 1.
    turn: ``gyro`` = trapezoid integrals (°), ``rate`` = ±360·n·up (°), ``force`` = up·T (g·s),
    ``tau`` = T (s), the record duration.
    """

    record: str
    kind: str
    up: np.ndarray
    rate: np.ndarray
    force: np.ndarray
    tau: float
    gyro: np.ndarray
    gyro_sigma: np.ndarray
    accel: np.ndarray | None = None  # means, m/s² (statics only)
    accel_sigma: np.ndarray | None = None
    turns: int | None = None


@dataclass(frozen=True, eq=False)
class LinearFit:
    """Result of :func:`fit_linear`. NaN marks what the records do not determine."""

    accel_m: np.ndarray  # Ma
    accel_bias: np.ndarray
    gyro_m: np.ndarray  # Mg (NaN columns: no turn about that axis)
    gyro_gsens: np.ndarray
    gyro_bias: np.ndarray
    std_errors: dict[str, float]
    accel_residuals: dict[str, np.ndarray]  # record -> mean residual, m/s²
    gyro_residuals: dict[str, np.ndarray]  # record -> residual (°/s for means, ° for turns)
    chi2_per_dof: dict[str, float]  # 'accel'/'gyro' -> reduced chi²


def _solve_channel(
    x: np.ndarray, y: np.ndarray, sigma: np.ndarray, free: np.ndarray, nominal: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, float, int]:
    """Weighted LSQ of y = x·p with the non-free parameters held at ``nominal``.

    Returns (p, std errors (NaN for fixed), residuals y − x·p, chi², dof). The std errors are
    scaled by sqrt(reduced χ²) when that exceeds 1 (the noise model is too optimistic).
    """
    p = nominal.astype(np.float64).copy()
    y_free = y - x[:, ~free] @ nominal[~free]
    xf = x[:, free] / sigma[:, None]
    yf = y_free / sigma
    sol, *_ = np.linalg.lstsq(xf, yf, rcond=None)
    p[free] = sol
    resid = y - x @ p
    chi2 = float(np.sum((resid / sigma) ** 2))
    dof = int(len(y) - free.sum())
    se = np.full(len(p), np.nan)
    cov = np.linalg.pinv(xf.T @ xf)
    scale = max(1.0, chi2 / dof) if dof > 0 else 1.0
    se[free] = np.sqrt(np.diag(cov) * scale)
    return p, se, resid, chi2, dof


def fit_linear(observations: Iterable[Observation], g: float) -> LinearFit:
    """Weighted least-squares fit of the §2 model to the observations, channel by channel.

    Accelerometer channel i: 4 parameters ((I+Ma)[i,:], A0[i]) from the static means.
    Gyro channel i: 7 parameters ((I+Mg)[i,:], GA[i,:], G0[i]); a column of (I+Mg) is fitted only
    if some turn/rate record excites that axis (else NaN = not measured).
    Raises UserError when the records cannot determine the rest.
    """
    obs = list(observations)
    acc = [o for o in obs if o.accel is not None and o.accel_sigma is not None]
    if not obs or not acc:
        raise UserError("no static records: the calibration needs the static attitudes")
    # accelerometer
    xa = np.array([np.concatenate([g * o.up, [1.0]]) for o in acc])
    if np.linalg.matrix_rank(xa) < 4:
        raise UserError(
            "the static records do not determine the accelerometer (need gravity along each "
            "axis and a way to separate the bias: e.g. the six x_up … z_dn records)"
        )
    accel_rows, accel_bias, accel_res = np.zeros((3, 3)), np.zeros(3), np.zeros((len(acc), 3))
    se: dict[str, float] = {}
    chi2a, dofa = 0.0, 0
    se_m = np.zeros((3, 3))
    for i in range(3):
        y = np.array([o.accel[i] for o in acc if o.accel is not None])
        s = np.array([o.accel_sigma[i] for o in acc if o.accel_sigma is not None])
        nominal = np.zeros(4)
        nominal[i] = 1.0
        p, e, r, c2, dof = _solve_channel(xa, y, s, np.ones(4, bool), nominal)
        accel_rows[i], accel_bias[i], accel_res[:, i] = p[:3], p[3], r
        se_m[i] = e[:3]
        se[ACCEL_BIAS_NAMES[i]] = float(e[3])
        chi2a, dofa = chi2a + c2, dofa + dof
    se.update({k: abs(v) for k, v in matrix_to_names("A", se_m).items()})
    # gyro
    xg = np.array([np.concatenate([o.rate, o.force, [o.tau]]) for o in obs])
    excited = np.array(
        [any(abs(o.rate[k]) > 1.0 for o in obs if o.kind in ("turn", "rate")) for k in range(3)]
    )
    free = np.concatenate([excited, np.ones(4, bool)])
    if np.linalg.matrix_rank(xg[:, free]) < int(free.sum()):
        raise UserError(
            "the records do not determine the gyro bias and g-sensitivity (need static records "
            "with gravity along each axis, e.g. the six x_up … z_dn records)"
        )
    gyro_rows, ga, gb = np.zeros((3, 3)), np.zeros((3, 3)), np.zeros(3)
    gyro_res = np.zeros((len(obs), 3))
    se_g, se_ga = np.zeros((3, 3)), np.zeros((3, 3))
    chi2g, dofg = 0.0, 0
    for i in range(3):
        y = np.array([o.gyro[i] for o in obs])
        s = np.array([o.gyro_sigma[i] for o in obs])
        nominal = np.zeros(7)
        nominal[i] = 1.0
        p, e, r, c2, dof = _solve_channel(xg, y, s, free, nominal)
        gyro_rows[i] = np.where(excited, p[:3], np.nan)
        ga[i], gb[i], gyro_res[:, i] = p[3:6], p[6], r
        se_g[i], se_ga[i] = e[:3], e[3:6]
        se[GYRO_BIAS_NAMES[i]] = float(e[6])
        chi2g, dofg = chi2g + c2, dofg + dof
    se.update({k: abs(v) for k, v in matrix_to_names("G", se_g).items()})
    se.update(gsens_to_names(se_ga))
    return LinearFit(
        accel_m=accel_rows - np.eye(3),
        accel_bias=accel_bias,
        gyro_m=gyro_rows - np.eye(3),
        gyro_gsens=ga,
        gyro_bias=gb,
        std_errors=se,
        accel_residuals={o.record: accel_res[j] for j, o in enumerate(acc)},
        gyro_residuals={o.record: gyro_res[j] for j, o in enumerate(obs)},
        chi2_per_dof={
            "accel": chi2a / dofa if dofa else float("nan"),
            "gyro": chi2g / dofg if dofg else float("nan"),
        },
    )


# ---- checks and observations --------------------------------------------------------------
def _axis_label(v: np.ndarray) -> str:
    k = int(np.argmax(np.abs(v)))
    return ("+" if v[k] > 0 else "-") + "XYZ"[k]


def remedy(record: Record, bench: str = "re-measure") -> str:
    """What to do about a bad record: on the bench, ``re-measure NAME``; for data imported
    from elsewhere (meta ``importer``) there is nothing to re-measure — fix the cut instead."""
    if "importer" in record.meta:
        return (
            f"check the {record.name} segment (SERIAL_segments.tsv, --labels) or the import "
            "options (--columns, --units, --axes)"
        )
    return f"{bench} {record.name}"


def check_orientation(record: Record, stats: RecordStats, g: float, file_name: str) -> None:
    """Gravity must be along the record's up direction (static, turn): else UserError naming
    the file, where gravity is and what to re-measure."""
    if record.kind not in ("static", "turn"):
        return
    up = record.up
    a = stats.accel_mean
    norm = float(np.linalg.norm(a))
    if not 0.7 * g < norm < 1.3 * g:
        raise UserError(
            f"{file_name}: the mean specific force is {norm:.2f} m/s², expected about "
            f"{g:.2f}: was the unit moving or not connected? {remedy(record)}"
        )
    angle = math.degrees(math.acos(max(-1.0, min(1.0, float(a @ up) / norm))))
    if angle > ORIENTATION_TOL_DEG:
        if np.count_nonzero(up) == 1:
            raise UserError(
                f"{file_name}: gravity is on {_axis_label(a)}, expected {_axis_label(up)}: "
                f"the cube was on the wrong face; {remedy(record)}"
            )
        raise UserError(
            f"{file_name}: gravity is {angle:.0f}° away from the expected up direction "
            f"{np.round(up, 3).tolist()}; {remedy(record)}"
        )
    if record.kind == "static":
        if np.any(stats.accel_std > STATIC_MAX_ACCEL_STD) or np.any(
            stats.gyro_std > STATIC_MAX_GYRO_STD
        ):
            raise UserError(
                f"{file_name}: the cube moved during the static measurement (std "
                f"{stats.accel_std.max():.3f} m/s², {stats.gyro_std.max():.3f} °/s); "
                f"{remedy(record)}"
            )


def check_range(record: Record, file_name: str) -> None:
    """§4: every gyro sample of a turn must stay inside the working range (meta
    ``gyro_range_dps``, e.g. 250); no check when the record does not state its range."""
    if "gyro_range_dps" not in record.meta:
        return
    try:
        rng = float(record.meta["gyro_range_dps"])
    except ValueError as exc:
        raise UserError(f"{file_name}: bad meta gyro_range_dps") from exc
    peak = float(np.abs(record.gyro).max()) if len(record) else 0.0
    if peak >= rng - 0.01:
        raise UserError(
            f"{file_name}: the rate reached {peak:.1f} °/s, outside the working range "
            f"±{rng:g} °/s; {remedy(record, 'turn more slowly and re-measure')}"
        )


def _turns_of(record: Record, default: int | None) -> int | None:
    if "turns" in record.meta:
        try:
            n = int(record.meta["turns"])
        except ValueError as exc:
            raise UserError(
                f"record {record.name}: bad meta turns {record.meta['turns']!r}"
            ) from exc
        if default is not None and default != n:
            raise UserError(
                f"--turns {default}, but record {record.name} says 'turns: {n}' in its header; "
                f"drop --turns (the header is used) or give --turns {n}"
            )
        return n
    return default


def check_record_lengths(session: Session) -> None:
    """UserError naming the first record with fewer than MIN_RECORD_ROWS samples (a one-row
    record has no std; its mean would enter the fit as if it were measured)."""
    for name, rec in session.records.items():
        if len(rec) < MIN_RECORD_ROWS:
            raise UserError(
                f"{session.path_of(name)}: {len(rec)} data row{'s' if len(rec) != 1 else ''}; "
                f"a record needs at least {MIN_RECORD_ROWS} samples (its mean and std) — "
                "re-measure this record"
            )


def build_observations(
    session: Session,
    g: float,
    *,
    turns: int | None = None,
    earth_rate: bool = False,
    latitude_deg: float = DEFAULT_LATITUDE_DEG,
    turn_angle_sigma_deg: float = TURN_ANGLE_SIGMA_DEG,
    stats: Mapping[str, RecordStats] | None = None,
) -> tuple[list[Observation], list[str]]:
    """Check every record and turn it into an :class:`Observation`; returns (observations,
    notes). ``turns``: n for turn records without meta ``turns`` (None: inferred from the
    integral). ``earth_rate``: add the vertical Earth-rate component Ω·sinφ along up (°/s) to the
    static reference (the horizontal part depends on the unknown heading and is ignored).
    """
    check_record_lengths(session)
    st = (
        dict(stats)
        if stats is not None
        else {n: record_stats(r) for n, r in session.records.items()}
    )
    notes: list[str] = []
    statics = [n for n, r in session.records.items() if r.kind == "static"]
    if not statics:
        raise UserError("no static records (SERIAL_x_up.txt …): the calibration needs them")
    for name in statics:
        check_orientation(session.records[name], st[name], g, session.path_of(name))
    accel_noise = np.maximum(np.max([st[n].accel_std for n in statics], axis=0), 1e-4)
    gyro_noise = np.maximum(np.max([st[n].gyro_std for n in statics], axis=0), 1e-3)
    earth = EARTH_RATE_DPS * math.sin(math.radians(latitude_deg)) if earth_rate else 0.0

    # static-only preliminary gyro bias and g-sensitivity for the turn checks
    xs = np.array([np.concatenate([session.records[n].up, [1.0]]) for n in statics])
    pre: np.ndarray | None = None
    if np.linalg.matrix_rank(xs) == 4:
        ys = np.array([st[n].gyro_mean for n in statics])
        pre, *_ = np.linalg.lstsq(xs, ys, rcond=None)  # (4,3): rows GA^T (3), bias

    obs: list[Observation] = []
    for name, rec in session.records.items():
        s = st[name]
        fname = session.path_of(name)
        up = rec.up if rec.kind in ("static", "turn") else None
        if rec.kind == "static":
            assert up is not None
            obs.append(
                Observation(
                    record=name, kind="static", up=up, rate=earth * up, force=up.copy(), tau=1.0,
                    gyro=s.gyro_mean, gyro_sigma=gyro_noise / math.sqrt(s.n),
                    accel=s.accel_mean, accel_sigma=accel_noise / math.sqrt(s.n),
                )
            )  # fmt: skip
        elif rec.kind == "turn":
            assert up is not None
            check_orientation(rec, s, g, fname)
            check_range(rec, fname)
            t = s.duration_s
            drift = np.zeros(3) if pre is None else (pre[:3].T @ up + pre[3]) * t
            along = float(up @ (s.gyro_integral - drift))
            n = _turns_of(rec, turns)
            if n is None:
                n = max(1, round(abs(along) / 360.0))
            if n < 1:
                raise UserError(f"{fname}: turns must be at least 1")
            want = rec.sign * 360.0 * n
            tol = 0.05 * 360.0 * n + TURN_ANGLE_TOL_DEG + (0.0 if pre is not None else 20.0 * t)
            if along * rec.sign < -90.0:
                direction = "counter-clockwise" if rec.sign > 0 else "clockwise"
                raise UserError(
                    f"{fname}: the cube turned {along:+.0f}° about {_axis_label(up)}, the wrong "
                    f"way (expected {direction}); {remedy(rec)}"
                )
            if abs(along - want) > tol:
                raise UserError(
                    f"{fname}: the cube turned {along:+.0f}° about {_axis_label(up)}, expected "
                    f"{want:+.0f}° ({n} turn{'s' if n > 1 else ''}): the turn was not complete "
                    f"or --turns is wrong; {remedy(rec)}"
                )
            sig = np.sqrt(gyro_noise**2 * s.dt_s * t + turn_angle_sigma_deg**2)
            obs.append(
                Observation(
                    record=name, kind="turn", up=up, rate=want * up + earth * up * t,
                    force=up * t, tau=t, gyro=s.gyro_integral, gyro_sigma=sig, turns=n,
                )
            )  # fmt: skip
        elif rec.kind == "rate":
            if "up" not in rec.meta:
                raise UserError(f"{fname}: a rate-table record needs meta 'up: [x, y, z]'")
            up_r = rec.up
            axis = rec.rate_axis
            force = up_r if abs(float(up_r @ axis)) > 0.999 else float(up_r @ axis) * axis
            obs.append(
                Observation(
                    record=name, kind="rate", up=up_r, rate=rec.rate_dps * axis + earth * up_r,
                    force=force, tau=1.0, gyro=s.gyro_mean,
                    gyro_sigma=np.maximum(s.gyro_std, gyro_noise) / math.sqrt(s.n),
                )
            )  # fmt: skip
        else:
            notes.append(f"{fname}: not a static, turn or rate record; ignored")
    turn_axes = {(_axis_label(o.up), int(np.sign(o.rate @ o.up))) for o in obs if o.kind == "turn"}
    for lab, sg in sorted(turn_axes):
        if (lab, -sg) not in turn_axes:
            notes.append(
                f"turn about {lab} only {'CCW' if sg > 0 else 'CW'}: its bias·T comes from the "
                "static records"
            )
    return obs, notes


# ---- result -------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class RecordResidual:
    """Residual of one record after the fit.

    static/rate: ``accel_mean``/``gyro_mean`` = mean residual (m/s², °/s), ``*_std`` = std of the
    sample residuals. turn: ``gyro_mean`` = integral residual / T (°/s equivalent),
    ``angle_deg`` = integral residual (°), stds NaN.
    """

    record: str
    kind: str
    n: int
    duration_s: float
    accel_mean: tuple[float, float, float]
    accel_std: tuple[float, float, float]
    gyro_mean: tuple[float, float, float]
    gyro_std: tuple[float, float, float]
    angle_deg: tuple[float, float, float] | None = None

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict (NaN -> None)."""
        return {f.name: _jsonable(getattr(self, f.name)) for f in dataclasses.fields(self)}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> RecordResidual:
        """Inverse of :meth:`to_dict`."""

        def t3(v: Any) -> tuple[float, float, float]:
            a, b, c = (_num(x) for x in v)
            return (a, b, c)

        return cls(
            record=str(d["record"]), kind=str(d["kind"]), n=int(d["n"]),
            duration_s=float(d["duration_s"]), accel_mean=t3(d["accel_mean"]),
            accel_std=t3(d["accel_std"]), gyro_mean=t3(d["gyro_mean"]),
            gyro_std=t3(d["gyro_std"]),
            angle_deg=None if d.get("angle_deg") is None else t3(d["angle_deg"]),
        )  # fmt: skip


def _num(v: Any) -> float:
    return float("nan") if v is None else float(v)


def _jsonable(v: Any) -> Any:
    if isinstance(v, float | np.floating):
        f = float(v)
        return None if not math.isfinite(f) else f
    if isinstance(v, tuple | list | np.ndarray):
        return [_jsonable(x) for x in v]
    if isinstance(v, dict):
        return {str(k): _jsonable(x) for k, x in v.items()}
    return v


@dataclass(frozen=True, eq=False)
class CalibrationResult:
    """All constants of one unit under the report's names (method.md §7); NaN = not measured.

    Units: scale errors and misalignments dimensionless (rad); A0. m/s²; G0. °/s; GA.. (°/s)/g;
    Astd. m/s²; Gstd. °/s. ``g`` m/s² (local, :func:`local_gravity`), ``latitude_deg``,
    ``height_m``. ``turns``: n of the turn records (None: none, or mixed).
    """

    FORMAT_VERSION: ClassVar[int] = 1

    serial: str
    created: str
    g: float
    latitude_deg: float
    height_m: float
    turns: int | None
    Gxx: float
    Gyy: float
    Gzz: float
    Gxz: float
    Gxy: float
    Gyz: float
    Gyx: float
    Gzy: float
    Gzx: float
    G0x: float
    G0y: float
    G0z: float
    GAxx: float
    GAxy: float
    GAxz: float
    GAyx: float
    GAyy: float
    GAyz: float
    GAzx: float
    GAzy: float
    GAzz: float
    Gstdx: float
    Gstdy: float
    Gstdz: float
    Axx: float
    Ayy: float
    Azz: float
    Axz: float
    Axy: float
    Ayz: float
    Ayx: float
    Azy: float
    Azx: float
    A0x: float
    A0y: float
    A0z: float
    Astdx: float
    Astdy: float
    Astdz: float
    earth_rate: bool = False
    method: str = "weighted least squares over all records (method.md §2)"
    records: tuple[str, ...] = ()
    #: the three closed-form bias estimates (§3, from the x, y, z pairs) per A0./G0. name
    bias_estimates: dict[str, tuple[float, float, float]] = field(default_factory=dict)
    #: closed-form values (§3, §4) where the plan has them
    closed_form: dict[str, float] = field(default_factory=dict)
    #: 1-sigma standard errors of the fitted constants
    std_errors: dict[str, float] = field(default_factory=dict)
    residuals: tuple[RecordResidual, ...] = ()
    notes: tuple[str, ...] = ()

    # ---- views ---------------------------------------------------------------------------
    def constants(self) -> dict[str, float]:
        """name -> value in report order."""
        return {n: float(getattr(self, n)) for n in CONSTANT_NAMES}

    def passed(self) -> dict[str, bool | None]:
        """name -> True within tolerance, False outside or not measured, None no tolerance."""
        out: dict[str, bool | None] = {}
        for n in CONSTANT_NAMES:
            tol = TOLERANCES[n]
            v = float(getattr(self, n))
            if tol is None:
                out[n] = None
            elif not math.isfinite(v):
                out[n] = False
            else:
                out[n] = v <= tol if n in NOISE_NAMES else abs(v) <= tol
        return out

    @property
    def all_passed(self) -> bool:
        """True when every toleranced value is within its tolerance."""
        return all(p is not False for p in self.passed().values())

    def accel_m(self) -> np.ndarray:
        """Ma (3×3)."""
        return names_to_matrix("A", self.constants())

    def accel_bias(self) -> np.ndarray:
        """A0 (3,), m/s²."""
        return np.array([getattr(self, n) for n in ACCEL_BIAS_NAMES], dtype=np.float64)

    def gyro_m(self) -> np.ndarray:
        """Mg (3×3), NaN where not measured."""
        return names_to_matrix("G", self.constants())

    def gyro_gsens(self) -> np.ndarray:
        """GA (3×3), (°/s)/g."""
        return names_to_gsens(self.constants())

    def gyro_bias(self) -> np.ndarray:
        """G0 (3,), °/s."""
        return np.array([getattr(self, n) for n in GYRO_BIAS_NAMES], dtype=np.float64)

    # ---- JSON ----------------------------------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict: constants under their names + units, tolerances, pass flags."""
        return {
            "format": "imu-bench calibration result",
            "format_version": self.FORMAT_VERSION,
            "serial": self.serial,
            "created": self.created,
            "constants": _jsonable(self.constants()),
            "units": dict(UNITS),
            "tolerances": dict(TOLERANCES),
            "pass": self.passed(),
            "all_passed": self.all_passed,
            "g": self.g,
            "g_unit": "m/s²",
            "latitude_deg": self.latitude_deg,
            "height_m": self.height_m,
            "turns": self.turns,
            "earth_rate": self.earth_rate,
            "method": self.method,
            "records": list(self.records),
            "bias_estimates": _jsonable(self.bias_estimates),
            "closed_form": _jsonable(self.closed_form),
            "std_errors": _jsonable(self.std_errors),
            "residuals": [r.to_dict() for r in self.residuals],
            "notes": list(self.notes),
        }

    def to_json(self) -> str:
        """The JSON text of :meth:`to_dict` (UTF-8, indented)."""
        return json.dumps(self.to_dict(), indent=2, ensure_ascii=False) + "\n"

    @classmethod
    def from_json(cls, text: str | bytes) -> CalibrationResult:
        """Parse :meth:`to_json` output; UserError on bad JSON or another format version."""
        try:
            d = json.loads(text)
        except (ValueError, UnicodeDecodeError) as exc:
            raise UserError(f"calibration result: not valid JSON ({exc})") from exc
        if not isinstance(d, dict) or "format_version" not in d:
            raise UserError("calibration result: not an imu-bench result (no format_version)")
        if d["format_version"] != cls.FORMAT_VERSION:
            raise UserError(
                f"calibration result format v{d['format_version']} but this program reads "
                f"v{cls.FORMAT_VERSION}; recompute it with 'python -m host calibrate --from-dir'"
            )
        try:
            consts: dict[str, Any] = {n: _num(d["constants"][n]) for n in CONSTANT_NAMES}
            return cls(
                serial=str(d["serial"]),
                created=str(d["created"]),
                g=float(d["g"]),
                latitude_deg=float(d["latitude_deg"]),
                height_m=float(d["height_m"]),
                turns=None if d.get("turns") is None else int(d["turns"]),
                earth_rate=bool(d.get("earth_rate", False)),
                method=str(d.get("method", "")),
                records=tuple(d.get("records", ())),
                bias_estimates={
                    k: (_num(v[0]), _num(v[1]), _num(v[2]))
                    for k, v in d.get("bias_estimates", {}).items()
                },
                closed_form={k: _num(v) for k, v in d.get("closed_form", {}).items()},
                std_errors={k: _num(v) for k, v in d.get("std_errors", {}).items()},
                residuals=tuple(RecordResidual.from_dict(r) for r in d.get("residuals", [])),
                notes=tuple(str(x) for x in d.get("notes", [])),
                **consts,
            )
        except (KeyError, TypeError, ValueError, IndexError) as exc:
            raise UserError(f"calibration result: missing or bad field ({exc})") from exc


# ---- the whole computation ----------------------------------------------------------------
def calibrate_from_records(
    session: Session,
    *,
    turns: int | None = None,
    latitude_deg: float = DEFAULT_LATITUDE_DEG,
    height_m: float = DEFAULT_HEIGHT_M,
    earth_rate: bool = False,
    created: str | None = None,
) -> CalibrationResult:
    """Check the records of ``session``, fit the §2 model, return every constant.

    ``turns``: n for turn records without meta ``turns`` (None: inferred per record).
    ``created``: date/time for the report header (default: now, local time, ISO).
    """
    from datetime import datetime

    g = local_gravity(latitude_deg, height_m)
    check_record_lengths(session)
    stats = {n: record_stats(r) for n, r in session.records.items()}
    obs, notes = build_observations(
        session, g, turns=turns, earth_rate=earth_rate, latitude_deg=latitude_deg, stats=stats
    )
    fit = fit_linear(obs, g)
    statics = [n for n, r in session.records.items() if r.kind == "static"]
    consts: dict[str, Any] = {}
    consts.update(matrix_to_names("A", fit.accel_m))
    consts.update(zip(ACCEL_BIAS_NAMES, map(float, fit.accel_bias), strict=True))
    consts.update(matrix_to_names("G", fit.gyro_m))
    consts.update(gsens_to_names(fit.gyro_gsens))
    consts.update(zip(GYRO_BIAS_NAMES, map(float, fit.gyro_bias), strict=True))
    anoise = np.max([stats[n].accel_std for n in statics], axis=0)
    gnoise = np.max([stats[n].gyro_std for n in statics], axis=0)
    consts.update(zip(ACCEL_NOISE_NAMES, map(float, anoise), strict=True))
    consts.update(zip(GYRO_NOISE_NAMES, map(float, gnoise), strict=True))

    # closed form where the plan has it
    closed: dict[str, float] = {}
    bias_est: dict[str, tuple[float, float, float]] = {}
    if all(n in stats for n in STATIC_NAMES):
        s1 = stage1(stats, g)
        closed.update(s1.constants())
        for i in range(3):
            a, b, c = (float(x) for x in s1.accel_bias_estimates[i])
            bias_est[ACCEL_BIAS_NAMES[i]] = (a, b, c)
            a, b, c = (float(x) for x in s1.gyro_bias_estimates[i])
            bias_est[GYRO_BIAS_NAMES[i]] = (a, b, c)
    turn_obs = {o.record: o for o in obs if o.kind == "turn"}
    ns = {o.turns for o in turn_obs.values()}
    n_turns = next(iter(ns)) if len(ns) == 1 else None
    if all(n in turn_obs for n in TURN_NAMES) and n_turns is not None:
        closed.update(matrix_to_names("G", stage2(stats, n_turns)))
    if len(ns) > 1:
        notes.append(
            "turn records with different numbers of turns: "
            f"{sorted(n for n in ns if n is not None)}"
        )

    # residuals per record
    ma, ba = fit.accel_m + np.eye(3), fit.accel_bias
    residuals: list[RecordResidual] = []
    for o in obs:
        rec = session.records[o.record]
        st = stats[o.record]
        nan3 = (math.nan, math.nan, math.nan)
        gr = fit.gyro_residuals[o.record]
        if o.kind == "turn":
            gm = tuple(float(x) for x in gr / o.tau)
            residuals.append(
                RecordResidual(
                    o.record, o.kind, st.n, st.duration_s, nan3, nan3,
                    (gm[0], gm[1], gm[2]), nan3, (float(gr[0]), float(gr[1]), float(gr[2])),
                )
            )  # fmt: skip
            continue
        if o.accel is not None:
            pred_a = ma @ (g * o.up) + ba
            am = rec.accel.mean(axis=0) - pred_a
            asd = st.accel_std
        else:
            am = asd = np.full(3, math.nan)
        residuals.append(
            RecordResidual(
                o.record, o.kind, st.n, st.duration_s,
                (float(am[0]), float(am[1]), float(am[2])),
                (float(asd[0]), float(asd[1]), float(asd[2])),
                (float(gr[0]), float(gr[1]), float(gr[2])),
                (float(st.gyro_std[0]), float(st.gyro_std[1]), float(st.gyro_std[2])),
            )
        )  # fmt: skip
    if not turn_obs:
        notes.append("no turn records: gyro scale and misalignment not measured")
    else:
        missing = [
            a
            for a, k in zip("XYZ", range(3), strict=True)
            if not np.all(np.isfinite(fit.gyro_m[:, k]))
        ]
        if missing:
            notes.append(f"no turn about {', '.join(missing)}: that gyro column not measured")

    return CalibrationResult(
        serial=session.serial,
        created=created or datetime.now().astimezone().isoformat(timespec="seconds"),
        g=g,
        latitude_deg=latitude_deg,
        height_m=height_m,
        turns=n_turns,
        earth_rate=earth_rate,
        records=tuple(session.records),
        bias_estimates=bias_est,
        closed_form=closed,
        std_errors=fit.std_errors,
        residuals=tuple(residuals),
        notes=tuple(notes),
        **consts,
    )


# ---- applying a calibration ---------------------------------------------------------------
def apply(
    result: CalibrationResult, accel_mps2: np.ndarray, gyro_dps: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Invert the §2 model: raw outputs -> calibrated specific force (m/s²) and rate (°/s).

    a = (I+Ma)⁻¹·(A − A0);  ω = (I+Mg)⁻¹·(G − G0 − GA·a/g). Accepts (3,) or (N,3) arrays.
    Gyro scale/misalignment not measured (NaN) are taken as nominal (0).
    """
    a_raw = np.asarray(accel_mps2, dtype=np.float64)
    g_raw = np.asarray(gyro_dps, dtype=np.float64)
    ia = np.eye(3) + result.accel_m()
    mg = np.nan_to_num(result.gyro_m(), nan=0.0)
    ig = np.eye(3) + mg
    a_cal = np.linalg.solve(ia, (a_raw - result.accel_bias()).T).T
    corr = g_raw - result.gyro_bias() - (a_cal / result.g) @ result.gyro_gsens().T
    g_cal = np.linalg.solve(ig, corr.T).T
    return a_cal, g_cal
