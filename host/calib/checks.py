"""The checks every record passes before a fit (method.md §3, §4: the face up, the cube at
rest, the whole turn, the gyro range) and each record's observation of the §2 model."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from host.calib.method import (
    DEFAULT_LATITUDE_DEG,
    EARTH_RATE_DPS,
    ORIENTATION_TOL_DEG,
    STATIC_MAX_ACCEL_STD,
    STATIC_MAX_GYRO_STD,
    TURN_ANGLE_SIGMA_DEG,
    TURN_ANGLE_TOL_DEG,
    RecordStats,
    record_stats,
)
from host.calib.records import MIN_RECORD_ROWS, STATIC_NAMES, TURN_NAMES, Record, Session
from host.errors import RecordCheckError, UserError


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


def failed_record(exc: RecordCheckError, serial: str) -> str | None:
    """The bench record (``x_up`` … ``z_cw``) a check failure is about, when its file is this
    serial's ``SERIAL_name.txt``; None otherwise (another file, or a record the bench does not
    measure by that name)."""
    for name in STATIC_NAMES + TURN_NAMES:
        if exc.file_name == f"{serial}_{name}.txt":
            return name
    return None


def check_orientation(record: Record, stats: RecordStats, g: float, file_name: str) -> None:
    """Gravity must be along the record's up direction (static, turn): else UserError naming
    the file, where gravity is and what to re-measure."""
    if record.kind not in ("static", "turn"):
        return
    up = record.up
    a = stats.accel_mean
    norm = float(np.linalg.norm(a))
    if not 0.7 * g < norm < 1.3 * g:
        raise RecordCheckError(
            f"{file_name}: the mean specific force is {norm:.2f} m/s², expected about "
            f"{g:.2f}: was the unit moving or not connected? {remedy(record)}",
            file_name=file_name,
        )
    angle = math.degrees(math.acos(max(-1.0, min(1.0, float(a @ up) / norm))))
    if angle > ORIENTATION_TOL_DEG:
        if np.count_nonzero(up) == 1:
            raise RecordCheckError(
                f"{file_name}: gravity is on {_axis_label(a)}, expected {_axis_label(up)}: "
                f"the cube was on the wrong face; {remedy(record)}",
                file_name=file_name,
            )
        raise RecordCheckError(
            f"{file_name}: gravity is {angle:.0f}° away from the expected up direction "
            f"{np.round(up, 3).tolist()}; {remedy(record)}",
            file_name=file_name,
        )
    if record.kind == "static":
        if np.any(stats.accel_std > STATIC_MAX_ACCEL_STD) or np.any(
            stats.gyro_std > STATIC_MAX_GYRO_STD
        ):
            raise RecordCheckError(
                f"{file_name}: the cube moved during the static measurement (std "
                f"{stats.accel_std.max():.3f} m/s², {stats.gyro_std.max():.3f} °/s); "
                f"{remedy(record)}",
                file_name=file_name,
            )


def check_range(record: Record, file_name: str) -> None:
    """§4: every gyro sample of a turn must stay inside the working range (meta
    ``gyro_range_dps``, e.g. 250); no check when the record does not state its range."""
    if "gyro_range_dps" not in record.meta:
        return
    try:
        rng = float(record.meta["gyro_range_dps"])
    except ValueError as exc:
        raise RecordCheckError(
            f"{file_name}: bad meta gyro_range_dps", file_name=file_name
        ) from exc
    peak = float(np.abs(record.gyro).max()) if len(record) else 0.0
    if peak >= rng - 0.01:
        raise RecordCheckError(
            f"{file_name}: the rate reached {peak:.1f} °/s, outside the working range "
            f"±{rng:g} °/s; {remedy(record, 'turn more slowly and re-measure')}",
            file_name=file_name,
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
            raise RecordCheckError(
                f"{session.path_of(name)}: {len(rec)} data row{'s' if len(rec) != 1 else ''}; "
                f"a record needs at least {MIN_RECORD_ROWS} samples (its mean and std) — "
                "re-measure this record",
                file_name=session.path_of(name),
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
                raise RecordCheckError(f"{fname}: turns must be at least 1", file_name=fname)
            want = rec.sign * 360.0 * n
            tol = 0.05 * 360.0 * n + TURN_ANGLE_TOL_DEG + (0.0 if pre is not None else 20.0 * t)
            if along * rec.sign < -90.0:
                direction = "counter-clockwise" if rec.sign > 0 else "clockwise"
                raise RecordCheckError(
                    f"{fname}: the cube turned {along:+.0f}° about {_axis_label(up)}, the wrong "
                    f"way (expected {direction}); {remedy(rec)}",
                    file_name=fname,
                )
            if abs(along - want) > tol:
                raise RecordCheckError(
                    f"{fname}: the cube turned {along:+.0f}° about {_axis_label(up)}, expected "
                    f"{want:+.0f}° ({n} turn{'s' if n > 1 else ''}): the turn was not complete "
                    f"or --turns is wrong; {remedy(rec)}",
                    file_name=fname,
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
                raise RecordCheckError(
                    f"{fname}: a rate-table record needs meta 'up: [x, y, z]'", file_name=fname
                )
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
