"""``python3 -m host model diagnose|add|ladder|terms``: the model workbench on the command line
(:mod:`host.workbench`: the diagnosis, a term added, the ladder, their words in
:mod:`host.workbench.text`); the demo that shows it finding an effect is :mod:`host.cli.demo`.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import shlex
import sys
from collections.abc import Sequence
from dataclasses import dataclass, replace
from functools import partial
from pathlib import Path
from typing import Any

from host.calib.commands import command_lines
from host.calib.publish import session_noise
from host.cli import pyplot
from host.cli.figures import write_plots
from host.cli.options import (
    Command,
    WorkbenchOptions,
    add_workbench_arguments,
    workbench_options,
)
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
from host.dialogue.poses import next_pose, without_cube
from host.errors import UserError
from host.model.catalogue import CATALOGUE
from host.model.dataset import Dataset, build_dataset
from host.model.loader import load_term_file
from host.model.signals import RecordSignals
from host.model.spec import ModelTerm, parse_model, short_spec
from host.model.terms import Term
from host.session.directory import Session, read_session
from host.session.method import local_gravity
from host.session.spacing import timing_report
from host.workbench.ladder import LadderStep, add_term, ladder, new_terms
from host.workbench.text import (
    format_addition,
    format_diagnosis,
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


# ---- command line ---------------------------------------------------------------------------
@dataclass(frozen=True)
class DiagnoseOptions:
    """``model diagnose``: the records and model, the plots' directory, no compare table."""

    bench: WorkbenchOptions
    plot: Path | None = None
    brief: bool = False


@dataclass(frozen=True)
class AddOptions:
    """``model add``: the records and model, the term to add, the plots' directory."""

    bench: WorkbenchOptions
    term: str
    plot: Path | None = None


@dataclass(frozen=True)
class LadderOptions:
    """``model ladder``: the records and model options, the model the ladder starts from."""

    bench: WorkbenchOptions
    start: str = "bias"


@dataclass(frozen=True)
class TermsOptions:
    """``model terms``: the term files whose terms are listed too, JSON on stdout."""

    term_files: tuple[str, ...] = ()
    json: bool = False


ModelCommandOptions = DiagnoseOptions | AddOptions | LadderOptions | TermsOptions


def _catalogue(term_files: Sequence[str]) -> dict[str, Term]:
    cat = dict(CATALOGUE)
    for f in term_files:
        cat = load_term_file(f, cat)
    return cat


def _dataset(w: WorkbenchOptions) -> Dataset:
    return _session_dataset(w)[1]


def start_times(session: Session) -> dict[str, str]:
    """Each record's start time (wall clock, ISO 8601), where its header has one."""
    return {n: str(r.meta["start_time"]) for n, r in session.records.items()
            if r.meta.get("start_time")}  # fmt: skip


def _session_dataset(w: WorkbenchOptions) -> tuple[Session, Dataset]:
    session = read_session(w.dir, w.serial)
    sys.stderr.write(timing_report(session.records))
    return session, build_dataset(
        session,
        noise=session_noise(session, w.floor.floor, w.floor.noise),
        latitude_deg=w.site.latitude_deg,
        height_m=w.site.height_m,
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


def run_diagnose(args: DiagnoseOptions) -> int:
    w = args.bench
    w.model.bound_term_files()
    cat = _catalogue(w.model.term_files)
    model = parse_model(w.model.spec, cat)
    if args.plot:
        pyplot()  # no matplotlib: say so now, not after the fits
    with working("diagnose: reading the records, fitting the model and every candidate"):
        session, ds = _session_dataset(w)
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
        planned = [] if w.json else next_record_lines(w, session, model, d, ds.signals)
    if w.json:
        obj = d.to_dict()
        if plots:
            obj["plots"] = [str(p) for p in plots]
        _print_json(obj)
    else:
        try_line = None
        width, now = terminal_width(sys.stdout), short_spec(d.fit.model)
        if d.recommended_spec:
            cmd = add_command(w, d.recommended_spec, now)
            try_line = command_lines(cmd, width, lead="  try: ")
        see_one = {t: command_lines(add_command(w, t, now), width, lead="  to see one: ")
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
    w: WorkbenchOptions,
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
    if without_cube(session.records):
        return _next_pose_lines(w, session, width)
    out: list[str] = []
    try:
        with working("diagnose: ranking the records to measure next"):
            p = plan_next(session, model, noise=session_noise(session, *_floor(w)))
    except UserError:
        return out
    if p.ranked:
        r = p.ranked[0]
        gain = (f"determines {', '.join(r.determines)}" if r.determines
                else f"worst σ/tolerance {p.worst_now:.3g} → {r.worst_after:.3g}")  # fmt: skip
        out.append(wrap(f"next record: {r.candidate.label} ({r.candidate.operator_s:.0f} s of "
                        f"the operator's time): {gain}", width))  # fmt: skip
        out.append(command_lines(["python3", "-m", "host", "plan", str(w.dir)], width,
                                 lead="  the ranking: "))  # fmt: skip
    for e in d.equals:
        if e.terms and len(e.members) >= 2:  # a term and another term or a signal of the scan
            rest = "".join(f" and from {m}" for m in e.members[2:])  # all: each pair apart
            out.append(wrap(f"to tell {e.members[0]} from {e.members[1]}{rest} apart:", width))
            members = [_short_member(signals, m) for m in e.members]
            cmd = ["python3", "-m", "host", "plan", str(w.dir), "--separate", *members]
            out.append(command_lines(cmd, width, lead="  "))
    return out


def _next_pose_lines(w: WorkbenchOptions, session: Session, width: int) -> list[str]:
    """A session without a cube: the next pose (:func:`host.dialogue.poses.next_pose`), never
    a face or a turn, and the command that says more."""
    p = next_pose(session.records, local_gravity(w.site.latitude_deg, w.site.height_m))
    line = (f"next pose: {p.attitude}, moved there by hand (RMS σ/tolerance of the "
            f"planner's linearised model {p.rms_now:.3g} → {p.rms_after:.3g})")  # fmt: skip
    cmd = command_lines(["python3", "-m", "host", "plan", str(w.dir)], width, lead="  more: ")
    return [wrap(line, width), cmd]


def _floor(w: WorkbenchOptions) -> tuple[str | None, str | None]:
    """The ``--floor`` text and the ``--noise`` file (:func:`host.calib.publish.session_noise`)."""
    return w.floor.floor, w.floor.noise


def _same_options(w: WorkbenchOptions) -> list[str]:
    """The options that say which records and how (serial, site, floor, term files)."""
    cmd: list[str] = []
    for f in w.model.term_files:
        cmd += ["--term-file", f]
    if w.serial is not None:
        cmd += ["--serial", w.serial]
    cmd += w.site.words()
    for opt, val in (("--floor", w.floor.floor), ("--noise", w.floor.noise)):
        if val is not None:
            cmd += [opt, str(val)]
    return cmd


def calibrate_command(w: WorkbenchOptions, model: str) -> str:
    """The exact ``calibrate`` command that fits and ships ``model`` on the records the
    workbench just used (same directory, serial, site, floor and term files)."""
    cmd = ["python3", "-m", "host", "calibrate", "--from-dir", w.dir, "--model", model]
    return shlex.join(cmd + _same_options(w))


def add_command(w: WorkbenchOptions, term: str, model: str) -> list[str]:
    """The ``model add`` command that adds ``term`` to ``model`` on the same records."""
    cmd = ["python3", "-m", "host", "model", "add", w.dir, term]
    return cmd + (["--model", model] if model != "base" else []) + _same_options(w)


def run_add(args: AddOptions) -> int:
    w = args.bench
    w.model.bound_term_files()
    cat = _catalogue(w.model.term_files)
    model = parse_model(w.model.spec, cat)
    # a term that is none, or one the model has: said now, not after reading the records
    new_terms(model, args.term, cat)
    if args.plot:
        pyplot()  # no matplotlib: say so now, not after the fits
    paths: list[Path] = []
    with working(f"add: reading the records, fitting with and without {args.term}"):
        session, ds = _session_dataset(w)
        a = add_term(ds, model, args.term, cat)
        if args.plot:
            paths = write_plots(args.plot, ds, a.before, a.after, a.added[0].label,
                                start_times(session))  # fmt: skip
    ship = calibrate_command(w, short_spec(a.after.model))
    # a term these records do not determine is not a model to ship: calibrate would end on
    # "not determined" (exit 1); was "— ± —" and the ship command
    lost = [p.name for p in a.new_parameters if not math.isfinite(p.value)]
    if w.json:
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
                       f"python3 -m host plan {w.dir}", width))  # fmt: skip
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


def ladder_start(model: str | None, start: str | None) -> str:
    """The ladder's start: ``--model`` or ``--start`` (the same option), ``bias`` when neither
    is given; both, naming different models, are refused (one would be ignored)."""
    given = [v for v in (model, start) if v is not None]
    if len(set(given)) > 1:
        raise UserError(
            f"--model {model} and --start {start} both name the ladder's start: give "
            "one (the ladder climbs from it; its terms stay in)"
        )
    return given[0] if given else "bias"


def run_ladder(args: LadderOptions) -> int:
    w = args.bench
    w.model.bound_term_files()
    cat = _catalogue(w.model.term_files)
    progress = Progress()
    progress.show(f"ladder: reading the records of {w.dir} ...")
    ds = _dataset(w)
    progress.show("ladder: fitting the start model ...")
    width = terminal_width(sys.stdout)
    columns = ladder_columns()
    shown = fit_columns(columns, width)
    at = [any(c is s for s in shown) for c in columns]
    start = short_spec(parse_model(args.start, cat))
    rows: list[LadderStep] = []

    def on_step(step: LadderStep) -> None:
        progress.done()
        if w.json:
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
    ship = calibrate_command(w, short_spec(final))
    if w.json:
        _print_json({"steps": [dataclasses.asdict(s) for s in steps], "calibrate_command": ship})
    else:
        for line in left_out(columns, shown, width):
            print(line)
        print(f"final model: {readable_spec(final)}")
        print(command_lines(shlex.split(ship), width, lead="ship this model: "))
    return 0


def run_terms(args: TermsOptions) -> int:
    """``model terms``: the catalogue (with --term-file: and those terms too)."""
    cat = _catalogue(args.term_files)
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


def cli_model(p: argparse.ArgumentParser) -> Command[ModelCommandOptions | None]:
    """``model diagnose|add|ladder|terms``."""
    sub = p.add_subparsers(dest="model_command", metavar="diagnose|add|ladder|terms")

    def command(name: str, text: str, examples: str) -> argparse.ArgumentParser:
        return sub.add_parser(
            name, help=text, description=text, epilog="examples:\n" + examples,
            formatter_class=argparse.RawDescriptionHelpFormatter,
        )  # fmt: skip

    t = command("terms", "list the terms: physics, parameters and units",
                "  python3 -m host model terms\n"
                "  python3 -m host model terms --term-file my_terms.py\n"
                "      with your own")  # fmt: skip
    t.add_argument("--term-file", action="append", default=[], metavar="F",
                   help="also list the terms of this Python file (repeatable)")  # fmt: skip
    t.add_argument("--json", action="store_true", help="the list as JSON")
    d = command("diagnose", "compare model and records, say what is missing",
                "  python3 -m host model diagnose U17/\n"
                "  python3 -m host model diagnose U17/ --brief --plot plots/")  # fmt: skip
    add_workbench_arguments(d)
    d.add_argument("--plot", metavar="DIR", type=plot_dir, default=None,
                   help="write the PNG plots into this directory (made if missing)")  # fmt: skip
    d.add_argument("--brief", action="store_true", help="leave out the compare table")
    a = command("add", "refit with a term added: before → after",
                "  python3 -m host model add U17/ temperature_bias:gyro:x\n"
                "  python3 -m host model add U17/ lever_arm:accel --plot plots/")  # fmt: skip
    add_workbench_arguments(a)
    a.add_argument("term", help="term[:sensor[:axes]] to add, e.g. temperature_bias:gyro:x")
    a.add_argument("--plot", metavar="DIR", type=plot_dir, default=None,
                   help="write the PNG plots into this directory (made if missing)")  # fmt: skip
    lad = command("ladder", "the stepwise path of models from 'bias' upward: at each rung the "
                  "term that lowers BIC most, while significant, then every earlier rung's "
                  "term tested again and dropped when it no longer earns its place; ends with "
                  "the calibrate command that ships the last model",
                  "  python3 -m host model ladder U17/\n"
                  "  python3 -m host model ladder U17/ --model base")  # fmt: skip
    add_workbench_arguments(lad)
    lad.set_defaults(model=None)  # the start: --model or --start, bias when neither
    for act in lad._actions:
        if act.dest == "model":
            act.help = "the starting model (default bias): comma list of term[:sensor[:axes]]"
    lad.add_argument("--start", default=None,
                     help="starting model, the same as --model (default bias)")  # fmt: skip
    return Command(model_command_options, partial(run_model, p), data_out=_json_out)


def model_command_options(ns: argparse.Namespace) -> ModelCommandOptions | None:
    """The options of the ``model`` subcommand chosen (None: none chosen)."""
    name = ns.model_command
    if name is None:
        return None
    if name == "terms":
        return TermsOptions(term_files=tuple(ns.term_file), json=ns.json)
    if name == "ladder":  # its --model is its start
        start = ladder_start(ns.model, ns.start)
        w = workbench_options(ns)
        return LadderOptions(replace(w, model=replace(w.model, spec=start)), start=start)
    w = workbench_options(ns)
    if name == "diagnose":
        return DiagnoseOptions(w, plot=ns.plot, brief=ns.brief)
    return AddOptions(w, term=ns.term, plot=ns.plot)


def _json_out(o: ModelCommandOptions | None) -> bool:
    """The subcommand prints JSON (data for programs)."""
    if o is None:
        return False
    return o.json if isinstance(o, TermsOptions) else o.bench.json


def run_model(p: argparse.ArgumentParser, o: ModelCommandOptions | None) -> int:
    """Runner of ``model``: its subcommand's, or the help (exit status 2) without one."""
    if isinstance(o, DiagnoseOptions):
        return run_diagnose(o)
    if isinstance(o, AddOptions):
        return run_add(o)
    if isinstance(o, LadderOptions):
        return run_ladder(o)
    if isinstance(o, TermsOptions):
        return run_terms(o)
    p.print_help()
    return 2
