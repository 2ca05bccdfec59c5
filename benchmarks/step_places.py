"""Issue 39's yardstick per place of the plan: a bias step at every place, on data the bench's
physics did not write.

For each place of :data:`tests.independent.effects.STEP_PLACES` (between the two faces of a
pair, between pairs, between the faces and the turns, between the turns, before the closing
record, inside a static, inside a turn, inside the first and the last record), each sensor
(gyro 0.05–0.5 °/s, accel 0.02–0.1 m/s², either sign) and each plan (with the closing x_up_2
and without it, ``open``), ``--sessions`` sessions of the independent simulator
(``tests/independent``, seeds ``--seed0`` …) are diagnosed in this process (``model
diagnose``'s engine, floor from the session, ``base``), and per row it prints:

* ``adeq``: the verdict `adequate` (want 0);
* ``named``: the strongest unexplained signal a step on the step's own channel (want ≥ 9/10);
* ``unid``: the diagnosis says a step there could not be told apart (counted as named);
* ``rec``: a catalogue term recommended (want 0).

Then the rows that must not be lost: controls (median RMS z, want 0.8–1.25; `adequate`; the
p-values' Kolmogorov–Smirnov p against uniform, want > 0.01) and a drift per sensor and a
temperature bias (the expected term recommended alone). ::

    OPENBLAS_NUM_THREADS=1 python3 benchmarks/step_places.py --sessions 10 --jobs 2

``--places``, ``--sensors`` and ``--plans`` take comma lists to run a part; ``--no-controls``
leaves the last rows out.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import tempfile
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

for _v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")  # before numpy loads: one BLAS thread

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from tests.independent.effects import STEP_PLACES  # noqa: E402
from tests.independent.simulate import SessionSpec, write_session  # noqa: E402

#: the rows that must not be lost: (row, the simulator's fields, the term expected alone)
KEPT = (
    ("control", {"effect": "none"}, None),
    ("drift_accel", {"effect": "bias_drift_accel"}, "time_drift:accel"),
    ("drift_gyro", {"effect": "bias_drift_gyro"}, "time_drift:gyro"),
    ("temp_bias", {"effect": "temperature_bias", "warmup_s": 120.0}, "temperature_bias"),
)
#: places a plan without the closing record does not have
CLOSED_ONLY = ("closing", "in_last")


def diagnose_one(fields: dict[str, Any], seed: int) -> dict[str, Any]:
    """Simulate one session and diagnose it: its truth and what the diagnosis said."""
    from host.model.dataset import load_dataset
    from host.model.spec import parse_model
    from host.workbench.scan import STEP
    from host.workbench.verdict import diagnose

    with tempfile.TemporaryDirectory() as tmp:
        e = write_session(tmp, SessionSpec(seed=seed, **fields)).truth()["effect"]
        d = diagnose(load_dataset(Path(tmp)), parse_model("base"))
    top = d.dominant[0] if d.dominant else None
    named = (
        top is not None
        and (top.sensor, top.axis) == (e.get("sensor"), e.get("axis"))
        and top.signal.startswith(STEP)
    )
    return {
        "effect": e,
        "verdict": d.verdict,
        "recommended": ",".join(d.recommended),
        "named": bool(named),
        "unid": any("could not be told" in n for n in d.notes),
        "rms_z": d.fit.rms_z,
        "p": d.fit.chi2_p,
    }


def step_rows(a: argparse.Namespace) -> list[tuple[str, dict[str, Any]]]:
    """(row name, the simulator's fields) of every place × sensor × plan asked for."""
    out = []
    for plan in a.plans.split(","):
        for place in a.places.split(",") if a.places != "all" else STEP_PLACES:
            if plan == "open" and place in CLOSED_ONLY:
                continue
            for sensor in a.sensors.split(","):
                fields = {"effect": f"bias_step_{sensor}_at_{place}", "closing": plan == "closed"}
                out.append((f"{place:<13}{sensor:<7}{plan}", fields))
    return out


def run_all(
    rows: Sequence[tuple[str, dict[str, Any]]], n: int, seed0: int, jobs: int
) -> dict[str, list[dict[str, Any]]]:
    """Every row's ``n`` sessions (seeds ``seed0`` …), ``jobs`` processes."""
    tasks = [(name, fields, seed0 + k) for name, fields in rows for k in range(n)]
    out: dict[str, list[dict[str, Any]]] = {}
    with ProcessPoolExecutor(max_workers=jobs) as pool:
        results = pool.map(diagnose_one, [t[1] for t in tasks], [t[2] for t in tasks])
        for k, ((name, _, seed), r) in enumerate(zip(tasks, results, strict=True)):
            out.setdefault(name, []).append(r)
            print(f"{k + 1}/{len(tasks)} {name} {seed}: {r['verdict']}, named {r['named']}",
                  file=sys.stderr, flush=True)  # fmt: skip
    return out


def step_table(res: dict[str, list[dict[str, Any]]]) -> list[str]:
    """The places' lines: adequate, named, named unidentifiable, a term recommended."""
    lines = [
        "== a bias step at each place: adeq = `adequate` (want 0); named = the top signal a",
        "   step on the step's channel (want >= 9/10); unid = said it could not be told",
        "   apart; rec = a catalogue term recommended (want 0)",
        f"{'place':<13}{'sensor':<7}{'plan':<7}{'adeq':>6}{'named':>7}{'unid':>6}{'rec':>5}",
    ]
    for name, rs in res.items():
        n = len(rs)
        counts = (
            sum(r["verdict"] == "adequate" for r in rs),
            sum(r["named"] for r in rs),
            sum(r["unid"] for r in rs),
            sum(bool(r["recommended"]) for r in rs),
        )
        lines.append(f"{name:<27}" + "".join(f"{f'{c}/{n}':>6}" for c in counts))
    return lines


def kept_table(res: dict[str, list[dict[str, Any]]]) -> list[str]:
    """The controls', drifts' and temperature bias's lines."""
    from scipy import stats

    lines = ["", "== what must not be lost: controls (RMS z 0.8–1.25, KS p > 0.01), terms alone"]
    for name, _, term in KEPT:
        rs = res.get(name, [])
        if not rs:
            continue
        z = np.array([r["rms_z"] for r in rs])
        adequate = sum(r["verdict"] == "adequate" for r in rs)
        if term is None:
            ks = float(stats.kstest([r["p"] for r in rs], "uniform").pvalue)
            lines.append(f"{name:<13}RMS z median {np.median(z):.2f} "
                         f"({np.min(z):.2f}–{np.max(z):.2f}), adequate {adequate}/{len(rs)}, "
                         f"KS p {ks:.2f}")  # fmt: skip
            continue
        alone = sum(_alone(r, term) for r in rs)
        lines.append(f"{name:<13}{term} recommended alone {alone}/{len(rs)}")
    return lines


def _alone(r: dict[str, Any], term: str) -> bool:
    """Is the one recommended term ``term`` on the effect's own axis?"""
    rec = r["recommended"]
    return (
        bool(rec)
        and "," not in rec
        and rec.startswith(term)
        and rec.endswith(":" + r["effect"]["axis"])
    )


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sessions", type=int, default=10, help="sessions per row (default 10)")
    ap.add_argument("--seed0", type=int, default=1000, help="first seed (default 1000)")
    ap.add_argument("--jobs", type=int, default=1, help="processes (default 1)")
    ap.add_argument("--places", default="all", help=f"comma list or all: {', '.join(STEP_PLACES)}")
    ap.add_argument("--sensors", default="accel,gyro")
    ap.add_argument("--plans", default="closed,open", help="closed (x_up_2 last), open")
    ap.add_argument("--no-controls", action="store_true", help="leave the kept rows out")
    a = ap.parse_args(argv)
    bad = [p for p in a.places.split(",") if a.places != "all" and p not in STEP_PLACES]
    if bad or any(p not in ("closed", "open") for p in a.plans.split(",")):
        print(f"unknown place or plan: {', '.join(bad) or a.plans}", file=sys.stderr)
        return 2
    rows = step_rows(a)
    if not a.no_controls:
        rows += [(name, fields) for name, fields, _ in KEPT]
    res = run_all(rows, a.sessions, a.seed0, a.jobs)
    steps = {k: v for k, v in res.items() if k not in {name for name, _, _ in KEPT}}
    print("\n".join(step_table(steps) + kept_table(res)))
    return 0 if all(math.isfinite(r["rms_z"]) for rs in res.values() for r in rs) else 1


if __name__ == "__main__":
    raise SystemExit(main())
