"""``python3 -m host export RESULT --to FORMAT``: the calibration in another tool's convention.

RESULT is ``SERIAL_result.json`` (or the directory holding one); ``--to kalibr --noise F``
needs no result, only the noise file of a long static recording (``noise FILE --save F``);
given one, it checks it as the other formats do.
The text goes to stdout, or to ``--out FILE`` (written atomically; an earlier export there is
replaced, any other file refused and kept). ``--axes`` maps our chip
axes to the target's, with the same spelling as ``import --axes``. A result whose verdict is
not a pass (a value outside tolerance, undecided under the decision rule or not determined,
a failed self-test, records of the method not measured) is not exported: exit status 1 and
one line naming why, unless ``--allow-fail`` (the file then says FAILED). Formats and their
conventions: :mod:`host.calib.exporting`.
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import dataclass
from pathlib import Path

from host.calib import exporting
from host.calib.codec import result_from_json
from host.calib.result import CalibrationResult
from host.cli.options import Command
from host.errors import FailedResultError, ResultFileError, UserError
from host.ingest.importing import parse_axes
from host.session.atomic import write_text_atomic


def _result_path(path: Path) -> Path:
    if path.is_dir():
        found = sorted(path.glob("*_result.json"))
        if len(found) != 1:
            what = "no" if not found else f"{len(found)}"
            raise UserError(f"{path}: {what} SERIAL_result.json here; give the file itself")
        return found[0]
    if not path.exists():
        raise UserError(
            f"{path}: no such file (python3 -m host calibrate writes SERIAL_result.json)"
        )
    return path


#: a file name for each format, for the message that asks for one
_FILE_NAMES = {"ardupilot": "U17.parm", "px4": "U17.params", "imucal": "U17_imucal.json",
               "c-header": "imu_calibration.h", "kalibr": "imu.yaml"}  # fmt: skip
#: the words every export of this program carries near its top (an earlier one is replaced)
_OURS = b"imu-bench"


def check_out(out: Path | None, to: str) -> None:
    """UserError, before anything is computed, when ``--out`` cannot take the export: a
    directory (was 'permission denied'), or a file that is not an earlier export of this
    program — a vehicle's whole parameter file given by mistake is kept, not replaced."""
    if out is None:
        return
    name = _FILE_NAMES.get(to.strip().lower(), "calibration.txt")
    if out.is_dir():
        raise UserError(f"--out {out}: is a directory; give a file name, e.g. {out / name}")
    if out.exists():
        try:
            with out.open("rb") as f:
                head = f.read(4096)
        except OSError as exc:
            raise UserError(f"--out {out}: cannot read it ({exc.strerror or exc})") from None
        if _OURS not in head:
            raise UserError(
                f"--out {out}: exists and is no export of this program; it is kept: give "
                "another --out, or move it away first"
            )


@dataclass(frozen=True)
class ExportOptions:
    """``export``: the result (a file or its directory; None: kalibr from ``noise`` alone),
    the format, the output file (None: stdout), the target's axes from ours (None: x,y,z),
    ``thermal`` (None: not asked; '': the result's own bias(T); else its file), whether a
    failed result is exported, the noise file (kalibr)."""

    result: Path | None
    to: str
    out: Path | None = None
    axes: str | None = None
    thermal: str | None = None
    allow_fail: bool = False
    noise: Path | None = None


def export_options(ns: argparse.Namespace) -> ExportOptions:
    """The ``export`` options from its arguments."""
    return ExportOptions(result=ns.result, to=ns.to, out=ns.out, axes=ns.axes,
                         thermal=ns.thermal, allow_fail=ns.allow_fail, noise=ns.noise)  # fmt: skip


def run(args: ExportOptions) -> int:
    """Runner of ``python3 -m host export``."""
    if args.axes is not None and not args.axes.strip():  # e.g. --axes "$UNSET"
        raise UserError("--axes '': give three axes, e.g. x,-y,-z (or leave --axes out: x,y,z)")
    check_out(args.out, args.to)
    if args.to.strip().lower() == "kalibr":
        return _run_kalibr(args)
    if args.noise is not None:
        raise UserError(f"--noise: only --to kalibr reads a noise file, not --to {args.to}")
    if args.result is None:
        raise UserError(f"--to {args.to}: give the result, SERIAL_result.json or its directory")
    return _export_result(args, _read_result(args.result))


def _read_result(given: Path) -> CalibrationResult:
    """The result in the file ``given`` (or the one in its directory)."""
    path = _result_path(given)
    try:
        text = path.read_bytes()
    except OSError as exc:
        raise UserError(f"{path}: cannot read ({exc.strerror or exc})") from exc
    try:
        return result_from_json(text)
    except ResultFileError as exc:  # which file: a record given by mistake said only 'JSON'
        raise ResultFileError(f"{path}: {exc}") from None


def _export_result(args: ExportOptions, result: CalibrationResult) -> int:
    """The result in the format asked for, with the bias(T) asked for; exit status 1 for a
    failed result (unless --allow-fail)."""
    axes = parse_axes(args.axes) if args.axes else None
    thermal = None
    if args.thermal:  # a file; --thermal alone: the result's own bias(T), which it must carry
        from host.calib.thermal import ThermalCalibration

        if not Path(args.thermal).is_file():  # was: '[Errno 2] No such file or directory: …'
            raise UserError(
                f"--thermal {args.thermal}: no such file (python3 -m host thermal DIR writes "
                "SERIAL_thermal.json)"
            )

        thermal = ThermalCalibration.load(args.thermal)
    elif args.thermal is not None and result.thermal_range_c is None:
        raise UserError(
            f"--thermal: the result of {result.serial} carries no bias(T); give the file "
            "(--thermal SERIAL_thermal.json) or calibrate with --thermal"
        )
    try:
        out = exporting.export(
            result, args.to, axes, args.axes or "x,y,z", thermal, allow_fail=args.allow_fail
        )
    except FailedResultError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 1
    _emit(args, out)
    return 0


def _emit(args: ExportOptions, out: str) -> None:
    if args.out:
        again = args.out.exists()  # an earlier export (check_out refused anything else)
        write_text_atomic(args.out, out)
        print(f"written: {args.out}" + (" (the earlier export replaced)" if again else ""),
              file=sys.stderr)  # fmt: skip
    else:
        sys.stdout.write(out)


def _run_kalibr(args: ExportOptions) -> int:
    """``export [RESULT] --to kalibr --noise NOISE.json``: Kalibr's imu.yaml from noise
    figures; the unit's result, when given, is refused as every format refuses it when it
    failed (exit status 1), and its marks (FAILED, SIMULATED BOARD …) head the file."""
    if args.noise is None:
        raise UserError(f"--to kalibr: {exporting.PENDING['kalibr']}")
    from host.calib.kalibr import export_kalibr
    from host.model.recording import load_noise_file

    marks: tuple[str, ...] = ()
    if args.result is not None:
        result = _read_result(args.result)
        try:
            if not args.allow_fail:
                exporting.refuse_failed(result)
        except FailedResultError as exc:
            print(f"error: {exc}", file=sys.stderr)
            return 1
        marks = exporting.marks_of(result)
    text = export_kalibr(load_noise_file(args.noise))
    _emit(args, "".join(f"# *** {m} ***\n" for m in marks) + text)
    return 0


def cli_export(p: argparse.ArgumentParser) -> Command[ExportOptions]:
    """Fill in the ``export`` subparser; returns the command."""
    p.add_argument(
        "result",
        type=Path,
        nargs="?",
        help="SERIAL_result.json (or its directory); kalibr needs none, and checks one given",
    )
    p.add_argument(
        "--to",
        required=True,
        help=f"format: {', '.join(exporting.FORMATS)}, kalibr (with --noise)",
    )
    p.add_argument(
        "--out", type=Path,
        help="write to this file instead of stdout (an earlier export is replaced, any other "
        "file kept)",
    )  # fmt: skip
    p.add_argument(
        "--axes",
        help="target axes from ours with signs, e.g. x,-y,-z (default x,y,z; starting with a "
        "minus: --axes=-x,-y,z)",
    )  # fmt: skip
    p.add_argument(
        "--thermal",
        nargs="?",
        const="",
        metavar="FILE",
        help="bias(T) for px4 (TC_*) and ardupilot (INS_TCAL1_*): SERIAL_thermal.json, or "
        "alone the result's own (calibrate --thermal); the result's own is used by default",
    )
    p.add_argument(
        "--allow-fail",
        action="store_true",
        help="export a result whose verdict is not a pass (outside tolerance, undecided, not "
        "determined, failed self-test, records missing), marked FAILED in the file",
    )
    p.add_argument(
        "--noise", type=Path, help="noise file (python3 -m host noise FILE --save F): for kalibr"
    )
    return Command(export_options, run)
