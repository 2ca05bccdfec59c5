"""The placement geometry the model assumes: how a cube resting with a body vector up stands
on the plate (:func:`pose_from_up`), and the plate's axes in body coordinates
(:func:`placement`). The model's own convention; the simulator (:mod:`host.bench.physics`)
imports it from here."""

from __future__ import annotations

import math

import numpy as np


def pose_from_up(up_body: np.ndarray) -> np.ndarray:
    """Attitude (3, 3) of the cube resting with body vector ``up_body`` pointing up.

    For the six faces the result is a signed permutation; the heading about the vertical is
    fixed by a deterministic choice of which body axis points east (so the pose of a named
    orientation is always the same matrix).
    """
    u = np.asarray(up_body, dtype=np.float64)
    u = u / math.sqrt(u.dot(u))
    # east: the first body axis (x, y, z order) not parallel to up, made orthogonal to it
    for k in range(3):
        e = _BODY_AXES[k] - u[k] * u
        size = math.sqrt(e.dot(e))
        if size > 1e-6:
            break
    e = e / size
    # north = up × east, the 3-vector cross product in plain arithmetic (called per record)
    (u0, u1, u2), (e0, e1, e2) = u.tolist(), e.tolist()
    n = np.array([u1 * e2 - u2 * e1, u2 * e0 - u0 * e2, u0 * e1 - u1 * e0])
    # rows of R are the world axes expressed in body coordinates: R^T = [e n u] as columns
    return np.stack([e, n, u], axis=0)


#: the body axes x, y, z as rows (read only)
_BODY_AXES = np.eye(3)
_BODY_AXES.flags.writeable = False


def placement(up: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(east, north) of the fixture frame in body axes for a cube resting with body ``up`` up,
    the program's placement convention: the first body axis (x, y, z order) that is not along
    up lies along the ruler (east), north = up × east (:func:`pose_from_up`)."""
    r = pose_from_up(up)
    return r[0], r[1]


#: the heading at which the live dialogue asks the operator to place the cube, ° (and writes in
#: every record's header as ``placement_heading_deg``): the reference axis along the fence,
#: pointing right — :func:`placement`'s plate axes at zero heading
DIALOGUE_HEADING_DEG = 0.0

#: where the reference axis points at each placement heading, seen by the operator standing
#: in front of the fence (the fence runs left to right, east = right, north = toward the fence)
_HEADING_WORDS = {
    0: "pointing right, along the fence",
    90: "pointing at the fence",
    180: "pointing left, along the fence",
    270: "pointing at you, away from the fence",
}


def reference_axis(up: np.ndarray) -> str:
    """'+x'|'+y'|'+z': the record's reference axis, the first of +x, +y, +z not along ``up``
    (not parallel to it, as :func:`placement` takes it: on a 45° attitude an axis at 45° to
    the vertical, made level) — the axis whose heading ``placement_heading_deg`` gives."""
    u = np.asarray(up, dtype=np.float64)
    u = u / np.linalg.norm(u)
    k = next(i for i in range(3) if abs(float(u[i])) < 1.0 - 1e-9)
    return "+" + "xyz"[k]


def placement_words(up: np.ndarray, heading_deg: float = DIALOGUE_HEADING_DEG) -> str:
    """The operator's instruction for a placement at ``heading_deg`` (a multiple of 90°): which
    arrow of the cube points where, and the number the record carries."""
    k = int(round(heading_deg / 90.0)) % 4 * 90
    if abs((heading_deg - k + 180.0) % 360.0 - 180.0) > 1e-6:
        raise ValueError(f"a cube against a fence sits at a multiple of 90°, not {heading_deg}")
    axis = reference_axis(up)
    return (
        f"against the fence, its {axis[1].upper()} arrow {_HEADING_WORDS[k]} "
        f"(placement heading {k}°)"
    )


def plate_axes(up: np.ndarray, heading_rad: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(east, north) (N, 3) each: the plate's axes in body coordinates for a cube resting with
    body ``up`` up at heading ``heading_rad`` (N,) rad (counter-clockwise seen from above, from
    the fence to the reference axis). At zero heading they are :func:`placement`'s."""
    e0, n0 = placement(up)
    c, s = np.cos(heading_rad)[:, None], np.sin(heading_rad)[:, None]
    return e0 * c - n0 * s, n0 * c + e0 * s
