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
    remedy,
    turn_in_motion,
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
    ``tau`` = T (s), the record duration; ``in_motion``: which of its ends are in motion and
    how fast (:func:`host.session.checks.turn_in_motion`; '': both at rest): its angle is then
    not ±360·n but an unknown of the fit.
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
    in_motion: str = ""


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


def _turn_observation(
    rec: Record,
    s: RecordStats,
    fname: str,
    g: float,
    bias: np.ndarray | None,
    turns: int | None,
    sigmas: tuple[np.ndarray, float],
    earth: float,
) -> Observation:
    """A turn record's observation after its checks (``g`` the local gravity, m/s²): its
    integral against ±360·n (n from ``turns``, its header or the integral) about up, with
    ``bias`` (3,) the gyro bias on its face from the statics (None: not known); ``sigmas``:
    the per-sample gyro noise (3,) °/s and the turn angle's σ, °. A turn that starts or ends
    in motion is kept, with which ends (:attr:`Observation.in_motion`); one far from whole
    turns is refused with its name."""
    check_orientation(rec, s, g, fname)
    check_range(rec, fname)
    up, t = rec.up, s.duration_s
    moving = turn_in_motion(rec, bias)
    along = float(up @ (s.gyro_integral - (np.zeros(3) if bias is None else bias * t)))
    n = turns_of(rec, turns)
    n = max(1, round(abs(along) / 360.0)) if n is None else n
    if n < 1:
        raise RecordCheckError(f"{fname}: turns must be at least 1", file_name=fname)
    want = rec.sign * 360.0 * n
    tol = 0.05 * 360.0 * n + TURN_ANGLE_TOL_DEG + (0.0 if bias is not None else 20.0 * t)
    if along * rec.sign < -90.0:
        direction = "counter-clockwise" if rec.sign > 0 else "clockwise"
        raise RecordCheckError(
            f"{fname}: the cube turned {along:+.0f}° about {axis_label(up)}, the wrong way "
            f"(expected {direction}); {remedy(rec)}",
            file_name=fname,
        )
    if abs(along - want) > tol:
        cut = f" (the record {moving}: cut it where the cube rests)" if moving else ""
        raise RecordCheckError(
            f"{fname}: the cube turned {along:+.0f}° about {axis_label(up)}, expected "
            f"{want:+.0f}° ({n} turn{'s' if n > 1 else ''}){cut}: the turn was not complete "
            f"or --turns is wrong; {remedy(rec)}",
            file_name=fname,
        )
    noise, angle_sd = sigmas
    return Observation(
        record=rec.name, kind="turn", up=up, rate=want * up + earth * up * t, force=up * t,
        tau=t, gyro=s.gyro_integral, gyro_sigma=np.sqrt(noise**2 * s.dt_s * t + angle_sd**2),
        turns=n, in_motion=moving,
    )  # fmt: skip


def _rate_observation(
    rec: Record, s: RecordStats, fname: str, earth: float, gyro_noise: np.ndarray
) -> Observation:
    """A rate-table record's observation: its gyro means against ``rate_dps`` about its
    ``rate_axis`` (and the vertical Earth rate ``earth`` °/s along up)."""
    if "up" not in rec.meta:
        raise RecordCheckError(
            f"{fname}: a rate-table record needs meta 'up: [x, y, z]'", file_name=fname
        )
    up_r = rec.up
    axis = rec.rate_axis
    force = up_r if abs(float(up_r @ axis)) > 0.999 else float(up_r @ axis) * axis
    return Observation(
        record=rec.name, kind="rate", up=up_r, rate=rec.rate_dps * axis + earth * up_r,
        force=force, tau=1.0, gyro=s.gyro_mean,
        gyro_sigma=np.maximum(s.gyro_std, gyro_noise) / math.sqrt(s.n),
    )  # fmt: skip


def _rest_bias(
    session: Session, st: Mapping[str, RecordStats], rests: list[str]
) -> np.ndarray | None:
    """(4, 3) the rests-only preliminary gyro g-sensitivity (rows GAᵀ, per g) and bias, °/s,
    for the turn checks; None unless the rests' attitudes span the three axes."""
    xs = np.array([np.concatenate([rest_up(session.records[n], st[n]), [1.0]]) for n in rests])
    if np.linalg.matrix_rank(xs) < 4:
        return None
    ys = np.array([st[n].gyro_mean for n in rests])
    pre, *_ = np.linalg.lstsq(xs, ys, rcond=None)
    return np.asarray(pre)


def _turn_notes(obs: list[Observation]) -> list[str]:
    """What the turns leave to the statics or to the fit: an axis turned one way only, a turn
    in motion at an end (its angle an unknown)."""
    notes = [
        f"{o.record}: the turn record {o.in_motion}: its angle is an unknown of the fit, and "
        "the gyro scale about its axis comes from the other records"
        for o in obs
        if o.kind == "turn" and o.in_motion
    ]
    turn_axes = {(axis_label(o.up), int(np.sign(o.rate @ o.up))) for o in obs if o.kind == "turn"}
    for lab, sg in sorted(turn_axes):
        if (lab, -sg) not in turn_axes:
            notes.append(
                f"turn about {lab} only {'CCW' if sg > 0 else 'CW'}: its bias·T comes from the "
                "static records"
            )
    return notes


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
    A turn record that starts or ends in motion is kept with its angle an unknown
    (:attr:`Observation.in_motion`, a note says so).
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
    pre = _rest_bias(session, st, statics)
    poses = {n for n, r in session.records.items() if r.kind == "pose"}
    obs: list[Observation] = []
    for name, rec in session.records.items():
        s, fname = st[name], session.path_of(name)
        if rec.kind == "static":
            obs.append(
                Observation(
                    record=name, kind="static", up=rec.up, rate=earth * rec.up,
                    force=rec.up.copy(), tau=1.0, gyro=s.gyro_mean,
                    gyro_sigma=gyro_noise / math.sqrt(s.n), accel=s.accel_mean,
                    accel_sigma=accel_noise / math.sqrt(s.n),
                )
            )  # fmt: skip
        elif rec.kind == "turn":
            bias = None if pre is None else pre[:3].T @ rec.up + pre[3]
            sigmas = (gyro_noise, turn_angle_sigma_deg)
            obs.append(_turn_observation(rec, s, fname, g, bias, turns, sigmas, earth))
        elif rec.kind == "rate":
            obs.append(_rate_observation(rec, s, fname, earth, gyro_noise))
        elif rec.kind in ("pose", "move"):
            if rec.kind == "move":
                check_move(rec, poses, fname)
            obs.append(pose_or_move(rec, s, earth, accel_noise, gyro_noise))
        else:
            notes.append(f"{fname}: not a static, turn or rate record; ignored")
    return obs, notes + _turn_notes(obs)
