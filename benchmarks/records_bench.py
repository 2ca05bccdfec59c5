"""Time reading and writing record files: the text <-> Record of ``host.session.records``
against the row-by-row reader and writer it replaced (kept here as the reference), on the
same simulated session in the same run. Run: ``python3 benchmarks/records_bench.py``.

The reference reads each line with ``str.split`` and ``float`` and writes each value with its
own ``str.format``, a regex per row for minus zero, and splits the rows again for the mean
and std; the program reads a well-formed
file's rows in one ``np.loadtxt`` and writes them with one ``%`` over all the values. Both
must give the same values and the same text (checked before timing).
"""

from __future__ import annotations

import argparse
import re
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from host.bench.plan import Plan, simulate_session
from host.bench.truth import SensorTruth
from host.session.records import (
    DECIMALS,
    RECORD_FORMAT_VERSION,
    SUMMARY_DECIMALS,
    Record,
    format_record,
    parse_record_text,
)

_NEG_ZERO = re.compile(r"(^|\t)-(0(?:\.0*)?)(?=\t|$)")


def _summary_value(v: float) -> str:
    s = f"{v:.{SUMMARY_DECIMALS}f}"
    return s[1:] if s.startswith("-") and float(s) == 0.0 else s


def reference_write(record: Record) -> str:
    """The file text as the row-by-row writer printed it: one format per value, a regex per row
    for minus zero, the rows split again for the mean and std."""
    lines = [f"# imu-bench record v{RECORD_FORMAT_VERSION}"]
    lines += [f"# {k}: {v}".rstrip() for k, v in {**record.meta, "record": record.name}.items()]
    data = np.column_stack([record.t_ms, record.accel, record.gyro, record.temp])
    fmts = [f"{{:.{d}f}}" for d in DECIMALS]
    rows = ["\t".join(f.format(v) for f, v in zip(fmts, row, strict=True)) for row in data.tolist()]
    rows = [_NEG_ZERO.sub(r"\1\2", r) for r in rows]
    printed = np.array([r.split("\t") for r in rows], dtype=np.float64)[:, 1:]
    lines += [*rows, "_" * 72]
    lines.append("mean\t" + "\t".join(_summary_value(float(v)) for v in printed.mean(axis=0)))
    lines.append("std\t" + "\t".join(_summary_value(float(v)) for v in printed.std(axis=0, ddof=1)))
    return "\n".join(lines) + "\n"


def reference_read(text: str) -> np.ndarray:
    """The data rows as the row-by-row reader read them: ``float`` per field, per line."""
    rows: list[list[float]] = []
    for raw in text.splitlines():
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        if line.startswith("___"):
            break
        vals = [float(f) for f in line.split()]
        if len(vals) != 8 or (rows and vals[0] < rows[-1][0]):
            raise ValueError("not a record row")
        rows.append(vals)
    return np.array(rows, dtype=np.float64)


def best_of(repeats: int, work: Callable[[], object]) -> float:
    """The least CPU time of ``repeats`` runs of ``work``, s."""
    best = float("inf")
    for _ in range(repeats):
        t0 = time.process_time()
        work()
        best = min(best, time.process_time() - t0)
    return best


def check_same(records: list[Record], texts: list[str]) -> None:
    """The program and the reference agree on every record, value for value, line for line."""
    for rec, text in zip(records, texts, strict=True):
        got = parse_record_text(text, "bench.txt", name=rec.name)
        cols = np.column_stack([got.t_ms, got.accel, got.gyro, got.temp])
        if cols.tobytes() != reference_read(text).tobytes():
            raise SystemExit(f"{rec.name}: the reader and the reference read different values")
        if text != reference_write(rec):
            raise SystemExit(f"{rec.name}: the writer and the reference print different text")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--static-s", type=float, default=30.0, help="seconds of each static")
    ap.add_argument("--repeats", type=int, default=3, help="runs of each, the best kept")
    a = ap.parse_args()
    truth = SensorTruth.random(np.random.default_rng(0))
    records = list(simulate_session(truth, Plan(static_s=a.static_s, turns=2), seed=1).values())
    texts = [format_record(r) for r in records]
    check_same(records, texts)
    n = sum(len(r) for r in records)
    rd = best_of(a.repeats, lambda: [parse_record_text(t, "b.txt") for t in texts])
    rd_ref = best_of(a.repeats, lambda: [reference_read(t) for t in texts])
    wr = best_of(a.repeats, lambda: [format_record(r) for r in records])
    wr_ref = best_of(a.repeats, lambda: [reference_write(r) for r in records])
    print(f"{len(records)} records, {n} rows (CPU, best of {a.repeats}):")
    for what, ours, ref in (("read", rd, rd_ref), ("write", wr, wr_ref)):
        times = f"{ours * 1e3:5.0f} ms, row by row {ref * 1e3:5.0f} ms"
        print(f"  {what:5s} {times}: {ref / ours:.1f}× faster")


if __name__ == "__main__":
    main()
