"""The operator's time of ``calibrate --plan adaptive`` itself, on virtual units (``sim://``).

Runs the dialogue (``--yes``, no warm-up, no closing check) on ``sim://?seed=S`` for each seed
and counts the operator's time of the records it saved, in the order it saved them, as the
adaptive engine counts it (:func:`host.workbench.adaptive.cost_after`: placing, settling, the
record, the 'get ready' and turn window of each turn; a record on the face the cube already
rests on is not placed again; a face that stopped when it had enough counts its own length).
The count reads only the record files and the order of the ``Saved`` lines, so it measures any
version of the dialogue the same way; where the dialogue says its own figure (``Adaptive plan:
about N s of your time``) it is printed beside it::

    OPENBLAS_NUM_THREADS=1 python3 benchmarks/planning_dialogue.py --seeds 1-10 --target 0.005 \\
        --sim '&effects=linear,noise'
"""

from __future__ import annotations

import argparse
import contextlib
import io
import os
import re
import statistics
import sys
import tempfile
from pathlib import Path

for _v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")  # before numpy loads: one BLAS thread

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from host.dialogue import flow, options  # noqa: E402
from host.dialogue.console import ScriptedConsole  # noqa: E402
from host.session.directory import read_session  # noqa: E402
from host.session.records import Record  # noqa: E402
from host.workbench.adaptive import cost_after, last_up  # noqa: E402
from host.workbench.planner import candidates  # noqa: E402


def operator_s(saved: list[str], records: dict[str, Record], static_s: float, turns: int) -> float:
    """The operator's time of ``records`` measured in the order ``saved``, s."""
    menu = candidates(static_s, turns, tilted=False)
    faces = {c.records[0][0]: c for c in menu if c.records[0][2] == "static"}
    pairs = {c.records[0][0][0]: c for c in menu if c.records[0][2] == "turn"}
    done: dict[str, Record] = {}
    spent = 0.0
    for name in saved:
        r = records[name]
        base = name[:4] if name[2:4] in ("up", "dn") else name
        if r.meta.get("kind") == "static":
            c = faces[base]
            t = r.t_ms / 1000.0
            own = float(t[-1] - t[0]) + float(t[1] - t[0])
            spent += cost_after(c, last_up(done)) - c.records[0][3] + own
        elif name.split("_")[1] == "ccw":  # a pair's cost, counted at its first turn
            spent += cost_after(pairs[name[0]], last_up(done))
        done[name] = r
    return spent


def one(seed: int, args: argparse.Namespace) -> tuple[float, str, list[str]]:
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "PD1"
        o = options.DialogueOptions(
            port=f"sim://?seed={seed}&speed=max{args.sim}", serial="PD1", out=out,
            static_seconds=args.static_seconds, turns=args.turns, warmup_s=0.0, yes=True,
            ready_s=0.0, plan="adaptive", target=args.target, max_extra=args.max_extra,
            closing=False,
        )  # fmt: skip
        con = ScriptedConsole()
        with contextlib.redirect_stdout(io.StringIO()):
            flow.run_dialogue(o, con, None)
        saved = re.findall(r"Saved \S+/PD1_(\w+)\.txt", con.text)
        recs = read_session(out).records
        told = re.search(r"about (\d+) s of your time", con.text)
        spent = operator_s(saved, recs, args.static_seconds, args.turns)
        return spent, told.group(1) if told else "-", saved


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", default="1-10", help="A-B: the sim:// seeds (default 1-10)")
    ap.add_argument("--target", type=float, default=0.05)
    ap.add_argument("--static-seconds", type=float, default=60.0, help="a face at most, s")
    ap.add_argument("--turns", type=int, default=1)
    ap.add_argument("--max-extra", type=int, default=0, help="the planner's records at most")
    ap.add_argument("--sim", default="", help="more sim:// options, e.g. '&effects=linear,noise'")
    args = ap.parse_args(argv)
    a, _, b = args.seeds.partition("-")
    times = []
    print("seed operator s (the dialogue says) records order")
    for seed in range(int(a), int(b or a) + 1):
        spent, told, saved = one(seed, args)
        times.append(spent)
        print(f"{seed:>4} {spent:>10.0f} {told:>18} {len(saved):>7} {' '.join(saved)}", flush=True)
    print(f"median operator time {statistics.median(times):.0f} s over {len(times)} units")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
