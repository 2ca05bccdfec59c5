"""``calibrate --plan poses``: a calibration without a cube (the multi-position method of
Tedaldi, Pretto and Menegatti, ICRA 2014). The operator holds the unit still in an attitude,
then, at the beep, moves it to a new one and holds it still again; each measurement is the
move and the rest after it, cut into a move record (from the last sample of the rest before to
the first sample of the rest after) and a pose record (:func:`cut_move`). Before each one the
dialogue shows which directions of gravity are covered so far and asks for the attitude the
planner values most (:func:`next_up`: the one that most lowers the RMS σ/tolerance of a
linearised model of the accelerometer's rests and the gyro's moves) or the next of a fixed
scheme (``--plan poses16``: :data:`SIXTEEN`); from the tenth pose on it fits every record and
stops when every value the records determine meets ``--target`` (or after ``--max-extra``
poses). The fit is the engine's (:mod:`host.model.poses`)."""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Protocol

import numpy as np

from host.board.acquisition import Acquisition
from host.board.driver import Board
from host.calib.calibration import CalibrationOptions, calibrate_from_records
from host.dialogue.console import Questions
from host.dialogue.options import DialogueOptions
from host.errors import UserError
from host.model.poses import FRAME_FIXED
from host.session.checks import check_pose, check_range
from host.session.directory import Session
from host.session.method import TOLERANCES, record_stats
from host.session.records import POSE_NAME_RE, Record, move_name, pose_name

#: the 16 attitudes of the Earth-rate article's turntable scheme, as its text gives them (its
#: figure is not in the seed): every axis at −1 g, 0 and +1 g, in 8 opposite pairs — the six
#: faces, then the twelve edges' bisectors cut to ten by the pairs not repeating a face pair
SIXTEEN: tuple[tuple[float, float, float], ...] = tuple(
    tuple(float(c) for c in v / np.linalg.norm(v))  # type: ignore[misc]
    for v in np.array(
        [[0, 0, 1], [0, 0, -1], [1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0],
         [1, 1, 0], [-1, -1, 0], [1, -1, 0], [-1, 1, 0], [1, 0, 1], [-1, 0, -1],
         [0, 1, 1], [0, -1, -1], [1, 0, -1], [0, 1, -1]], dtype=float,
    )
)  # fmt: skip
#: poses before the first fit (the accelerometer's nine numbers need nine rests, the gyro's five
#: moves), and how long a move may take, s
FIRST_FIT_POSES = 10
MOVE_MAX_S = 5.0
#: a rate above this many σ of the gyro's noise (and above MOTION_MIN_DPS) is motion
MOTION_SIGMAS = 8.0
MOTION_MIN_DPS = 1.5
#: samples kept on either side of the motion found (the rest's last and first)
EDGE_S = 0.2


class Measuring(Protocol):
    """What the poses plan needs of the dialogue (:class:`host.dialogue.recorder.Recorder`)."""

    op: Questions
    serial: str
    g: float
    done: dict[str, Record]
    board: Board

    def _ask_static_seconds(self) -> float: ...

    def _acquire(
        self, name: str, seconds: float, title: str,
        enough: Callable[[np.ndarray, float], bool] | None = None,
    ) -> Acquisition | None: ...  # fmt: skip

    def _record(self, name: str, acq: Acquisition, extra: dict[str, str]) -> Record: ...

    def _loss_problems(self, name: str, acq: Acquisition) -> list[str]: ...

    def _decide(self, name: str, problems: list[str], attempts: int) -> bool: ...

    def _save(self, rec: Record, problems: Sequence[str] = ()) -> None: ...


def candidates(n: int = 200) -> np.ndarray:
    """(n, 3) unit vectors spread evenly over the sphere (a Fibonacci lattice)."""
    k = np.arange(n) + 0.5
    z = 1.0 - 2.0 * k / n
    phi = math.pi * (1.0 + math.sqrt(5.0)) * k
    r = np.sqrt(1.0 - z * z)
    return np.column_stack([r * np.cos(phi), r * np.sin(phi), z])


def _accel_row(u: np.ndarray, g: float) -> np.ndarray:
    """(9,) what a rest along ``u`` tells of the accelerometer's scales, its three free
    misalignments and biases (the magnitude of its reading, linearised at the ideal unit)."""
    return np.array([g * u[0] ** 2, g * u[1] ** 2, g * u[2] ** 2, g * u[0] * u[1],
                     g * u[0] * u[2], g * u[1] * u[2], u[0], u[1], u[2]])  # fmt: skip


def _gyro_rows(u0: np.ndarray, u1: np.ndarray) -> np.ndarray:
    """(2, 9) what a move from ``u0`` to ``u1`` tells of the gyro's matrix (the shortest
    rotation: its angle θ times its axis read through the matrix, seen across u1)."""
    cross = np.cross(u0, u1)
    s = float(np.linalg.norm(cross))
    if s < 1e-9:
        return np.zeros((2, 9))
    axis = cross / s
    theta = math.atan2(s, float(u0 @ u1))
    across = np.array([axis, np.cross(u1, axis)])
    return np.array([-theta * np.outer(np.cross(u1, e), axis).reshape(9) for e in across])


def worst_after(ups: Sequence[np.ndarray], up: np.ndarray, noise: tuple[float, float],
                g: float) -> float:  # fmt: skip
    """The RMS σ/tolerance over the accelerometer's and the gyro's values of the linearised
    model after a pose along ``up`` and the move to it from the last of ``ups`` (a value not
    determined yet counts as its prior, 10 tolerances): every value counts, so that the
    poses spread; ``noise``: σ of a pose's mean, m/s², and of a move's rows, rad."""
    rows_a = [_accel_row(u, g) / noise[0] for u in [*ups, up]]
    chain = [*ups, up]
    rows_g = [r / noise[1] for a, b in zip(chain[:-1], chain[1:], strict=False)
              for r in _gyro_rows(a, b)]  # fmt: skip
    out = 0.0
    for rows, tol in ((rows_a, _ACCEL_TOL), (rows_g, _GYRO_TOL)):
        # a prior of 10 tolerances keeps a value the poses do not yet determine finite
        info = np.diag((0.1 / tol) ** 2)
        if rows:
            info = info + np.array(rows).T @ np.array(rows)
        sd = np.sqrt(np.diag(np.linalg.inv(info)))
        out += float(np.sum((sd / tol) ** 2))
    return math.sqrt(out / (len(_ACCEL_TOL) + len(_GYRO_TOL)))


def _tolerance(name: str, default: float) -> float:
    tol = TOLERANCES.get(name)
    return float(tol) if tol is not None and math.isfinite(tol) else default


_ACCEL_TOL = np.array([_tolerance(n, 0.005) for n in
                       ("Axx", "Ayy", "Azz", "Axz", "Axy", "Ayx")] +
                      [_tolerance(n, 0.05) for n in ("A0x", "A0y", "A0z")])  # fmt: skip
_GYRO_TOL = np.array([_tolerance(f"G{a}{b}", 0.005) for a in "xyz" for b in "xyz"])


def next_up(ups: Sequence[np.ndarray], noise: tuple[float, float], g: float) -> np.ndarray:
    """The attitude (gravity's direction in the body) the planner values most next: of
    :func:`candidates`, the one after which :func:`worst_after` is lowest."""
    cands = candidates()
    scores = [worst_after(ups, c, noise, g) for c in cands]
    return np.asarray(cands[int(np.argmin(scores))])


def coverage_line(ups: Sequence[np.ndarray]) -> str:
    """Which directions of gravity the poses so far cover: per axis direction how many poses
    lie within 45° of it, and the direction farthest from every pose."""
    if not ups:
        return "Gravity so far: no pose yet."
    u = np.array(ups)
    parts = []
    for k, axis in enumerate("XYZ"):
        for sign, mark in ((1, "+"), (-1, "−")):
            near = int(np.sum(sign * u[:, k] > math.cos(math.radians(45.0))))
            parts.append(f"{mark}{axis} {near}")
    cands = candidates()
    gap = np.degrees(np.arccos(np.clip(np.max(cands @ u.T, axis=1), -1.0, 1.0)))
    far = cands[int(np.argmax(gap))]
    return (
        f"Gravity so far ({len(ups)} poses, within 45° of): {', '.join(parts)}; "
        f"farthest from every pose: {float(gap.max()):.0f}° ({attitude_words(far)})"
    )


def attitude_words(up: np.ndarray) -> str:
    """How the operator holds the unit for gravity along ``up``: each axis's angle above (+)
    or below (−) the horizon, e.g. 'X +35°, Y −35°, Z +35°'."""
    return ", ".join(
        f"{a} {math.degrees(math.asin(max(-1.0, min(1.0, float(c))))):+.0f}°"
        for a, c in zip("XYZ", up, strict=True)
    )


def cut_move(gyro: np.ndarray, bias: np.ndarray, dt_s: float, sd_dps: float) -> tuple[int, int]:
    """Where the motion in a measurement (gyro (N, 3) °/s) lies: (the last sample of the rest
    before it, the first sample of the rest after it), ``EDGE_S`` beyond the samples whose rate
    (``bias`` (3,) °/s taken out) exceeds :data:`MOTION_SIGMAS` × ``sd_dps``; (0, 0) when it
    holds no motion."""
    rate = np.linalg.norm(gyro - bias, axis=1)
    moving = np.flatnonzero(rate > max(MOTION_SIGMAS * sd_dps, MOTION_MIN_DPS))
    if not len(moving):
        return 0, 0
    edge = max(1, int(round(EDGE_S / dt_s)))
    return max(0, int(moving[0]) - edge), min(len(gyro) - 1, int(moving[-1]) + edge)


def pose_ups(records: Mapping[str, Record]) -> list[np.ndarray]:
    """Gravity's direction (normalised mean specific force) of every pose in ``records``."""
    out = []
    for name, rec in records.items():
        if rec.kind == "pose":
            m = rec.accel.mean(axis=0)
            out.append(m / np.linalg.norm(m))
            del name
    return out


def without_cube(records: Mapping[str, Record]) -> bool:
    """Whether ``records`` are a session without a cube: poses (and moves), no face, turn or
    rate record — whose next record is a pose, never a face or a turn."""
    kinds = {r.kind for r in records.values()}
    return "pose" in kinds and not kinds & {"static", "turn", "rate"}


@dataclass(frozen=True, eq=False)
class NextPose:
    """The pose the planner values most after ``records`` (:func:`next_pose`): gravity's
    direction ``up`` in the body, how many poses and moves there are, the RMS σ/tolerance of
    the planner's linearised model now and after it (:func:`worst_after`) and the coverage
    of gravity's directions so far (:func:`coverage_line`)."""

    up: np.ndarray
    poses: int
    moves: int
    rms_now: float
    rms_after: float
    coverage: str

    @property
    def attitude(self) -> str:
        """How to hold it: 'X +15°, Y −11°, Z +71°' (:func:`attitude_words`)."""
        return attitude_words(self.up)


def next_pose(records: Mapping[str, Record], g: float) -> NextPose:
    """The next pose of a session without a cube (:func:`next_up`, the dialogue's planner)
    after its ``records``, with the noise their own poses show (``g`` m/s²)."""
    ups = pose_ups(records)
    if not ups:
        raise UserError("no pose records: the pose planner needs at least one pose")
    noise = _noise(records, g)
    up = next_up(ups, noise, g)
    moves = sum(r.kind == "move" for r in records.values())
    now = worst_after(ups[:-1], ups[-1], noise, g)
    return NextPose(up, len(ups), moves, now, worst_after(ups, up, noise, g), coverage_line(ups))


def worst_fitted(records: Mapping[str, Record], opts: DialogueOptions, serial: str) -> (
    tuple[float, str]
):  # fmt: skip
    """(the worst σ/tolerance of the values the records determine, its name), from the fit of
    every record so far (``calibrate --from-dir``'s); ∞ while a value is not determined."""
    c = opts.compute
    res = calibrate_from_records(
        Session(serial=serial, records=dict(records)),
        CalibrationOptions(model=c.model, latitude_deg=c.latitude_deg, height_m=c.height_m),
    )
    worst, name = 0.0, ""
    for p in res.parameters:
        tol = TOLERANCES.get(p.name)
        if tol is None or p.name in FRAME_FIXED or not math.isfinite(tol):
            continue
        ratio = p.stderr / tol if math.isfinite(p.value) else math.inf
        if ratio > worst:
            worst, name = ratio, p.name
    return worst, name


def measure_poses(dlg: Measuring, opts: DialogueOptions) -> None:
    """The records of ``--plan poses`` / ``poses16``: pose after pose (kept ones count, the
    first after a resume without a move), until the target is met or the scheme ends. A pose
    measured where a repeat left the unit (:func:`measure_pose`) is a pose of the session but
    none of the scheme's attitudes."""
    seconds = dlg._ask_static_seconds()
    scheme = opts.planning.plan == "poses16"
    op = dlg.op
    numbers = [int(m.group("n")) for n in dlg.done if (m := POSE_NAME_RE.match(n))]
    k = asked = max(numbers, default=0)
    previous: str | None = None  # a resumed sitting starts without a move
    misses = 0  # moves in a row not kept (a pose measured where the unit was instead)
    limit = len(SIXTEEN) if scheme else FIRST_FIT_POSES + opts.planning.max_extra
    while (asked if scheme else k) < limit:
        ups = pose_ups(dlg.done)
        op.say(coverage_line(ups))
        if scheme:
            up = np.array(SIXTEEN[asked])
        elif not ups:
            up = np.array([0.0, 0.0, 1.0])
        else:
            up = next_up(ups, _noise(dlg.done, dlg.g), dlg.g)
        k += 1
        kept = measure_pose(dlg, pose_name(k), up, seconds, previous, misses)
        previous = pose_name(k)
        asked, misses = (asked + 1, 0) if kept else (asked, misses + 1)
        if scheme or k < FIRST_FIT_POSES:
            continue
        if _target_met(dlg, opts):
            return
    op.say(
        f"Poses: {k} poses measured"
        + ("" if scheme else f" (--max-extra {opts.planning.max_extra})")
    )


def _target_met(dlg: Measuring, opts: DialogueOptions) -> bool:
    """Whether every value the records so far determine meets the target (said either way)."""
    worst, name = worst_fitted(dlg.done, opts, dlg.serial)
    shown = f"{worst:.3g}" if math.isfinite(worst) else "∞ (a value not determined)"
    target = opts.planning.target
    met = worst <= target
    dlg.op.say(
        f"Poses: worst σ/tolerance {shown} ({name}): target {target:g} met."
        if met
        else f"Poses: worst σ/tolerance {shown} ({name}), target {target:g}."
    )
    return met


def _noise(records: Mapping[str, Record], g: float) -> tuple[float, float]:
    """(σ of a pose's accelerometer mean, m/s²; σ of a move's row, rad) from the records."""
    poses = [r for r in records.values() if r.kind == "pose"]
    sd_a = float(np.median([r.accel.std(axis=0).max() / math.sqrt(len(r)) for r in poses]))
    sd_g = float(np.median([r.gyro.std(axis=0).max() for r in poses]))
    dt = float(np.median([np.median(np.diff(r.t_ms)) for r in poses])) / 1000.0
    del g
    return max(sd_a, 1e-5), max(math.radians(sd_g) * math.sqrt(dt * 2.0), 1e-7)


def move_name_of(previous: str, name: str) -> str:
    """``move_01_02`` for the move from ``pose_01`` to ``pose_02``."""
    a = POSE_NAME_RE.match(previous)
    b = POSE_NAME_RE.match(name)
    assert a is not None and b is not None
    return move_name(int(a.group("n")), int(b.group("n")))


def measure_pose(
    dlg: Measuring, name: str, up: np.ndarray, seconds: float, previous: str | None,
    attempts: int = 0,
) -> bool:  # fmt: skip
    """One pose: the operator moves the unit from pose ``previous`` (None: places it) to gravity
    along ``up`` and holds it ``seconds`` s; saved as the move record and the pose record (True).
    A move not kept (repeated, aborted) leaves the unit where it went, not in ``previous``: a
    move from ``previous`` measured now would start elsewhere than its record says. So
    ``name`` is then measured where the unit is, with no move into it (:func:`rest_where_it_is`;
    False), and the next attitude is asked from there. ``attempts``: made before, for
    ``--yes``'s limit on attempts."""
    while True:
        attempts += 1
        dlg.board.hint("pose", up=[float(c) for c in up], first=previous is None)
        if previous is None:
            prompt = f"Hold it still with {attitude_words(up)} (no cube needed). Press any key."
        else:
            prompt = (
                f"Keep it still in {previous}; at the beep move it to {attitude_words(up)} and "
                "hold it still until the second beep. Press any key."
            )
        if _attempt(dlg, name, prompt, seconds, previous, attempts):
            return True
        if previous is not None:
            rest_where_it_is(dlg, name, seconds, previous, attempts)
            return False


def rest_where_it_is(
    dlg: Measuring, name: str, seconds: float, previous: str, attempts: int
) -> None:  # fmt: skip
    """After a move from ``previous`` not kept: pose ``name`` measured wherever the unit is now
    (no hint, no move into it), until it is saved."""
    dlg.op.say(
        f"{name} not kept: the unit is no longer in {previous}, so the next move cannot start "
        f"from it. {name} is measured where the unit is now; the next attitude is asked from "
        "there."
    )
    prompt = f"Hold it still where it is now ({name}). Press any key."
    while not _attempt(dlg, name, prompt, seconds, None, attempts + 1):
        attempts += 1


def _attempt(
    dlg: Measuring, name: str, prompt: str, seconds: float, previous: str | None, attempts: int
) -> bool:  # fmt: skip
    """Ask with ``prompt``, measure the move from ``previous`` (None: none) and the pose
    ``name``; save them when the operator keeps them (True)."""
    dlg.op.any_key(prompt)
    length = seconds if previous is None else seconds + MOVE_MAX_S + 1.0
    acq = dlg._acquire(name, length, "Hold still" if previous is None else "Move, then hold")
    if acq is None:
        return False
    whole = dlg._record(name, acq, {"kind": "pose"})
    records, problems = _cut(dlg, whole, name, previous, seconds)
    problems = dlg._loss_problems(name, acq) + problems
    if not dlg._decide(name, problems, attempts):
        return False
    for rec in records:
        dlg._save(rec, problems)
    return True


def _slice(rec: Record, name: str, a: int, b: int, meta: Mapping[str, str]) -> Record:
    """Samples [a, b) of ``rec`` as record ``name`` with ``meta``; its start times moved on."""
    shift = (float(rec.t_ms[a]) - float(rec.t_ms[0])) / 1000.0
    new = dict(rec.meta, **meta)
    for key in ("power_on_s", "session_s"):
        if key in new:
            new[key] = f"{float(new[key]) + shift:.3f}"
    return replace(rec, name=name, t_ms=rec.t_ms[a:b], accel=rec.accel[a:b],
                   gyro=rec.gyro[a:b], temp=rec.temp[a:b], meta=new)  # fmt: skip


def _cut(dlg: Measuring, whole: Record, name: str, previous: str | None, seconds: float) -> (
    tuple[list[Record], list[str]]
):  # fmt: skip
    """The move and pose records of one measurement, and what is wrong with them."""
    problems: list[str] = []
    if previous is None:
        recs = [whole]
    else:
        before = dlg.done[previous]
        bias = before.gyro.mean(axis=0)
        dt = float(np.median(np.diff(whole.t_ms))) / 1000.0
        start, end = cut_move(whole.gyro, bias, dt, float(before.gyro.std(axis=0).max()))
        if end <= start:
            return [], [f"{name}: no move found: move the unit to the new attitude at the beep"]
        move = _slice(whole, move_name_of(previous, name), start, end + 1,
                      {"kind": "move", "from": previous, "to": name})  # fmt: skip
        recs = [move, _slice(whole, name, end, len(whole), {})]
        try:
            check_range(move, f"{dlg.serial}_{move.name}.txt")
        except UserError as exc:
            problems.append(str(exc))
        held = recs[1].duration_s
        if held < 0.5 * seconds:
            problems.append(f"{name}: held still {held:.1f} s after the move, under half the "
                            f"{seconds:g} s asked; hold it longer")  # fmt: skip
    pose = recs[-1]
    try:
        check_pose(pose, record_stats(pose), dlg.g, f"{dlg.serial}_{name}.txt")
    except UserError as exc:
        problems.append(str(exc))
    return recs, problems
