"""The operator's time per unit of a sitting of several boards in one cube against one board's
(issue 45), on the virtual bench (``host.bench``: N boards in one cube, one hand).

A sitting's boards share every face and every turn, so the operator places and turns the cube
once for all of them; what each board adds is its mounting: taking it from the tray, seating
it in its slot of the cube and plugging its cable — ``--mount-s`` s per board (default
:data:`MOUNT_S`, 30 s; a single board is mounted too). The plan is the method's fixed plan
(six faces, then a turn pair about each axis, :func:`host.workbench.adaptive.fixed_plan_s`:
placing, settling, the record, the 'get ready' of each turn — the planning benchmark's
count), as short as reaches the target: from a ladder of face lengths (``--faces``) and turns
(``--turns``), in order of operator time, the first whose worst σ/tolerance (the fit's own σ,
model ``base`` and the board's lever arm) is at most ``--target`` on *every* board of the
sitting — all boards get the same records, so the worst board decides. A board alone gets the
first plan that reaches the target on it (the same unit, the same hand, the same place: the
records it would have had in the sitting). Each plan is a fresh sitting (new noise).

Units: ``SensorTruth.random`` of seed ``cube·100 + k`` with the linear model and noise only,
at slot k of cube ``cube``: each board's own lever arm (1.5–4 cm) and mounting (1–5 mrad).
Prints per cube the plan of the sitting and of each board alone, then over the cubes: the
operator's time per unit of the sitting and of a board alone (one by one: the mean), their
ratio (the issue asks at most 1/3), and the mounting time per board at which the ratio would
be exactly 1/3::

    OPENBLAS_NUM_THREADS=1 python3 benchmarks/planning_sitting.py --cubes 10 --target 0.02
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time as wall
from pathlib import Path
from typing import Any

for _v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")  # before numpy loads: one BLAS thread

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from host.bench.cube import SLOTS, simulate_sitting  # noqa: E402
from host.bench.physics import Bench  # noqa: E402
from host.bench.plan import Plan  # noqa: E402
from host.bench.truth import SensorTruth  # noqa: E402
from host.model.dataset import build_dataset  # noqa: E402
from host.model.fit import fit_model  # noqa: E402
from host.model.spec import merge_model, parse_model  # noqa: E402
from host.session.directory import Session  # noqa: E402
from host.workbench.adaptive import fixed_plan_s  # noqa: E402
from host.workbench.planner import unscaled_sigmas, worst_ratio  # noqa: E402

#: the operator's time to mount one board into the cube, s: take it from the tray, seat it in
#: its slot, plug its cable (and take it out afterwards)
MOUNT_S = 30.0
MODEL = merge_model(parse_model("base") + parse_model("lever_arm:accel"))


def ladder(faces: list[float], turns: list[int]) -> list[tuple[float, int, float]]:
    """Every (face s, turns) plan with its operator time, cheapest first."""
    plans = [(f, t, fixed_plan_s(f, t)) for f in faces for t in turns]
    return sorted(plans, key=lambda p: p[2])


def worst_per_board(cube: int, boards: int, face_s: float, turns: int, run: int) -> list[float]:
    """Each board's worst σ/tolerance after one sitting of the plan (fresh noise: ``run``)."""
    units = [
        SensorTruth.random(np.random.default_rng(cube * 100 + k)).only("linear", "noise")
        for k in range(boards)
    ]
    plan = Plan(static_s=face_s, turns=turns, warmup_s=0.0, bench=Bench())
    seeds = [cube * 100_000 + run * 100 + k for k in range(boards)]
    sessions = simulate_sitting(units, plan, cube, seeds)
    worst = []
    for k, records in enumerate(sessions):
        fit = fit_model(build_dataset(Session(f"C{cube}B{k}", records)), MODEL)
        worst.append(worst_ratio(unscaled_sigmas(fit, fit))[0])
    return worst


def one_cube(cube: int, args: argparse.Namespace) -> dict[str, Any] | None:
    """Climb the ladder until the plan reaches the target on every board: the sitting's plan,
    and each board's own first plan that reached it (None: no plan of the ladder does)."""
    alone: list[tuple[float, int, float] | None] = [None] * args.boards
    for run, (face_s, turns, cost) in enumerate(ladder(args.faces, args.turns)):
        worst = worst_per_board(cube, args.boards, face_s, turns, run)
        for k, w in enumerate(worst):
            if alone[k] is None and w <= args.target:
                alone[k] = (face_s, turns, cost)
        if max(worst) <= args.target:
            mine = [a for a in alone if a is not None]
            return {"cube": cube, "sitting": (face_s, turns, cost), "alone": mine, "worst": worst}
    print(f"{cube:>4}  out of reach: no plan of the ladder reaches {args.target:g} on every "
          f"board (worst {max(worst):.4f} at the last)", flush=True)  # fmt: skip
    return None


def print_cube(r: dict[str, Any], mount_s: float, boards: int) -> None:
    face_s, turns, cost = r["sitting"]
    alone = " ".join(f"{f:g}s/{t}:{c + mount_s:.0f}" for f, t, c in r["alone"])
    print(f"{r['cube']:>4}  {face_s:>4g} s, {turns} turns: {cost + boards * mount_s:>5.0f} s  "
          f"worst {max(r['worst']):.4f}   alone {alone}", flush=True)  # fmt: skip


def summary(rows: list[dict[str, Any]], mount_s: float, boards: int) -> None:
    """The operator's time per unit, sitting and alone, their ratio, and the break-even
    mounting time."""
    plan_sitting = sum(r["sitting"][2] for r in rows)
    plan_alone = sum(c for r in rows for _, _, c in r["alone"])
    units = len(rows) * boards
    per_sitting = (plan_sitting + units * mount_s) / units
    per_alone = (plan_alone + units * mount_s) / units
    ratio = per_sitting / per_alone
    # (P_s + U·m)/(P_a + U·m) = 1/3 at m = (P_a − 3·P_s)/(2·U): P the plans' time, U units
    even = (plan_alone - 3 * plan_sitting) / (2 * units)
    ratios = [
        (r["sitting"][2] + boards * mount_s) / sum(c + mount_s for _, _, c in r["alone"])
        for r in rows
    ]
    print(
        f"operator time per unit, mounting {mount_s:g} s a board: sitting of {boards} "
        f"{per_sitting:.0f} s, one board alone {per_alone:.0f} s (over {units} units)\n"
        f"  sitting/alone {ratio:.3f} (at most 1/3 = 0.333: {'yes' if ratio <= 1 / 3 else 'NO'}); "
        f"per cube {min(ratios):.3f} … {max(ratios):.3f}, median {statistics.median(ratios):.3f}\n"
        f"  1/3 exactly at a mounting of {even:.0f} s a board"
    )


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--boards", type=int, default=4, help=f"boards in the cube (1 … {SLOTS})")
    ap.add_argument("--cubes", type=int, default=5, help="sittings (cubes of new units)")
    ap.add_argument("--cube0", type=int, default=1)
    ap.add_argument("--target", type=float, default=0.02, help="worst σ/tolerance")
    ap.add_argument("--mount-s", type=float, default=MOUNT_S, help="s to mount one board")
    ap.add_argument(
        "--faces", type=lambda t: [float(x) for x in t.split(",")], default=[10, 20, 30, 60, 120],
        help="face lengths of the ladder, s (comma list)",
    )  # fmt: skip
    ap.add_argument(
        "--turns", type=lambda t: [int(x) for x in t.split(",")], default=[1, 2, 3],
        help="turns each way of the ladder (comma list)",
    )  # fmt: skip
    args = ap.parse_args(argv)
    if not 1 <= args.boards <= SLOTS:
        ap.error(f"--boards: a cube holds 1 … {SLOTS} boards, not {args.boards}")
    return args


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    t0 = wall.monotonic()
    print("cube  the sitting's plan (faces, turns): operator s   worst   alone (plan: s)")
    rows = []
    for cube in range(args.cube0, args.cube0 + args.cubes):
        row = one_cube(cube, args)
        if row is not None:
            rows.append(row)
            print_cube(row, args.mount_s, args.boards)
    print(f"{len(rows)} of {args.cubes} cubes of {args.boards} boards reached target "
          f"{args.target:g}; {wall.monotonic() - t0:.0f} s to run")  # fmt: skip
    if rows:
        summary(rows, args.mount_s, args.boards)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
