"""Continuous calibration sessions written from method.md alone (not from host/bench/).

A whole session as one stream, no beeps, no labels: the cube rests on each face in the plan's
order, is re-oriented between faces by a rotation about a horizontal axis, and is turned about
the vertical by hand; the sensor is the linear model of method.md §2 with white noise and
quantisation to the MPU-6000's LSB (±2 g, ±250 °/s). Operators differ in how they work: fast,
slow or stepped turns, long or short rests, a warm-up first, a face placed twice, a turn begun
and turned back, the cube pressed into place before its turns. Each session carries its truth:
the constants and where each record really is (the labelled windows), for the segmentation
tests and ``benchmarks/segmentation.py``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

#: gravity at the calibration's default site (55.75° N, 150 m), Helmert's formula of method.md §3
G = 9.78030 * (1 + 0.005302 * math.sin(math.radians(55.75)) ** 2
               - 0.000007 * math.sin(math.radians(111.5)) ** 2) - 0.000003086 * 150  # fmt: skip
ACCEL_LSB = 4 * 9.81 / 2**16  #: m/s² per count at ±2 g (method.md §1)
GYRO_LSB = 500 / 2**16  #: °/s per count at ±250 °/s
FACES = ("x_up", "x_dn", "y_up", "y_dn", "z_up", "z_dn")
LABEL_PAD_S = 0.5  #: a labelled turn holds this much of the rests before and after its motion, s


@dataclass(frozen=True)
class Operator:
    """How one person runs the plan (all durations in s, rates in °/s)."""

    name: str
    static_s: float = 12.0
    turn_rate: float = 120.0  #: mean rate of a turn
    turns: int = 2
    steps: int = 1  #: a turn in this many equal steps with pauses
    step_pause_s: float = 0.8
    pre_turn_s: float = 1.5  #: rest on the face before its first turn
    between_turns_s: float = 2.0
    reorient_s: float = 2.0
    warmup_s: float = 0.0
    replaced_face: str | None = None  #: this face is placed, lifted and placed again
    aborted_turn: bool = False  #: the first turn is begun, turned back, then made
    reseat: bool = False  #: before the turns on a face, the cube is pressed down: it rocks 1.5°
    rate_hz: float = 50.0
    jitter: float = 0.0  #: sample time jitter, fraction of the period


OPERATORS = (
    Operator("fast", turn_rate=360.0, turns=1),
    Operator("slow", turn_rate=45.0, turns=2),
    Operator("stepped", turns=1, steps=4, turn_rate=200.0),
    Operator("long rests", static_s=40.0, between_turns_s=5.0),
    Operator("short rests", static_s=4.0, between_turns_s=1.2, pre_turn_s=1.0, reorient_s=1.2),
    Operator("warm-up first", warmup_s=180.0),
    Operator("re-placed face", replaced_face="y_up"),
    Operator("aborted turn", aborted_turn=True),
    Operator("stepped, warm-up", turns=1, steps=4, warmup_s=120.0, turn_rate=150.0),
    Operator("jittery 100 Hz", rate_hz=100.0, jitter=0.3, turns=3, turn_rate=180.0),
    Operator("re-seated", turns=1, steps=4, turn_rate=300.0, pre_turn_s=4.0, reseat=True),
)


@dataclass
class ContinuousSession:
    """The stream (t s, accel m/s², gyro °/s, temp °C), the true constants (method.md §7
    names), the labelled windows: record name -> (t0, t1) s — a static's rest, a turn's motion
    with ``LABEL_PAD_S`` of the rests around it — and each turn's motion."""

    t: np.ndarray
    accel: np.ndarray
    gyro: np.ndarray
    temp: np.ndarray
    truth: dict[str, float]
    windows: dict[str, tuple[float, float]] = field(default_factory=dict)
    motions: dict[str, tuple[float, float]] = field(default_factory=dict)


def random_truth(rng: np.random.Generator) -> dict[str, float]:
    """Constants of realistic size (method.md §7), each drawn with a random sign."""
    size = {"A": 0.012, "Am": 0.006, "A0": 0.15, "G": 0.015, "Gm": 0.008, "G0": 1.5, "GA": 0.05}
    out: dict[str, float] = {}
    for ax in "xyz":
        out[f"A{ax}{ax}"] = size["A"] * rng.uniform(0.3, 1) * rng.choice([-1, 1])
        out[f"G{ax}{ax}"] = size["G"] * rng.uniform(0.3, 1) * rng.choice([-1, 1])
        out[f"A0{ax}"] = size["A0"] * rng.uniform(0.3, 1) * rng.choice([-1, 1])
        out[f"G0{ax}"] = size["G0"] * rng.uniform(0.3, 1) * rng.choice([-1, 1])
        for b in "xyz":
            out[f"GA{ax}{b}"] = size["GA"] * rng.uniform(-1, 1)
    for name in ("xz", "xy", "yz", "yx", "zy", "zx"):
        out[f"A{name}"] = size["Am"] * rng.uniform(-1, 1)
        out[f"G{name}"] = size["Gm"] * rng.uniform(-1, 1)
    return out


def _matrix(p: str, c: dict[str, float]) -> np.ndarray:
    """The 3×3 of method.md §2 for sensor prefix ``p`` (A or G): outputs = (I + M)·input."""
    return np.array(
        [
            [c[f"{p}xx"], c[f"{p}xz"], -c[f"{p}xy"]],
            [-c[f"{p}yz"], c[f"{p}yy"], c[f"{p}yx"]],
            [c[f"{p}zy"], -c[f"{p}zx"], c[f"{p}zz"]],
        ]
    )


def _rot(axis: np.ndarray, angle_rad: np.ndarray) -> np.ndarray:
    """Rotation matrices (N,3,3) about a unit ``axis`` (world) by ``angle_rad`` (N,)."""
    k = np.asarray(axis, float) / np.linalg.norm(axis)
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    s, c = np.sin(angle_rad)[:, None, None], np.cos(angle_rad)[:, None, None]
    return np.eye(3) + s * kx + (1 - c) * (kx @ kx)


def _body_axis(face: str) -> np.ndarray:
    v = np.zeros(3)
    v["xyz".index(face[0])] = 1.0 if face.endswith("up") else -1.0
    return v


class _Builder:
    """Appends motions to a session: attitude R (body -> world) and body rate per sample."""

    def __init__(self, rng: np.random.Generator, op: Operator) -> None:
        self.rng, self.op = rng, op
        self.t_now = 0.0
        self.R = np.eye(3)  # z_up, heading 0
        self.pieces: list[tuple[float, float, object]] = []

    def rest(self, seconds: float) -> tuple[float, float]:
        R = self.R.copy()
        t0 = self.t_now
        self.pieces.append((t0, t0 + seconds, ("rest", R)))
        self.t_now += seconds
        return t0, self.t_now

    def rotate(self, axis_world: np.ndarray, angle_deg: float, seconds: float) -> None:
        t0 = self.t_now
        self.pieces.append((t0, t0 + seconds, ("rot", self.R.copy(), axis_world, angle_deg)))
        self.R = _rot(axis_world, np.array([math.radians(angle_deg)]))[0] @ self.R
        self.t_now += seconds

    def to_face(self, face: str) -> None:
        """Re-orient so that ``face``'s axis points up (90° or 180° about a horizontal)."""
        w = self.R @ _body_axis(face)
        if w[2] > 0.99:
            return
        if w[2] < -0.99:
            h = self.R @ np.roll(_body_axis(face), 1)
            h[2] = 0.0
            self.rotate(h / np.linalg.norm(h), 180.0, self.op.reorient_s * 1.3)
            return
        h = np.cross(w, [0.0, 0.0, 1.0])
        self.rotate(h / np.linalg.norm(h), math.degrees(math.acos(np.clip(w[2], -1, 1))),
                    self.op.reorient_s)  # fmt: skip

    def turn(self, angle_deg: float) -> None:
        op = self.op
        if op.steps > 1:
            part = angle_deg / op.steps
            for k in range(op.steps):
                self.rotate(np.array([0.0, 0.0, 1.0]), part, abs(part) / op.turn_rate)
                if k < op.steps - 1:
                    self.rest(op.step_pause_s * self.rng.uniform(0.6, 1.4))
            return
        self.rotate(np.array([0.0, 0.0, 1.0]), angle_deg, abs(angle_deg) / op.turn_rate)


def _profile(s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Raised-cosine motion: fraction done and its rate (per unit s) at s in [0, 1]."""
    return s - np.sin(2 * np.pi * s) / (2 * np.pi), 1 - np.cos(2 * np.pi * s)


def make_session(seed: int, op: Operator) -> ContinuousSession:
    """One continuous session by ``op`` (module docstring), reproducible from ``seed``."""
    rng = np.random.default_rng(seed)
    truth = random_truth(rng)
    b = _Builder(rng, op)
    windows: dict[str, tuple[float, float]] = {}
    motions: dict[str, tuple[float, float]] = {}
    if op.warmup_s:
        windows["warmup"] = b.rest(op.warmup_s)
    for face in FACES:
        b.to_face(face)
        if face == op.replaced_face:
            b.rest(3.0)
            h = b.R @ np.roll(_body_axis(face), 1)
            b.rotate(h, 55.0, 1.0)
            b.rotate(h, -55.0, 1.0)
        windows[face] = b.rest(op.static_s * rng.uniform(0.9, 1.1))
    for ax in "xyz":
        b.to_face(f"{ax}_up")
        if op.reseat:  # settles, is pressed into place, rocks about a horizontal axis
            b.rest(0.2)
            h = b.R @ np.roll(_body_axis(f"{ax}_up"), 1)
            b.rotate(h, 1.5, 0.15)
            b.rotate(h, -1.5, 0.15)
        b.rest(op.pre_turn_s)
        for k, (d, sfx) in enumerate(((1, "ccw"), (-1, "cw"))):
            if k:
                b.rest(op.between_turns_s)
            if op.aborted_turn and ax == "x" and k == 0:
                b.rotate(np.array([0.0, 0.0, 1.0]), 120.0, 1.2)
                b.rest(0.6)
                b.rotate(np.array([0.0, 0.0, 1.0]), -121.0, 1.2)
                b.rest(1.5)
            t0 = b.t_now
            b.turn(d * (360.0 * op.turns + rng.normal(0, 0.5)))
            motions[f"{ax}_{sfx}"] = (t0, b.t_now)
        b.rest(op.between_turns_s)
    for name, (t0, t1) in motions.items():  # the labelled turn: its motion, 0.5 s of rest around
        windows[name] = (t0 - LABEL_PAD_S, t1 + LABEL_PAD_S)
    cs = _sample(b, rng, op, truth, windows)
    cs.motions = motions
    return cs


def make_adaptive_session(seed: int, op: Operator) -> ContinuousSession:
    """One continuous session by ``op`` in the adaptive dialogue's order (``calibrate --plan
    adaptive``): axis by axis the down face, the up face, then the turns about that axis
    without placing the cube again — the up face's rest is the rest before its first turn,
    and no other visit rests on it."""
    rng = np.random.default_rng(seed)
    truth = random_truth(rng)
    b = _Builder(rng, op)
    windows: dict[str, tuple[float, float]] = {}
    motions: dict[str, tuple[float, float]] = {}
    for ax in "xyz":
        for face in (f"{ax}_dn", f"{ax}_up"):
            b.to_face(face)
            windows[face] = b.rest(op.static_s * rng.uniform(0.9, 1.1))
        for k, (d, sfx) in enumerate(((1, "ccw"), (-1, "cw"))):
            if k:
                b.rest(op.between_turns_s)
            t0 = b.t_now
            b.turn(d * (360.0 * op.turns + rng.normal(0, 0.5)))
            motions[f"{ax}_{sfx}"] = (t0, b.t_now)
        b.rest(op.between_turns_s)
    for name, (t0, t1) in motions.items():
        windows[name] = (t0 - LABEL_PAD_S, t1 + LABEL_PAD_S)
    cs = _sample(b, rng, op, truth, windows)
    cs.motions = motions
    return cs


def _sample(
    b: _Builder,
    rng: np.random.Generator,
    op: Operator,
    truth: dict[str, float],
    windows: dict[str, tuple[float, float]],
) -> ContinuousSession:
    period = 1.0 / op.rate_hz
    n = int(b.t_now / period)
    t = np.arange(n) * period + rng.uniform(-op.jitter, op.jitter, n) * period
    t = np.sort(np.clip(t, 0.0, b.t_now))
    force = np.zeros((n, 3))
    rate = np.zeros((n, 3))
    up_world = np.array([0.0, 0.0, G])
    for t0, t1, piece in b.pieces:
        sel = (t >= t0) & (t < t1)
        if not np.any(sel):
            continue
        kind = piece[0]  # type: ignore[index]
        if kind == "rest":
            R = piece[1]  # type: ignore[index]
            force[sel] = R.T @ up_world
            continue
        _, R0, axis, angle = piece  # type: ignore[misc]
        s = (t[sel] - t0) / (t1 - t0)
        done, speed = _profile(s)
        Rt = _rot(axis, np.radians(angle) * done) @ R0
        force[sel] = np.einsum("nji,j->ni", Rt, up_world)
        w_world = np.outer(np.radians(angle) * speed / (t1 - t0), axis)
        rate[sel] = np.degrees(np.einsum("nji,nj->ni", Rt, w_world))
    accel = force @ (np.eye(3) + _matrix("A", truth)).T
    accel += np.array([truth["A0x"], truth["A0y"], truth["A0z"]])
    ga = np.array([[truth[f"GA{a}{c}"] for c in "xyz"] for a in "xyz"])
    gyro = rate @ (np.eye(3) + _matrix("G", truth)).T + (force / G) @ ga.T
    gyro += np.array([truth["G0x"], truth["G0y"], truth["G0z"]])
    accel = np.round((accel + rng.normal(0, 0.009, accel.shape)) / ACCEL_LSB) * ACCEL_LSB
    gyro = np.round((gyro + rng.normal(0, 0.025, gyro.shape)) / GYRO_LSB) * GYRO_LSB
    temp = 24.0 + 7.0 * (1 - np.exp(-t / 250.0)) + rng.normal(0, 0.05, n)
    return ContinuousSession(t, accel, gyro, np.round(temp, 1), truth, windows)
