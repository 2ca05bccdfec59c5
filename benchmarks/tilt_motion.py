"""The plate's tilt from the turns' motion (issue 40), on the independent simulator.

Sessions of ``tests/independent`` whose turns are each ONE motion, resting only at its ends
(``turn_motion="continuous"``), every record at a random multiple of 90° and no heading
recorded. Per case, in-process (one dataset per session, the floor from the session):

* ``tilt``: the plate tilted 0.1°–1° toward any azimuth; ``base,plate_tilt:accel`` fitted:
  the tilt's size within 10 % and within 3σ (its own σ, along the tilt), the pulls
  (fitted − truth)/σ of the tilt's two angles, of its size and of every static's own view of
  it (``seen_ref``, ``seen_side``), RMS z after;
* ``lever``: the sensor 10–50 mm off the cube's centre on every axis; ``base,lever_arm:accel``:
  each component within 3σ, pulls;
* ``both``: the two at once; ``base,plate_tilt:accel,lever_arm:accel``;
* with ``--diagnose K``: the diagnosis of the first K sessions of each case (what it
  recommends: never a lever arm or a face error on a tilt alone, never a tilt on a lever arm
  alone).

    OPENBLAS_NUM_THREADS=1 python3 benchmarks/tilt_motion.py --sessions 50 --diagnose 10
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import tempfile
from collections.abc import Sequence
from pathlib import Path
from typing import Any

for _v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")  # before numpy loads: one BLAS thread

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from benchmarks.yardstick_pulls import truth_of  # noqa: E402
from host.model.catalogue import CATALOGUE  # noqa: E402
from host.model.components import fit_with_components  # noqa: E402
from host.model.dataset import load_dataset  # noqa: E402
from host.model.fit import Fit  # noqa: E402
from host.model.spec import parse_model  # noqa: E402
from host.workbench.verdict import diagnose  # noqa: E402
from tests.independent.simulate import SessionSpec, write_session  # noqa: E402

#: case -> (the simulator's effect, the model fitted)
CASES = {
    "tilt": ("plate_tilt", "base,plate_tilt:accel"),
    "lever": ("lever_arm_mm", "base,lever_arm:accel"),
    "both": ("plate_tilt_lever_arm", "base,plate_tilt:accel,lever_arm:accel"),
}
#: terms a case must never be recommended (a geometry it does not hold)
WRONG = {"tilt": ("lever_arm", "face_error"), "lever": ("plate_tilt", "face_error"),
         "both": ("face_error",)}  # fmt: skip


def tilt_size(fit: Fit) -> tuple[float, float]:
    """|tilt| and its σ along the tilt's direction, from the two angles' covariance (they are
    correlated where the headings are unknown: the diagonal alone overstates the size's σ)."""
    names = [p.name for p in fit.parameters]
    i = [names.index("plate_tilt.east"), names.index("plate_tilt.north")]
    v = np.array([fit.parameters[k].value for k in i])
    cov = fit.covariance
    c = np.diag([fit.parameters[k].stderr ** 2 for k in i]) if cov is None else cov[np.ix_(i, i)]
    size = float(np.hypot(*v))
    u = v / size
    return size, math.sqrt(float(u @ c @ u))


def run_session(case: str, seed: int, workdir: Path, with_diagnosis: bool) -> dict[str, Any]:
    """One session of ``case``: its fit's pulls and, if asked, what the diagnosis recommends."""
    effect, model = CASES[case]
    d = workdir / f"{case}_{seed}"
    spec = SessionSpec(seed=seed, effect=effect, headings="random", turn_motion="continuous")
    truth = write_session(d, spec).truth()
    ds = load_dataset(d)
    fit = fit_with_components(ds, parse_model(model)).fit
    row: dict[str, Any] = {"case": case, "seed": seed, "rms_z": fit.rms_z, "pulls": {}}
    by = {p.name: p for p in fit.parameters}
    for p in fit.parameters:
        t = truth_of(p.name, truth) if p.name.startswith(("plate_tilt", "lever_arm")) else None
        if t is not None and p.stderr > 0 and math.isfinite(p.stderr):
            group = "seen" if ".seen_" in p.name else p.name
            row["pulls"].setdefault(group, []).append((p.value - t) / p.stderr)
    if "plate_tilt.east" in by:
        size, sd = tilt_size(fit)
        true = float(truth["effect"]["tilt_rad"])
        row.update(size=size, size_sd=sd, size_true=true)
        row["pulls"]["size"] = [(size - true) / sd]
    if with_diagnosis:
        dg = diagnose(ds, parse_model("base"), dict(CATALOGUE))
        row["recommended"] = dg.recommended_spec or ""
        row["verdict"] = dg.verdict
    return row


def _sd(x: Sequence[float]) -> float:
    return float(np.std(x, ddof=1)) if len(x) > 1 else math.nan


def report(rows: Sequence[dict[str, Any]]) -> str:
    """The tables, per case."""
    out = []
    for case in CASES:
        rs = [r for r in rows if r["case"] == case]
        if not rs:
            continue
        z = [r["rms_z"] for r in rs]
        out.append(f"== {case} ({CASES[case][0]}, {CASES[case][1]}): {len(rs)} sessions, RMS z "
                   f"after median {np.median(z):.2f}, max {max(z):.2f}, ≤ 1.5 in "
                   f"{sum(v <= 1.5 for v in z)}")  # fmt: skip
        sized = [r for r in rs if "size" in r]
        if sized:
            in10 = sum(abs(r["size"] - r["size_true"]) <= 0.1 * r["size_true"] for r in sized)
            in3 = sum(abs(r["size"] - r["size_true"]) <= 3 * r["size_sd"] for r in sized)
            ratio = [r["size"] / r["size_true"] for r in sized]
            out.append(
                f"   tilt size: within 10 % {in10}/{len(sized)}, within 3σ {in3}/"
                f"{len(sized)}, |fit|/|truth| {min(ratio):.3f}–{max(ratio):.3f}"
            )
        groups = sorted({g for r in rs for g in r["pulls"]})
        for g in groups:
            v = [x for r in rs for x in r["pulls"].get(g, [])]
            out.append(f"   pulls {g:<18} n {len(v):>4}  mean {np.mean(v):+.2f}  sd {_sd(v):.2f}"
                       f"  |·|>3 {sum(abs(x) > 3 for x in v)}")  # fmt: skip
        dg = [r for r in rs if "recommended" in r]
        if dg:
            wrong = [r["seed"] for r in dg if any(w in r["recommended"] for w in WRONG[case])]
            verdicts = {v: sum(r["verdict"] == v for r in dg) for v in {r["verdict"] for r in dg}}
            recs: dict[str, int] = {}
            for r in dg:
                key = ",".join(x for x in r["recommended"].split(",") if x) or "nothing"
                recs[key] = recs.get(key, 0) + 1
            out.append(f"   diagnosed {len(dg)}: verdicts {verdicts}; recommended {recs}")
            out.append(f"   a wrong geometry ({', '.join(WRONG[case])}) recommended: "
                       f"{len(wrong)} of {len(dg)} {wrong if wrong else ''}")  # fmt: skip
    return "\n".join(out)


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cases", default="tilt,lever,both", help="comma list of tilt, lever, both")
    ap.add_argument("--sessions", type=int, default=10, help="sessions per case (default 10)")
    ap.add_argument("--seed0", type=int, default=4000, help="first seed (default 4000)")
    ap.add_argument("--diagnose", type=int, default=0, help="diagnose the first K sessions")
    a = ap.parse_args(argv)
    rows = []
    with tempfile.TemporaryDirectory(prefix="tilt-motion-") as tmp:
        for case in a.cases.split(","):
            for k in range(a.sessions):
                rows.append(run_session(case, a.seed0 + k, Path(tmp), k < a.diagnose))
                print(f"{case} seed {a.seed0 + k}: RMS z {rows[-1]['rms_z']:.2f} "
                      f"{rows[-1].get('recommended', '')}", file=sys.stderr)  # fmt: skip
    print(report(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
