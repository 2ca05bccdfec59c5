"""``python3 -m host model diagnose|add|ladder`` and ``python3 -m host demo hidden-effect``.

The model workbench on the command line (:mod:`host.workbench`: the diagnosis, a term added,
the ladder, their words in :mod:`host.workbench.text`), and a demo that hides ONE physical effect
in a simulated session (:mod:`host.workbench.scenarios`) and shows the workbench finding it.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import shlex
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from host.calib.commands import command_lines
from host.calib.publish import session_noise
from host.cli import pyplot
from host.cli.figures import write_plots
from host.cli.screen import (
    Column,
    Progress,
    fit_columns,
    left_out,
    table_row,
    terminal_width,
    working,
    wrap,
)
from host.errors import UserError
from host.model.catalogue import CATALOGUE
from host.model.dataset import Dataset, build_dataset
from host.model.loader import load_term_file
from host.model.signals import RecordSignals
from host.model.spec import ModelTerm, parse_model, short_spec
from host.model.terms import Term
from host.session.directory import Session, read_session
from host.session.spacing import timing_report
from host.workbench.ladder import LadderStep, add_term, ladder
from host.workbench.scenarios import DEFAULT_EFFECTS, EFFECTS, hidden_effect_case, run_case
from host.workbench.text import (
    format_addition,
    format_case,
    format_diagnosis,
    format_outcome,
    format_terms,
    physics_paragraph,
    readable_spec,
)
from host.workbench.verdict import Diagnosis, diagnose

# ---- plots ----------------------------------------------------------------------------------
_FILE_SUFFIXES = (".png", ".pdf", ".svg", ".jpg", ".jpeg")


def plot_dir(text: str) -> Path:
    """``--plot DIR``: a directory (several PNG files go there), not an image file name."""
    p = Path(text)
    if p.suffix.lower() in _FILE_SUFFIXES or (p.exists() and not p.is_dir()):
        raise argparse.ArgumentTypeError(
            f"{text!r} looks like a file: --plot takes a directory for its PNG files, "
            f"e.g. --plot {p.with_suffix('') if p.suffix else 'plots'}/"
        )
    return p


class _Renamed(argparse.Action):
    """An option's old spelling: still works, with a note naming the new one."""

    def __init__(self, *args: Any, new: str, **kw: Any) -> None:
        self.new = new
        super().__init__(*args, **kw)

    def __call__(self, parser: Any, ns: argparse.Namespace, values: Any, opt: Any = None) -> None:
        print(f"note: {opt} is now {self.new} (the old spelling still works)", file=sys.stderr)
        setattr(ns, self.dest, values)


# ---- command line ---------------------------------------------------------------------------
def _common(p: argparse.ArgumentParser) -> None:
    p.add_argument("dir", help="directory with the records SERIAL_name.txt")
    p.add_argument(
        "--model",
        default="base",
        help="comma list of term[:sensor[:axes]] "
        "(default base = bias,scale,misalignment,g_sensitivity, method.md §2)",
    )
    p.add_argument(
        "--term-file",
        action="append",
        default=[],
        metavar="F",
        help="Python file defining extra terms (repeatable)",
    )
    p.add_argument(
        "--term-timeout", type=float, metavar="S",
        help="how long the term files' code may run, s (default 120; a progress line every 5 s)",
    )  # fmt: skip
    p.add_argument("--serial", default=None, help="serial whose records to use")
    p.add_argument(
        "--floor",
        default=None,
        metavar="accel=A,gyro=G",
        help="bias-instability floor of a record mean (m/s², °/s), e.g. accel=5e-4,gyro=3e-3; a "
        "sensor not given comes from --noise, else from the records' own samples (the wander of "
        "their block means beyond white noise)",
    )
    p.add_argument(
        "--noise",
        default=None,
        metavar="NOISE.json",
        help="noise file of this unit (python3 -m host noise FILE --save NOISE.json): the floor "
        "is its Allan variance at the static records' length without the white part",
    )
    p.add_argument("--latitude", type=float, default=None, help="site latitude, degrees")
    p.add_argument("--height", type=float, default=None, help="site height, m")
    p.add_argument("--json", action="store_true", help="print one JSON object")


def _catalogue(args: argparse.Namespace) -> dict[str, Term]:
    cat = dict(CATALOGUE)
    for f in args.term_file:
        cat = load_term_file(f, cat)
    return cat


def _dataset(args: argparse.Namespace) -> Dataset:
    return _session_dataset(args)[1]


def start_times(session: Session) -> dict[str, str]:
    """Each record's start time (wall clock, ISO 8601), where its header has one."""
    return {n: str(r.meta["start_time"]) for n, r in session.records.items()
            if r.meta.get("start_time")}  # fmt: skip


def _session_dataset(args: argparse.Namespace) -> tuple[Session, Dataset]:
    from host.session.method import DEFAULT_HEIGHT_M, DEFAULT_LATITUDE_DEG

    session = read_session(args.dir, args.serial)
    sys.stderr.write(timing_report(session.records))
    return session, build_dataset(
        session,
        noise=session_noise(session, args.floor, getattr(args, "noise", None)),
        latitude_deg=DEFAULT_LATITUDE_DEG if args.latitude is None else args.latitude,
        height_m=DEFAULT_HEIGHT_M if args.height is None else args.height,
    )


def finite_json(obj: Any) -> Any:
    """``obj`` with every float that is not finite as None: JSON has no NaN (``json.dumps``
    wrote ``NaN``, which a strict reader — jq, a browser — refuses)."""
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: finite_json(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [finite_json(v) for v in obj]
    return obj


def _print_json(obj: Any) -> None:
    print(json.dumps(finite_json(obj), indent=2, ensure_ascii=False, allow_nan=False))


def run_diagnose(args: argparse.Namespace) -> int:
    cat = _catalogue(args)
    model = parse_model(args.model, cat)
    if args.plot:
        pyplot()  # no matplotlib: say so now, not after the fits
    with working("diagnose: reading the records, fitting the model and every candidate"):
        session, ds = _session_dataset(args)
        d = diagnose(ds, model, cat)
        plots: list[Path] = []
        if args.plot:
            after = None
            suspect = None
            if d.recommended_spec:
                suspect = d.recommended_spec
                after = add_term(ds, model, suspect, cat).after
            plots = write_plots(args.plot, ds, d.fit, after, suspect, start_times(session))
        # the planner fits too: inside the wait that shows progress, not after it
        planned = [] if args.json else next_record_lines(args, session, model, d, ds.signals)
    if args.json:
        obj = d.to_dict()
        if plots:
            obj["plots"] = [str(p) for p in plots]
        _print_json(obj)
    else:
        try_line = None
        width, now = terminal_width(sys.stdout), short_spec(d.fit.model)
        if d.recommended_spec:
            cmd = add_command(args, d.recommended_spec, now)
            try_line = command_lines(cmd, width, lead="  try: ")
        see_one = {t: command_lines(add_command(args, t, now), width, lead="  to see one: ")
                   for e in d.equals for t in e.terms}  # fmt: skip
        print(format_diagnosis(d, compare=not args.brief, try_line=try_line, see_one=see_one))
        for line in planned:
            print(line)
        for p in plots:
            print(f"plot: {p}")
    return 0


def _short_member(signals: tuple[RecordSignals, ...], member: str) -> str:
    """A member of a group as the command gives it: a step's signal in its short form (the
    same steps, :func:`host.workbench.steps.short_step_name`), anything else as named."""
    from host.workbench.steps import short_step_name

    head, sep, signal = member.partition(" follows ")
    return f"{head}{sep}{short_step_name(signals, signal)}" if sep else member


def next_record_lines(
    args: argparse.Namespace,
    session: Session,
    model: Sequence[ModelTerm],
    d: Diagnosis,
    signals: tuple[RecordSignals, ...] = (),
) -> list[str]:
    """The planner's first line (host.workbench.planner) and, for each group of equals that
    holds a term, the command that finds the record telling its first two members apart (two
    terms, or a term and a signal of the scan; a step in time as short as ``signals``, the
    records', let it be said); [] when the planner cannot fit the session."""
    from host.workbench.planner import plan_next

    width = terminal_width(sys.stdout)
    out: list[str] = []
    try:
        with working("diagnose: ranking the records to measure next"):
            p = plan_next(session, model, noise=session_noise(session, args.floor, args.noise))
    except UserError:
        return out
    if p.ranked:
        r = p.ranked[0]
        gain = (f"determines {', '.join(r.determines)}" if r.determines
                else f"worst σ/tolerance {p.worst_now:.3g} → {r.worst_after:.3g}")  # fmt: skip
        out.append(wrap(f"next record: {r.candidate.label} ({r.candidate.operator_s:.0f} s of "
                        f"the operator's time): {gain}", width))  # fmt: skip
        out.append(command_lines(["python3", "-m", "host", "plan", str(args.dir)], width,
                                 lead="  the ranking: "))  # fmt: skip
    for e in d.equals:
        if e.terms and len(e.members) >= 2:  # a term and another term or a signal of the scan
            rest = "".join(f" and from {m}" for m in e.members[2:])  # all: each pair apart
            out.append(wrap(f"to tell {e.members[0]} from {e.members[1]}{rest} apart:", width))
            members = [_short_member(signals, m) for m in e.members]
            cmd = ["python3", "-m", "host", "plan", str(args.dir), "--separate", *members]
            out.append(command_lines(cmd, width, lead="  "))
    return out


def _same_options(args: argparse.Namespace) -> list[str]:
    """The options that say which records and how (serial, site, floor, term files)."""
    cmd: list[str] = []
    for f in args.term_file:
        cmd += ["--term-file", f]
    for opt, val in (("--serial", args.serial), ("--latitude", args.latitude),
                     ("--height", args.height), ("--floor", args.floor),
                     ("--noise", getattr(args, "noise", None))):  # fmt: skip
        if val is not None:
            cmd += [opt, str(val)]
    return cmd


def calibrate_command(args: argparse.Namespace, model: str) -> str:
    """The exact ``calibrate`` command that fits and ships ``model`` on the records the
    workbench just used (same directory, serial, site, floor and term files)."""
    cmd = ["python3", "-m", "host", "calibrate", "--from-dir", args.dir, "--model", model]
    return shlex.join(cmd + _same_options(args))


def add_command(args: argparse.Namespace, term: str, model: str) -> list[str]:
    """The ``model add`` command that adds ``term`` to ``model`` on the same records."""
    cmd = ["python3", "-m", "host", "model", "add", args.dir, term]
    return cmd + (["--model", model] if model != "base" else []) + _same_options(args)


def run_add(args: argparse.Namespace) -> int:
    cat = _catalogue(args)
    model = parse_model(args.model, cat)
    if args.plot:
        pyplot()  # no matplotlib: say so now, not after the fits
    paths: list[Path] = []
    with working(f"add: reading the records, fitting with and without {args.term}"):
        session, ds = _session_dataset(args)
        a = add_term(ds, model, args.term, cat)
        if args.plot:
            paths = write_plots(args.plot, ds, a.before, a.after, a.added[0].label,
                                start_times(session))  # fmt: skip
    ship = calibrate_command(args, short_spec(a.after.model))
    # a term these records do not determine is not a model to ship: calibrate would end on
    # "not determined" (exit 1); was "— ± —" and the ship command
    lost = [p.name for p in a.new_parameters if not math.isfinite(p.value)]
    if args.json:
        _print_json({**a.to_dict(), "calibrate_command": None if lost else ship,
                     "not_determined": lost})  # fmt: skip
    else:
        print(format_addition(a))
        for p in paths:
            print(f"plot: {p}")
        width = terminal_width(sys.stdout)
        if lost:
            print(wrap(f"not shipped: these records do not determine {', '.join(lost)} (no "
                       "variation of the term's input, or it acts like terms already in the "
                       f"model); leave {args.term} out, or measure what determines it: "
                       f"python3 -m host plan {args.dir}", width))  # fmt: skip
        else:
            print(command_lines(shlex.split(ship), width, lead="ship this model: "))
    return 0


def ladder_columns() -> list[Column]:
    """The ladder's table: what matters most is kept on a narrow terminal."""
    return [
        Column("step", size=4),
        Column("added", align="<", size=31),
        Column("RMS z", size=7),
        Column("held-out z", rank=1),
        Column("ΔBIC", rank=2, size=8),
        Column("p", rank=3, size=8),
        Column("params", rank=4),
        Column("dof", rank=5, size=4),
        Column("χ²", rank=6, size=10),
    ]


def ladder_cells(i: int, step: LadderStep, before: LadderStep | None, start: str) -> list[str]:
    """One rung as table cells: the term added without ``:xyz`` (every rung adds all three
    axes), the start as its short spec."""
    added = (step.added.removesuffix(":xyz") if step.added
             else f"drop {step.dropped.removesuffix(':xyz')}" if step.dropped
             else f"start: {start}")  # fmt: skip
    return [
        str(i),
        added,
        f"{step.rms_z:.2f}",
        f"{step.held_out_rms_z:.2f}",
        f"{step.bic - before.bic:+.1f}" if before is not None else "—",
        f"{step.p_value:.2g}" if math.isfinite(step.p_value) else "—",
        str(step.n_params),
        str(step.dof),
        f"{step.chi2:.1f}",
    ]


def ladder_start(args: argparse.Namespace) -> str:
    """The ladder's start: ``--model`` or ``--start`` (the same option), ``bias`` when neither
    is given; both, naming different models, are refused (one would be ignored)."""
    given = [v for v in (args.model, args.start) if v is not None]
    if len(set(given)) > 1:
        raise UserError(
            f"--model {args.model} and --start {args.start} both name the ladder's start: give "
            "one (the ladder climbs from it; its terms stay in)"
        )
    return given[0] if given else "bias"


def run_ladder(args: argparse.Namespace) -> int:
    cat = _catalogue(args)
    args.start = ladder_start(args)
    progress = Progress()
    progress.show(f"ladder: reading the records of {args.dir} ...")
    ds = _dataset(args)
    progress.show("ladder: fitting the start model ...")
    width = terminal_width(sys.stdout)
    columns = ladder_columns()
    shown = fit_columns(columns, width)
    at = [any(c is s for s in shown) for c in columns]
    start = short_spec(parse_model(args.start, cat))
    rows: list[LadderStep] = []

    def on_step(step: LadderStep) -> None:
        progress.done()
        if args.json:
            return
        if not rows:
            print(table_row(shown, [c.header for c in shown]))
        cells = ladder_cells(len(rows), step, rows[-1] if rows else None, start)
        print(table_row(shown, [c for c, keep in zip(cells, at, strict=True) if keep]), flush=True)
        rows.append(step)

    def on_try(rung: int, tried: int, of: int) -> None:
        progress.show(f"ladder: rung {rung}, trying term {tried + 1} of {of} ...")

    steps = ladder(ds, args.start, cat, on_step=on_step, on_try=on_try)
    progress.done()
    final = parse_model(steps[-1].model, cat)
    ship = calibrate_command(args, short_spec(final))
    if args.json:
        _print_json({"steps": [dataclasses.asdict(s) for s in steps], "calibrate_command": ship})
    else:
        for line in left_out(columns, shown, width):
            print(line)
        print(f"final model: {readable_spec(final)}")
        print(command_lines(shlex.split(ship), width, lead="ship this model: "))
    return 0


def run_terms(args: argparse.Namespace) -> int:
    """``model terms``: the catalogue (with --term-file: and those terms too)."""
    cat = _catalogue(args)
    if args.json:
        _print_json(
            [
                {
                    "name": t.name,
                    "physics": physics_paragraph(t),
                    "sensors": list(t.sensors),
                    "parameters": {
                        s: dict(zip(t.params, t.param_units(s), strict=True)) for s in t.sensors
                    },  # fmt: skip
                    "needs": t.needs,
                }
                for t in cat.values()
            ]
        )
    else:
        sys.stdout.write(format_terms(cat))
    return 0


def cli_model(p: argparse.ArgumentParser) -> Callable[[argparse.Namespace], int]:
    """``model diagnose|add|ladder|terms``."""
    sub = p.add_subparsers(dest="model_command", metavar="diagnose|add|ladder|terms")

    def command(name: str, text: str, examples: str) -> argparse.ArgumentParser:
        return sub.add_parser(
            name, help=text, description=text, epilog="examples:\n" + examples,
            formatter_class=argparse.RawDescriptionHelpFormatter,
        )  # fmt: skip

    t = command("terms", "list the terms: physics, parameters and units",
                "  python3 -m host model terms\n"
                "  python3 -m host model terms --term-file my_terms.py  with your own")  # fmt: skip
    t.add_argument("--term-file", action="append", default=[], metavar="F",
                   help="also list the terms of this Python file (repeatable)")  # fmt: skip
    t.add_argument("--json", action="store_true", help="the list as JSON")
    d = command("diagnose", "compare model and records, say what is missing",
                "  python3 -m host model diagnose U17/\n"
                "  python3 -m host model diagnose U17/ --brief --plot plots/")  # fmt: skip
    _common(d)
    d.add_argument("--plot", metavar="DIR", type=plot_dir, default=None,
                   help="write the PNG plots into this directory (made if missing)")  # fmt: skip
    d.add_argument("--brief", action="store_true", help="leave out the compare table")
    a = command("add", "refit with a term added: before → after",
                "  python3 -m host model add U17/ temperature_bias:gyro:x\n"
                "  python3 -m host model add U17/ lever_arm:accel --plot plots/")  # fmt: skip
    _common(a)
    a.add_argument("term", help="term[:sensor[:axes]] to add, e.g. temperature_bias:gyro:x")
    a.add_argument("--plot", metavar="DIR", type=plot_dir, default=None,
                   help="write the PNG plots into this directory (made if missing)")  # fmt: skip
    lad = command("ladder", "the stepwise path of models from 'bias' upward: at each rung the "
                  "term that lowers BIC most, while significant, then every earlier rung's "
                  "term tested again and dropped when it no longer earns its place; ends with "
                  "the calibrate command that ships the last model",
                  "  python3 -m host model ladder U17/\n"
                  "  python3 -m host model ladder U17/ --model base")  # fmt: skip
    _common(lad)
    lad.set_defaults(model=None)  # the start: --model or --start, bias when neither
    for act in lad._actions:
        if act.dest == "model":
            act.help = "the starting model (default bias): comma list of term[:sensor[:axes]]"
    lad.add_argument("--start", default=None,
                     help="starting model, the same as --model (default bias)")  # fmt: skip
    runners = {"diagnose": run_diagnose, "add": run_add, "ladder": run_ladder, "terms": run_terms}

    def run(args: argparse.Namespace) -> int:
        if not args.model_command:
            p.print_help()
            return 2
        return runners[args.model_command](args)

    return run


# ---- demo -----------------------------------------------------------------------------------
def run_demo(args: argparse.Namespace) -> int:
    effects = DEFAULT_EFFECTS if args.effect == "all" else (args.effect,)
    for eff in effects:
        if eff not in EFFECTS:
            raise UserError(f"unknown effect {eff!r}; known: all, {', '.join(EFFECTS)}")
    width = terminal_width(sys.stdout)
    for eff in effects:
        case = hidden_effect_case(eff, args.seed, tilted=args.tilted, static_s=args.static_s)
        print(format_case(case))
        # the unit's noise known, as from a noise file (--noise): the floor does not carry
        # the hidden effect the way the session's repeated attitudes would. The commands below
        # give that floor, so that they print the figures printed here.
        floor = ",".join(f"{s}={v:.6g}" for s, v in sorted(case.known_floor.items()))
        print(f"noise floor of a record mean: {floor.replace(',', ', ')} (the unit's, known: "
              "as a noise file gives it; --floor below gives the same)")  # fmt: skip
        with working(f"demo {eff}: diagnosing the simulated session"):
            outcome = run_case(case, case.known_noise())
        try_line = None
        if args.out:
            from host.bench.plan import write_session

            out = Path(args.out) / eff
            write_session(out, "DEMO", dict(case.records))
            cmd = ["python3", "-m", "host", "model", "diagnose", str(out), "--floor", floor]
            print(f"records written to {out}; the same diagnosis:")
            print(command_lines(cmd, width, lead="  "))
            spec = outcome.diagnosis.recommended_spec
            if spec:
                add = ["python3", "-m", "host", "model", "add", str(out), spec, "--floor", floor]
                try_line = command_lines(add, width, lead="  try: ")
        print(format_outcome(outcome, try_line=try_line))
        print()
    return 0


def cli_demo(p: argparse.ArgumentParser) -> Callable[[argparse.Namespace], int]:
    """``demo hidden-effect``."""
    sub = p.add_subparsers(dest="demo_command", metavar="DEMO", title="demos")
    text = ("simulate a session with one effect hidden from the fit and let the workbench "
            "find it: what it names, and how close its coefficient comes to the truth")  # fmt: skip
    h = sub.add_parser(
        "hidden-effect", help="an effect hidden in a simulated session, found by the workbench",
        description=text, formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="examples:\n  python3 -m host demo hidden-effect --effect temperature --seed 4\n"
        "  python3 -m host demo hidden-effect --out /tmp/demo     every effect, records kept",
    )  # fmt: skip
    h.add_argument("--effect", default="all", help=f"all (default) or one of {', '.join(EFFECTS)}")
    h.add_argument("--seed", type=int, default=1, help="simulation seed (default 1)")
    h.add_argument("--out", default=None, help="also write the records to OUT/EFFECT/")
    h.add_argument("--tilted", action="store_true", help="add the 12 45° attitudes")
    h.add_argument("--static-seconds", type=float, default=10.0, dest="static_s", metavar="S",
                   help="static record length, s (as in calibrate; default 10)")  # fmt: skip
    h.add_argument("--static-s", type=float, dest="static_s", action=_Renamed,
                   new="--static-seconds", help=argparse.SUPPRESS)  # fmt: skip

    def run(args: argparse.Namespace) -> int:
        if args.demo_command != "hidden-effect":
            p.print_help()
            return 2
        return run_demo(args)

    return run
