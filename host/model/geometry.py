"""The placement geometry the model assumes: how a cube resting with a body vector up stands
on the plate (:func:`pose_from_up`), and the plate's axes in body coordinates
(:func:`placement`). The model's own convention; the simulator (:mod:`host.bench.physics`)
imports it from here."""

from __future__ import annotations

import numpy as np


def pose_from_up(up_body: np.ndarray) -> np.ndarray:
    """Attitude (3, 3) of the cube resting with body vector ``up_body`` pointing up.

    For the six faces the result is a signed permutation; the heading about the vertical is
    fixed by a deterministic choice of which body axis points east (so the pose of a named
    orientation is always the same matrix).
    """
    u = np.asarray(up_body, dtype=np.float64)
    u = u / np.linalg.norm(u)
    # east: the first body axis (x, y, z order) not parallel to up, made orthogonal to it
    for cand in np.eye(3):
        e = cand - np.dot(cand, u) * u
        if np.linalg.norm(e) > 1e-6:
            break
    e = e / np.linalg.norm(e)
    n = np.cross(u, e)
    # rows of R are the world axes expressed in body coordinates: R^T = [e n u] as columns
    return np.stack([e, n, u], axis=0)


def placement(up: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(east, north) of the fixture frame in body axes for a cube resting with body ``up`` up,
    the program's placement convention: the first body axis (x, y, z order) that is not along
    up lies along the ruler (east), north = up × east (:func:`pose_from_up`)."""
    r = pose_from_up(up)
    return r[0], r[1]
