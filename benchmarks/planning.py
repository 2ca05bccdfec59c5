"""The adaptive plan against the fixed plan (issue 30), on units the bench's physics did not
write.

Each session is one unit of the independent simulator (``tests/independent``: white noise,
quantisation, hand turns; its noise densities drawn ×0.5–×2 of the defaults per session). The
fixed plan is the method's: six faces of ``--fixed-static`` s, two turns each way about each
axis, the closing X up. The adaptive plan measures the six faces for ``--min-static`` s and one
turn each way about each axis, then asks :func:`host.workbench.adaptive.adaptive_run` for the
planner's next record (a face again, short or long, or a turn pair) until its worst
σ/tolerance is at least as good as the fixed plan's on the same unit (or ``--target``).
Its first records stop when they have enough, asked of the engine the operator's dialogue asks
(:class:`host.workbench.adaptive.AdaptivePlan`, ``calibrate --plan adaptive``; ``--no-stopping``:
they last ``--min-static`` s and one pair a axis), axis by axis (``--method-order``: six faces,
then the turns): the down face measured up to ``--max-static`` s and cut where the σ of its
mean met the target, looked at once a second; the up face where the face pair's g-sensitivity
meets it with the rest its turns will add (``--faces-alone``: its own mean); then turn pairs
about the axis, right after the up face without placing the cube again, until its gyro scale
meets the target.
Operator time counts every placement, settling, record and turn
(:class:`host.workbench.planner.OperatorTime`; a record on the face the cube already rests on
is not placed again, :func:`host.workbench.adaptive.cost_after`, for both plans).

Prints per session and then the medians and the ratio fixed/adaptive; the least time any
plan of these records needs for the same precision (:mod:`host.workbench.least_time`); and,
for the record each adaptive plan planned last, the σ predicted before measuring against the
scatter of (fitted − truth) over the sessions::

    OPENBLAS_NUM_THREADS=1 python3 benchmarks/planning.py --sessions 20
"""

from __future__ import annotations

import argparse
import math
import os
import statistics
import sys
import time as wall
from collections.abc import Sequence
from pathlib import Path
from typing import Any

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
from host.session.method import GROUPS, TOLERANCES, local_gravity  # noqa: E402
from host.session.records import STATIC_NAMES, Record  # noqa: E402
from host.workbench.adaptive import (  # noqa: E402
    AdaptiveRun,
    Measure,
    Stopping,
    adaptive_run,
    cost_after,
    minimal_plan,
)
from host.workbench.least_time import (  # noqa: E402
    balanced_plan_s,
    least_operator_s,
    least_rest_s,
    rest_information,
)
from host.workbench.planner import (  # noqa: E402
    Candidate,
    candidates,
    unique_name,
    unscaled_sigmas,
    worst_ratio,
)
from host.workbench.stopping import StaticRule  # noqa: E402
from tests.independent.hand import IndependentHand  # noqa: E402
from tests.independent.simulate import SessionSpec, SimRecord, simulate  # noqa: E402

BASE = parse_model("base", CATALOGUE)


def as_record(r: SimRecord) -> Record:
    """The simulator's record as the host's."""
    return Record(r.name, r.t_ms, r.accel, r.gyro, r.temp_c, r.meta)


def fixed_plan(spec: SessionSpec) -> tuple[float, str, float, np.ndarray]:
    """(worst σ/tolerance, its name, operator time s, information per second of rest on each
    gyro channel (:func:`host.workbench.least_time.rest_information`)) of the method's fixed
    plan, its records in the method's order (the six faces, the turn pairs, the closing X up)
    counted as the adaptive plan's are (:func:`host.workbench.adaptive.cost_after`)."""
    s = simulate(spec)
    ds = build_dataset(Session(spec.serial, {r.name: as_record(r) for r in s.records}))
    fit = fit_model(ds, BASE)
    worst, name = worst_ratio(unscaled_sigmas(fit, fit))
    menu = {c.label: c for c in candidates(spec.static_s, spec.turns, tilted=False)}
    order = [f"{f} again" for f in STATIC_NAMES]
    order += [f"{ax} turns, {spec.turns} each way" for ax in "xyz"]
    order += ["x_up again"] if spec.closing else []
    operator, up = 0.0, None
    for label in order:
        operator += cost_after(menu[label], up)
        up = np.asarray(menu[label].records[-1][1], dtype=float)
    return worst, name, operator, rest_information(ds, fit, BASE)


def planned_pulls(
    run: AdaptiveRun, hand: IndependentHand, measure: Measure
) -> tuple[str, dict[str, float]]:
    """The record the adaptive plan planned last — its last step taken from the planner, or
    when it took none the record the planner would take next, measured now — and for every
    value with a tolerance its pull: (fitted − truth) / the σ the planner predicted for it
    before it was measured. -> (the record's label, name -> pull)."""
    records = dict(run.records)
    if len(run.steps) > 1:
        label, predicted = run.steps[-1].label, run.steps[-1].predicted
    elif run.next is not None:
        label, predicted = run.next.candidate.label, run.next.sigma_after
        names: list[str] = []
        for base, *_ in run.next.candidate.records:
            names.append(unique_name(base, list(records) + names))
        records.update(measure(run.next.candidate, names))
    else:
        return "", {}
    fit = fit_model(build_dataset(Session("ADAPT", records)), BASE)
    truth = simulate(hand.spec).truth()["constants"]
    pulls = {}
    for p in fit.parameters:
        sigma = predicted.get(p.name, math.nan)
        if TOLERANCES.get(p.name) and p.name in truth and math.isfinite(sigma) and sigma > 0:
            pulls[p.name] = (p.value - float(truth[p.name])) / sigma
    return label, pulls


def one(seed: int, args: argparse.Namespace) -> dict[str, Any]:
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

    stopping, first = None, minimal_plan(args.min_static, 1)
    if args.stopping:
        rule = StaticRule.for_target(
            target, local_gravity(), min_s=args.min_static, max_s=args.max_static
        )
        stopping = Stopping(rule, 1, by_axis=args.by_axis, pair_rule=args.pair_rule)
        first = []
    run = adaptive_run(
        measure, BASE, target=target, first=first, menu=menu, stopping=stopping,
        max_operator_s=3 * t_fixed,
    )  # fmt: skip
    label, pulls = planned_pulls(run, hand, measure)
    return {
        "planned": label,
        "pulls": pulls,  # type: ignore[dict-item]
        "seed": seed,
        "fixed_s": t_fixed,
        "fixed_worst": w_fixed,
        "fixed_name": n_fixed,
        "adaptive_s": run.operator_s,
        "adaptive_worst": run.worst,
        "adaptive_name": run.worst_name,
        "reached": run.reached,
        "records": len(run.records),
        "took": len(run.steps) > 1,
        "bound_s": least_operator_s(rest),
        "balanced_s": balanced_plan_s(rest),
    }


def print_pulls(rows: Sequence[dict[str, Any]]) -> None:
    """Per value group of method.md §7, the RMS over the sessions of the pulls of the record
    each adaptive plan planned last (:func:`planned_pulls`): 1 when the σ predicted before
    measuring is the scatter of (fitted − truth); the item's ±15 %."""
    taken = sum(1 for r in rows if r["took"])
    print(
        f"σ predicted for the record planned last (a planner's step in {taken} sessions,\n"
        f"  the record it would plan next in {len(rows) - taken}), before measuring, against "
        f"the scatter\n  of (fitted − truth): RMS of the pulls, 1 when σ is the scatter"
    )
    print("  value group                  pulls   RMS  within ±15 %")
    pooled: list[float] = []
    by_title: dict[str, list[float]] = {}
    for title, names, _, tol in GROUPS:
        if tol is None:
            continue
        for r in rows:
            by_title.setdefault(title, []).extend(r["pulls"][n] for n in names if n in r["pulls"])
    for title, pulls in by_title.items():
        if not pulls:
            continue
        rms = float(np.sqrt(np.mean(np.square(pulls))))
        pooled.extend(pulls)
        ok = "yes" if 0.85 <= rms <= 1.15 else "NO"
        print(f"  {title:<27}{len(pulls):>6}  {rms:>5.2f}  {ok}")
    if pooled:
        rms = float(np.sqrt(np.mean(np.square(pooled))))
        ok = "yes" if 0.85 <= rms <= 1.15 else "NO"
        print(f"  {'all':<27}{len(pooled):>6}  {rms:>5.2f}  {ok}")


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
    ap.add_argument(
        "--method-order", dest="by_axis", action="store_false",
        help="the first records in the method's order (six faces, then the turns), not axis "
        "by axis with each pair right after its up face; each face then stops on its own "
        "mean (the pair rule asks the up face measured second)",
    )  # fmt: skip
    ap.add_argument(
        "--faces-alone", dest="pair_rule", action="store_false",
        help="each face stops on its own mean, not the face pair's g-sensitivity with the "
        "rest its turns add",
    )  # fmt: skip
    args = ap.parse_args(argv)
    rows = []
    t0 = wall.monotonic()
    print("seed fixed s worst (name)     adaptive s worst (name)   records ratio bound s")
    for seed in range(args.seed0, args.seed0 + args.sessions):
        r = one(seed, args)
        rows.append(r)
        ratio = float(r["fixed_s"]) / float(r["adaptive_s"])
        print(
            f"{seed:>4} {r['fixed_s']:>7.0f} {r['fixed_worst']:.4f} ({r['fixed_name']:<5})  "
            f"{r['adaptive_s']:>10.0f} {r['adaptive_worst']:.4f} ({r['adaptive_name']:<5})"
            f"{r['records']:>5} {ratio:5.2f} {r['bound_s']:>7.0f}"
            f"{'' if r['reached'] else ' not reached'}",
            flush=True,
        )
    fixed_s = [float(r["fixed_s"]) for r in rows]
    adaptive_s = [float(r["adaptive_s"]) for r in rows]
    bound = [float(r["bound_s"]) for r in rows]
    balanced = [float(r["balanced_s"]) for r in rows]

    def ratio_of(a: list[float], b: list[float]) -> float:
        return statistics.median(x / y for x, y in zip(a, b, strict=True))

    print(
        f"median operator time: fixed {statistics.median(fixed_s):.0f} s, adaptive "
        f"{statistics.median(adaptive_s):.0f} s, ratio fixed/adaptive "
        f"{ratio_of(fixed_s, adaptive_s):.2f}\n  (target reached in "
        f"{sum(bool(r['reached']) for r in rows)}/{len(rows)}; {wall.monotonic() - t0:.0f} s)"
    )
    what = "the fixed plan's precision" if args.target is None else f"σ/tolerance {args.target:g}"
    print(
        f"no plan of these records reaches {what} in less than\n"
        f"  {statistics.median(bound):.0f} s (median; ratio fixed/bound "
        f"{ratio_of(fixed_s, bound):.2f}); six balanced faces, a pair after\n"
        f"  each up face: {statistics.median(balanced):.0f} s (ratio "
        f"{ratio_of(fixed_s, balanced):.2f})"
    )
    print_pulls(rows)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
