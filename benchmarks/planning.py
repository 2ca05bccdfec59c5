"""The adaptive plan against the fixed plan (issue 30), on units the bench's physics did not
write.

Each session is one unit of the independent simulator (``tests/independent``: white noise,
quantisation, hand turns; its noise densities drawn ×0.5–×2 of the defaults per session). The
fixed plan is the method's: six faces of ``--fixed-static`` s, two turns each way about each
axis, the closing X up. The adaptive plan measures the six faces for ``--min-static`` s and one
turn each way about each axis, then asks :func:`host.workbench.adaptive.adaptive_run` for the
planner's next record (a face again, short or long, or a turn pair) until its worst
σ/tolerance is at least as good as the fixed plan's on the same unit (or ``--target``).
Its first records stop when they have enough (:mod:`host.workbench.stopping`; ``--no-stopping``:
they last ``--min-static`` s and one pair a axis): each face measured up to ``--max-static`` s
and cut where the σ of its mean met the target, looked at once a second; turn pairs about an
axis until its gyro scale meets the target.
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
from host.session.method import local_gravity  # noqa: E402
from host.session.records import STOPPED_KEY, Record  # noqa: E402
from host.workbench.adaptive import adaptive_run, minimal_plan  # noqa: E402
from host.workbench.least_time import (  # noqa: E402
    balanced_plan_s,
    least_operator_s,
    least_rest_s,
    rest_information,
)
from host.workbench.planner import (  # noqa: E402
    OPERATOR_TIME,
    Candidate,
    candidates,
    unique_name,
    unscaled_sigmas,
    worst_ratio,
)
from host.workbench.stopping import (  # noqa: E402
    StaticRule,
    stop_index,
    turn_scale_ratio,
    turns_stop,
)
from tests.independent.hand import IndependentHand  # noqa: E402
from tests.independent.simulate import SessionSpec, SimRecord, simulate  # noqa: E402

BASE = parse_model("base", CATALOGUE)


def as_record(r: SimRecord) -> Record:
    """The simulator's record as the host's."""
    return Record(r.name, r.t_ms, r.accel, r.gyro, r.temp_c, r.meta)


def fixed_plan(spec: SessionSpec) -> tuple[float, str, float, np.ndarray]:
    """(worst σ/tolerance, its name, operator time s, information per second of rest on each
    gyro channel (:func:`host.workbench.least_time.rest_information`)) of the method's fixed
    plan."""
    s = simulate(spec)
    ds = build_dataset(Session(spec.serial, {r.name: as_record(r) for r in s.records}))
    fit = fit_model(ds, BASE)
    worst, name = worst_ratio(unscaled_sigmas(fit, fit))
    t = OPERATOR_TIME
    window = {1: 7.0, 2: 12.0, 3: 15.0}[spec.turns]
    statics = 7 if spec.closing else 6
    operator = statics * (t.place + t.settle + spec.static_s)
    operator += 6 * (t.place + t.turn_ready + window)
    return worst, name, operator, rest_information(ds, fit, BASE)


def stopping_first(
    hand: IndependentHand, target: float, min_s: float, max_s: float
) -> tuple[dict[str, Record], float]:
    """The six faces (each up to ``max_s`` s, cut where it had enough), then turn pairs about
    each axis until its gyro scale meets ``target``: (the records, the operator's time s)."""
    t = OPERATOR_TIME
    rule = StaticRule.for_target(target, local_gravity(), min_s=min_s, max_s=max_s)
    menu = candidates(max_s, 1, tilted=False)
    records: dict[str, Record] = {}
    spent = 0.0
    for c in menu:
        if c.records[0][2] != "static":
            continue
        name = c.records[0][0]
        r = as_record(hand(c, [name])[name])
        t_s = r.t_ms / 1000.0
        n, why = stop_index(rule, t_s, r.accel, r.gyro)
        meta = {**r.meta, STOPPED_KEY: why}
        records[name] = Record(name, r.t_ms[:n], r.accel[:n], r.gyro[:n], r.temp[:n], meta)
        spent += t.place + t.settle + float(t_s[n - 1] - t_s[0]) + float(t_s[1] - t_s[0])
    for ax in "xyz":
        pair = next(c for c in menu if c.label.startswith(f"{ax} turns"))
        for pairs in range(1, 100):
            names = [unique_name(base, records) for base, *_ in pair.records]
            records.update({k: as_record(v) for k, v in hand(pair, names).items()})
            spent += pair.operator_s
            ratio = turn_scale_ratio(Session("ADAPT", dict(records)), BASE, ax)
            if turns_stop(ratio, target, pairs) is not None:
                break
    return records, spent


def one(seed: int, args: argparse.Namespace) -> dict[str, float | str | bool]:
    rng = np.random.default_rng([seed, 30])
    noise = {
        "accel_density": 0.0020 * float(rng.uniform(0.5, 2.0)),
        "gyro_density": 0.0050 * float(rng.uniform(0.5, 2.0)),
    }
    fixed = SessionSpec(seed=seed, static_s=args.fixed_static, turns=2, **noise)  # type: ignore[arg-type]
    w_fixed, n_fixed, t_fixed, rho = fixed_plan(fixed)
    first_s = args.max_static if args.stopping else args.min_static
    minimal = SessionSpec(seed=seed, static_s=first_s, turns=1, closing=False, **noise)  # type: ignore[arg-type]
    menu = candidates((args.min_static, 3 * args.min_static), 1, tilted=False)
    target = w_fixed if args.target is None else args.target
    rest = least_rest_s(rho, target)
    hand = IndependentHand(minimal)

    def measure(c: Candidate, names: Sequence[str]) -> dict[str, Record]:
        return {n: as_record(r) for n, r in hand(c, names).items()}

    if args.stopping:
        measured, measured_s = stopping_first(hand, target, args.min_static, args.max_static)
        first: list[Candidate] = []
    else:
        measured, measured_s, first = {}, 0.0, minimal_plan(args.min_static, 1)
    run = adaptive_run(
        measure, BASE, target=target, first=first, menu=menu, max_operator_s=3 * t_fixed,
        measured=measured, measured_s=measured_s,
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
        "bound_s": least_operator_s(rest),
        "balanced_s": balanced_plan_s(rest),
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sessions", type=int, default=20)
    ap.add_argument("--seed0", type=int, default=0)
    ap.add_argument("--fixed-static", type=float, default=60.0, help="s per face, fixed plan")
    ap.add_argument("--min-static", type=float, default=10.0, help="s per face, minimal plan")
    ap.add_argument("--max-static", type=float, default=120.0, help="s per face at most")
    ap.add_argument(
        "--no-stopping", dest="stopping", action="store_false",
        help="the first faces last --min-static s and one turn pair an axis (no stopping rule)",
    )  # fmt: skip
    ap.add_argument(
        "--target", type=float, default=None,
        help="worst σ/tolerance the adaptive plan stops at (default: the fixed plan's own, on "
        "the same unit)",
    )  # fmt: skip
    args = ap.parse_args(argv)
    rows = []
    t0 = wall.monotonic()
    print("seed  fixed s  worst (name)        adaptive s  worst (name)    records  ratio  bound s")
    for seed in range(args.seed0, args.seed0 + args.sessions):
        r = one(seed, args)
        rows.append(r)
        ratio = float(r["fixed_s"]) / float(r["adaptive_s"])
        print(
            f"{seed:>4}  {r['fixed_s']:>7.0f}  {r['fixed_worst']:.4f} ({r['fixed_name']:<5})   "
            f"{r['adaptive_s']:>10.0f}  {r['adaptive_worst']:.4f} ({r['adaptive_name']:<5})"
            f"{r['records']:>5}  {ratio:5.2f}  {r['bound_s']:>7.0f}"
            f"{'' if r['reached'] else '  not reached'}",
            flush=True,
        )
    ratios = [float(r["fixed_s"]) / float(r["adaptive_s"]) for r in rows]
    print(
        f"median operator time: fixed {statistics.median(float(r['fixed_s']) for r in rows):.0f} s,"
        f" adaptive {statistics.median(float(r['adaptive_s']) for r in rows):.0f} s; "
        f"median ratio fixed/adaptive {statistics.median(ratios):.2f}; target reached in "
        f"{sum(bool(r['reached']) for r in rows)}/{len(rows)} ({wall.monotonic() - t0:.0f} s)"
    )
    fixed_s = [float(r["fixed_s"]) for r in rows]
    bound = [float(r["bound_s"]) for r in rows]
    balanced = [float(r["balanced_s"]) for r in rows]
    what = "the fixed plan's precision" if args.target is None else f"σ/tolerance {args.target:g}"
    print(
        f"no plan of these records reaches {what} in less than "
        f"{statistics.median(bound):.0f} s (median; ratio fixed/bound "
        f"{statistics.median(f / b for f, b in zip(fixed_s, bound, strict=True)):.2f}); six "
        f"balanced faces, a pair after each up face: {statistics.median(balanced):.0f} s (ratio "
        f"{statistics.median(f / b for f, b in zip(fixed_s, balanced, strict=True)):.2f})"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
