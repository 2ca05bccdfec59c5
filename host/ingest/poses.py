"""A session read as poses and moves: every rest a pose record, the motion between two a move.

A unit held still by hand in many attitudes nobody set and moved by hand between them (the
multi-position method of Tedaldi, Pretto and Menegatti, ICRA 2014, that imu_tk implements) has
no faces and no turns: the method's reading (:mod:`host.ingest.reading`) keeps few of its rests.

1. **Whose session** (:func:`is_pose_session`): the method's own when its reading explains its
   rests (a record, an alternative for one, a shorter rest of a visit, a rest between turns);
   a pose session when the rests it leaves out without a role outnumber the records it found.
2. **Poses** (:func:`read_poses`): every rest of at least ``MIN_POSE_S`` in time order,
   ``pose_01``, ``pose_02``, … (a shorter rest is a pause inside a move).
3. **Moves**: the motion between two consecutive poses, ``move_01_02``, …, cut as a turn is:
   from the end of the rest before (its last two samples) to the start of the rest after (its
   first two). No move spans a gap in time (:mod:`host.ingest.gaps`). Each move's quality
   says how far it turned (the gyro integrated with exact attitude kinematics, bias removed)
   and by how much that rotation misses turning the gravity seen at the first pose into the
   gravity seen at the next: a few degrees with the nominal scale, tens of degrees when the
   gyro's unit is wrong (:func:`gyro_unit_hint`).
"""

from __future__ import annotations

import math

import numpy as np

from host.ingest.gaps import gap_between, gap_starts
from host.ingest.reading import MIN_STATIC_S, Segment
from host.ingest.stillness import Rest, attitude, axis_text, rests
from host.session.records import move_name, pose_name

MIN_POSE_S = MIN_STATIC_S  #: a rest at least this long is a pose (shorter: a pause), s
#: reasons of the method's reading for a rest it explains without making it a record
EXPLAINED = ("alternative for", "a shorter rest", "a rest on")
#: a rotation that misses the next pose's gravity by more than this (median over the moves, °)
#: with the gyro as read, and by a third of it or less in another unit, names that unit
UNIT_MISS_DEG = 20.0


def is_pose_session(method_segments: list[Segment]) -> bool:
    """True when the method's reading leaves out more rests (of at least ``MIN_POSE_S``)
    without a role than it finds records (module docstring, item 1)."""
    records = [s for s in method_segments if s.label != "-"]
    unused = [
        s
        for s in method_segments
        if s.found.startswith("still")
        and s.label == "-"
        and s.duration_s >= MIN_POSE_S
        and not s.reason.startswith(EXPLAINED)
    ]
    return len(unused) > len(records)


def _gravity_text(mean: np.ndarray) -> str:
    _, up, off = attitude(mean)
    return f"{off:.0f}° off {axis_text(up)}"


def read_poses(t: np.ndarray, acc: np.ndarray, gyr: np.ndarray) -> list[Segment]:
    """Pose and move segments of a stream (times s, accel m/s², gyro °/s) in time order
    (module docstring, items 2-3)."""
    found, _, bias = rests(t, acc, gyr)
    poses = [r for r in found if float(t[r.stop - 1] - t[r.start]) >= MIN_POSE_S]
    gaps = gap_starts(t)
    segs = [_pose_segment(t, acc, gyr, r, k + 1) for k, r in enumerate(poses)]
    for k in range(len(poses) - 1):
        a, b = poses[k], poses[k + 1]
        if not gap_between(gaps, a.stop - 1, b.start):  # the gap's own row says why not
            segs.append(_move_segment(t, acc, gyr - bias, a, b, k + 1))
    segs.sort(key=lambda s: (s.start, s.stop))
    return segs


def _pose_segment(t: np.ndarray, acc: np.ndarray, gyr: np.ndarray, r: Rest, n: int) -> Segment:
    a = acc[r.start : r.stop]
    mean = a.mean(axis=0)
    q = (
        f"gravity {_gravity_text(mean)}, |a| {np.linalg.norm(mean):.3f} m/s², std a "
        f"{a.std(axis=0).max():.3g} m/s², std g {gyr[r.start : r.stop].std(axis=0).max():.3g} °/s"
    )
    found = f"still, {_gravity_text(mean)}"
    why = f"{pose_name(n)}: the {n}. rest, a pose (its attitude is fitted)"
    up = tuple(float(x) for x in mean / max(float(np.linalg.norm(mean)), 1e-12))
    return Segment(r.start, r.stop, float(t[r.start]), float(t[r.stop - 1]), found,
                   pose_name(n), q, (up[0], up[1], up[2]), reason=why)  # fmt: skip


def _move_segment(
    t: np.ndarray, acc: np.ndarray, rate: np.ndarray, a: Rest, b: Rest, n: int
) -> Segment:
    start, stop = max(a.start, a.stop - 2), min(b.stop, b.start + 2)
    g0, g1 = acc[a.start : a.stop].mean(axis=0), acc[b.start : b.stop].mean(axis=0)
    angle, miss = move_rotation(t[start:stop], rate[start:stop], g0, g1)
    q = (
        f"{angle:.1f}° from {pose_name(n)} to {pose_name(n + 1)}; the rotation turns the first "
        f"one's gravity onto the next one's within {miss:.1f}°"
    )
    why = f"{move_name(n, n + 1)}: the motion from {pose_name(n)} to {pose_name(n + 1)}"
    return Segment(start, stop, float(t[start]), float(t[stop - 1]), f"move {angle:.0f}°",
                   move_name(n, n + 1), q, reason=why)  # fmt: skip


def _rotation(v: np.ndarray) -> np.ndarray:
    """The rotation matrix of rotation vector ``v`` (rad), Rodrigues' formula."""
    th = float(np.linalg.norm(v))
    if th < 1e-12:
        return np.eye(3)
    k = v / th
    kx = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + math.sin(th) * kx + (1.0 - math.cos(th)) * (kx @ kx)


def move_rotation(
    t_s: np.ndarray, rate_dps: np.ndarray, gravity_before: np.ndarray, gravity_after: np.ndarray
) -> tuple[float, float]:
    """The angle a move turned (°: of the body rotation, the body rates ``rate_dps`` (N,3)
    integrated interval by interval, midpoint rates, exact kinematics) and the angle (°)
    between the gravity it predicts at the next rest (the first rest's, carried by the
    rotation) and the gravity seen there."""
    w = np.radians(np.asarray(rate_dps, dtype=np.float64))
    dt = np.diff(np.asarray(t_s, dtype=np.float64))
    r = np.eye(3)
    for k in range(dt.size):
        r = r @ _rotation(0.5 * (w[k] + w[k + 1]) * dt[k])
    angle = math.degrees(math.acos(max(-1.0, min(1.0, (float(np.trace(r)) - 1.0) / 2.0))))
    g_pred = r.T @ (np.asarray(gravity_before) / np.linalg.norm(gravity_before))
    g_seen = np.asarray(gravity_after) / np.linalg.norm(gravity_after)
    miss = math.degrees(math.acos(max(-1.0, min(1.0, float(g_pred @ g_seen)))))
    return angle, miss


def gyro_unit_hint(
    t: np.ndarray, acc: np.ndarray, gyr: np.ndarray, segments: list[Segment]
) -> str | None:
    """When the moves' rotations miss the next pose's gravity by more than ``UNIT_MISS_DEG``
    (median) and a gyro read in another unit would not: the ``--units`` to add, else None."""
    moves = [s for s in segments if s.label.startswith("move_")]
    poses = {s.label: s for s in segments if s.label.startswith("pose_")}
    if len(moves) < 3:
        return None
    rest = np.median(gyr[np.concatenate([np.arange(p.start, p.stop) for p in poses.values()])],
                     axis=0)  # fmt: skip

    def median_miss(factor: float) -> float:
        misses = []
        for m in moves:
            a, b = m.label.split("_")[1:]
            pa, pb = poses[f"pose_{a}"], poses[f"pose_{b}"]
            g0 = acc[pa.start : pa.stop].mean(axis=0)
            g1 = acc[pb.start : pb.stop].mean(axis=0)
            sl = slice(m.start, m.stop)
            misses.append(move_rotation(t[sl], factor * (gyr[sl] - rest), g0, g1)[1])
        return float(np.median(misses))

    as_read = median_miss(1.0)
    if as_read <= UNIT_MISS_DEG:
        return None
    for factor, units in ((180.0 / math.pi, "gyro=rad/s"), (math.pi / 180.0, "gyro=deg/s")):
        other = median_miss(factor)
        if other <= as_read / 3.0:
            return (
                f"the moves' rotations miss the next pose's gravity by {as_read:.0f}° (median), "
                f"by {other:.1f}° with the gyro read in the other unit: is the gyro's unit "
                f"wrong? try --units {units}"
            )
    return None
