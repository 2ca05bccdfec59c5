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
from pathlib import Path

from host.calib.commands import command_lines, said_with_command
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
from host.cli.screen import terminal_width, working, wrap
from host.dialogue.options import DEFAULT_READY_S, MAX_EXTRA, PLANS, WARMUP_DEFAULT_S
from host.errors import RecordCheckError, UserError
from host.session.checks import failed_record
from host.session.directory import Session, read_session
from host.session.method import DEFAULT_HEIGHT_M, DEFAULT_LATITUDE_DEG
from host.session.spacing import timing_report


def add_arguments(p: argparse.ArgumentParser) -> None:
    """The calibrate options (the live-mode options are added beside these)."""
    src = p.add_mutually_exclusive_group()
    src.add_argument("--from-dir", metavar="DIR", help="recompute from the record files in DIR")
    src.add_argument(
        "--port",
        help="live calibration on a serial port or URL (default: the first APM found, "
        "else the virtual board sim://)",
    )
    p.add_argument("--serial", help="serial number (default: from the file names in DIR)")
    p.add_argument(
        "--out",
        metavar="DIR",
        help="where to write the result files (default: DIR; made if missing)",
    )
    p.add_argument(
        "--turns", type=int, help="turns per turn record (default: the records' header or inferred)"
    )
    p.add_argument(
        "--latitude", type=float, default=DEFAULT_LATITUDE_DEG,
        help=f"site latitude, degrees (default {DEFAULT_LATITUDE_DEG})",
    )  # fmt: skip
    p.add_argument(
        "--height", type=float, default=DEFAULT_HEIGHT_M,
        help=f"site height above sea level, m (default {DEFAULT_HEIGHT_M:g})",
    )  # fmt: skip
    p.add_argument(
        "--json", action="store_true", help="print the JSON result instead of the report"
    )
    p.add_argument(
        "--model",
        default="base",
        help="the model to fit and ship: comma list of term[:sensor[:axes]] (default base = "
        "bias,scale,misalignment,g_sensitivity, method.md §2; see 'model diagnose')",
    )
    p.add_argument(
        "--floor",
        default=None,
        metavar="accel=A,gyro=G",
        help="bias-instability floor of a record mean (m/s², °/s), as 'model diagnose'; "
        "default: from --noise, else measured from the records",
    )
    p.add_argument(
        "--noise",
        default=None,
        metavar="NOISE.json",
        help="noise file of this unit (noise FILE --save): the floor of a record mean from its "
        "Allan variance, as 'model diagnose --noise'",
    )
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
    p.add_argument(
        "--archive", metavar="URL",
        help="archive the result here: an SQLite file or postgresql://user@host/db (default "
        "$IMU_BENCH_ARCHIVE, else ~/.local/share/imu-bench/archive.sqlite)",
    )  # fmt: skip
    p.add_argument("--no-archive", action="store_true", help="do not archive the result")
    p.add_argument(
        "--pdf",
        action="store_true",
        help="also write the report as SERIAL_result.pdf, with its residual plots",
    )
    p.add_argument(
        "--bench", help="bench name: the records and the archive (default $IMU_BENCH_NAME)"
    )
    p.add_argument(
        "--operator", help="who measures: the records and the archive ($IMU_BENCH_OPERATOR)"
    )
    p.add_argument("--lot", help="production lot for the archive")
    p.add_argument(
        "--term-file",
        action="append",
        default=[],
        metavar="F",
        help="Python file defining extra terms for --model (repeatable)",
    )
    p.add_argument(
        "--term-timeout", type=float, metavar="S",
        help="how long the term files' code may run, s (default 120; a progress line every 5 s)",
    )  # fmt: skip


def compute_settings(args: argparse.Namespace) -> ComputeSettings:
    """The ``calibrate`` options that say how to compute (:class:`ComputeSettings`)."""
    return ComputeSettings(
        turns=args.turns,
        latitude_deg=args.latitude,
        height_m=args.height,
        model=args.model,
        term_files=tuple(args.term_file),
        floor=getattr(args, "floor", None),
        verify=getattr(args, "verify", None),
        thermal=getattr(args, "thermal", None),
        noise_file=getattr(args, "noise", None),
        pdf=bool(getattr(args, "pdf", False)),
    )


def run_computation(
    session: Session,
    args: argparse.Namespace,
    out_dir: Path,
    before_write: Callable[[CalibrationResult], object] | None = None,
) -> CalibrationResult:
    """Compute from ``session``, write both result files into ``out_dir``, print the report
    (or the JSON with ``--json``) on stdout (:func:`host.calib.publish.compute_and_write`;
    ``before_write`` as there)."""
    with working("calibrate: checking the records and fitting the model"):
        pub = compute_and_write(session, out_dir, compute_settings(args), before_write=before_write)
    show_result(pub, args.json)
    if not args.json:
        pdf = [] if pub.pdf_path is None else [pub.pdf_path]
        written = path_lines("written:", [pub.report_path, pub.json_path, *pdf])
        print("\n".join(written), file=sys.stderr)
    if not getattr(args, "no_archive", False):
        print(archive_line(pub.json_path.parent, session, args), file=sys.stderr)
    print(verdict_line(pub.result, pub.report_path, pub.records_dir), file=sys.stderr)  # last
    return pub.result


def archive_line(out_dir: Path, session: Session, args: argparse.Namespace) -> str:
    """Archive the result just written in ``out_dir`` (:func:`host.archive.store.
    archive_directory`); the line saying where, or — when it cannot — why, with the command
    that archives it later (the result files are kept either way)."""
    from host.archive.store import archive_directory

    records = session.directory if session.directory is not None else out_dir
    try:
        return wrap(archive_directory(
            out_dir, getattr(args, "archive", None), serial=session.serial,
            records_dir=records, bench=getattr(args, "bench", None),
            operator=getattr(args, "operator", None), lot=getattr(args, "lot", None),
        ))  # fmt: skip
    except UserError as exc:
        later = ["python3", "-m", "host", "archive", "add", str(out_dir), "--records", str(records)]
        width = terminal_width()
        return (
            wrap(f"not archived: {exc}; later:", width)
            + "\n"
            + command_lines(later, width, lead="  ")
        )


def adaptive_options(args: argparse.Namespace) -> None:
    """UserError for the adaptive plan's options where nothing reads them (was: silently
    ignored, a fixed session measured or a directory recomputed as if they were not given)."""
    values = (("--target", getattr(args, "target", None)),
              ("--max-extra", getattr(args, "max_extra", None)))  # fmt: skip
    given = [o for o, v in values if v is not None]
    plan = getattr(args, "plan", "fixed")
    if args.from_dir and (plan != "fixed" or given):
        what = "--plan adaptive" if plan != "fixed" else given[0]
        raise UserError(
            f"{what} is for a live calibration: the records in {args.from_dir} are measured "
            f"(python3 -m host plan {args.from_dir} names the next record worth measuring)"
        )
    if given and plan not in ("adaptive", "poses"):
        raise UserError(
            f"{given[0]}: only --plan adaptive reads it; add --plan adaptive (or --plan poses, "
            "which reads it too)"
        )


def run(args: argparse.Namespace) -> int:
    """Runner of ``python3 -m host calibrate``."""
    adaptive_options(args)
    for given in getattr(args, "redo", None) or ():  # was: '--redo ,' began a whole new sitting
        if not any(n.strip() for n in given.split(",")):
            raise UserError(f"--redo {given!r}: give the record names, e.g. --redo x_ccw,y_up")
    if args.from_dir and getattr(args, "no_self_test", False):
        raise UserError(
            f"--no-self-test is for a live calibration: the records in {args.from_dir} say "
            "whether the self-test ran"
        )
    if not args.from_dir:
        from host.dialogue.flow import run_dialogue

        if not args.no_archive:
            args.after_publish = lambda out_dir, session: archive_line(out_dir, session, args)
        return run_dialogue(args)
    session = read_session(args.from_dir, args.serial)
    sys.stderr.write(timing_report(session.records))
    out_dir = out_directory(args.out) if args.out else Path(args.from_dir)
    try:
        with directory_locks(Path(args.from_dir), out_dir, f"calibrate --from-dir {args.from_dir}"):
            result = run_computation(session, args, out_dir, lambda r: set_aside_other_result(
                out_dir, r, lambda text: print(wrap(text), file=sys.stderr)
            ))  # fmt: skip
    except RecordCheckError as exc:
        name = failed_record(exc, session.serial)
        rec = session.records.get(name) if name is not None else None
        if name is None or rec is None or "importer" in rec.meta:  # imported: nothing to redo
            raise
        cmd = ["python3", "-m", "host", "calibrate", "--serial", session.serial,
               "--out", str(args.from_dir), "--redo", name]  # fmt: skip
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


def cli_calibrate(p: argparse.ArgumentParser) -> Callable[[argparse.Namespace], int]:
    """Fill in the ``calibrate`` subparser; returns the runner."""
    add_arguments(p)
    add_live_arguments(p)
    return run
