"""The adaptive plan against the fixed plan (issue 30), on units the bench's physics did not
write.

Each session is one unit of the independent simulator (``tests/independent``: white noise,
quantisation, hand turns; its noise densities drawn ×0.5–×2 of the defaults per session). The
fixed plan is the method's: six faces of ``--fixed-static`` s, two turns each way about each
axis, the closing X up. The adaptive plan measures the six faces for ``--min-static`` s and one
turn each way about each axis, then asks :func:`host.workbench.adaptive.adaptive_run` for the
planner's next record (a face again, short or long, or a turn pair) until its worst
σ/tolerance is at least as good as the fixed plan's on the same unit (or ``--target``).
Operator time counts every placement, settling, record and turn
(:class:`host.workbench.planner.OperatorTime`).

Prints per session and then the medians and the ratio fixed/adaptive::

    OPENBLAS_NUM_THREADS=1 python3 benchmarks/planning.py --sessions 20
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time as wall
from collections.abc import Sequence
from pathlib import Path

for _v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")  # before numpy loads: one BLAS thread

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from host.model.catalogue import CATALOGUE  # noqa: E402
from host.model.dataset import build_dataset  # noqa: E402
from host.model.fit import fit_model  # noqa: E402
from host.model.spec import parse_model  # noqa: E402
from host.session.directory import Session  # noqa: E402
from host.session.records import Record  # noqa: E402
from host.workbench.adaptive import adaptive_run, minimal_plan  # noqa: E402
from host.workbench.planner import (  # noqa: E402
    OPERATOR_TIME,
    Candidate,
    candidates,
    unscaled_sigmas,
    worst_ratio,
)
from tests.independent.hand import IndependentHand  # noqa: E402
from tests.independent.simulate import SessionSpec, SimRecord, simulate  # noqa: E402

BASE = parse_model("base", CATALOGUE)


def as_record(r: SimRecord) -> Record:
    """The simulator's record as the host's."""
    return Record(r.name, r.t_ms, r.accel, r.gyro, r.temp_c, r.meta)


def fixed_plan(spec: SessionSpec) -> tuple[float, str, float]:
    """(worst σ/tolerance, its name, operator time s) of the method's fixed plan."""
    s = simulate(spec)
    fit = fit_model(
        build_dataset(Session(spec.serial, {r.name: as_record(r) for r in s.records})), BASE
    )
    worst, name = worst_ratio(unscaled_sigmas(fit, fit))
    t = OPERATOR_TIME
    window = {1: 7.0, 2: 12.0, 3: 15.0}[spec.turns]
    statics = 7 if spec.closing else 6
    operator = statics * (t.place + t.settle + spec.static_s)
    operator += 6 * (t.place + t.turn_ready + window)
    return worst, name, operator


def one(seed: int, args: argparse.Namespace) -> dict[str, float | str | bool]:
    rng = np.random.default_rng([seed, 30])
    noise = {
        "accel_density": 0.0020 * float(rng.uniform(0.5, 2.0)),
        "gyro_density": 0.0050 * float(rng.uniform(0.5, 2.0)),
    }
    fixed = SessionSpec(seed=seed, static_s=args.fixed_static, turns=2, **noise)  # type: ignore[arg-type]
    w_fixed, n_fixed, t_fixed = fixed_plan(fixed)
    minimal = SessionSpec(seed=seed, static_s=args.min_static, turns=1, closing=False, **noise)  # type: ignore[arg-type]
    menu = candidates((args.min_static, 3 * args.min_static), 1, tilted=False)
    target = w_fixed if args.target is None else args.target
    hand = IndependentHand(minimal)

    def measure(c: Candidate, names: Sequence[str]) -> dict[str, Record]:
        return {n: as_record(r) for n, r in hand(c, names).items()}

    run = adaptive_run(
        measure, BASE, target=target, first=minimal_plan(args.min_static, 1), menu=menu,
        max_operator_s=3 * t_fixed,
    )  # fmt: skip
    return {
        "seed": seed,
        "fixed_s": t_fixed,
        "fixed_worst": w_fixed,
        "fixed_name": n_fixed,
        "adaptive_s": run.operator_s,
        "adaptive_worst": run.worst,
        "adaptive_name": run.worst_name,
        "reached": run.reached,
        "records": len(run.records),
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sessions", type=int, default=20)
    ap.add_argument("--seed0", type=int, default=0)
    ap.add_argument("--fixed-static", type=float, default=60.0, help="s per face, fixed plan")
    ap.add_argument("--min-static", type=float, default=10.0, help="s per face, minimal plan")
    ap.add_argument(
        "--target", type=float, default=None,
        help="worst σ/tolerance the adaptive plan stops at (default: the fixed plan's own, on "
        "the same unit)",
    )  # fmt: skip
    args = ap.parse_args(argv)
    rows = []
    t0 = wall.monotonic()
    print("seed  fixed s  worst (name)        adaptive s  worst (name)    records  ratio")
    for seed in range(args.seed0, args.seed0 + args.sessions):
        r = one(seed, args)
        rows.append(r)
        ratio = float(r["fixed_s"]) / float(r["adaptive_s"])
        print(
            f"{seed:>4}  {r['fixed_s']:>7.0f}  {r['fixed_worst']:.4f} ({r['fixed_name']:<5})   "
            f"{r['adaptive_s']:>10.0f}  {r['adaptive_worst']:.4f} ({r['adaptive_name']:<5})"
            f"{r['records']:>5}  {ratio:5.2f}{'' if r['reached'] else '  not reached'}",
            flush=True,
        )
    ratios = [float(r["fixed_s"]) / float(r["adaptive_s"]) for r in rows]
    print(
        f"median operator time: fixed {statistics.median(float(r['fixed_s']) for r in rows):.0f} s,"
        f" adaptive {statistics.median(float(r['adaptive_s']) for r in rows):.0f} s; "
        f"median ratio fixed/adaptive {statistics.median(ratios):.2f}; target reached in "
        f"{sum(bool(r['reached']) for r in rows)}/{len(rows)} ({wall.monotonic() - t0:.0f} s)"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
