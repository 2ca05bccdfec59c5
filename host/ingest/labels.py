"""The found segments as the user sees and corrects them: the printed table and the labels file.

The import prints one row per segment (start, duration, what was found, the label it got, its
quality and the reason for the label) and writes the same rows to ``SERIAL_segments.tsv``. The
user edits the label column (or the times, or the ``heading_deg`` column: the cube's placement
heading on the plate, written into the record as ``placement_heading_deg``) and imports again
with ``--labels``: the file then defines the records. Rows the plan left out keep ``-`` and say
why (an alternative for a record is named so): relabelling one and setting the chosen row to
``-`` swaps them.
"""

from __future__ import annotations

import math
import os
import re
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path

import numpy as np

from host.ingest.gaps import gap_between, gap_starts
from host.ingest.importing import Stream
from host.ingest.reading import Segment
from host.ingest.stillness import SegmentationError, attitude, axis_text
from host.session.records import MOVE_NAME_RE, POSE_NAME_RE, WARMUP_NAME
from host.session.spacing import trapezoid

LABELS_HEADER = "# imu-bench segments v2"
#: the column-names line; a file whose names line lacks ``heading_deg`` (v1) carries none
_COLUMNS = ("row", "start_s", "end_s", "label", "heading_deg", "found", "quality", "reason")
#: a repeat's suffix: up to 8 letters or digits (a longer one made a file name the disk refused)
_LABEL_RE = re.compile(r"^(?P<axis>[xyz])_(?P<dir>up|dn|ccw|cw)(?:_(?P<rep>[0-9A-Za-z]{1,8}))?$")
#: the versions of the labels file this program reads (v1: no heading_deg column)
_VERSIONS = ("v1", "v2")
#: how far a row's times may reach past the stream's first and last sample, s (hand-edited)
_SLACK_S = 0.5
#: a turn record turns at least this far about its axis, ° (a rest labelled as a turn: not)
_MIN_TURN_DEG = 180.0


def _t3(v: np.ndarray) -> tuple[float, float, float]:
    return (float(v[0]), float(v[1]), float(v[2]))


def format_table(segments: list[Segment]) -> str:
    """The printed table: row, start, duration, found, label; under each row its quality and
    the reason for the label (indented, so that a narrow terminal wraps them under the row)."""
    lines = [
        f"{'#':>3} {'start s':>9} {'dur s':>7}  {'found':<24} label",
        f"{'':6}quality; ↳ the reason for the label",
    ]
    for i, s in enumerate(segments, start=1):
        lines.append(f"{i:>3} {s.t0_s:>9.2f} {s.duration_s:>7.2f}  {s.found:<24} {s.label}")
        if s.quality:
            lines.append(f"{'':6}{s.quality}")
        if s.reason:
            lines.append(f"{'':6}↳ {s.reason}")
    return "\n".join(lines) + "\n"


def format_labels(segments: list[Segment], source: str) -> str:
    """The labels file (TSV) the user edits: one row per segment, times in s of the stream."""
    out = [
        f"{LABELS_HEADER} of {source}",
        "# Edit the label column (x_up … z_dn, x_ccw … z_cw, x_up_2 for a repeat, warmup, "
        "pose_01, move_01_02, '-' to leave a row out),",
        "# or the start/end times; add rows for what was missed. heading_deg: where the cube's "
        "reference axis",
        "# (the first of +x, +y, +z not up) pointed, ° counter-clockwise seen from above from "
        "the fence",
        "# (0, 90, 180, 270 against a fence; '-' if not known). Then run the same import with "
        "--labels THIS_FILE.",
        "# " + "\t".join(_COLUMNS),
    ]
    for i, s in enumerate(segments, start=1):
        h = "-" if s.heading_deg is None else f"{s.heading_deg:g}"
        out.append(
            f"{i}\t{s.t0_s:.3f}\t{s.t1_s:.3f}\t{s.label}\t{h}\t{s.found}\t{s.quality}\t{s.reason}"
        )
    return "\n".join(out) + "\n"


def valid_label(label: str) -> bool:
    """A record name the import writes: x_up … z_cw (optional _repeat suffix), warmup, a pose
    (pose_01) or a move (move_01_02)."""
    return label == WARMUP_NAME or bool(
        _LABEL_RE.match(label) or POSE_NAME_RE.match(label) or MOVE_NAME_RE.match(label)
    )


def read_labels(path: str | os.PathLike[str], stream: Stream) -> list[Segment]:
    """Segments from a labels file (:func:`format_labels`, edited): each row's start/end
    times (s) and label; turns are measured from the stream (angle about the label's axis)."""
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8-sig")  # an editor's byte-order mark is no text
    except OSError as exc:
        raise SegmentationError(
            f"{p}: cannot read the labels file ({exc.strerror or exc})"
        ) from exc
    except UnicodeDecodeError as exc:
        raise SegmentationError(
            f"{p}: not a labels file (byte {exc.start} is not UTF-8 text); give the "
            "SERIAL_segments.tsv the import wrote, edited as text"
        ) from None
    return parse_labels(text, str(p), stream)


def parse_labels(text: str, source: str, stream: Stream) -> list[Segment]:
    """The segments of a labels file's text (see :func:`read_labels`); ``source`` names it."""
    segs: list[Segment] = []
    seen: dict[str, int] = {}
    for lineno, f, col_heading in _rows(text, source):
        where = f"{source}:{lineno}"
        if len(f) < 4:
            raise SegmentationError(f"{where}: expected row, start_s, end_s, label")
        label = f[3].strip()
        if label == "-":
            continue
        if not valid_label(label):
            raise SegmentationError(
                f"{where}: label {label!r} is not a record name (x_up … z_dn, x_ccw … z_cw, "
                "x_up_2, warmup, pose_01, move_01_02, or - to leave the row out)"
            )
        if label in seen:
            raise SegmentationError(
                f"{where}: label {label} is also on line {seen[label]}; name a repeat {label}_2"
            )
        seen[label] = lineno
        start, stop = _samples(f, stream, where)
        segs.append(
            _row_segment(stream, start, stop, label, _heading(f, col_heading, where), where)
        )
    if not segs:
        raise SegmentationError(f"{source}: no labelled rows (every label is '-')")
    segs.sort(key=lambda s: s.start)
    # two rests (statics, poses), or two motions (turns, moves), on one sample (a turn's window
    # reaches into the rests around it by design; the warm-up is kept apart)
    for group in ("rest", "motion"):
        _no_overlap([s for s in segs if _group(s.label) == group], source)
    return segs


def _rows(text: str, source: str) -> Iterator[tuple[int, list[str], int | None]]:
    """The data rows of a labels file: (line number, fields, heading_deg's column or None);
    SegmentationError on a version this program does not read."""
    col_heading: int | None = None
    for lineno, raw in enumerate(text.splitlines(), start=1):
        line = raw.strip()
        names = line.lstrip("#").split()
        version = line.removeprefix(LABELS_HEADER[:-2]).split(" ", 1)[0]
        if line.startswith(LABELS_HEADER[:-2]) and version not in _VERSIONS:
            raise SegmentationError(
                f"{source}:{lineno}: labels file {version}; this program reads "
                f"{' and '.join(_VERSIONS)}: write it again with this program's import"
            )
        if line.startswith("#") and names[:4] == list(_COLUMNS[:4]):
            col_heading = names.index("heading_deg") if "heading_deg" in names else None
            continue
        if not line or line.startswith("#"):
            continue
        yield lineno, (line.split("\t") if "\t" in line else line.split()), col_heading


def _samples(f: list[str], stream: Stream, where: str) -> tuple[int, int]:
    """A row's start and end times as samples ``start`` … ``stop − 1`` of the stream."""
    t = stream.t_s
    try:
        t0, t1 = float(f[1]), float(f[2])
    except ValueError:
        raise SegmentationError(f"{where}: start_s and end_s must be numbers") from None
    if not t1 > t0:
        raise SegmentationError(f"{where}: end_s must be after start_s")
    if t0 < t[0] - _SLACK_S or t1 > t[-1] + _SLACK_S:
        raise SegmentationError(
            f"{where}: {t0:g}..{t1:g} s reaches past the stream, which spans "
            f"{t[0]:.3f}..{t[-1]:.3f} s: give times within it"
        )
    start = int(np.searchsorted(t, t0, side="left"))
    stop = int(np.searchsorted(t, t1, side="right"))
    if stop - start < 2:
        raise SegmentationError(
            f"{where}: {t0:g}..{t1:g} s holds fewer than 2 samples (the stream spans "
            f"{t[0]:.3f}..{t[-1]:.3f} s)"
        )
    return start, stop


def _group(label: str) -> str | None:
    """'rest' (a static or a pose), 'motion' (a turn or a move) or None (the warm-up)."""
    if POSE_NAME_RE.match(label):
        return "rest"
    if MOVE_NAME_RE.match(label):
        return "motion"
    m = _LABEL_RE.match(label)
    if m is None:
        return None
    return "rest" if m.group("dir") in ("up", "dn") else "motion"


def _row_segment(
    stream: Stream, start: int, stop: int, label: str, heading: float | None, where: str
) -> Segment:
    """The segment of one labelled row (samples ``start`` … ``stop − 1``)."""
    t = stream.t_s
    t0, t1 = float(t[start]), float(t[stop - 1])
    if label == WARMUP_NAME or POSE_NAME_RE.match(label):
        up = attitude(stream.accel[start:stop].mean(axis=0))[1]
        note = "(kept apart from the plan)" if label == WARMUP_NAME else "(a pose)"
        return Segment(start, stop, t0, t1, "labelled", label, f"from the labels file {note}",
                       _t3(up))  # fmt: skip
    if MOVE_NAME_RE.match(label):
        _no_gap(stream, start, stop, label, where, "move")
        return Segment(start, stop, t0, t1, "labelled", label, "from the labels file (a move)")
    m = _LABEL_RE.match(label)
    assert m
    axis, d = m.group("axis"), m.group("dir")
    if d in ("up", "dn"):
        up = np.zeros(3)
        up["xyz".index(axis)] = 1.0 if d == "up" else -1.0
        found, _, off = attitude(stream.accel[start:stop].mean(axis=0))
        if found != f"{axis}_{d}":
            raise SegmentationError(
                f"{where}: {label} on {t0:g}..{t1:g} s, but there gravity is along "
                + (f"{found} ({off:.0f}° off)" if found != "tilted" else "no face's axis")
                + ": correct the label or the times"
            )
        return Segment(start, stop, t0, t1, "labelled", label, "from the labels file", _t3(up),
                       heading_deg=heading)  # fmt: skip
    seg = _turn_from_label(stream, start, stop, label, axis, d, where)
    return replace(seg, heading_deg=heading)


def _no_overlap(segs: list[Segment], source: str) -> None:
    """SegmentationError naming the first two of ``segs`` (sorted by start) that overlap."""
    for a, b in zip(segs, segs[1:], strict=False):
        if b.start < a.stop:
            raise SegmentationError(
                f"{source}: {a.label} ({a.t0_s:.3f}..{a.t1_s:.3f} s) and {b.label} "
                f"({b.t0_s:.3f}..{b.t1_s:.3f} s) overlap: a sample belongs to one record; "
                "correct the times"
            )


def _heading(fields: list[str], col: int | None, where: str) -> float | None:
    """The row's placement heading, ° in [0, 360) (None: no such column, or '-'/empty)."""
    if col is None or col >= len(fields):
        return None
    txt = fields[col].strip()
    if txt in ("", "-"):
        return None
    try:
        deg = float(txt)
    except ValueError:
        deg = math.nan
    if not math.isfinite(deg):
        raise SegmentationError(
            f"{where}: heading_deg {txt!r} is not a number of degrees (0, 90, 180, 270 against "
            "a fence; - if not known)"
        )
    deg %= 360.0
    return 0.0 if deg >= 360.0 else deg  # −1e-300 % 360 rounds to 360.0


def _no_gap(stream: Stream, start: int, stop: int, label: str, where: str, what: str) -> None:
    """SegmentationError when samples ``start`` … ``stop − 1`` span a gap in time."""
    t = stream.t_s
    gaps = gap_starts(t)
    if gap_between(gaps, start, stop - 1):
        g = int(gaps[np.searchsorted(gaps, start, side="right")])
        raise SegmentationError(
            f"{where}: {label} spans a gap in the time column ({t[g - 1]:.3f} s to {t[g]:.3f} s, "
            f"no samples): a {what} is never integrated across one; correct the times"
        )


def _turn_from_label(
    stream: Stream, start: int, stop: int, label: str, axis: str, d: str, where: str
) -> Segment:
    t, acc, gyr = stream.t_s, stream.accel, stream.gyro
    _no_gap(stream, start, stop, label, where, "turn")
    k = "xyz".index(axis)
    sign_up = 1.0 if acc[start:stop, k].mean() >= 0 else -1.0
    up = np.zeros(3)
    up[k] = sign_up
    angle = float(trapezoid(t[start:stop], gyr[start:stop]) @ up)
    n = max(1, round(abs(angle) / 360.0))
    direction = 1 if d == "ccw" else -1
    if abs(angle) < _MIN_TURN_DEG:
        raise SegmentationError(
            f"{where}: {label} turned {angle:+.0f}° about {axis_text(up)}: no turn; correct "
            "the times, or label the row - (a rest) or a face"
        )
    if angle * direction < 0:
        raise SegmentationError(
            f"{where}: {label} turned {angle:+.0f}° about {axis_text(up)}, the other way: "
            f"label it {axis}_{'cw' if d == 'ccw' else 'ccw'}"
        )
    q = f"{n} turn{'s' if n > 1 else ''}, {angle:+.1f}° about {axis_text(up)} (labelled)"
    return Segment(
        start, stop, float(t[start]), float(t[stop - 1]), "labelled", label, q, _t3(up), n,
        direction,
    )  # fmt: skip
