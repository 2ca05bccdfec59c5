"""Sessions without a cube: a unit held still in random attitudes and moved by hand between
them (random axes), written from first principles like the rest of this directory (it imports
nothing from ``host``).

The truth is the unit's §2 error model (:func:`tests.independent.truth.random_base`: scale,
misalignment, bias, g-sensitivity) in the unit's own body frame. Each pose is a rest with
gravity along a random body direction; each move turns the body by two rotations about random
axes (a smooth speed profile each), integrated exactly: a room-fixed vector seen in the body
turns by the inverse rotation. With ``creep_dps`` the hand that holds each pose is not quite
still: the body turns at a constant rate of its own during each rest (each axis normal with
that sd, °/s), so a pose's gyro reads that rate and its attitude drifts from the rest's start
to its end, where the move starts. The records are ``pose_01`` … and ``move_01_02`` … (the move
from the last sample of the rest before to the first sample of the rest after, so each move's
first and last samples are at rest). Outputs: white noise, quantised to the MPU-6000's counts.

The frame a fit without a cube reports in is the accelerometer's own (imu_tk's convention:
its x axis along x, its y axis in the xy plane, as a skew basis), so :func:`truth_in_frame`
turns the truth into that frame exactly (an RQ decomposition of the accelerometer's matrix).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from tests.independent.physics import (
    ACCEL_LSB,
    AXES,
    FS_HZ,
    GYRO_LSB,
    error_matrix,
    local_g,
    quantise,
    rot_about,
    white_noise,
)
from tests.independent.recordfile import record_text
from tests.independent.truth import MIS_KEYS, BaseTruth, random_base

#: white-noise densities (unit/√Hz): MPU-6000-like
ACCEL_DENSITY = 400e-6 * 9.81
GYRO_DENSITY = 0.005


@dataclass(frozen=True)
class PoseSpec:
    """One session: ``poses`` rests of ``pose_s`` s, moves of two rotations of ``move_s`` s
    each (their angles 40–120°), ``seed``; ``latitude_deg``/``height_m`` set local g;
    ``creep_dps`` the hand's rate during each rest (module docstring; 0: perfectly still)."""

    seed: int = 1
    poses: int = 30
    pose_s: float = 3.0
    move_s: float = 1.2
    latitude_deg: float = 45.0
    height_m: float = 0.0
    creep_dps: float = 0.0


@dataclass
class PoseSession:
    """The records (name -> file text), the truth and local g."""

    records: dict[str, str] = field(default_factory=dict)
    truth: BaseTruth | None = None
    g: float = 9.80665
    ups: list[np.ndarray] = field(default_factory=list)


def _random_unit(rng: np.random.Generator) -> np.ndarray:
    v = rng.normal(size=3)
    return v / np.linalg.norm(v)


def _smooth_angle(n: int, angle: float) -> tuple[np.ndarray, np.ndarray]:
    """(angle turned so far (n,), rate (n,) rad/s) of a rotation of ``angle`` rad over ``n``
    samples: a raised-cosine rate, zero at both ends."""
    t = np.arange(n) / FS_HZ
    dur = (n - 1) / FS_HZ
    phase = t / dur
    turned = angle * (phase - np.sin(2 * math.pi * phase) / (2 * math.pi))
    rate = angle / dur * (1 - np.cos(2 * math.pi * phase))
    return turned, rate


def _move_path(
    rng: np.random.Generator, up: np.ndarray, n: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A move from gravity along ``up`` (body): (gravity's direction (2n, 3), body rate
    (2n, 3) rad/s, gravity's direction at the end) over two rotations of ``n`` samples about
    random body axes. A room-fixed vector seen in the body turns by R(axis, −angle)."""
    ups, rates = [], []
    u = up.copy()
    for _ in range(2):
        axis = _random_unit(rng)
        angle = math.radians(rng.uniform(40.0, 120.0)) * rng.choice([-1.0, 1.0])
        turned, rate = _smooth_angle(n, angle)
        ups.append(np.array([rot_about(axis, -a) @ u for a in turned]))
        rates.append(rate[:, None] * axis[None, :])
        u = rot_about(axis, -angle) @ u
    return np.concatenate(ups), np.concatenate(rates), u


def _outputs(
    rng: np.random.Generator, truth: BaseTruth, g: float, ups: np.ndarray, rate_rad: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """(accel m/s², gyro °/s) (N, 3) read by the unit at gravity directions ``ups`` and body
    rates ``rate_rad`` (rad/s): §2 model, white noise, quantised."""
    force = g * ups
    rate = np.degrees(rate_rad)
    accel = force @ truth.accel_matrix.T + truth.accel_bias
    gyro = rate @ truth.gyro_matrix.T + (force / g) @ truth.g_sens.T + truth.gyro_bias
    accel = accel + white_noise(rng, ACCEL_DENSITY, accel.shape)
    gyro = gyro + white_noise(rng, GYRO_DENSITY, gyro.shape)
    return quantise(accel, ACCEL_LSB), quantise(gyro, GYRO_LSB)


def _text(name: str, meta: dict[str, str], t0_s: float, accel: np.ndarray, gyro: np.ndarray) -> str:
    n = len(accel)
    t_ms = np.arange(n) * 1000.0 / FS_HZ
    temp = np.full(n, 30.0)
    return record_text(name, {**meta, "power_on_s": f"{t0_s:.3f}"}, t_ms, accel, gyro, temp)


def _rest_path(up: np.ndarray, rate_rad: np.ndarray, n: int) -> np.ndarray:
    """(n, 3) gravity's direction in the body during a rest that starts at ``up`` while the
    body turns at ``rate_rad`` (3,) rad/s: by R(axis, −|ω|·t)."""
    speed = float(np.linalg.norm(rate_rad))
    if speed == 0.0:
        return np.tile(up, (n, 1))
    axis = rate_rad / speed
    return np.array([rot_about(axis, -speed * k / FS_HZ) @ up for k in range(n)])


def simulate_poses(spec: PoseSpec) -> PoseSession:
    """A session of ``spec.poses`` poses and the moves between them, the truth beside it."""
    rng = np.random.default_rng(spec.seed)
    truth = random_base(rng)
    g = local_g(spec.latitude_deg, spec.height_m)
    out = PoseSession(truth=truth, g=g)
    n_pose = int(round(spec.pose_s * FS_HZ))
    n_move = int(round(spec.move_s * FS_HZ))
    up = _random_unit(rng)
    t = 10.0

    def creep() -> np.ndarray:  # drawn only with a creep: a still hand's sessions unchanged
        return np.radians(rng.normal(0.0, spec.creep_dps, 3)) if spec.creep_dps else np.zeros(3)

    omega = creep()
    for i in range(1, spec.poses + 1):
        name = f"pose_{i:02d}"
        rest = _rest_path(up, omega, n_pose)
        accel, gyro = _outputs(rng, truth, g, rest, np.tile(omega, (n_pose, 1)))
        out.records[name] = _text(name, {"source": "independent"}, t, accel, gyro)
        out.ups.append(up)
        t += spec.pose_s
        if i == spec.poses:
            break
        up = rest[-1]
        path, rate, end = _move_path(rng, up, n_move)
        nxt = creep()
        # from the last sample of the rest before to the first sample of the rest after
        path = np.vstack([up, path, end])
        rate = np.vstack([omega, rate, nxt])
        accel, gyro = _outputs(rng, truth, g, path, rate)
        mname = f"move_{i:02d}_{i + 1:02d}"
        meta = {"source": "independent", "from": name, "to": f"pose_{i + 1:02d}"}
        out.records[mname] = _text(mname, meta, t, accel, gyro)
        t += 2 * spec.move_s
        up, omega = end, nxt
    return out


def _rq(m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """m = U·Q with U upper triangular (positive diagonal), Q a rotation."""
    # the QR of the flipped transpose: m = U Q ⟺ (P mᵀ P) = (P Qᵀ P)(P Uᵀ P)
    p = np.eye(3)[::-1]
    q, r = np.linalg.qr((p @ m).T)
    u = p @ r.T @ p
    qm = p @ q.T
    signs = np.diag(np.sign(np.diag(u)))
    u, qm = u @ signs, signs @ qm
    if np.linalg.det(qm) < 0:
        raise AssertionError("not a rotation")
    return u, qm


def _names(prefix: str, matrix: np.ndarray) -> dict[str, float]:
    """§2 names of an I + M matrix (:func:`error_matrix`'s layout)."""
    out = {f"{prefix}{a}{a}": float(matrix[i, i] - 1.0) for i, a in enumerate(AXES)}
    signs = {"xz": (0, 1, 1), "xy": (0, 2, -1), "yz": (1, 0, -1), "yx": (1, 2, 1),
             "zy": (2, 0, 1), "zx": (2, 1, -1)}  # fmt: skip
    for k in MIS_KEYS:
        i, j, sg = signs[k]
        out[f"{prefix}{k}"] = float(sg * matrix[i, j])
    return out


def truth_in_frame(truth: BaseTruth) -> dict[str, float]:
    """The §2 constants of ``truth`` in the accelerometer's own frame (imu_tk's convention),
    exactly: the accelerometer's matrix M = U·Q (U upper triangular), so a force f in the body
    is Q·f in that frame, and every matrix that reads a body vector is multiplied by Qᵀ."""
    u, q = _rq(truth.accel_matrix)
    gyro = truth.gyro_matrix @ q.T
    gsens = truth.g_sens @ q.T
    out = {**_names("A", u), **_names("G", gyro)}
    check = error_matrix(np.array([out[f"A{a}{a}"] for a in AXES]),
                         {k: out[f"A{k}"] for k in MIS_KEYS}, "accel")  # fmt: skip
    assert np.allclose(check, u)
    for i, a in enumerate(AXES):
        out[f"A0{a}"] = float(truth.accel_bias[i])
        out[f"G0{a}"] = float(truth.gyro_bias[i])
        for j, b in enumerate(AXES):
            out[f"GA{a}{b}"] = float(gsens[i, j])
    return out


def write_poses(directory: str, session: PoseSession, serial: str = "POS01") -> None:
    """Write every record of ``session`` as ``directory/SERIAL_name.txt``."""
    from pathlib import Path

    from tests.independent.recordfile import write_record_file

    Path(directory).mkdir(parents=True, exist_ok=True)
    for name, text in session.records.items():
        write_record_file(Path(directory), serial, name, text)
