"""``python3 -m host import FILE …``: foreign data in, the project's record files out.

Reads a column file (``--columns``), an imucal session (its CSV with ``--sections LIST.json``)
or a capture (``.cap``), cuts the stream into records (automatically, from a labels file, from
imucal's sections, or the whole file as one ``--record``), prints the table of what was found,
warns about irregular timing, and writes ``DIR/SERIAL_x_up.txt`` … plus the labels file
``DIR/SERIAL_segments.tsv`` to correct the cut. Records already in DIR are never overwritten
without ``--force``.
"""

from __future__ import annotations

import argparse
import shlex
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from host.cli.options import Command
from host.errors import UserError
from host.ingest import importing, labels, segmentation
from host.ingest.reading import Segment
from host.ingest.stillness import Thresholds, attitude
from host.session import spacing
from host.session.atomic import write_text_atomic
from host.session.directory import record_path, write_record
from host.session.records import Record


def add_arguments(p: argparse.ArgumentParser) -> None:
    """The import options (spellings fixed by issue 15)."""
    p.add_argument("file", type=Path, help="column file (CSV/TSV/spaces), imucal CSV or .cap")
    p.add_argument(
        "--columns",
        help="what each column is, in order: t,ax,ay,az,gx,gy,gz,temp (skip = ignore a column; "
        "t and temp optional)",
    )
    p.add_argument(
        "--units",
        help="t=s|ms|us, accel=m/s2|g|counts:LSB_PER_G, gyro=deg/s|rad/s|counts:LSB_PER_DPS "
        "(default t=s,accel=m/s2,gyro=deg/s)",
    )
    p.add_argument(
        "--axes", help="our x,y,z from the file's axes with signs, e.g. x,-y,z (default x,y,z)"
    )
    p.add_argument("--rate", type=float, help="sample rate, Hz, when the file has no time column")
    p.add_argument(
        "--sections",
        type=Path,
        help="imucal's section list JSON for its session CSV (without one, and none beside the "
        "CSV, the records are found in the stream)",
    )
    p.add_argument(
        "--labels", type=Path, help="labels file (SERIAL_segments.tsv, edited) to cut the stream"
    )
    p.add_argument("--record", help="import the whole file as this one record (e.g. x_up)")
    p.add_argument(
        "--poses",
        action="store_true",
        help="every rest a pose record, each motion between two a move, even of the method's "
        "session (without: when the faces and turns leave most rests out)",
    )
    p.add_argument("--serial", required=True, help="serial number: prefixes every file name")
    p.add_argument("--out", required=True, type=Path, help="directory for the record files")
    p.add_argument("--force", action="store_true", help="overwrite records already in --out")


@dataclass(frozen=True)
class ImportOptions:
    """``import``: the file; what its columns are, their units, our axes from its axes, its
    sample rate, Hz (None: from its time column); imucal's section list, a labels file, or
    the whole file as one record; every rest a pose (``poses``); the serial, the output
    directory, overwrite or not."""

    file: Path
    serial: str
    out: Path
    columns: str | None = None
    units: str | None = None
    axes: str | None = None
    rate: float | None = None
    sections: Path | None = None
    labels: Path | None = None
    record: str | None = None
    poses: bool = False
    force: bool = False


def import_options(ns: argparse.Namespace) -> ImportOptions:
    """The ``import`` options from its arguments."""
    return ImportOptions(
        file=ns.file, serial=ns.serial, out=ns.out, columns=ns.columns, units=ns.units,
        axes=ns.axes, rate=ns.rate, sections=ns.sections, labels=ns.labels, record=ns.record,
        poses=ns.poses, force=ns.force,
    )  # fmt: skip


def _read_stream(args: ImportOptions) -> tuple[importing.Stream, list[Segment]]:
    """The stream, and the segments when the file itself says where they are (imucal)."""
    path: Path = args.file
    if path.suffix.lower() == ".cap":
        if args.columns:
            raise UserError(f"{path}: a capture has its own columns; drop --columns")
        return importing.read_capture_stream(path), []
    text = importing.read_text(path)
    beside = path.with_name(f"{path.stem}_list.json")  # imucal's own naming
    sections = args.sections
    if sections is None and not args.columns and beside.exists():
        if importing.looks_like_imucal(text):
            print(f"sections: {beside.name} (beside the session)")
            sections = beside
    if sections is not None:
        if not importing.looks_like_imucal(text):
            raise UserError(
                f"{path}: --sections is for imucal's session CSV, whose header names "
                f"{', '.join(importing.IMUCAL_COLUMNS)}"
            )
        sections_text = importing.read_text(sections)
        stream, spans = importing.parse_imucal_session(
            text, sections_text, str(path), str(sections), args.rate
        )
        return stream, [_section_segment(stream, lab, a, b) for lab, a, b in spans]
    if not args.columns:
        if importing.looks_like_imucal(text):
            stream = importing.parse_imucal_stream(text, str(path), args.rate)
            print(f"sections: none given (no {beside.name}): the records are found in the stream")
            return stream, []
        raise UserError(
            f"{path}: say what each column is with --columns, e.g. "
            "--columns t,ax,ay,az,gx,gy,gz,temp (skip for a column to ignore)"
        )
    columns = importing.parse_columns(args.columns)
    units = importing.parse_units(args.units)
    axes = importing.parse_axes(args.axes)
    return importing.parse_column_text(text, str(path), columns, units, axes, args.rate), []


def _section_segment(stream: importing.Stream, label: str, a: int, b: int) -> Segment:
    """A segment for one imucal section; a rotation's direction and turns from its integral."""
    t = stream.t_s
    acc = stream.accel[a:b].mean(axis=0)
    if label.endswith("_turn"):
        axis = label[0]
        k = "xyz".index(axis)
        up = np.zeros(3)
        up[k] = 1.0 if acc[k] >= 0 else -1.0
        angle = float(spacing.trapezoid(t[a:b], stream.gyro[a:b]) @ up)
        n = max(1, round(abs(angle) / 360.0))
        d = 1 if angle > 0 else -1
        name = f"{axis}_{'ccw' if d > 0 else 'cw'}"
        q = f"{n} turn{'s' if n > 1 else ''}, {angle:+.1f}° about {'+' if up[k] > 0 else '-'}{axis}"
        return Segment(
            a, b, float(t[a]), float(t[b - 1]), "imucal section", name, q,
            (float(up[0]), float(up[1]), float(up[2])), n, d,
        )  # fmt: skip
    lab, up, angle = attitude(acc)
    if lab != label:
        raise UserError(
            f"section {label}: gravity is on {lab} ({angle:.0f}° off), not on {label}; "
            "check the section list or --axes"
        )
    return Segment(
        a, b, float(t[a]), float(t[b - 1]), "imucal section", label,
        f"gravity {angle:.1f}° off the axis", (float(up[0]), float(up[1]), float(up[2])),
    )  # fmt: skip


def _whole_file(stream: importing.Stream, name: str) -> list[Segment]:
    if not labels.valid_label(name):
        raise UserError(f"--record {name}: not a record name (x_up … z_dn, x_ccw … z_cw)")
    t = stream.t_s
    rows = f"0\t{t[0]:.6f}\t{t[-1]:.6f}\t{name}\n"
    return labels.parse_labels(rows, f"--record {name}", stream)


def _checked_serial(args: ImportOptions) -> str:
    """The serial; UserError (one line) for a bad one or options that exclude each other."""
    from host.session.inputs import parse_serial

    try:
        serial = parse_serial(args.serial)
    except ValueError as exc:
        raise UserError(f"--serial: {exc}") from None
    if args.out.exists() and not args.out.is_dir():  # was: '[Errno 17] File exists'
        raise UserError(f"--out {args.out}: is a file; give a directory for the record files")
    if args.record and args.labels is not None:  # was: --labels silently left unused
        raise UserError("--record and --labels: give one (the whole file as one record, or "
                        "the labels file's rows)")  # fmt: skip
    if args.poses and (args.record or args.labels is not None):
        raise UserError("--poses reads the stream as found; --record and --labels say the "
                        "records themselves: give one")  # fmt: skip
    return serial


def _cut(
    args: ImportOptions, stream: importing.Stream, segments: list[Segment]
) -> tuple[list[Segment], Thresholds | None, list[str]]:
    """The segments the records are cut from (the whole file, the labels file, imucal's
    sections or those found), the stillness thresholds when found, and the notes on ambiguous
    choices; the stream's warnings (rows left out, gaps, a gyro unit) on stderr."""
    for note in (*stream.notes, *segmentation.gap_notes(stream)):
        print(f"warning: {note}", file=sys.stderr)
    if args.record:
        return _whole_file(stream, args.record), None, []
    if args.labels is not None:
        return labels.read_labels(args.labels, stream), None, []
    if segments:  # imucal's sections
        return segments, None, []
    found, thresholds, notes = segmentation.segment_stream(stream, poses=args.poses)
    hint = segmentation.gyro_unit_hint(stream, found)
    if hint:
        print(f"warning: {hint}", file=sys.stderr)
    return found, thresholds, notes


def run(args: ImportOptions) -> int:
    """Runner of ``python3 -m host import``."""
    serial = _checked_serial(args)
    stream, segments = _read_stream(args)
    segments, thresholds, notes = _cut(args, stream, segments)
    records = segmentation.build_records(stream, segments, thresholds, serial)
    if not records:
        raise UserError(f"{args.file}: nothing labelled to write (every label is '-')")
    out: Path = args.out
    out.mkdir(parents=True, exist_ok=True)
    paths = [record_path(out, serial, n) for n in records]
    existing = [p for p in paths if p.exists()]
    if existing and not args.force:
        raise UserError(
            f"{existing[0]} already exists (and {len(existing) - 1} more); choose another --out "
            "or add --force to overwrite"
        )
    src = stream.meta.get("source", str(args.file))
    print(f"{src}: {len(stream)} samples, {stream.t_s[-1] - stream.t_s[0]:.1f} s")
    if thresholds is not None:
        print(f"stillness: {thresholds.text()}")
    sys.stdout.write(labels.format_table(segments))
    for note in notes:
        print(f"ambiguous: {note}; to take the other, swap their labels in the labels file")
    sys.stdout.write(spacing.timing_table(records))
    _warn_timing(records)
    _write(args, serial, records, segments, src)
    _others_there(out, serial, paths)
    print(f"next: python3 -m host calibrate --from-dir {shlex.quote(str(out))}")
    return 0


def _write(
    args: ImportOptions, serial: str, records: dict[str, Record], segments: list[Segment],
    src: str,
) -> None:  # fmt: skip
    """The record files and (the cut found or from imucal's sections) the labels file."""
    out = args.out
    labels_path = out / f"{serial}_segments.tsv"
    editable = not args.record and args.labels is None  # found or from imucal's sections
    if editable:
        write_text_atomic(labels_path, labels.format_labels(segments, src))
    for name, rec in records.items():
        write_record(record_path(out, serial, name), rec)
    print(segmentation.plan_summary(records))
    first = record_path(out, serial, next(iter(records))).name
    print(f"written: {len(records)} records to {out}/ ({first} …)")
    if editable:
        print(f"to correct the cut: edit {labels_path} and run again with --labels {labels_path}")


def _others_there(out: Path, serial: str, paths: list[Path]) -> None:
    """A note on this serial's other records in ``out``: calibrate reads them too."""
    others = sorted(
        p.name
        for p in out.glob(f"{serial}_*.txt")
        if p not in set(paths) and not p.name.endswith("_result.txt")
    )
    if others:
        print(
            f"note: {out}/ also holds {', '.join(others)}, not written by this import: "
            "calibrate --from-dir uses them too",
            file=sys.stderr,
        )


def _warn_timing(records: dict[str, Record]) -> None:
    for line in spacing.timing_warnings(records):
        print(line, file=sys.stderr)


def cli_import(p: argparse.ArgumentParser) -> Command[ImportOptions]:
    """Fill in the ``import`` subparser; returns the command."""
    add_arguments(p)
    return Command(import_options, run)
