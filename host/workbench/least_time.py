"""The least operator time any plan of the planner's records needs for a precision (issue 30).

A gyro's g-sensitivity GA (method.md §2/§3: nine values, tolerance ±0.1 (°/s)/g) is read only
while the cube rests: with the up vector u (a unit vector in chip axes) gyro channel k reads
G0k + GA_k·u. A face, a 45° attitude (an edge up) and the window of a turn about the vertical
(the specific force stays g·u all the while) are all such rest, each second of it worth the
same information ρ_k ((°/s)⁻² per s) on that reading. Knowing every other parameter only adds
information, so a plan's information on (G0k, GA_k) is at most ρ_k·Σ_a T_a·(1, u_a)(1, u_a)ᵀ,
T_a its rest (s) at attitude a. With G0k taken out (Schur complement) the information on GA_k
is J = ρ_k·(B − m·mᵀ/S), B = Σ T·u·uᵀ, m = Σ T·u, S = Σ T, and for a positive-definite J
σ²(GA_kj) = (J⁻¹)_jj ≥ 1/J_jj. A worst σ/tolerance R needs J_jj ≥ 1/(R·tol)² for each of the
three axes j, so trace J = ρ_k·(S − |m|²/S) ≥ 3/(R·tol)²:

    S ≥ 3·κ_k,   κ_k = 1 / (ρ_k·(R·tol)²)   (s)

whatever the attitudes — the rest time no plan of faces, 45° attitudes and turns can do
without. On top of it a plan needs a turn pair about each axis (only turns determine the gyro
scales) and at least one static record (turn windows rest only with +x, +y, +z up: three
attitudes do not separate G0 from three GA): :func:`least_operator_s`.

The bound is reached by six faces balanced about each axis — the down face κ/2, the up face
κ/2 less the rest its pair of turns adds, the pair made right after its up face without placing
the cube again (:func:`balanced_plan_s`): the least time lies between the two.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from host.model.dataset import Dataset
from host.model.design import design
from host.model.fit import Fit
from host.model.spec import ModelTerm
from host.session.records import turn_window_s
from host.workbench.planner import OPERATOR_TIME, OperatorTime

#: the tolerance of a gyro g-sensitivity, (°/s)/g (method.md §7)
GSENS_TOLERANCE = 0.1


def rest_information(ds: Dataset, fit: Fit, model: Sequence[ModelTerm]) -> np.ndarray:
    """(3,) information per second of rest on each gyro channel's reading at rest, (°/s)⁻²/s:
    the Fisher information the fit's own weighted rows (its whitening) give the gyro bias
    G0k, summed over the records of ``ds`` (statics and turn windows alike), divided by their
    total length. ``fit``: ``model`` fitted to ``ds`` (for its parameters' names)."""
    x, _, _ = design(ds, model)
    names = [p.name for p in fit.parameters]
    seconds = 0.0
    for i, sig in enumerate(ds.signals):
        n = ds.aggregators[i].shape[1]
        dt = float(np.median(np.diff(sig.t_s))) if n > 1 else 0.0
        seconds += n * dt
    out = np.zeros(3)
    for k, ax in enumerate("xyz"):
        on = (ds.row_sensor == 1) & (ds.row_axis == k)
        col = np.where(on, x[:, names.index(f"G0{ax}")], 0.0)
        out[k] = float(np.sum(ds.whiten.apply(col) ** 2)) / seconds if seconds > 0 else 0.0
    return out


def least_rest_s(
    rho: Sequence[float] | np.ndarray, worst: float, tolerance: float = GSENS_TOLERANCE
) -> float:
    """3·κ (s): the rest no plan can do without for every GA to reach σ ≤ ``worst``·
    ``tolerance``, on the channel with the least information ``rho`` (per s, (°/s)⁻²/s)."""
    least = min(float(r) for r in rho)
    if least <= 0.0 or worst <= 0.0:
        return math.inf
    return 3.0 / (least * (worst * tolerance) ** 2)


def least_overhead_s(time: OperatorTime = OPERATOR_TIME) -> float:
    """The operator's time beyond rest (s) no plan can do without: one static record (placing,
    settling) and a turn pair about each axis (two placements and two 'get ready' each; one
    placement less for the pair made right after a record of its own face)."""
    static = time.place + time.settle
    pairs = 3 * 2 * (time.place + time.turn_ready) - time.place
    return static + pairs


def least_operator_s(rest_s: float, time: OperatorTime = OPERATOR_TIME) -> float:
    """No plan of faces, 45° attitudes and turn pairs reaches the precision that needs
    ``rest_s`` s of rest (:func:`least_rest_s`) in less operator time than this, s."""
    return rest_s + least_overhead_s(time)


def balanced_plan_s(rest_s: float, turns: int = 1, time: OperatorTime = OPERATOR_TIME) -> float:
    """Operator time (s) of the plan that reaches the bound's rest ``rest_s`` (3κ): each axis
    down for κ/2 s, up for κ/2 less its pair's two turn windows, then its pair of ``turns``
    each way without placing the cube again. It gives every GA exactly σ = R·tolerance (a
    better σ when the windows alone give the up side more than κ/2: the face is still placed)."""
    half = rest_s / 6.0
    window = turn_window_s(turns)
    up = max(half - 2.0 * window, 0.0)
    per_axis = 2 * (time.place + time.settle) + half + up
    per_axis += 2 * (time.turn_ready + window) + time.place
    return 3 * per_axis
