"""Minimal truth-based session generator for the calibration tests (method.md §2 model).

Every constant has a different value on every axis, so a swapped axis or sign fails a test.
Not a physics simulator (that is host/bench/sim.py): statics are gravity along an axis, turns are a
smooth raised-cosine rate profile about the up axis, white noise, rounding to the printed
precision, a sample period that is not 20 ms and jitters.
"""

from __future__ import annotations

import numpy as np

from host.session.method import local_gravity, matrix_to_names, names_to_gsens, names_to_matrix
from host.session.records import DECIMALS, STATIC_NAMES, TURN_NAMES, Record

#: the true constants (names of method.md §7); all different, realistic magnitudes
TRUTH: dict[str, float] = {
    "Axx": -0.00284, "Ayy": 0.00910, "Azz": 0.01313,
    "Axz": 0.0041, "Axy": -0.0063, "Ayz": 0.0027, "Ayx": -0.0052, "Azy": 0.0075, "Azx": -0.0018,
    "A0x": 0.08362, "A0y": -0.19953, "A0z": -0.08358,
    "Gxx": -0.01949, "Gyy": -0.00356, "Gzz": -0.00176,
    "Gxz": 0.0061, "Gxy": -0.0043, "Gyz": 0.0029, "Gyx": -0.0081, "Gzy": 0.0057, "Gzx": -0.0034,
    "G0x": 0.72911, "G0y": 2.56893, "G0z": 1.07202,
    "GAxx": 0.021, "GAxy": -0.013, "GAxz": 0.034, "GAyx": -0.027, "GAyy": 0.018,
    "GAyz": -0.041, "GAzx": 0.009, "GAzy": 0.046, "GAzz": -0.016,
}  # fmt: skip

TURN_SECONDS = {1: 7.0, 2: 12.0, 3: 15.0}


def up_of(name: str) -> np.ndarray:
    """'y_dn' / 'z_ccw' -> unit up vector."""
    v = np.zeros(3)
    v["xyz".index(name[0])] = -1.0 if name.endswith("_dn") else 1.0
    return v


def make_record(
    name: str,
    rng: np.random.Generator,
    *,
    truth: dict[str, float] = TRUTH,
    g: float | None = None,
    up: np.ndarray | None = None,
    sign: int = 0,
    seconds: float = 30.0,
    turns: int = 2,
    period_ms: float = 19.7,
    accel_noise: float = 0.01,
    gyro_noise: float = 0.025,
    angle_error_deg: float = 0.2,
    rate_dps: float = 0.0,
    meta: dict[str, str] | None = None,
) -> Record:
    """One record from the §2 model. ``sign`` 0: static; ±1: a turn of ±360·turns° about up
    (plus a random hand error of ``angle_error_deg`` std) lasting TURN_SECONDS[turns]."""
    g = local_gravity() if g is None else g
    up = up_of(name) if up is None else np.asarray(up, float) / np.linalg.norm(up)
    if sign:
        seconds = TURN_SECONDS[turns]
    n = int(seconds * 1000 / period_ms) + 1
    t = np.arange(n) * period_ms + rng.uniform(-0.3, 0.3, n)
    t[0] = 0.0
    t = np.sort(t)
    ts = t / 1000.0
    rate = np.zeros(n)
    if sign:
        t0, dur = 1.0, seconds - 2.0
        angle = sign * 360.0 * turns + rng.normal(0.0, angle_error_deg)
        ph = np.clip((ts - t0) / dur, 0.0, 1.0)
        rate = np.where((ph > 0) & (ph < 1), angle / dur * (1 - np.cos(2 * np.pi * ph)), 0.0)
    rate = rate + rate_dps
    omega = rate[:, None] * up[None, :]
    a_true = np.tile(g * up, (n, 1))
    ma = np.eye(3) + names_to_matrix("A", truth)
    mg = np.eye(3) + names_to_matrix("G", truth)
    ga = names_to_gsens(truth)
    ba = np.array([truth[k] for k in ("A0x", "A0y", "A0z")])
    bg = np.array([truth[k] for k in ("G0x", "G0y", "G0z")])
    acc = a_true @ ma.T + ba + rng.normal(0, accel_noise, (n, 3))
    gyr = omega @ mg.T + (a_true / g) @ ga.T + bg + rng.normal(0, gyro_noise, (n, 3))
    temp = 31.0 + 0.01 * ts
    data = np.column_stack([t, acc, gyr, temp])
    data = np.column_stack([np.round(data[:, i], d) for i, d in enumerate(DECIMALS)])
    return Record(name, data[:, 0], data[:, 1:4], data[:, 4:7], data[:, 7], dict(meta or {}))


def make_records(
    names: tuple[str, ...] = STATIC_NAMES + TURN_NAMES, seed: int = 1, **kw: object
) -> dict[str, Record]:
    """Records of a standard session (or the given names), seeded."""
    rng = np.random.default_rng(seed)
    out = {}
    for nm in names:
        sign = 0 if nm in STATIC_NAMES else (1 if nm.split("_")[1] == "ccw" else -1)
        out[nm] = make_record(nm, rng, sign=sign, **kw)  # type: ignore[arg-type]
    return out


__all__ = ["TRUTH", "make_record", "make_records", "matrix_to_names", "up_of"]
