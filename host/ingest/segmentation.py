"""Cutting a continuous stream into the plan's records (method.md §3-§6).

:func:`segment_stream` checks the stream's units (time spacing, gravity at rest), then reads it
as a person would (:mod:`host.ingest.reading`: rests, visits to faces, turns, the plan's choice
of statics, the warm-up apart); :func:`build_records` turns the labelled segments into records
with their timing quality (:mod:`host.session.spacing`). The table and the labels file that let
the user correct the cut are :mod:`host.ingest.labels`.

Every integral uses the true sample times (trapezoid rule over ``t``), never a nominal rate.
"""

from __future__ import annotations

import math

import numpy as np

from host.ingest import poses
from host.ingest.gaps import gap_between, gap_starts
from host.ingest.importing import Stream
from host.ingest.poses import is_pose_session, read_poses
from host.ingest.reading import Segment, read_session
from host.ingest.stillness import SegmentationError, Thresholds, axis_text
from host.session.records import (
    HEADING_KEY,
    MOVE_FROM_KEY,
    MOVE_NAME_RE,
    MOVE_TO_KEY,
    POSE_NAME_RE,
    STATIC_NAMES,
    TURN_NAMES,
    WARMUP_NAME,
    Record,
)
from host.session.spacing import timing_quality, trapezoid

MIN_SPACING_S = 20e-6  #: a median sample spacing outside these bounds means a wrong time unit
MAX_SPACING_S = 2.0
#: rests this close in gravity's direction, °, are one attitude (a whole turn's start and end)
SAME_ATTITUDE_DEG = 3.0


def segment_stream(
    stream: Stream, poses: bool = False
) -> tuple[list[Segment], Thresholds, list[str]]:
    """Segments in time order with proposed labels and the reason for each, the stillness
    thresholds, and notes on ambiguous choices (the alternatives are rows of the table).
    ``poses``: read every rest as a pose and each motion as a move, whoever's the session
    (else only when it is no session of the method's, :func:`host.ingest.poses.is_pose_session`)."""
    check_time_unit(stream)
    temp_recorded = "temperature" not in stream.meta and bool(np.ptp(stream.temp) > 0)
    segs, thr, notes = read_session(
        stream.t_s, stream.accel, stream.gyro, stream.temp, temp_recorded
    )
    if poses or is_pose_session(segs):  # every rest a pose, the moves between
        segs, notes = read_poses(stream.t_s, stream.accel, stream.gyro), []
    rests = [s for s in segs if s.found.startswith("still")]
    if not rests:
        raise SegmentationError(
            f"{stream.meta.get('source', 'stream')}: no still period found ({thr.text()}); "
            "is the time column in the right unit?"
        )
    norms = [float(np.linalg.norm(stream.accel[s.start : s.stop].mean(axis=0))) for s in rests]
    _check_gravity(stream, norms)
    segs = sorted(segs + gap_segments(stream), key=lambda s: (s.start, s.stop))
    return segs, thr, notes


def _where(stream: Stream, i: int) -> str:
    """'line 12' of the file (or 'sample 11' of a stream not from a text file)."""
    if stream.lines is not None:
        return f"line {int(stream.lines[i])}"
    return f"sample {i}"


def gap_segments(stream: Stream) -> list[Segment]:
    """One table row per gap in the stream's time (:mod:`host.ingest.gaps`), label ``-``."""
    t = stream.t_s
    out = []
    for g in gap_starts(t).tolist():
        dt = float(t[g] - t[g - 1])
        where = f"no samples from {_where(stream, g - 1)} to {_where(stream, g)}"
        why = "a gap in the time column: nothing is integrated across it"
        found = f"gap of {dt:.4g} s"
        out.append(Segment(g - 1, g + 1, float(t[g - 1]), float(t[g]), found, "-", where,
                           reason=why))  # fmt: skip
    return out


def gap_notes(stream: Stream) -> list[str]:
    """One line per gap in the stream's time, for the screen: where, how long, what it means."""
    src = stream.meta.get("source", "the file")
    return [
        f"{src}: {s.found} in the time column ({s.t0_s:.3f} s to {s.t1_s:.3f} s, {s.quality}): "
        "no rest, turn or move spans it"
        for s in gap_segments(stream)
    ]


def _check_gravity(stream: Stream, norms: list[float]) -> None:
    """At rest the accelerometer must read about g: else the unit is wrong — say which."""
    if not norms:
        return
    m = float(np.median(norms))
    src = stream.meta.get("source", "the file")
    if 7.0 < m < 12.5:
        return
    hint = ""
    if 0.7 < m < 1.3:
        hint = " — it looks like g: add --units accel=g"
    elif m > 100:
        hint = " — it looks like raw counts: add --units accel=counts:LSB_PER_G"
    elif 700 < m < 1300:
        hint = " — it looks like mg"
    raise SegmentationError(
        f"{src}: at rest the accelerometer reads |a| = {m:.4g} m/s² after the unit conversion, "
        f"gravity is about 9.81{hint}"
    )


def check_time_unit(stream: Stream) -> None:
    """Sample spacing must be plausible for an IMU (``MIN_SPACING_S`` … ``MAX_SPACING_S``):
    else the time column's unit is wrong — say which one it looks like."""
    t = stream.t_s
    if t.size < 2:
        return
    dt = float(np.median(np.diff(t)))
    src = stream.meta.get("source", "the file")
    if dt > MAX_SPACING_S:
        raise SegmentationError(
            f"{src}: the samples are {dt:.4g} s apart after the unit conversion "
            f"({stream.meta.get('units', '')}): is the time column in ms or µs? "
            "add --units t=ms or t=us"
        )
    if 0 < dt < MIN_SPACING_S:
        raise SegmentationError(
            f"{src}: the samples are {dt * 1e6:.3g} µs apart after the unit conversion "
            f"({stream.meta.get('units', '')}): is the time column in s or ms? "
            "add --units t=s or t=ms"
        )


def gyro_unit_hint(stream: Stream, segments: list[Segment]) -> str | None:
    """When no turn was found but the rotation between two still periods of one attitude is
    close to a whole number of 2π, the gyro is probably in rad/s: the hint, else None. Of a
    pose session: when the moves' rotations miss the poses' gravity (:mod:`host.ingest.poses`)."""
    if any(s.label.startswith("move_") for s in segments):
        return poses.gyro_unit_hint(stream.t_s, stream.accel, stream.gyro, segments)
    if any(s.turns for s in segments):
        return None
    still = [s for s in segments if s.found.startswith("still")]
    t, gyr = stream.t_s, stream.gyro
    gaps = gap_starts(t)
    for a, b in zip(still, still[1:], strict=False):
        lo, hi = a.stop - 1, b.start + 1
        if not _same_attitude(stream, a, b) or gap_between(gaps, lo, hi - 1):
            continue  # a whole turn comes back to the attitude it left, with no gap between
        bias = gyr[a.start : a.stop].mean(axis=0)
        angle = abs(float(trapezoid(t[lo:hi], gyr[lo:hi] - bias) @ np.asarray(a.up)))
        k = round(angle / (2 * math.pi))
        if k >= 1 and abs(angle - 2 * math.pi * k) < 0.15 * 2 * math.pi:
            return (
                f"between {a.t1_s:.1f} s and {b.t0_s:.1f} s the gyro integral about "
                f"{axis_text(np.asarray(a.up))} is {angle:.2f}, close to {k}·2π, and no turn "
                "was found: is the gyro in rad/s? add --units gyro=rad/s"
            )
    return None


def _same_attitude(stream: Stream, a: Segment, b: Segment) -> bool:
    """Two rests on one face whose gravity is within ``SAME_ATTITUDE_DEG`` (whole turns about
    up, in whatever unit, come back to the attitude they left; a tilted rest is on no face)."""
    if a.found != b.found or not a.found.startswith("still") or "tilted" in a.found:
        return False
    ga = stream.accel[a.start : a.stop].mean(axis=0)
    gb = stream.accel[b.start : b.stop].mean(axis=0)
    cos = float(ga @ gb) / max(float(np.linalg.norm(ga) * np.linalg.norm(gb)), 1e-12)
    return cos >= math.cos(math.radians(SAME_ATTITUDE_DEG))


def _up_text(up: tuple[float, float, float]) -> str:
    return axis_text(up)


def build_records(
    stream: Stream, segments: list[Segment], thresholds: Thresholds | None, serial: str
) -> dict[str, Record]:
    """Records (method.md §6) for every labelled segment: time since the segment's first sample
    (ms, from the stream's true times), the data, and metadata — source, column map, units,
    segmentation thresholds, the segment's place in the stream and its timing quality; its
    start as ``session_s`` (s since the stream's start) and, from a capture, ``power_on_s`` (the
    device clock, as live records have it: the workbench's time terms read it)."""
    out: dict[str, Record] = {}
    for s in segments:
        if s.label == "-":
            continue
        sl = slice(s.start, s.stop)
        t = stream.t_s[sl]
        tq = timing_quality(t)
        meta = {"serial": serial, **stream.meta}
        device_t0 = meta.pop("device_clock_s_at_t0", None)
        if device_t0 is not None:  # a capture: the device clock is the power-on time
            meta["power_on_s"] = f"{float(device_t0) + float(t[0]):.3f}"
        meta["session_s"] = f"{float(t[0] - stream.t_s[0]):.3f}"
        meta.update(_kind_meta(s))
        meta["segment_s"] = f"{s.t0_s:.3f}..{s.t1_s:.3f} of the stream"
        meta["segment_found"] = s.found
        if s.reason:
            meta["segment_reason"] = s.reason
        if thresholds is not None:
            meta["segmentation"] = thresholds.text()
        meta.update(tq.meta())
        out[s.label] = Record(
            name=s.label,
            t_ms=(t - t[0]) * 1000.0,
            accel=stream.accel[sl],
            gyro=stream.gyro[sl],
            temp=stream.temp[sl],
            meta=meta,
        )
    return out


def _kind_meta(s: Segment) -> dict[str, str]:
    """What a record's header says of its kind: a pose or a move (no ``up``: the attitude is
    fitted; a move its two poses), a turn (up, turns, direction), a static or the warm-up."""
    if POSE_NAME_RE.match(s.label):
        return {"kind": "pose"}
    if MOVE_NAME_RE.match(s.label):
        a, b = s.label.split("_")[1:]
        return {"kind": "move", MOVE_FROM_KEY: f"pose_{a}", MOVE_TO_KEY: f"pose_{b}"}
    turn = s.turns > 0 or s.label[1:].startswith(("_ccw", "_cw"))
    meta = {"kind": "turn" if turn else ("warmup" if s.label == WARMUP_NAME else "static")}
    meta["up"] = _up_text(s.up)
    if s.heading_deg is not None:
        meta[HEADING_KEY] = f"{s.heading_deg:g}"
    if turn:
        meta["turns"] = str(max(1, s.turns))
        meta["direction"] = "ccw" if s.direction > 0 else "cw"
    return meta


def plan_summary(records: dict[str, Record]) -> str:
    """Which records of the standard plan (6 statics, 6 turns) were found and which not; of a
    pose session, how many poses and moves."""
    n_pose = sum(1 for r in records.values() if r.kind == "pose")
    if n_pose:
        n_move = sum(1 for r in records.values() if r.kind == "move")
        return (f"{n_pose} pose records, {n_move} move records (every rest a pose, each motion "
                "between two a move)")  # fmt: skip
    have_s = [n for n in STATIC_NAMES if n in records]
    have_t = [n for n in TURN_NAMES if n in records]
    miss = [n for n in STATIC_NAMES + TURN_NAMES if n not in records]
    extra = [n for n in records if n not in STATIC_NAMES + TURN_NAMES]
    txt = f"{len(have_s)} of 6 static records, {len(have_t)} of 6 turn records"
    if miss:
        txt += f"; not found: {', '.join(miss)}"
    if extra:
        txt += f"; also: {', '.join(extra)}"
    return txt
