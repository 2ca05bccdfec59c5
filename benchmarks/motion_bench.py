"""Time the turns' motion in the model: a rate's derivative (``host.model.turning.derivative``,
inside every lever-arm matrix) and the tilt each turn sees from its motion
(``host.model.turn_motion.motion_tilts``, in every dataset with turns), each against the way
it was computed before (kept here as the reference), on the same simulated session in the
same run. Run: ``python3 benchmarks/motion_bench.py``.

The references: the derivative's five-point weights from the full (5, 5, 5, n) products; a
turn's rows averaged range by range with a ``mean`` each, and the leverages by a
three-operand ``einsum``. The program takes the weights' products factor by factor (the
same numbers, bit for bit), every range's mean from one running sum and the leverages from
one matrix product (the same to rounding: the tilts' difference is printed in σ).
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.records_bench import best_of
from host.bench.plan import Plan, simulate_session
from host.bench.truth import SensorTruth
from host.model import plate, turn_motion, turning
from host.model.dataset import build_dataset
from host.model.geometry import plate_axes
from host.model.noise import still_runs
from host.session.directory import Session


def reference_derivative(t: np.ndarray, y: np.ndarray) -> np.ndarray:
    """dy/dt with the weights from the full products (as before)."""
    n = len(t)
    out = np.asarray(np.gradient(y, t, axis=0), dtype=np.float64)
    if n < 5:
        return out
    i = np.arange(2, n - 2)
    d = np.stack([t[i + k] - t[i] for k in range(-2, 3)])
    same = np.eye(5, dtype=bool)
    diff = d[:, None, :] - d[None, :, :]
    diff[same] = 1.0
    neg = np.broadcast_to(-d, (5, 5, 5, len(i))).copy()
    neg[same[:, None, :] | same[None, :, :]] = 1.0
    terms = np.prod(neg, axis=2)
    terms[same] = 0.0
    w = np.sum(terms, axis=1) / np.prod(diff, axis=1)
    out[2 : n - 2] = sum(w[k][:, None] * y[i + k - 2] for k in range(5))
    return out


def reference_turn_rows(rows, sig, gyro_sd, white):  # type: ignore[no-untyped-def]
    """A turn's rows range by range, a ``mean`` each (as before)."""
    t_rel = sig.t_s - sig.t_s[0]
    rate_up = sig.rate @ sig.up
    runs = still_runs(rate_up, t_rel, gyro_sd)
    ranges = [*runs, *turning.moving_blocks(rate_up, t_rel, gyro_sd)]
    if len(ranges) < turn_motion.MIN_ROWS:
        return -1
    up_k = int(np.argmax(np.abs(sig.up)))
    east, north = plate_axes(sig.up, sig.heading)
    scale = np.ones(3) if sig.accel_matrix is None else np.diag(np.asarray(sig.accel_matrix))
    lever = turning.sensed_lever_matrix(sig.t_s, sig.rate, np.diag(scale))
    for k in (i for i in range(3) if i != up_k):
        tilt = sig.g * scale[k] * np.column_stack([east[:, k], north[:, k]])
        for b, (a, e) in enumerate(ranges):
            row = len(rows.y)
            rows.y.append(float(sig.accel[a:e, k].mean()))
            rows.white.append(float(white[k]) / (e - a))
            rows.rest.append(b < len(runs))
            rows.cols.setdefault(("c", sig.name, str(k)), {})[row] = 1.0
            te, tn = tilt[a:e].mean(axis=0)
            rows.cols.setdefault(("t", sig.name, "e"), {})[row] = float(te)
            rows.cols.setdefault(("t", sig.name, "n"), {})[row] = float(tn)
            for j, v in enumerate(lever[a:e, k, :].mean(axis=0)):
                if v != 0.0:
                    rows.cols.setdefault(("r", "xyz"[j]), {})[row] = float(v)
    return len(runs)


def reference_weighted_fit(x, y, var):  # type: ignore[no-untyped-def]
    """The weighted fit with its leverages by a three-operand einsum (as before)."""
    sw = 1.0 / np.sqrt(np.maximum(var, turn_motion.VAR_FLOOR))
    xw = x * sw[:, None]
    cov = np.linalg.pinv(xw.T @ xw)
    beta = cov @ (xw.T @ (y * sw))
    lev = np.einsum("ij,jk,ik->i", xw, cov, xw)
    return beta, cov, y - x @ beta, np.clip(lev, 0.0, 1.0)


def motion_inputs(static_s: float, turns: int) -> tuple:
    """The arguments a dataset build gives ``motion_tilts``, on a simulated session."""
    truth = SensorTruth.random(np.random.default_rng(0))
    records = simulate_session(truth, Plan(static_s=static_s, turns=turns), seed=1)
    seen: list[tuple] = []
    original = plate.motion_tilts
    plate.motion_tilts = lambda *a: seen.append(a) or original(*a)  # type: ignore[assignment]
    try:
        build_dataset(Session("BENCH", records))
    finally:
        plate.motion_tilts = original
    return seen[0]


def with_reference(work: Callable[[], object]) -> object:
    """``work`` run with the reference rows and fit in the module."""
    rows, fit = turn_motion._turn_rows, turn_motion._weighted_fit
    turn_motion._turn_rows, turn_motion._weighted_fit = reference_turn_rows, reference_weighted_fit
    try:
        return work()
    finally:
        turn_motion._turn_rows, turn_motion._weighted_fit = rows, fit


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--static-s", type=float, default=10.0, help="seconds of each static")
    ap.add_argument("--turns", type=int, default=2, help="turns per turn record")
    ap.add_argument("--repeats", type=int, default=3, help="runs of each, the best kept")
    a = ap.parse_args()
    args = motion_inputs(a.static_s, a.turns)
    turn = next(s for s in args[0] if s.kind == "turn")
    if (
        turning.derivative(turn.t_s, turn.rate).tobytes()
        != reference_derivative(turn.t_s, turn.rate).tobytes()
    ):
        raise SystemExit("the derivative and its reference differ")
    new = turn_motion.motion_tilts(*args)
    ref = with_reference(lambda: turn_motion.motion_tilts(*args))
    assert new is not None and ref is not None
    off = max(
        float(np.max(np.abs(m.tilt - r.tilt) / np.sqrt(np.diag(r.cov))))
        for m, r in zip(new.tilts, ref.tilts, strict=True)
    )
    turns = [s for s in args[0] if s.kind == "turn"]
    d = best_of(a.repeats, lambda: [turning.derivative(s.t_s, s.rate) for s in turns])
    d_ref = best_of(a.repeats, lambda: [reference_derivative(s.t_s, s.rate) for s in turns])
    m = best_of(a.repeats, lambda: turn_motion.motion_tilts(*args))
    m_ref = best_of(a.repeats, lambda: with_reference(lambda: turn_motion.motion_tilts(*args)))
    n = sum(len(s.t_s) for s in turns)
    print(f"{len(new.tilts)} turn records, {n} samples (CPU, best of {a.repeats}):")
    for what, ours, old in (("derivative", d, d_ref), ("motion_tilts", m, m_ref)):
        print(f"  {what:12s} {ours * 1e3:6.1f} ms, before {old * 1e3:6.1f} ms: {old / ours:.1f}×")
    print(f"  the derivative bit for bit the same; the tilts within {off:.1g} σ of before")


if __name__ == "__main__":
    main()
