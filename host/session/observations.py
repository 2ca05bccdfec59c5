"""Each record's observation of the §2 model (method.md §3, §4), after its checks
(:mod:`host.session.checks`): the means of a static or rate-table record, the integral of
a turn, with their standard errors."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from host.errors import RecordCheckError, UserError
from host.session.checks import (
    axis_label,
    check_move,
    check_orientation,
    check_pose,
    check_range,
    check_record_lengths,
    check_turn_at_rest,
    remedy,
    turns_of,
)
from host.session.directory import Session
from host.session.method import (
    DEFAULT_LATITUDE_DEG,
    EARTH_RATE_DPS,
    TURN_ANGLE_SIGMA_DEG,
    TURN_ANGLE_TOL_DEG,
    RecordStats,
    record_stats,
)
from host.session.records import Record


@dataclass(frozen=True, eq=False)
class Observation:
    """One record's contribution to the linear fit.

    Per gyro channel i the model is ``gyro[i] = (I+Mg)[i]·rate + GA[i]·force + G0[i]·tau``;
    per accel channel ``accel[i] = (I+Ma)[i]·(g·up) + A0[i]`` (means only).

    static / rate / pose: ``gyro`` = channel means (°/s), ``rate`` = reference rate (°/s),
    ``force`` = up direction (g; a pose's first estimate of its attitude), ``tau`` = 1.
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


def rest_up(record: Record, stats: RecordStats) -> np.ndarray:
    """(3,) the up direction of a rest: a static's set one, a pose's first estimate (its mean
    specific force, normalised; the model refines it, :mod:`host.model.poses`)."""
    if record.kind == "pose":
        return np.asarray(stats.accel_mean / np.linalg.norm(stats.accel_mean))
    return record.up


def pose_or_move(
    rec: Record, s: RecordStats, earth: float, accel_noise: np.ndarray, gyro_noise: np.ndarray
) -> Observation:
    """The observation of a pose (its means, against gravity along its first attitude, and
    the vertical Earth rate ``earth`` °/s along it) or of a move (its integral; the model reads
    it against the rests it joins, :mod:`host.model.poses`). ``accel_noise``, ``gyro_noise``
    (3,): the per-sample σ of the rests, m/s² and °/s."""
    if rec.kind == "pose":
        up = rest_up(rec, s)
        return Observation(
            record=rec.name, kind="pose", up=up, rate=earth * up, force=up.copy(), tau=1.0,
            gyro=s.gyro_mean, gyro_sigma=gyro_noise / math.sqrt(s.n), accel=s.accel_mean,
            accel_sigma=accel_noise / math.sqrt(s.n),
        )  # fmt: skip
    t = s.duration_s
    up = s.accel_mean / max(float(np.linalg.norm(s.accel_mean)), 1e-9)
    return Observation(
        record=rec.name, kind="move", up=up, rate=np.zeros(3), force=up, tau=t,
        gyro=s.gyro_integral, gyro_sigma=gyro_noise * math.sqrt(s.dt_s * t),
    )  # fmt: skip


def _checked_rests(session: Session, stats: Mapping[str, RecordStats], g: float) -> list[str]:
    """The static and pose records, each checked (:func:`check_orientation`,
    :func:`check_pose`); UserError when there are none."""
    rests = [n for n, r in session.records.items() if r.kind in ("static", "pose")]
    if not rests:
        raise UserError(
            "no static or pose records (SERIAL_x_up.txt …, SERIAL_pose_01.txt …): the "
            "calibration needs rests"
        )
    for name in rests:
        rec = session.records[name]
        check = check_pose if rec.kind == "pose" else check_orientation
        check(rec, stats[name], g, session.path_of(name))
    return rests


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
    statics = _checked_rests(session, st, g)
    accel_noise = np.maximum(np.max([st[n].accel_std for n in statics], axis=0), 1e-4)
    gyro_noise = np.maximum(np.max([st[n].gyro_std for n in statics], axis=0), 1e-3)
    earth = EARTH_RATE_DPS * math.sin(math.radians(latitude_deg)) if earth_rate else 0.0

    # rests-only preliminary gyro bias and g-sensitivity for the turn checks
    xs = np.array([np.concatenate([rest_up(session.records[n], st[n]), [1.0]]) for n in statics])
    pre: np.ndarray | None = None
    if np.linalg.matrix_rank(xs) == 4:
        ys = np.array([st[n].gyro_mean for n in statics])
        pre, *_ = np.linalg.lstsq(xs, ys, rcond=None)  # (4,3): rows GA^T (3), bias

    poses = {n for n, r in session.records.items() if r.kind == "pose"}
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
            check_turn_at_rest(rec, fname, None if pre is None else pre[:3].T @ up + pre[3])
            t = s.duration_s
            drift = np.zeros(3) if pre is None else (pre[:3].T @ up + pre[3]) * t
            along = float(up @ (s.gyro_integral - drift))
            n = turns_of(rec, turns)
            if n is None:
                n = max(1, round(abs(along) / 360.0))
            if n < 1:
                raise RecordCheckError(f"{fname}: turns must be at least 1", file_name=fname)
            want = rec.sign * 360.0 * n
            tol = 0.05 * 360.0 * n + TURN_ANGLE_TOL_DEG + (0.0 if pre is not None else 20.0 * t)
            if along * rec.sign < -90.0:
                direction = "counter-clockwise" if rec.sign > 0 else "clockwise"
                raise RecordCheckError(
                    f"{fname}: the cube turned {along:+.0f}° about {axis_label(up)}, the wrong "
                    f"way (expected {direction}); {remedy(rec)}",
                    file_name=fname,
                )
            if abs(along - want) > tol:
                raise RecordCheckError(
                    f"{fname}: the cube turned {along:+.0f}° about {axis_label(up)}, expected "
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
        elif rec.kind in ("pose", "move"):
            if rec.kind == "move":
                check_move(rec, poses, fname)
            obs.append(pose_or_move(rec, s, earth, accel_noise, gyro_noise))
        else:
            notes.append(f"{fname}: not a static, turn or rate record; ignored")
    turn_axes = {(axis_label(o.up), int(np.sign(o.rate @ o.up))) for o in obs if o.kind == "turn"}
    for lab, sg in sorted(turn_axes):
        if (lab, -sg) not in turn_axes:
            notes.append(
                f"turn about {lab} only {'CCW' if sg > 0 else 'CW'}: its bias·T comes from the "
                "static records"
            )
    return obs, notes
