"""The record that settles a doubt (issue 30): measure what ``plan --separate`` names, then
ask the diagnosis again — on units the bench's physics did not write.

For each pair, sessions of the independent simulator (``tests/independent``: white noise,
quantisation, one effect each) go through the workbench's own commands (``model diagnose
--json``, ``plan DIR --separate A B --json``, run in this process through ``host``'s command
line entry):

1. ``model diagnose`` -> the group of equals that holds the true effect and its alternative;
2. ``plan --separate TRUE ALT`` -> the first-ranked record and the Δχ² it is predicted to buy
   (λ, the noncentrality);
3. the independent simulator measures that record (its hand: a face, a 45° attitude on a
   square wedge, turns at another pace) and adds it to the session directory;
4. ``model diagnose`` again: is the true effect named alone (recommended or, off the
   catalogue, the top unexplained signal) and no longer in a group with the other? While the
   two are still a group, ask ``plan --separate`` again and measure its first record (the
   "measure the first, then ask again" of docs/planning.md), up to ``--rounds`` records.

Pairs: ``asym`` (truth a gyro scale asymmetry, alternative a quadratic scale on that axis),
``nonlin`` (the reverse), ``lean`` (truth one pair of fixture faces leaning, alternative
accel i reading (f_j/g)²) and ``g2`` (the reverse), with the placement heading recorded; and
``lean_nh``, ``g2_nh`` the same with no heading recorded: the plate's tilt then joins the group
(each static carries it as two unknowns of its own), ``plan --separate`` is asked to tell the
truth from both others, and the truth is named alone only when the plate's tilt is neither
recommended nor in a group with it.

Prints per session the records measured and the Δχ² between the truth and the other(s)
predicted (the record's λ, the smallest over the pairs with the truth) and obtained (χ² of the
alternative minus that of the truth on the records with it, the smallest over the others),
then per pair the count named alone out of the sessions whose diagnosis held the group::

    OPENBLAS_NUM_THREADS=1 python3 benchmarks/separating.py --sessions 10
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import os
import statistics
import sys
import tempfile
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

for _v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")  # before numpy loads: one BLAS thread

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from host.__main__ import main as host_main  # noqa: E402
from tests.independent.hand import extra_record  # noqa: E402
from tests.independent.simulate import SessionSpec, write_session  # noqa: E402

Truth = dict[str, Any]
Group = dict[str, Any]


def host_json(args: Sequence[str]) -> dict[str, Any]:
    """``python3 -m host ARGS --json`` in this process: its JSON (``{"error": …}`` on a
    failure)."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = host_main([*args, "--json"])
        except SystemExit as exc:  # argparse
            code = int(exc.code or 0)
    try:
        return dict(json.loads(out.getvalue()))
    except json.JSONDecodeError:
        lines = err.getvalue().strip().splitlines()
        return {"error": lines[-1] if lines else f"exit {code}, no output"}


# ---- the pairs --------------------------------------------------------------------------------
def _signal_of(g: Group, sensor: str, axis: str, source: str) -> str | None:
    """The label of ``g``'s member that is a signal of the force along ``source`` on
    ``sensor`` ``axis`` ((f_j/g)², |f_j|), None if it has none."""
    for m, sig in zip([m for m in g["members"] if m not in g["terms"]], g["signals"], strict=True):
        if (sig["sensor"], sig["axis"]) == (sensor, axis) and f"force {source}" in sig["signal"]:
            return str(m)
    return None


def _face_term(g: Group, axis: str) -> str | None:
    return next((t for t in g["terms"] if t.startswith("face_error:accel:") and
                 axis in t.split(":")[2]), None)  # fmt: skip


@dataclass(frozen=True)
class Doubt:
    """One group of equals as a question: the true explanation and its alternative, as
    ``plan --separate`` takes them, and the channel ``(sensor, axis)``; ``others``: further
    members of the group (the plate's tilt, where statics carry no heading)."""

    truth: str
    other: str
    sensor: str
    axis: str
    source: str = ""  # the force axis of an (f_j/g)² signal
    others: tuple[str, ...] = ()


@dataclass(frozen=True)
class Pair:
    """A truth and its alternative: the effect simulated, the simulator's options, the doubts
    a diagnosis holds (``doubts``), and whether a diagnosis names the truth alone
    (``alone``)."""

    name: str
    effect: str
    spec: dict[str, Any]
    doubts: Callable[[dict[str, Any], Truth], list[Doubt]]
    alone: Callable[[dict[str, Any], Doubt], bool]


def _rec_has(rec: str | None, term: str, sensor: str, axis: str) -> bool:
    """Does the recommended spec hold ``term`` on ``sensor`` ``axis``?"""
    for entry in (rec or "").split(","):
        got = entry.split(":")
        if got[0] == term and (len(got) < 2 or got[1] == sensor):
            if len(got) < 3 or axis in got[2]:
                return True
    return False


def _scale_doubts(true: str, other: str) -> Callable[[dict[str, Any], Truth], list[Doubt]]:
    def doubts(diag: dict[str, Any], t: Truth) -> list[Doubt]:
        e = t["effect"]
        a, b = f"{true}:gyro:{e['axis']}", f"{other}:gyro:{e['axis']}"
        found = [g for g in diag.get("equals", []) if a in g["terms"] and b in g["terms"]]
        return [Doubt(a, b, "gyro", e["axis"])] if found else []

    return doubts


def _plate(g: Group) -> str | None:
    return next((t for t in g["terms"] if t.startswith("plate_tilt:accel")), None)


def _still_equal(diag: dict[str, Any], d: Doubt) -> bool:
    """Do the diagnosis's groups still hold the truth of ``d`` with another of its
    explanations?"""
    for g in diag.get("equals", []):
        labels = set(g["members"])
        if d.truth in labels and ({d.other, *d.others} & labels):
            return True
        face = _face_term(g, d.axis) if d.source else None
        signal = _signal_of(g, "accel", d.axis, d.source) if d.source else None
        if face and signal:
            return True
        if d.others and _plate(g) and (face or signal):
            return True
    return False


def _plate_named(diag: dict[str, Any], d: Doubt) -> bool:
    """Is the plate's tilt, a further member of ``d``, recommended?"""
    return bool(d.others) and _rec_has(diag.get("recommended"), "plate_tilt", "accel", d.axis)


def _term_alone(diag: dict[str, Any], d: Doubt) -> bool:
    term = d.truth.split(":")[0]
    named = _rec_has(diag.get("recommended"), term, d.sensor, d.axis)
    return named and not _plate_named(diag, d) and not _still_equal(diag, d)


def _lean_doubts(diag: dict[str, Any], t: Truth) -> list[Doubt]:
    out = []
    for g in diag.get("equals", []):
        for ax in "xyz":
            face = _face_term(g, ax)
            for src in "xyz":
                sig = _signal_of(g, "accel", ax, src) if face else None
                if face and sig:
                    out.append(Doubt(f"face_error:accel:{ax}", sig, "accel", ax, src,
                                     _others(g)))  # fmt: skip
    return out


def _others(g: Group) -> tuple[str, ...]:
    """The group's plate tilt, if it holds one (statics without a heading)."""
    plate = _plate(g)
    return (plate,) if plate else ()


def _g2_doubts(diag: dict[str, Any], t: Truth) -> list[Doubt]:
    e = t["effect"]
    out = []
    for g in diag.get("equals", []):
        face, sig = _face_term(g, e["axis"]), _signal_of(g, "accel", e["axis"], e["source"])
        if face and sig:
            out.append(Doubt(sig, f"face_error:accel:{e['axis']}", "accel", e["axis"],
                             e["source"], _others(g)))  # fmt: skip
    return out[:1]


def _signal_alone(diag: dict[str, Any], d: Doubt) -> bool:
    """The (f_j/g)² signal is the top one the diagnosis names on its channel, no face error is
    recommended there, and no group holds the two."""
    top = next((s for s in diag.get("unexplained_signals", [])
                if (s.get("sensor"), s.get("axis")) == (d.sensor, d.axis)), None)  # fmt: skip
    named = top is not None and f"force {d.source}" in str(top.get("signal", ""))
    face = _rec_has(diag.get("recommended"), "face_error", d.sensor, d.axis)
    return named and not face and not _plate_named(diag, d) and not _still_equal(diag, d)


PAIRS: dict[str, Pair] = {
    p.name: p
    for p in [
        Pair("asym", "scale_asymmetry", {}, _scale_doubts("scale_asymmetry",
                                                          "scale_nonlinearity"), _term_alone),
        Pair("nonlin", "scale_nonlinearity", {}, _scale_doubts("scale_nonlinearity",
                                                               "scale_asymmetry"), _term_alone),
        Pair("lean", "face_pair_lean", {"record_heading": True}, _lean_doubts, _term_alone),
        Pair("g2", "cross_g2", {"record_heading": True}, _g2_doubts, _signal_alone),
        Pair("lean_nh", "face_pair_lean", {}, _lean_doubts, _term_alone),
        Pair("g2_nh", "cross_g2", {}, _g2_doubts, _signal_alone),
    ]
}  # fmt: skip


# ---- one session ------------------------------------------------------------------------------
def _measure(spec: SessionSpec, d: Path, first: dict[str, Any], taken: set[str]) -> SessionSpec:
    """The independent hand measures the records of ``first`` (a ranked record of
    ``plan --separate --json``), each under a name the session has not used; the session is
    written again with them (the same unit, noise stream and plan)."""
    extra = list(spec.extra)
    for r in first["records"]:
        name, k = r["name"], 2
        while name in taken:
            name, k = f"{r['name']}_{k}", k + 1
        taken.add(name)
        extra.append(extra_record(name, r["up"], r["kind"], r["seconds"], first["pace"],
                                  r.get("heading_deg")))  # fmt: skip
    spec = replace(spec, extra=tuple(extra))
    write_session(d, spec)
    return spec


def _obtained(d: Path, doubt: Doubt) -> float:
    """χ²(alternative) − χ²(truth) on the records measured (> 0: the data prefer the truth),
    the smallest over the alternatives (the other and the further members), on the yardstick
    ``plan --separate`` weighs them on."""
    from host.model.catalogue import CATALOGUE
    from host.model.spec import parse_model
    from host.session.directory import read_session
    from host.workbench.separate import explanation, separate

    a = explanation(doubt.truth, CATALOGUE)
    got = []
    for other in (doubt.other, *doubt.others):
        b = explanation(other, CATALOGUE)
        s = separate(read_session(d), parse_model("base", CATALOGUE), a, b, only=())
        got.append(s.chi2_b - s.chi2_a)
    return min(got)


def _noted(ranked: dict[str, Any]) -> bool:
    """Does a ranked record of ``plan --separate --json`` ask the operator to note a heading?"""
    return any(r.get("heading_deg") is not None for r in ranked["records"])


def _predicted(first: dict[str, Any]) -> float:
    """The record's λ between the truth (the first explanation) and each other one, the
    smallest (``first['lam']`` is over every pair, the truth's or not)."""
    pairs = [v for i, _, v in first.get("pairs", []) if i == 0]
    return min(pairs) if pairs else float(first["lam"])


def run_session(pair: Pair, seed: int, workdir: Path, rounds: int = 3,
                noted: bool = True) -> dict[str, Any]:  # fmt: skip
    """One session of ``pair``: the diagnosis, the records the planner named and measured,
    and whether the true effect came out alone (``noted`` False: the first-ranked record
    whose heading is not noted, the comparison). One JSON-able row."""
    d = workdir / f"{pair.name}_{seed}"
    spec = SessionSpec(seed=seed, effect=pair.effect, **pair.spec)
    truth = write_session(d, spec).truth()
    row: dict[str, Any] = {"pair": pair.name, "seed": seed, "effect": truth["effect"]}
    diag = host_json(["model", "diagnose", str(d)])
    if "error" in diag:
        return {**row, "error": diag["error"]}
    doubts = pair.doubts(diag, truth)
    row["group"] = bool(doubts)
    row["recommended_before"] = diag.get("recommended")
    if not doubts:
        row["equals"] = [g["members"] for g in diag.get("equals", [])]
        return row
    taken = {p.stem.split("_", 1)[1] for p in d.glob(f"{spec.serial}_*.txt")}
    steps: list[dict[str, Any]] = []
    for _ in range(rounds):
        open_doubts = [x for x in doubts if _still_equal(diag, x)] if steps else doubts
        if not open_doubts:
            break
        doubt = open_doubts[0]
        plan = host_json(["plan", str(d), "--separate", doubt.truth, doubt.other,
                          *doubt.others])  # fmt: skip
        if "error" in plan or not plan.get("ranked"):
            row["error"] = plan.get("error", "plan --separate ranked nothing")
            break
        first = next(x for x in plan["ranked"] if noted or not _noted(x))
        spec = _measure(spec, d, first, taken)
        diag = host_json(["model", "diagnose", str(d)])
        if "error" in diag:
            row["error"] = diag["error"]
            break
        steps.append({"record": first["record"], "lam": _predicted(first), "doubt": doubt.truth,
                      "lam_all": first["lam"], "obtained": _obtained(d, doubt)})  # fmt: skip
    row["steps"] = steps
    row["recommended_after"] = diag.get("recommended")
    row["alone"] = bool(steps) and all(pair.alone(diag, x) for x in doubts)
    row["equals_after"] = [g["members"] for g in diag.get("equals", [])]
    return row


# ---- the summary ------------------------------------------------------------------------------
def summarise(rows: Sequence[dict[str, Any]]) -> str:
    """Per pair: sessions, those whose diagnosis held the group, the count named alone, the
    records it took, and the median Δχ² predicted vs obtained of the first record."""
    lines = [f"{'pair':<7} {'sessions':>8} {'group':>6} {'alone':>6} {'records':>8} "
             f"{'Δχ² predicted':>14} {'obtained':>9}"]  # fmt: skip
    for name in dict.fromkeys(r["pair"] for r in rows):
        rs = [r for r in rows if r["pair"] == name]
        grouped = [r for r in rs if r.get("group")]
        alone = sum(1 for r in grouped if r.get("alone"))
        n_rec = [len(r.get("steps", [])) for r in grouped]
        firsts = [r["steps"][0] for r in grouped if r.get("steps")]
        pred = statistics.median([s["lam"] for s in firsts]) if firsts else float("nan")
        got = statistics.median([s["obtained"] for s in firsts]) if firsts else float("nan")
        recs = f"{min(n_rec)}–{max(n_rec)}" if n_rec else "—"
        lines.append(f"{name:<7} {len(rs):>8} {len(grouped):>6} {alone:>3}/{len(grouped):<2} "
                     f"{recs:>8} {pred:>14.4g} {got:>9.4g}")  # fmt: skip
    return "\n".join(lines)


def _line(r: dict[str, Any]) -> str:
    head = f"{r['pair']:<7} seed {r['seed']:<5}"
    if "error" in r:
        return f"{head} error: {r['error']}"
    if not r.get("group"):
        return f"{head} no group of the pair (equals: {r.get('equals')})"
    steps = "; ".join(f"{s['record']} (λ {s['lam']:.3g}, got {s['obtained']:.3g})"
                      for s in r["steps"])  # fmt: skip
    return f"{head} {'alone' if r['alone'] else 'NOT alone'}: {steps}"


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--pairs", default=",".join(PAIRS), help=f"comma list: {', '.join(PAIRS)}")
    ap.add_argument("--sessions", type=int, default=10, help="sessions per pair (default 10)")
    ap.add_argument("--seed0", type=int, default=3000, help="first seed (default 3000)")
    ap.add_argument("--rounds", type=int, default=3, help="records at most per doubt (3)")
    ap.add_argument("--plain", action="store_true",
                    help="measure the first-ranked record whose heading is not noted")  # fmt: skip
    ap.add_argument("--out", type=Path, help="append one JSON line per session to this file")
    args = ap.parse_args(argv)
    names = [p.strip() for p in args.pairs.split(",") if p.strip()]
    unknown = [n for n in names if n not in PAIRS]
    if unknown:
        ap.error(f"unknown pair {unknown[0]!r}; one of {', '.join(PAIRS)}")
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for name in names:
            for seed in range(args.seed0, args.seed0 + args.sessions):
                r = run_session(PAIRS[name], seed, Path(tmp), args.rounds, not args.plain)
                rows.append(r)
                print(_line(r), flush=True)
                if args.out:
                    with args.out.open("a", encoding="utf-8") as f:
                        f.write(json.dumps(r) + "\n")
    print(summarise(rows))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
