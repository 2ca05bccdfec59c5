"""Calibration of the accelerometer and gyro triads from records (method.md §2-§4, §7).

Model (method.md §2), in matrix form with chip axes x, y, z::

    A = (I + Ma)·a + A0                     a: true specific force, m/s²
    G = (I + Mg)·ω + GA·(a/g) + G0          ω: true rate, °/s; a/g in units of local g

    Ma = [[ Axx,  Axz, -Axy],     Mg = [[ Gxx,  Gxz, -Gxy],     GA = [[GAxx, GAxy, GAxz],
          [-Ayz,  Ayy,  Ayx],           [-Gyz,  Gyy,  Gyx],           [GAyx, GAyy, GAyz],
          [ Azy, -Azx,  Azz]]           [ Gzy, -Gzx,  Gzz]]           [GAzx, GAzy, GAzz]]

One engine: every number the project reports comes from the workbench's weighted
least-squares fit (:func:`host.modelling.model.fit_model`, its noise model) of the chosen
model (default ``base`` = the linear model above) — :func:`calibrate_from_records`. It
accepts other plans: turns without their opposite partner (the bias then comes from the
statics), extra static attitudes (meta ``up``), several turns per axis, rate-table records
(meta ``rate_dps``, ``rate_axis``). The closed form of the method — stage 1 (§3, six
statics) and stage 2 (§4, CW/CCW turn pairs integrated by the trapezoid rule over the
recorded sample times), :func:`stage1`, :func:`stage2` — is computed beside it and printed
as a check.

This module also holds the method's constants and sign layout (§2, §7), local gravity (§3) and
the record checks (:func:`build_observations`).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from host.calib.records import MIN_RECORD_ROWS, STATIC_NAMES, TURN_NAMES, Record, Session
from host.errors import UserError

if TYPE_CHECKING:
    from host.calib.result import CalibrationResult

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


# ---- the whole computation: the one engine ------------------------------------------------
def _synthetic_record(
    name: str, g: float, turns: int, temp_c: float, meta: Mapping[str, str]
) -> Record:
    """An ideal record of the standard plan (statics and turns of method.md §3, §4), used only
    to ask whether adding it would determine a parameter (the values do not matter)."""
    from host.calib.records import turn_window_s

    rng = np.random.default_rng(abs(hash(name)) % 2**32)
    up = np.zeros(3)
    up["xyz".index(name[0])] = -1.0 if name.endswith("_dn") else 1.0
    turn = name.endswith(("_ccw", "_cw"))
    seconds = turn_window_s(turns) if turn else 10.0
    t_ms = np.arange(0.0, seconds * 1000.0, 20.0)
    n = len(t_ms)
    gyro = rng.normal(0.0, 0.02, (n, 3))
    if turn:
        sign = 1.0 if name.endswith("_ccw") else -1.0
        profile = 1.0 - np.cos(2 * np.pi * t_ms / t_ms[-1])
        profile *= sign * 360.0 * turns / float(trapezoid_integral(t_ms, profile))
        gyro += profile[:, None] * up[None, :]
    accel = g * up + rng.normal(0.0, 0.01, (n, 3))
    return Record(name, t_ms, accel, gyro, np.full(n, temp_c), dict(meta))


def what_would_determine(
    session: Session,
    model: Any,
    names: Iterable[str],
    *,
    latitude_deg: float = DEFAULT_LATITUDE_DEG,
    height_m: float = DEFAULT_HEIGHT_M,
    turns: int | None = None,
) -> dict[str, str]:
    """For each parameter in ``names`` that the records of ``session`` do not determine under
    ``model`` (model terms of :mod:`host.modelling.model`): which records of the standard plan
    (method.md §3, §4) would determine it — 'add any one of: x_dn, y_dn' or 'add all of:
    x_ccw, x_cw' — else the term's own ``needs`` text."""
    from host.modelling.model import build_dataset, fit_model

    wanted = list(names)
    if not wanted:
        return {}
    g = local_gravity(latitude_deg, height_m)
    have = set(session.records)
    candidates = [n for n in STATIC_NAMES + TURN_NAMES if n not in have]
    recs = list(session.records.values())
    temp = float(np.mean([float(np.mean(r.temp)) for r in recs])) if recs else 25.0
    ns = [int(r.meta["turns"]) for r in recs if r.meta.get("turns", "").isdigit()]
    n_turns = turns or (ns[0] if ns else 1)
    meta: dict[str, str] = {}
    if recs and all("power_on_s" in r.meta for r in recs):
        last = max(float(r.meta["power_on_s"]) + r.duration_s for r in recs)
        meta["power_on_s"] = f"{last + 60.0:.3f}"
    synth = {c: _synthetic_record(c, g, n_turns, temp, meta) for c in candidates}

    def determined(extra: Iterable[str]) -> set[str]:
        records = dict(session.records)
        records.update({c: synth[c] for c in extra})
        try:
            ds = build_dataset(
                Session(session.serial, records), latitude_deg=latitude_deg, height_m=height_m,
                turns=n_turns,
            )  # fmt: skip
        except UserError:
            return set()
        return set(wanted) - set(fit_model(ds, model).undetermined)

    singles = {c: determined([c]) for c in candidates}
    everything = determined(candidates) if candidates else set()
    needs_of = {
        p: mt.term.needs for mt in model for ax in mt.axes for p in mt.term.param_labels(
            mt.sensor, ax)
    }  # fmt: skip
    out: dict[str, str] = {}
    for name in wanted:
        alone = [c for c in candidates if name in singles[c]]
        if alone:
            out[name] = f"add any one of: {', '.join(alone)}"
        elif name in everything:
            need = list(candidates)
            for c in candidates:  # greedy: drop what is not needed
                rest = [x for x in need if x != c]
                if rest and name in determined(rest):
                    need = rest
            out[name] = f"add all of: {', '.join(need)}"
        else:
            out[name] = needs_of.get(name, "") or "records that excite it"
    return out


def calibrate_from_records(
    session: Session,
    *,
    turns: int | None = None,
    latitude_deg: float = DEFAULT_LATITUDE_DEG,
    height_m: float = DEFAULT_HEIGHT_M,
    earth_rate: bool = False,
    created: str | None = None,
    model: str = "base",
    term_files: Iterable[str] = (),
    noise: Any = None,
) -> CalibrationResult:
    """Check the records of ``session``, fit ``model`` (default ``base``, method.md §2) with
    the workbench's weighted least squares (:func:`host.modelling.model.fit_model`, its noise model
    ``noise``, default :class:`host.modelling.model.NoiseModel`), return every parameter.

    The closed form of §3/§4 is computed beside it where the plan has it (``closed_form``).
    Parameters the records do not determine are NaN with what would determine them; they make
    ``all_passed`` False. ``turns``: n for turn records without meta ``turns`` (None: inferred
    per record). ``term_files``: Python files with custom terms. ``created``: date/time for
    the report header (default: now, local time, ISO).
    """
    from datetime import datetime

    check_record_lengths(session)
    from host.calib.result import (
        CalibrationResult,
        FitQuality,
        ParameterResult,
        RecordResidual,
        within,
    )
    from host.modelling.model import (
        ALPHA_FIT,
        CATALOGUE,
        NoiseModel,
        build_dataset,
        fit_model,
        load_term_file,
        parse_model,
        short_spec,
    )

    files = tuple(str(f) for f in term_files)
    cat = dict(CATALOGUE)
    for f in files:
        cat = load_term_file(f, cat)
    mts = parse_model(model, cat)
    nm = noise if noise is not None else NoiseModel()
    g = local_gravity(latitude_deg, height_m)
    ds = build_dataset(
        session, noise=nm, latitude_deg=latitude_deg, height_m=height_m, turns=turns,
        earth_rate=earth_rate,
    )  # fmt: skip
    fit = fit_model(ds, mts)
    stats = {n: record_stats(r) for n, r in session.records.items()}
    statics = [s.name for s in ds.signals if s.kind == "static"]
    noise_std: dict[str, float] = {}
    anoise = np.max([stats[n].accel_std for n in statics], axis=0)
    gnoise = np.max([stats[n].gyro_std for n in statics], axis=0)
    noise_std.update(zip(GYRO_NOISE_NAMES, map(float, gnoise), strict=True))
    noise_std.update(zip(ACCEL_NOISE_NAMES, map(float, anoise), strict=True))

    needs = what_would_determine(
        session, mts, fit.undetermined, latitude_deg=latitude_deg, height_m=height_m,
        turns=turns,
    )  # fmt: skip
    params = tuple(
        ParameterResult(
            p.term_name,
            p.sensor,
            p.axis,
            p.key,
            p.name,
            p.value,
            p.stderr,
            p.unit,
            TOLERANCES.get(p.name),
            within(p.name, p.value),
            needs.get(p.name, ""),
        )  # fmt: skip
        for p in fit.parameters
    )

    # closed form where the plan has it (the check printed beside the fit)
    closed: dict[str, float] = {}
    bias_est: dict[str, tuple[float, float, float]] = {}
    if all(n in stats and session.records[n].kind == "static" for n in STATIC_NAMES):
        s1 = stage1(stats, g)
        closed.update(s1.constants())
        for i in range(3):
            a, b, c = (float(x) for x in s1.accel_bias_estimates[i])
            bias_est[ACCEL_BIAS_NAMES[i]] = (a, b, c)
            a, b, c = (float(x) for x in s1.gyro_bias_estimates[i])
            bias_est[GYRO_BIAS_NAMES[i]] = (a, b, c)
    ns = set(ds.turns_of.values())
    n_turns = next(iter(ns)) if len(ns) == 1 else None
    if all(n in ds.turns_of for n in TURN_NAMES) and n_turns is not None:
        closed.update(matrix_to_names("G", stage2(stats, n_turns)))

    # residuals per record, from the fit's record/channel values
    by = {(gr.record, gr.sensor, gr.axis): gr.residual for gr in fit.groups}
    nan3 = (math.nan, math.nan, math.nan)

    def t3(v: Iterable[float]) -> tuple[float, float, float]:
        a, b, c = (float(x) for x in v)
        return (a, b, c)

    residuals: list[RecordResidual] = []
    for sig in ds.signals:
        st = stats[sig.name]
        gr = t3(by.get((sig.name, "gyro", ax), math.nan) for ax in "xyz")
        if sig.kind == "turn":
            residuals.append(RecordResidual(
                sig.name, sig.kind, st.n, st.duration_s, nan3, nan3,
                t3(x / st.duration_s for x in gr), nan3, gr,
            ))  # fmt: skip
            continue
        ar = t3(by.get((sig.name, "accel", ax), math.nan) for ax in "xyz")
        residuals.append(RecordResidual(
            sig.name, sig.kind, st.n, st.duration_s, ar, t3(st.accel_std), gr, t3(st.gyro_std),
        ))  # fmt: skip

    # the power-on-time note matters only to time terms, which base does not have
    only_base = all(
        mt.term.name in ("bias", "scale", "misalignment", "g_sensitivity") for mt in mts
    )
    notes = [n for n in ds.notes if not (only_base and "power_on_s" in n)]
    if len(ns) > 1:
        notes.append(f"turn records with different numbers of turns: {sorted(ns)}")
    if fit.uncertainty_note():
        notes.append(fit.uncertainty_note())
    combos = tuple(c.describe() for ch in fit.channels for c in ch.combinations)
    if fit.undetermined:
        notes.append(
            f"not determined by these records: {', '.join(fit.undetermined)} (nothing is fixed "
            "at zero; see what would determine each)"
        )
    verdict = (
        "inadequate"
        if fit.scaled or fit.chi2_p < ALPHA_FIT
        else ("untestable" if fit.untestable else "adequate")
    )
    quality = FitQuality(
        fit.chi2, fit.dof, fit.rms_z, fit.chi2_p, verdict, fit.untestable, fit.uncertainty_note()
    )
    return CalibrationResult(
        serial=session.serial,
        created=created or datetime.now().astimezone().isoformat(timespec="seconds"),
        g=g,
        latitude_deg=latitude_deg,
        height_m=height_m,
        turns=n_turns,
        model=short_spec(mts),
        parameters=params,
        noise_std=noise_std,
        fit=quality,
        noise_model={"block_s": nm.block_s, "max_blocks": nm.max_blocks,
                     "floor": dict(nm.floor), "turn_angle_sigma_deg": nm.turn_angle_sigma_deg},
        term_files=tuple(str(Path(f).resolve()) for f in files),
        temp_mean_c=float(ds.signals[0].temp_mean_c) if ds.signals else 25.0,
        time_known=ds.time_known,
        earth_rate=earth_rate,
        records=tuple(s.name for s in ds.signals),
        bias_estimates=bias_est,
        closed_form=closed,
        combinations=combos,
        residuals=tuple(residuals),
        notes=tuple(notes),
    )  # fmt: skip


def __getattr__(name: str) -> Any:
    """``CalibrationResult``, ``RecordResidual`` and ``apply`` live in :mod:`host.calib.result`;
    imports from here keep working."""
    if name in ("CalibrationResult", "RecordResidual", "apply"):
        from host.calib import result

        return getattr(result, name)
    raise AttributeError(f"module 'host.calib.calibration' has no attribute {name!r}")
