"""``python3 -m host calibrate``: compute the calibration from records and write the report.

``--from-dir DIR`` recomputes from the record files in DIR. Otherwise the live dialogue of
method.md §5 runs (:func:`host.dialogue.flow.run_dialogue`) on ``--port`` — or, with no port
given, on the first board found, else the virtual board ``sim://``; it records into a
directory and then computes like the from-dir mode. Either way the result lands in the archive
(:func:`archive_line`; ``--no-archive`` opts out).
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from dataclasses import dataclass, replace
from functools import partial
from pathlib import Path

from host.calib.bench_file import find_bench_file, load_bench_file
from host.calib.certificate import FROM_BENCH_FILE, FROM_DEFAULT, FROM_OPTIONS, Issue
from host.calib.commands import command_lines, said_with_command
from host.calib.decision import DEFAULT_RULE, RULES
from host.calib.publish import (
    ComputeSettings,
    compute_and_write,
    directory_locks,
    set_aside_other_result,
    show_result,
)
from host.calib.report import path_lines, verdict_line
from host.calib.result import CalibrationResult
from host.cli import out_directory
from host.cli.options import (
    Command,
    ModelOptions,
    Site,
    add_archive_option,
    add_floor_options,
    add_model_options,
    add_site_options,
    floor_options,
    model_options,
    site_options,
)
from host.cli.screen import terminal_width, working, wrap
from host.dialogue.options import (
    DEFAULT_READY_S,
    MAX_EXTRA,
    PLANS,
    WARMUP_DEFAULT_S,
    DialogueOptions,
    Planning,
    Provenance,
    Schedule,
    SessionFiles,
)
from host.errors import RecordCheckError, UserError
from host.session.checks import failed_record
from host.session.directory import Session, read_session
from host.session.records import name_problem
from host.session.spacing import timing_report


@dataclass(frozen=True)
class CalibrateOptions:
    """The ``calibrate`` options: ``from_dir`` the records' directory to recompute from (None:
    a live calibration, the dialogue), ``dialogue`` everything else — the files, the schedule,
    the plan, how to compute, provenance and archive (:class:`host.dialogue.options.
    DialogueOptions`; with ``--from-dir`` only the serial, ``--out``, ``--json``, the compute
    settings and the provenance are read), ``model`` the model and its term files."""

    from_dir: str | None
    dialogue: DialogueOptions
    model: ModelOptions

    @property
    def compute(self) -> ComputeSettings:
        """How to compute from the records of ``from_dir`` (``--turns``: turns of the turn
        records whose header does not say it)."""
        return replace(self.dialogue.compute, turns=self.dialogue.schedule.turns)


def add_arguments(p: argparse.ArgumentParser) -> None:
    """The calibrate options (the live-mode options are added beside these)."""
    src = p.add_mutually_exclusive_group()
    src.add_argument("--from-dir", metavar="DIR", help="recompute from the record files in DIR")
    src.add_argument(
        "--port",
        action="append",
        help="live calibration on a serial port or URL (default: the first APM found, "
        "else the virtual board sim://); repeat it for a sitting of several boards, one "
        "--serial each in the same order",
    )
    p.add_argument(
        "--serial",
        action="append",
        help="serial number (default: from the file names in DIR); one per --port",
    )
    p.add_argument(
        "--out",
        metavar="DIR",
        help="where to write the result files (default: DIR; made if missing); several "
        "boards: each into DIR/SERIAL/",
    )
    p.add_argument(
        "--turns", type=int, help="turns per turn record (default: the records' header or inferred)"
    )
    add_site_options(p)
    p.add_argument(
        "--json", action="store_true", help="print the JSON result instead of the report"
    )
    add_model_options(p, lead="the model to fit and ship: ")
    add_floor_options(p)
    p.add_argument(
        "--decision-rule",
        choices=RULES,
        default=DEFAULT_RULE,
        help="how a value's mark is decided: guarded (default: + only where value ± U lies "
        "within the tolerance, ? where it reaches across a limit, not a pass) or simple "
        "(the value alone within the tolerance, U not used)",
    )
    add_result_arguments(p)


def add_result_arguments(p: argparse.ArgumentParser) -> None:
    """What is done with the result: verified, corrected for temperature, archived, in PDF."""
    p.add_argument(
        "--verify",
        metavar="DIR2",
        help="predict the records in DIR2 (another session, extra attitudes: not used in the "
        "fit) and report measured − predicted per record and channel",
    )
    p.add_argument(
        "--thermal",
        metavar="FILE",
        help="the unit's bias(T), SERIAL_thermal.json from 'python3 -m host thermal': removed "
        "from the records and carried in the result, which apply() then needs temperatures "
        "for (default: SERIAL_thermal.json in the records' directory if there; 'none': ignore)",
    )
    add_archive_option(p, "archive the result here")
    p.add_argument("--no-archive", action="store_true", help="do not archive the result")
    p.add_argument(
        "--pdf",
        action="store_true",
        help="also write the report as SERIAL_result.pdf, with its residual plots",
    )
    p.add_argument(
        "--bench",
        help="bench name: the records and the archive (default: the bench file's id, "
        "else $IMU_BENCH_NAME)",
    )
    p.add_argument(
        "--bench-file", metavar="FILE",
        help="the laboratory's bench file (TOML: laboratory, bench, signatory, the plate's and "
        "cube's last checks, the site; docs/bench-file.md) for the certificate (default "
        "$IMU_BENCH_FILE, else ~/.config/imu-bench/bench.toml if there; 'none': no file)",
    )  # fmt: skip
    p.add_argument("--customer", help="the customer, named on the certificate")
    p.add_argument(
        "--operator", help="who measures: the records and the archive ($IMU_BENCH_OPERATOR)"
    )
    p.add_argument("--lot", help="production lot for the archive")


def calibrate_options(ns: argparse.Namespace) -> CalibrateOptions:
    """The ``calibrate`` options from its arguments; UserError for options where nothing
    reads them (the live ones with ``--from-dir``) or that name no record."""
    _live_only(ns)
    for given in ns.redo or ():  # was: '--redo ,' began a whole new sitting
        if not any(n.strip() for n in given.split(",")):
            raise UserError(f"--redo {given!r}: give the record names, e.g. --redo x_ccw,y_up")
    return CalibrateOptions(from_dir=ns.from_dir, dialogue=dialogue_options(ns),
                            model=model_options(ns))  # fmt: skip


def certificate_issue(ns: argparse.Namespace) -> tuple[Site, Issue, str | None]:
    """The site, the certificate's facts (:class:`host.calib.certificate.Issue`) and the bench
    name from ``--bench-file`` (:func:`host.calib.bench_file.find_bench_file`), ``--customer``,
    ``--latitude``/``--height`` (given: they win over the bench file's site) and ``--bench``
    (default: the bench file's id; another is refused)."""
    path = find_bench_file(ns.bench_file)
    bench = load_bench_file(path) if path is not None else None
    if ns.customer is not None and (name_problem(ns.customer) or not ns.customer.strip()):
        raise UserError(f"--customer: {name_problem(ns.customer) or 'give a name'}")
    name = ns.bench
    if bench is not None and name is not None and name != bench.bench_id:
        raise UserError(
            f"--bench {name}: the bench file {bench.path} is of bench {bench.bench_id}; give "
            "that bench's file or leave --bench out"
        )
    origin = {True: FROM_OPTIONS, False: FROM_BENCH_FILE if bench else FROM_DEFAULT}
    lat_from, h_from = origin[ns.latitude is not None], origin[ns.height is not None]
    site = site_options(ns)
    if bench is not None:
        lat = bench.site.latitude_deg if ns.latitude is None else site.latitude_deg
        site = Site(latitude_deg=lat, height_m=bench.site.height_m if ns.height is None
                    else site.height_m)  # fmt: skip
        name = bench.bench_id
    issue = Issue(bench=bench, customer=ns.customer, site_from=(lat_from, h_from))
    return site, issue, name


def dialogue_options(ns: argparse.Namespace) -> DialogueOptions:
    """The live dialogue's options from the ``calibrate`` arguments."""
    model, floor = model_options(ns), floor_options(ns)
    site, issue, bench = certificate_issue(ns)
    plan = Planning(plan=ns.plan, target=0.05 if ns.target is None else ns.target,
                    max_extra=12 if ns.max_extra is None else ns.max_extra)  # fmt: skip
    port, serial, more = boards_of(ns.port, ns.serial)
    return DialogueOptions(
        port=port, yes=ns.yes, json=ns.json, more_boards=more,
        files=SessionFiles(
            serial=serial, out=Path(ns.out) if ns.out else None,
            capture=Path(ns.capture) if ns.capture else None, resume=ns.resume,
            redo=tuple(n.strip() for r in ns.redo or () for n in r.split(",") if n.strip()),
        ),
        schedule=Schedule(
            static_seconds=ns.static_seconds, turns=ns.turns, warmup_s=ns.warmup,
            ready_s=ns.ready_seconds, closing=not ns.no_closing, self_test=not ns.no_self_test,
        ),
        planning=plan,
        compute=ComputeSettings(
            latitude_deg=site.latitude_deg, height_m=site.height_m, model=model.spec,
            term_files=model.term_files, floor=floor.floor, verify=ns.verify,
            thermal=ns.thermal, noise_file=floor.noise, pdf=ns.pdf, issue=issue,
            decision_rule=ns.decision_rule,
        ),
        provenance=Provenance(operator=ns.operator, bench=bench, lot=ns.lot,
                              archive=ns.archive, no_archive=ns.no_archive),
    )  # fmt: skip


def boards_of(
    ports: list[str] | None, serials: list[str] | None
) -> tuple[str | None, str | None, tuple[tuple[str, str], ...]]:
    """The first board's port and serial and the (port, serial) of the others, from the
    ``--port`` and ``--serial`` given (one serial per port, in order, when there are several
    ports); UserError when the counts do not match."""
    ports, serials = ports or [], serials or []
    if len(ports) > 1 and len(serials) != len(ports):
        raise UserError(
            f"{len(ports)} --port but {len(serials)} --serial: give one --serial per --port, "
            "in the same order"
        )
    if len(ports) <= 1 and len(serials) > 1:
        raise UserError(
            f"{len(serials)} --serial but {len(ports)} --port: one --serial per board "
            "(a sitting of several boards gives a --port for each)"
        )
    more = tuple(zip(ports[1:], serials[1:], strict=True))
    return (ports[0] if ports else None), (serials[0] if serials else None), more


def _live_only(ns: argparse.Namespace) -> None:
    """UserError for the live options given with ``--from-dir`` (was: silently ignored, a
    directory recomputed as if they were not given), and for the adaptive plan's options
    without ``--plan adaptive``."""
    given = [o for o, v in (("--target", ns.target), ("--max-extra", ns.max_extra))
             if v is not None]  # fmt: skip
    if ns.from_dir and (ns.plan != "fixed" or given):
        what = "--plan adaptive" if ns.plan != "fixed" else given[0]
        raise UserError(
            f"{what} is for a live calibration: the records in {ns.from_dir} are measured "
            f"(python3 -m host plan {ns.from_dir} names the next record worth measuring)"
        )
    if given and ns.plan not in ("adaptive", "poses"):
        raise UserError(
            f"{given[0]}: only --plan adaptive reads it; add --plan adaptive (or --plan poses, "
            "which reads it too)"
        )
    if ns.from_dir and ns.no_self_test:
        raise UserError(
            f"--no-self-test is for a live calibration: the records in {ns.from_dir} say "
            "whether the self-test ran"
        )


def run_computation(
    session: Session,
    opts: CalibrateOptions,
    out_dir: Path,
    before_write: Callable[[CalibrationResult], object] | None = None,
) -> CalibrationResult:
    """Compute from ``session``, write both result files into ``out_dir``, print the report
    (or the JSON with ``--json``) on stdout (:func:`host.calib.publish.compute_and_write`;
    ``before_write`` as there)."""
    json = opts.dialogue.json
    with working("calibrate: checking the records and fitting the model"):
        pub = compute_and_write(session, out_dir, opts.compute, before_write=before_write)
    show_result(pub, json)
    if not json:
        pdf = [] if pub.pdf_path is None else [pub.pdf_path]
        written = path_lines("written:", [pub.report_path, pub.json_path, *pdf])
        print("\n".join(written), file=sys.stderr)
    if not opts.dialogue.provenance.no_archive:
        print(archive_line(pub.json_path.parent, session, opts.dialogue.provenance),
              file=sys.stderr)  # fmt: skip
    print(verdict_line(pub.result, pub.report_path, pub.records_dir), file=sys.stderr)  # last
    return pub.result


def archive_line(out_dir: Path, session: Session, who: Provenance) -> str:
    """Archive the result just written in ``out_dir`` (:func:`host.archive.store.
    archive_directory`); the line saying where, or — when it cannot — why, with the command
    that archives it later (the result files are kept either way)."""
    from host.archive.store import archive_directory

    records = session.directory if session.directory is not None else out_dir
    try:
        return wrap(archive_directory(
            out_dir, who.archive, serial=session.serial, records_dir=records, bench=who.bench,
            operator=who.operator, lot=who.lot,
        ))  # fmt: skip
    except UserError as exc:
        later = ["python3", "-m", "host", "archive", "add", str(out_dir), "--records", str(records)]
        width = terminal_width()
        return (
            wrap(f"not archived: {exc}; later:", width)
            + "\n"
            + command_lines(later, width, lead="  ")
        )


def run(opts: CalibrateOptions) -> int:
    """Runner of ``python3 -m host calibrate``."""
    opts.model.bound_term_files()
    if opts.from_dir is None:
        from host.dialogue.flow import run_dialogue

        who = opts.dialogue.provenance
        after = None if who.no_archive else partial(archive_line, who=who)
        return run_dialogue(opts.dialogue, after_publish=after)
    return run_from_dir(opts, opts.from_dir)


def run_from_dir(opts: CalibrateOptions, from_dir: str) -> int:
    """``calibrate --from-dir``: the records of ``from_dir`` computed and written; a record
    that fails its checks is said with the command that measures it again."""
    session = read_session(from_dir, opts.dialogue.files.serial)
    sys.stderr.write(timing_report(session.records))
    out = opts.dialogue.files.out
    out_dir = out_directory(out) if out else Path(from_dir)
    try:
        with directory_locks(Path(from_dir), out_dir, f"calibrate --from-dir {from_dir}"):
            result = run_computation(session, opts, out_dir, lambda r: set_aside_other_result(
                out_dir, r, lambda text: print(wrap(text), file=sys.stderr)
            ))  # fmt: skip
    except RecordCheckError as exc:
        name = failed_record(exc, session.serial)
        rec = session.records.get(name) if name is not None else None
        if name is None or rec is None or "importer" in rec.meta:  # imported: nothing to redo
            raise
        cmd = ["python3", "-m", "host", "calibrate", "--serial", session.serial,
               "--out", str(from_dir), "--redo", name]  # fmt: skip
        raise UserError(
            said_with_command(f"{exc}; measure {name} again (the others are kept) with:", cmd)
        ) from None
    return 0 if result.all_passed else 1


def add_live_arguments(p: argparse.ArgumentParser) -> None:
    """The live-mode options of ``calibrate`` that :func:`add_arguments` lacks
    (it has --port, --serial, --out, --turns, --latitude, --height, --json)."""
    p.add_argument(
        "--static-seconds", type=float, metavar="S",
        help="accumulation time per static orientation, s (asked if not given)",
    )  # fmt: skip
    p.add_argument(
        "--warmup", type=float, default=WARMUP_DEFAULT_S, metavar="SECONDS",
        help=f"warm-up wait before measuring, s (default {WARMUP_DEFAULT_S:g}; 0 skips)",
    )  # fmt: skip
    p.add_argument(
        "--no-closing", action="store_true",
        help="leave out the closing check (by default the session ends by measuring the first "
        "attitude again, SERIAL_x_up_2.txt: its difference from the first shows the drift, "
        "and the fit takes it as one more static record)",
    )  # fmt: skip
    p.add_argument(
        "--no-self-test", action="store_true",
        help="do not run the MPU-6000's self-test at the start (e.g. a firmware without it); "
        "the records, the report and the archive say 'not run', and so does the verdict",
    )  # fmt: skip
    p.add_argument(
        "--yes", action="store_true",
        help="non-interactive: every question gets its default (both stages, save every "
        "measurement); needs --serial and --static-seconds",
    )  # fmt: skip
    p.add_argument(
        "--resume", action="store_true",
        help="keep the records already in the output directory, measure only the missing ones",
    )  # fmt: skip
    p.add_argument(
        "--redo", action="append", metavar="NAME",
        help="measure this record again (x_up … z_dn, x_ccw … z_cw, a repeat: x_ccw_2; repeat "
        "or comma-separate for several) and keep the others, as --resume does",
    )  # fmt: skip
    p.add_argument(
        "--capture", metavar="FILE",
        help="IMUCAP01 capture of the session (default OUT/SERIAL_session.cap)",
    )  # fmt: skip
    add_plan_arguments(p)


def add_plan_arguments(p: argparse.ArgumentParser) -> None:
    """The live mode's plan: fixed or adaptive, its target and budget, the turns' pause."""
    p.add_argument(
        "--plan", choices=PLANS, default="fixed",
        help="fixed: the method's records; adaptive: axis by axis, each face ends when its mean "
        "(the up face: the face pair) is precise enough for --target (10 s to "
        "--static-seconds), turn pairs after the up face go on until the gyro scale "
        "meets it (3 pairs at most), then the records the planner names (a face again, a turn "
        "pair) until every value's σ/tolerance meets --target (plan DIR ranks them); poses: no "
        "cube, the unit held still in the attitudes the planner asks for, moved by hand "
        "between them, until every value the poses determine meets --target (at most 10 + "
        "--max-extra poses); poses16: the 16 attitudes of the Earth-rate article's scheme",
    )  # fmt: skip
    p.add_argument(  # None when not given: given without --plan adaptive, it is refused
        "--target", type=float, metavar="R",
        help="--plan adaptive: the worst σ/tolerance to reach (default 0.05)",
    )  # fmt: skip
    p.add_argument(
        "--max-extra", type=int, metavar="N",
        help=f"--plan adaptive: at most N records added (default 12, at most {MAX_EXTRA})",
    )  # fmt: skip
    p.add_argument(
        "--ready-seconds", type=float, metavar="S",
        help="pause between 'get ready' and the start beep of a turn, s "
        f"(default {DEFAULT_READY_S:g}; none with --yes on the virtual board: nobody turns)",
    )  # fmt: skip


def cli_calibrate(p: argparse.ArgumentParser) -> Command[CalibrateOptions]:
    """Fill in the ``calibrate`` subparser; returns the command."""
    add_arguments(p)
    add_live_arguments(p)
    return Command(calibrate_options, run, data_out=lambda o: o.dialogue.json)
