"""The least operator time for a precision (host/workbench/least_time.py): a hand calculation,
plans searched by brute force with their exact information, and the information a second of
rest gives on the independent simulator against its noise density."""

from __future__ import annotations

import itertools
import math
from pathlib import Path

import numpy as np
import pytest

from host.model.catalogue import CATALOGUE
from host.model.dataset import build_dataset
from host.model.fit import fit_model
from host.model.spec import parse_model
from host.session.directory import read_session
from host.workbench.least_time import (
    balanced_plan_s,
    least_operator_s,
    least_rest_s,
    rest_information,
)
from host.workbench.planner import OperatorTime
from tests.independent.simulate import SessionSpec, write_session

TIME = OperatorTime()  # place 15 s, on an edge 40 s, settle 3 s, get ready 8 s
WINDOW = {1: 7.0, 2: 12.0, 3: 15.0}  # method.md §4
AXES = np.eye(3)
FACES = [s * AXES[j] for j in range(3) for s in (1.0, -1.0)]  # x_up, x_dn, y_up, …
EDGES = [
    (s1 * AXES[i] + s2 * AXES[j]) / math.sqrt(2.0)
    for i, j in itertools.combinations(range(3), 2)
    for s1 in (1.0, -1.0)
    for s2 in (1.0, -1.0)
]


def test_least_time_by_hand() -> None:
    """ρ = 1 /s on the worst channel and R·tol = 0.1 (°/s)/g: κ = 1/(1·0.1²) = 100 s, so 300 s
    of rest; one face (15 + 3 s) and three pairs (2·(15 + 8) s each) less one placement: 141 s
    more; the balanced plan: each axis 50 s down, 50 − 14 s up, one 1-turn pair after it."""
    assert least_rest_s((4.0, 1.0, 2.0), worst=1.0, tolerance=0.1) == pytest.approx(300.0)
    assert least_operator_s(300.0, TIME) == pytest.approx(441.0)
    assert balanced_plan_s(300.0, 1, TIME) == pytest.approx(3 * (36 + 50 + 36 + 30 + 15))


def _sigma2(rests: list[tuple[np.ndarray, float]]) -> np.ndarray:
    """σ² of GA_x, GA_y, GA_z (one gyro channel, ρ = 1 /s, G0 unknown) from the rests
    (up vector, seconds): the diagonal of the inverse 4×4 information."""
    m = np.zeros((4, 4))
    for u, t in rests:
        h = np.concatenate([[1.0], u])
        m += t * np.outer(h, h)
    if np.linalg.matrix_rank(m, tol=1e-9) < 4:
        return np.full(3, np.inf)
    return np.diag(np.linalg.inv(m))[1:]


def _plan(
    statics: list[int], share: np.ndarray, scale: float, pairs: list[tuple[int, int]]
) -> tuple[float, np.ndarray]:
    """(operator time s, σ² of the three GA) of a plan: static attitudes (indices into
    FACES + EDGES) with rest ``scale``·``share``, pairs (axis, turns) after their own face
    when that face is measured."""
    ups = FACES + EDGES
    rests = [(ups[a], scale * float(p)) for a, p in zip(statics, share, strict=True)]
    cost = sum(
        (TIME.place if a < 6 else TIME.place_tilted) + TIME.settle + scale * float(p)
        for a, p in zip(statics, share, strict=True)
    )
    followed: set[int] = set()
    for axis, turns in pairs:
        rests.append((AXES[axis], 2 * WINDOW[turns]))
        cost += 2 * (TIME.place + TIME.turn_ready + WINDOW[turns])
        if 2 * axis in statics and axis not in followed:  # right after its up face
            followed.add(axis)
            cost -= TIME.place
    return cost, _sigma2(rests)


@pytest.mark.slow
def test_no_plan_found_by_brute_force_beats_the_bound() -> None:
    """Thousands of random plans of faces, 45° attitudes and turn pairs, each with the least
    rest that reaches σ² ≤ 0.01 on every GA (bisection): none costs less than the bound, the
    balanced plan reaches the precision at its own time and 1 % less rest does not."""
    rng = np.random.default_rng(30)
    need = 0.01  # (R·tol)² with ρ = 1 /s: κ = 100 s
    bound = least_operator_s(least_rest_s((1.0,), 1.0, 0.1), TIME)
    best = math.inf
    for _ in range(600):
        statics = list(rng.choice(18, size=int(rng.integers(1, 9)), replace=False))
        if rng.random() < 0.5:
            statics = list(rng.choice(6, size=int(rng.integers(1, 7)), replace=False))
        share = rng.dirichlet(np.ones(len(statics)))
        pairs = [(ax, int(rng.integers(1, 4))) for ax in range(3)]
        pairs += [(int(rng.integers(0, 3)), 3)] * int(rng.integers(0, 2))
        lo, hi = 0.0, 1e5
        if np.max(_plan(statics, share, hi, pairs)[1]) > need:
            continue
        for _ in range(30):
            mid = 0.5 * (lo + hi)
            ok = np.max(_plan(statics, share, mid, pairs)[1]) <= need
            lo, hi = (lo, mid) if ok else (mid, hi)
        best = min(best, _plan(statics, share, hi, pairs)[0])
    assert bound <= best < 1.5 * bound, (bound, best)

    half = 50.0  # κ/2
    statics = [0, 1, 2, 3, 4, 5]
    share = np.array([half - 14.0, half] * 3)
    cost, s2 = _plan(statics, share, 1.0, [(0, 1), (1, 1), (2, 1)])
    assert np.max(s2) == pytest.approx(need, rel=1e-9)
    assert cost == pytest.approx(balanced_plan_s(300.0, 1, TIME))
    assert bound < cost
    assert np.max(_plan(statics, 0.99 * share, 1.0, [(0, 1), (1, 1), (2, 1)])[1]) > need


def test_rest_information_is_the_noise_density(tmp_path: Path) -> None:
    """A second of rest informs a gyro channel's reading by 1/(σ²·dt): white noise of one-sided
    density d (°/s/√Hz) at 50 Hz has σ² = d²·25 a sample, so 2/d² per second (the simulator's
    own noise, not the bench's)."""
    d = 0.008
    sim = write_session(tmp_path / "s", SessionSpec(seed=5, static_s=20.0, gyro_density=d))
    assert sim.records
    ds = build_dataset(read_session(tmp_path / "s"))
    base = parse_model("base", CATALOGUE)
    rho = rest_information(ds, fit_model(ds, base), base)
    assert rho == pytest.approx(np.full(3, 2.0 / d**2), rel=0.08)
