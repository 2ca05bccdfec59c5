"""Measure automatic segmentation on continuous sessions with a labelled truth (issue 26).

Sessions come from the simulator in ``tests/host/ingest/continuous_sessions.py`` (written from
method.md, apart from host/bench/): per operator (fast, slow, stepped turns, long and short
rests, warm-up first, a face placed twice, an aborted turn, …) ``--seeds`` sessions. For each:

- records found right: the same record names as the labelled ones, statics within 1 s of their
  labelled start and end, turns within ``CUT_S`` of their motion's start and end and no other
  face;
- the constants of the segmented records against the truth, in units of their method.md §7
  tolerance (worst constant), and against the constants of the labelled records, in units of
  the latter's standard error (worst constant): what the cut costs beyond the noise;
- time: segmenting against fitting the same records (the baseline, same process).

Run: ``OPENBLAS_NUM_THREADS=1 python3 benchmarks/segmentation.py [--seeds 5]``.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from host.calib.calibration import calibrate_from_records
from host.ingest.importing import Stream
from host.ingest.labels import parse_labels
from host.ingest.segmentation import build_records, segment_stream
from host.ingest.stillness import attitude
from host.session.directory import Session
from host.session.method import TOLERANCES
from host.session.records import TURN_NAMES, WARMUP_NAME, Record
from tests.host.ingest.continuous_sessions import OPERATORS, ContinuousSession, make_session

#: a turn found right starts and ends this close to its motion, s (a raised-cosine start at
#: 45 °/s stays under the rest's noise for about 0.2 s: 0.04° of the turn)
CUT_S = 0.3


def _right(cs: ContinuousSession, records: dict[str, Record], segs: list) -> bool:
    if set(records) != set(cs.windows):
        return False
    for name, (t0, t1) in cs.windows.items():
        s = next(x for x in segs if x.label == name)
        if name in TURN_NAMES:
            m0, m1 = cs.motions[name]
            faces = {attitude(a)[0] for a in records[name].accel}
            if abs(s.t0_s - m0) > CUT_S or abs(s.t1_s - m1) > CUT_S or faces != {f"{name[0]}_up"}:
                return False
        elif abs(s.t0_s - t0) > 1.0 or abs(s.t1_s - t1) > 1.0:
            return False
    return True


def _fit(records: dict[str, Record]) -> object:
    return calibrate_from_records(
        Session("S", {k: v for k, v in records.items() if k != WARMUP_NAME})
    )


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", type=int, default=5, help="sessions per operator")
    args = ap.parse_args()
    print(f"{'operator':<18} {'right':>7} {'worst |Δ|/tol':>14} {'worst |Δ|/σ lab':>16} "
          f"{'seg/fit time':>13}")  # fmt: skip
    total_right = total = 0
    all_tol: list[float] = []
    for k, op in enumerate(OPERATORS):
        right = 0
        tol_off: list[float] = []
        sig_off: list[float] = []
        seg_s = fit_s = 0.0
        for seed in range(args.seeds):
            cs = make_session(1000 * k + seed, op)
            stream = Stream(cs.t, cs.accel, cs.gyro, cs.temp, {"source": op.name})
            c0 = time.process_time()
            segs, thr, _ = segment_stream(stream)
            records = build_records(stream, segs, thr, "S")
            c1 = time.process_time()
            rows = "".join(f"0\t{a:.6f}\t{b:.6f}\t{n}\n" for n, (a, b) in cs.windows.items())
            labelled = build_records(stream, parse_labels(rows, "truth", stream), None, "S")
            lab_fit = _fit(labelled)
            c2 = time.process_time()
            seg_s += c1 - c0
            fit_s += c2 - c1
            ok = _right(cs, records, segs)
            right += ok
            try:
                got = _fit(records).constants()  # type: ignore[attr-defined]
            except Exception:  # noqa: BLE001 - a cut the calibration refuses is a miss
                tol_off.append(math.inf)
                sig_off.append(math.inf)
                continue
            lab_c = lab_fit.constants()  # type: ignore[attr-defined]
            lab_s = lab_fit.std_errors  # type: ignore[attr-defined]
            tol_off.append(max(abs(got[n] - v) / TOLERANCES[n] for n, v in cs.truth.items()))
            sig_off.append(max(abs(got[n] - lab_c[n]) / lab_s[n] for n in cs.truth
                               if lab_s[n] > 0))  # fmt: skip
        total_right += right
        total += args.seeds
        all_tol += tol_off
        print(f"{op.name:<18} {right:>3}/{args.seeds:<3} {max(tol_off):>14.3f} "
              f"{max(sig_off):>16.2f} {seg_s / max(fit_s, 1e-9):>13.2f}")  # fmt: skip
    within = sum(1 for x in all_tol if x <= 0.1)
    print(f"records found right in {total_right} of {total} sessions; every constant within a "
          f"tenth of its tolerance of the truth in {within} of {total}")  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
