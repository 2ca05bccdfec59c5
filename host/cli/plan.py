"""``python3 -m host plan DIR``: which record to measure next, ranked by what it buys.

Every record the operator could add (a face again, a 45° attitude, a pair of turns about an
axis) is ranked by how much it shrinks the worst standard error relative to its tolerance per
minute of the operator's time; the math is :mod:`host.workbench.planner`. A session without a
cube (poses and moves only) gets the next pose instead, the one ``calibrate --plan poses``
would ask for (:func:`host.dialogue.poses.next_pose`): its records need no face or turn.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import textwrap
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from host.calib.publish import session_noise
from host.cli.model import _catalogue, finite_json
from host.cli.options import (
    Command,
    FloorOptions,
    WorkbenchOptions,
    add_workbench_arguments,
    workbench_options,
)
from host.dialogue.poses import NextPose, next_pose, without_cube
from host.errors import UserError
from host.model.geometry import placement_words
from host.model.spec import ModelTerm, parse_model, short_spec
from host.model.terms import Term
from host.session.directory import Session, read_session
from host.session.method import UNITS, local_gravity
from host.session.spacing import timing_report
from host.workbench.planner import NextPlan, OperatorTime, Ranked, plan_next
from host.workbench.separate import CLEAR, Explanation, Separation, explanation, separate


def _row(i: int, r: Ranked) -> str:
    c = r.candidate
    after = "—" if not math.isfinite(r.worst_after) else f"{r.worst_after:.3g} {r.worst_name}"
    if r.determines:
        gain = "determines " + ",".join(r.determines)
        gain = gain if len(gain) <= 22 else gain[:21] + "…"
    else:
        gain = f"{r.gain_per_min:.3g}"
    return f"{i:>2}  {c.label[:24]:<24} {c.operator_s:>5.0f} s  {after:<16} {gain}"


def format_plan(p: NextPlan, top: int) -> str:
    """The ranking for people, every line within 80 columns."""
    if math.isfinite(p.worst_now):
        sigma = p.sigma_now.get(p.worst_name, math.nan)
        unit = UNITS.get(p.worst_name, "")
        head = f"worst σ/tolerance now: {p.worst_now:.3g} ({p.worst_name}: σ {sigma:.3g} {unit})"
    else:
        head = f"worst σ/tolerance now: {p.worst_name} is not determined by these records"
    lines = [
        head.replace(" )", ")"),
        "next records, best first: the worst σ/tolerance each leaves, and how much of",
        "the worst it removes per minute of the operator's time",
        " #  record                    time   worst after      gain/min",
    ]
    lines += [_row(i + 1, r) for i, r in enumerate(p.ranked[:top])]
    if len(p.ranked) > top:
        lines.append(f"    … {len(p.ranked) - top} more (--top {len(p.ranked)})")
    for n in p.notes:
        lines += textwrap.wrap(n, 80, initial_indent="note: ", subsequent_indent="      ")
    return "\n".join(lines)


def _json(p: NextPlan) -> dict[str, Any]:
    def num(v: float) -> float | None:
        return v if math.isfinite(v) else None

    return {
        "worst_now": num(p.worst_now),
        "worst_name": p.worst_name,
        "ranked": [
            {
                "record": r.candidate.label,
                "records": [x[0] for x in r.candidate.records],
                "operator_s": r.candidate.operator_s,
                "worst_after": num(r.worst_after),
                "worst_name": r.worst_name,
                "determines": list(r.determines),
                "gain_per_min": num(r.gain_per_min),
            }
            for r in p.ranked
        ],
        "notes": list(p.notes),
    }


def _num(v: float) -> str:
    """A Δχ² for people: 0 below round-off."""
    return "0" if abs(v) < 1e-6 else f"{v:.3g}"


def format_separation(s: Separation, top: int) -> str:
    """The records that tell two explanations apart, for people, within 80 columns."""
    names = f"{s.a} from {s.b}" + "".join(f" and from {o}" for o in s.others)
    pairs = "between them" if not s.others else "between the closest two"
    lines = textwrap.wrap(f"to tell {names}: Δχ² {pairs} now {_num(s.lam_now)} "
                          f"({CLEAR:g} or more: the data choose at 3σ)", 80)  # fmt: skip
    lines += [" #  record                              time   Δχ² after  per minute"]
    for i, r in enumerate(s.ranked[:top]):
        c = r.candidate
        lines.append(f"{i + 1:>2}  {c.label[:34]:<34} {c.operator_s:>5.0f} s  {_num(r.lam):>9}"
                     f"  {_num(r.per_min):>10}")  # fmt: skip
    for r in s.ranked[:top]:  # the first record listed that asks for a heading, in words
        recs = r.candidate.records
        noted = [(x, h) for i, x in enumerate(recs) if (h := _noted(r.candidate.headings, i))
                 is not None]  # fmt: skip
        if noted:
            (name, up, *_), h = noted[0]
            lines += textwrap.wrap(
                f"heading noted: put {name} {placement_words(np.asarray(up), h)}, and its "
                f"record carries placement_heading_deg: {h:g} (the plate's tilt is known there)",
                80, subsequent_indent="  ",
            )  # fmt: skip
            break
    if s.ranked and s.ranked[0].lam < CLEAR:
        lines += textwrap.wrap(
            "none of these records alone separates them at 3σ: measure the first, then ask "
            "again (or records of another kind: 45° attitudes, turns at another rate, a "
            "sitting at another temperature)", 80,
        )  # fmt: skip
    return "\n".join(lines)


def separation_json(s: Separation) -> dict[str, Any]:
    """The separation for a script: every record ranked, with what the hand must do (each
    record's name, up vector in chip axes, kind, seconds, turns, direction; the pace of its
    turns)."""

    def num(v: float) -> float | None:
        return v if math.isfinite(v) else None

    return {
        "a": s.a, "b": s.b, "others": list(s.others), "lam_now": num(s.lam_now), "clear": CLEAR,
        "chi2_a": num(s.chi2_a), "chi2_b": num(s.chi2_b),
        "ranked": [
            {"record": r.candidate.label, "operator_s": r.candidate.operator_s,
             "pace": r.candidate.pace, "lam": num(r.lam), "per_min": num(r.per_min),
             "pairs": [[i, j, num(v)] for i, j, v in r.pairs],
             "records": [{"name": n, "up": list(up), "kind": k, "seconds": sec, "turns": t,
                          "direction": d, "heading_deg": _noted(r.candidate.headings, i)}
                         for i, (n, up, k, sec, t, d) in enumerate(r.candidate.records)]}
            for r in s.ranked
        ],
    }  # fmt: skip


def _noted(headings: tuple[float | None, ...], i: int) -> float | None:
    """The heading the operator notes for a candidate's ``i``-th record, ° (None: none)."""
    return headings[i] if i < len(headings) else None


@dataclass(frozen=True)
class PlanOptions:
    """``plan``: the records and model (:class:`host.cli.model.WorkbenchOptions`), how many
    records to list, the operator's time to place the cube on a face and on an edge, s, and
    the explanations to tell apart instead (None: the ranking)."""

    bench: WorkbenchOptions
    top: int = 10
    place_s: float = OperatorTime.place
    place_tilted_s: float = OperatorTime.place_tilted
    separate: tuple[str, ...] | None = None


def plan_options(ns: argparse.Namespace) -> PlanOptions:
    """The ``plan`` options from its arguments."""
    return PlanOptions(
        bench=workbench_options(ns), top=ns.top, place_s=ns.place_s,
        place_tilted_s=ns.place_tilted_s,
        separate=None if ns.separate is None else tuple(ns.separate),
    )  # fmt: skip


def run_plan(args: PlanOptions) -> int:
    """Runner of ``python3 -m host plan``."""
    w = args.bench
    if args.top < 1:
        raise UserError(f"--top {args.top}: give how many records to list, 1 or more")
    w.model.bound_term_files()
    session = read_session(w.dir, w.serial)
    sys.stderr.write(timing_report(session.records))
    cat = _catalogue(w.model.term_files)
    model = parse_model(w.model.spec, cat)
    time = OperatorTime(place=args.place_s, place_tilted=args.place_tilted_s)
    if without_cube(session.records):
        return _plan_poses(session, args)
    if args.separate:
        sep = _separation(session, model, cat, args.separate, time, w.floor)
        if w.json:
            print(json.dumps(finite_json(separation_json(sep)), indent=2, ensure_ascii=False))
        else:
            print(format_separation(sep, args.top))
        return 0

    def progress(done: int, total: int, label: str) -> None:
        if sys.stderr.isatty():
            end = "\n" if done == total else ""
            sys.stderr.write(f"\rtrying {done}/{total} {label[:40]:<40}{end}")
            sys.stderr.flush()

    noise = session_noise(session, w.floor.floor, w.floor.noise)
    p = plan_next(
        session, model, noise=noise, time=time, latitude_deg=w.site.latitude_deg,
        height_m=w.site.height_m, progress=progress,
    )  # fmt: skip
    if w.json:
        print(json.dumps(finite_json(_json(p)), indent=2, ensure_ascii=False))
    else:
        print(format_plan(p, args.top))
    return 0


def format_next_pose(p: NextPose) -> str:
    """The next pose of a session without a cube for people, every line within 80 columns."""
    lines = [
        f"a session without a cube ({p.poses} poses, {p.moves} moves): the next record is a "
        "pose, never a face or a turn (they need a cube)",
        p.coverage,
        f"next pose: hold it still with {p.attitude}, moved there by hand from the last pose "
        f"(python3 -m host calibrate --plan poses asks for it the same way)",
        f"RMS σ/tolerance of the planner's linearised model: {p.rms_now:.3g} now, "
        f"{p.rms_after:.3g} after it",
    ]
    return "\n".join(w for line in lines for w in textwrap.wrap(line, 80, subsequent_indent="  "))


def _plan_poses(session: Session, args: PlanOptions) -> int:
    """``plan`` on a session without a cube: the next pose (:func:`format_next_pose`)."""
    w = args.bench
    if args.separate:
        raise UserError(
            "--separate: this session has no cube (poses and moves only), and the records "
            "that tell two explanations apart are faces and turns; plan without --separate "
            "names the next pose"
        )
    p = next_pose(session.records, local_gravity(w.site.latitude_deg, w.site.height_m))
    if w.json:
        out = {"session": "poses", "poses": p.poses, "moves": p.moves,
               "next_pose": {"up": [float(c) for c in p.up], "attitude": p.attitude},
               "rms_now": p.rms_now, "rms_after": p.rms_after, "coverage": p.coverage}  # fmt: skip
        print(json.dumps(finite_json(out), indent=2, ensure_ascii=False))
    else:
        print(format_next_pose(p))
    return 0


def _separation(
    session: Session, model: Sequence[ModelTerm], cat: dict[str, Term],
    given: Sequence[str], time: OperatorTime, floor: FloorOptions,
) -> Separation:  # fmt: skip
    """``--separate A B …``: the records that tell the explanations apart."""
    if len(given) < 2:
        raise UserError("--separate needs two explanations or more (the members of a "
                        "group of equals as model diagnose names them)")  # fmt: skip
    a, b, *others = exps = [explanation(x, cat) for x in given]
    for i, x in enumerate(exps):
        for y in exps[i + 1 :]:
            _two_explanations(x, y, model)
    noise = session_noise(session, floor.floor, floor.noise)
    return separate(session, model, a, b, others=others, time=time, noise=noise)


def _two_explanations(a: Explanation, b: Explanation, model: Sequence[ModelTerm]) -> None:
    """UserError unless ``a`` and ``b`` are two explanations the model lacks (was: a ranking
    of records that all separate them by 0, for the same one twice or one the model has)."""

    def channels(e: Explanation) -> frozenset[tuple[str, str, int]]:
        return frozenset((mt.term.name, mt.sensor, k) for mt in e.terms for k in mt.axes)

    if a.signal == b.signal and channels(a) == channels(b):
        raise UserError(
            f"--separate {a.label} {b.label}: the same explanation twice; give two that differ "
            "(model diagnose names the groups of equals)"
        )
    have = frozenset((mt.term.name, mt.sensor, k) for mt in model for k in mt.axes)
    for e in (a, b):
        if e.signal is None and channels(e) <= have:
            raise UserError(
                f"--separate {e.label}: already in the model {short_spec(model)}; give an "
                "explanation the model lacks (or --model without it)"
            )


#: the longest a placement may take, s: an hour (1e300 s made the table unreadable)
MAX_PLACE_S = 3600.0


def _seconds(text: str) -> float:
    try:
        v = float(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number of seconds") from exc
    if not (math.isfinite(v) and 0.0 <= v <= MAX_PLACE_S):
        raise argparse.ArgumentTypeError(f"{text!r}: give 0 to {MAX_PLACE_S:g} seconds")
    return v


def cli_plan(p: argparse.ArgumentParser) -> Command[PlanOptions]:
    """Fill in the ``plan`` subparser; returns the command."""
    add_workbench_arguments(p)
    p.add_argument("--top", type=int, default=10, help="how many records to list (default 10)")
    p.add_argument(
        "--place-s", type=_seconds, default=OperatorTime.place, metavar="S",
        help="seconds to put the cube on a face (default %(default)g)",
    )  # fmt: skip
    p.add_argument(
        "--place-tilted-s", type=_seconds, default=OperatorTime.place_tilted, metavar="S",
        help="seconds to put it on an edge, 45° (default %(default)g)",
    )  # fmt: skip
    p.add_argument(
        "--separate", nargs="+", metavar="A", default=None,
        help="instead: the records that tell explanation A from B (and from C …) apart, each "
        "a model spec added to --model, e.g. scale_asymmetry:gyro:z scale_nonlinearity:gyro:z, "
        "or a signal as model diagnose names it, e.g. face_error:accel:y 'accel y follows "
        "(specific force z)²' plate_tilt:accel:xyz",
    )  # fmt: skip
    return Command(plan_options, run_plan, data_out=lambda o: o.bench.json)
