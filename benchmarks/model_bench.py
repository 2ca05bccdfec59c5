"""Time and score the model workbench (host/model/, host/workbench/).

Prints: fit times of a 12-record session (6 × 30 s statics + 6 turns) for the smallest, the §2
and the largest model (budget: well under 1 s); the full diagnosis (all candidates + signal
scan; budget 5 s) on it and on the real imucal data; then, per hidden effect of
``demo hidden-effect``, over ``--seeds`` seeds: how often the hidden term (or its confounded
group) is named first and significant, RMS z before → after, the coefficient error; and the
control's false-discovery rate over 100 seeds.
Run: ``python benchmarks/model_bench.py [--seeds 20]``.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from host.bench.plan import Plan, simulate_session
from host.bench.truth import SensorTruth
from host.model.catalogue import CATALOGUE
from host.model.dataset import build_dataset, load_dataset
from host.model.dataset import session_from_records as as_session
from host.model.fit import fit_model
from host.model.spec import parse_model
from host.workbench.scenarios import case_dataset, hidden_effect_case, run_case
from host.workbench.verdict import diagnose

REAL = Path(__file__).resolve().parents[2] / "shared" / "data" / "imucal-example"


def best_of(fn: object, n: int = 5) -> float:
    times = []
    for _ in range(n):
        t0 = time.perf_counter()
        fn()  # type: ignore[operator]
        times.append(time.perf_counter() - t0)
    return min(times)


def timings() -> None:
    truth = SensorTruth.random(np.random.default_rng(0)).only("linear", "noise", "bias_instability")
    recs = simulate_session(truth, Plan(static_s=30.0), 0)
    t_ds = best_of(lambda: build_dataset(as_session(recs)))
    ds = build_dataset(as_session(recs))
    print(f"12-record session (30 s statics), {ds.n_rows} rows: build rows {t_ds * 1e3:.0f} ms")
    for spec in ("bias", "base", ",".join(CATALOGUE)):
        m = parse_model(spec)
        t = best_of(lambda m=m: fit_model(ds, m))
        print(f"  fit {spec[:40]:<40} {sum(x.n_params for x in m):>4} params: {t * 1e3:6.1f} ms")
    t = best_of(lambda: diagnose(ds, parse_model("base")), 3)
    print(f"  full diagnosis of base (all candidates + scan): {t * 1e3:.0f} ms (budget 5000)")
    if REAL.is_dir():
        t = best_of(lambda: diagnose(load_dataset(REAL), parse_model("base")), 3)
        print(f"  real imucal data: read + full diagnosis {t * 1e3:.0f} ms")


def detection(seeds: int) -> None:
    print(f"hidden effects, {seeds} seeds each (named first & significant / RMS z / coefficient):")
    for effect, tilted in (("temperature", False), ("drift", False), ("asymmetry", False),
                           ("asymmetry", True), ("warmup", False)):  # fmt: skip
        named = ok = 0
        before, after, err = [], [], []
        for s in range(seeds):
            case = hidden_effect_case(effect, s, tilted=tilted)
            out = run_case(case)
            alone = effect in ("temperature", "drift") or tilted
            named += (out.group == (case.term,)) if alone else case.term in out.group
            a = out.addition
            assert a is not None
            before.append(a.before.rms_z)
            after.append(a.after.rms_z)
            e = abs(out.coefficient - case.truth) / abs(case.truth)
            err.append(e)
            ok += (case.term in out.group and a.after.rms_z <= 1.5
                   and a.before.rms_z >= 3 * a.after.rms_z and e <= 0.2)  # fmt: skip
        grp = "alone" if alone else "in its confounded group"
        print(
            f"  {effect + (' +45°' if tilted else ''):<16} named first ({grp}) {named}/{seeds}; "
            f"all criteria {ok}/{seeds}; RMS z {np.median(before):.2f} → {np.median(after):.2f} "
            f"(median); coefficient error median {100 * np.median(err):.1f} %, "
            f"max {100 * np.max(err):.1f} %"
        )
    t0 = time.perf_counter()
    verdicts = [
        diagnose(case_dataset(hidden_effect_case("none", s)), parse_model("base")).verdict
        for s in range(100)
    ]
    dt = time.perf_counter() - t0
    print(
        f"  control (nothing hidden), 100 seeds: adequate {verdicts.count('adequate')}, "
        f"missing_effect {verdicts.count('missing_effect')}, unexplained "
        f"{verdicts.count('unexplained')} ({dt:.1f} s)"
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=20)
    args = ap.parse_args()
    timings()
    detection(args.seeds)


if __name__ == "__main__":
    main()
