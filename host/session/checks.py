"""The checks every record passes before a fit (method.md §3, §4: the face up, the cube at
rest, the whole turn, the gyro range; a pose at rest without ``up``, a move joining two
poses); :mod:`host.session.observations` applies them."""

from __future__ import annotations

import math
from collections.abc import Collection

import numpy as np

from host.errors import RecordCheckError, UserError
from host.session.directory import Session, split_file_name
from host.session.method import (
    ORIENTATION_TOL_DEG,
    STATIC_MAX_ACCEL_STD,
    STATIC_MAX_GYRO_STD,
    RecordStats,
)
from host.session.records import (
    MIN_RECORD_ROWS,
    MOVE_NAME_RE,
    RECORD_NAME_RE,
    Record,
    RecordError,
    pose_name,
)


def axis_label(v: np.ndarray) -> str:
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
    """The bench record (``x_up`` … ``z_cw``, or a repeat such as ``x_ccw_2``) a check failure
    is about, when its file is this serial's ``SERIAL_name.txt``; None otherwise (another
    file, or a record the bench does not measure by that name)."""
    parts = split_file_name(exc.file_name) if exc.file_name else None
    if parts is None or parts[0] != serial or not RECORD_NAME_RE.fullmatch(parts[1]):
        return None
    return parts[1]


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
                f"{file_name}: gravity is on {axis_label(a)}, expected {axis_label(up)}: "
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


#: a turn record's first and last samples (this many) are where its opening and closing rests
#: end and begin (a cube stopped against the ruler rests from the sample after it stops) …
TURN_EDGE_SAMPLES = 2
#: … where the rate about up (the statics' bias removed) stays under this many °/s: faster, the
#: record starts or ends in motion and its angle is an unknown of the fit (the hand at rest
#: reads a fraction of a °/s; a turn cut there has missed under 0.1° of its angle)
TURN_EDGE_MOVING_DPS = 5.0
#: … and, without the bias from the statics (± its tolerance), under this fraction of the
#: turn's peak rate and at least this many °/s
TURN_EDGE_FRACTION = 0.1
TURN_EDGE_MIN_DPS = 20.0


def turn_edge_rates(record: Record, bias_dps: np.ndarray | None) -> tuple[float, float, float]:
    """(mean |rate| about up over the first ``TURN_EDGE_SAMPLES``, over the last, the peak
    |rate|), °/s, of a turn record; ``bias_dps`` (3,) the gyro bias on its face from the
    statics, or None (no bias removed)."""
    bias = np.zeros(3) if bias_dps is None else np.asarray(bias_dps, dtype=np.float64)
    rate = np.abs((record.gyro - bias) @ record.up)
    k = TURN_EDGE_SAMPLES
    return float(rate[:k].mean()), float(rate[-k:].mean()), float(rate.max())


def turn_in_motion(record: Record, bias_dps: np.ndarray | None) -> str:
    """Which ends of a turn record are in motion (method.md §4: the integral is the whole turn
    only between two rests): '' (it starts and ends at rest), 'starts', 'ends' or 'starts and
    ends', with the rates, e.g. 'ends in motion (83 °/s about +X at its last samples)'. An end
    is in motion when it turns faster than ``TURN_EDGE_MOVING_DPS`` about up (``bias_dps`` (3,)
    the gyro bias on this face from the statics), or, without that bias, faster than
    ``max(TURN_EDGE_FRACTION × peak, TURN_EDGE_MIN_DPS)``."""
    if record.kind != "turn" or len(record) < 4:
        return ""
    first, last, peak = turn_edge_rates(record, bias_dps)
    limit = (
        TURN_EDGE_MOVING_DPS
        if bias_dps is not None
        else max(TURN_EDGE_FRACTION * peak, TURN_EDGE_MIN_DPS)
    )
    where = [(w, r) for w, r in (("first", first), ("last", last)) if r > limit]
    if not where:
        return ""
    ends = " and ".join("starts" if w == "first" else "ends" for w, _ in where)
    rates = ", ".join(f"{r:.0f} °/s at its {w} samples" for w, r in where)
    return f"{ends} in motion ({rates}, about {axis_label(record.up)})"


def turns_of(record: Record, default: int | None) -> int | None:
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


def check_pose(record: Record, stats: RecordStats, g: float, file_name: str) -> None:
    """A pose (a rest at an attitude nobody set) must say no ``up`` (its attitude is fitted),
    read about one g and be at rest: else RecordCheckError naming the file and what to do."""
    if "up" in record.meta:
        raise RecordCheckError(
            f"{file_name}: a pose has no up direction (its attitude is fitted), but its header "
            "says 'up:'; delete that line, or name the record as a face (x_up …) if a cube "
            "set it",
            file_name=file_name,
        )
    norm = float(np.linalg.norm(stats.accel_mean))
    if not 0.7 * g < norm < 1.3 * g:
        raise RecordCheckError(
            f"{file_name}: the mean specific force is {norm:.2f} m/s², expected about "
            f"{g:.2f}: was the unit moving or not connected? {remedy(record)}",
            file_name=file_name,
        )
    if np.any(stats.accel_std > STATIC_MAX_ACCEL_STD) or np.any(
        stats.gyro_std > STATIC_MAX_GYRO_STD
    ):
        raise RecordCheckError(
            f"{file_name}: the unit moved during the pose (std {stats.accel_std.max():.3f} "
            f"m/s², {stats.gyro_std.max():.3f} °/s): hold it still; {remedy(record)}",
            file_name=file_name,
        )


def check_move(record: Record, poses: Collection[str], file_name: str) -> None:
    """A move must join two different poses of the session (header ``from:``/``to:``, or its
    name ``move_01_02``; both, they must agree) and stay inside the gyro range."""
    try:
        first, last = record.move_from, record.move_to
    except RecordError as exc:
        raise RecordCheckError(f"{file_name}: {exc}", file_name=file_name) from exc
    m = MOVE_NAME_RE.match(record.name)
    if m and (first, last) != (pose_name(int(m.group("a"))), pose_name(int(m.group("b")))):
        raise RecordCheckError(
            f"{file_name}: the header says the move goes from {first} to {last}, its name "
            f"says otherwise; rename the file or correct the header",
            file_name=file_name,
        )
    if first == last:
        raise RecordCheckError(
            f"{file_name}: the move starts and ends at {first}; a move joins two poses",
            file_name=file_name,
        )
    missing = [p for p in (first, last) if p not in poses]
    if missing:
        raise RecordCheckError(
            f"{file_name}: the move joins {first} and {last}, but the session has no "
            f"{' and no '.join(missing)}; add the pose record or delete the move",
            file_name=file_name,
        )
    check_range(record, file_name)
