"""Measurement records: one text table per static attitude or turn (method.md §6).

A record file is plain UTF-8 text::

    # imu-bench record v1            <- optional header: '#' lines, 'key: value' go to meta
    # serial: S123
    # record: x_up
    0.0<TAB>Ax<TAB>Ay<TAB>Az<TAB>Gx<TAB>Gy<TAB>Gz<TAB>temp      <- data rows, 8 numeric columns
    ...
    ________________________________                 <- a line of underscores
    mean<TAB>Ax<TAB>...<TAB>temp                     <- 7 means (label optional)
    std<TAB>Ax<TAB>...<TAB>temp                      <- 7 standard deviations (label optional)

Columns: time since the start beep in ms (1 decimal, device clock); Ax Ay Az in m/s²
(4 decimals); Gx Gy Gz in °/s (3 decimals); temperature in °C (1 decimal). Files without any
header and without the 'mean'/'std' labels (as the source program wrote them) are accepted.
File names are ``SERIAL_name.txt`` (method.md §6): :mod:`host.session.directory`.

This module is the format alone (text <-> :class:`Record`), so that the reader and the
writer cannot drift apart; the files on disk are :mod:`host.session.directory`.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field

import numpy as np

from host.errors import InputError
from host.session.rowtext import (
    UNDERSCORES_RE,
    format_rows,
    read_rows,
    spacing_problem,
    underscores_at_end,
)

RECORD_FORMAT_VERSION = 1
#: fewer data rows than this cannot be calibrated with (no std): such a record is refused
MIN_RECORD_ROWS = 2
STATIC_NAMES = ("x_up", "x_dn", "y_up", "y_dn", "z_up", "z_dn")
#: ccw = positive rotation about the up axis, seen from above; cw = negative
TURN_NAMES = ("x_ccw", "x_cw", "y_ccw", "y_cw", "z_ccw", "z_cw")

#: the fixed recording window of a turn record, s, for 1/2/3 turns (method.md §4): the same for
#: CW and CCW so that bias·T cancels between the pair
TURN_WINDOWS_S = {1: 7.0, 2: 12.0, 3: 15.0}


def turn_window_s(turns: int) -> float:
    """Recording window of an n-turn record, s: 7/12/15 for 1/2/3 (method.md §4), and 4 s more
    per turn beyond (15 + 4·(n − 3))."""
    return TURN_WINDOWS_S.get(turns, 15.0 + 4.0 * (turns - 3))


#: session time of a record's first sample, in its header (live and simulated records alike):
#: ``power_on_s`` s since the sensor was powered (device clock, unwrapped; the workbench's time
#: terms read it) and ``session_s`` s since the calibration session began
TIME_KEYS = ("power_on_s", "session_s")

#: how the cube was placed, in its header: degrees, counter-clockwise seen from above, from the
#: fence (the ruler) to the record's reference axis (the first of +x, +y, +z not along up) at
#: the record's first sample; a turn's rests follow at this heading + the angle turned. Absent:
#: the heading is unknown (the model then does not assume one)
HEADING_KEY = "placement_heading_deg"

#: why a record that stops when it has enough stopped (``calibrate --plan adaptive``,
#: :mod:`host.workbench.stopping`): a static's σ of its mean, or the turns about an axis
STOPPED_KEY = "stopped"
#: the worst σ/tolerance an adaptive plan measured towards (``calibrate --plan adaptive
#: --target``), in the header of each of its records: the report says whether it was met
TARGET_KEY = "plan_target"

#: which sensor a record measured, in its header (live records and imported captures):
#: :func:`host.wire.sensor.identity_meta` writes them
SENSOR_KEYS = ("who_am_i", "product_id", "sensor_revision")


#: names of the report/result files that live beside the records and are not records
#: the live dialogue's warm-up record (one attitude, temperature rising): read by ``thermal``,
#: not part of the calibration plan
WARMUP_NAME = "warmup"
NON_RECORD_NAMES = ("result", WARMUP_NAME)

_AXES = "xyz"
RECORD_NAME_RE = re.compile(r"^(?P<axis>[xyz])_(?P<dir>up|dn|ccw|cw)(?:_(?P<rep>[0-9A-Za-z]+))?$")
#: a rest at an attitude nobody set (no cube, no ``up``): ``pose_01``, ``pose_02``, …
POSE_NAME_RE = re.compile(r"^pose_(?P<n>[0-9]{2,})$")
#: the motion between two rests, from the last sample of the rest before to the first sample of
#: the rest after: ``move_01_02`` goes from ``pose_01`` to ``pose_02``
MOVE_NAME_RE = re.compile(r"^move_(?P<a>[0-9]{2,})_(?P<b>[0-9]{2,})$")
#: a move's header names the rests it joins: ``from: pose_01``, ``to: pose_02``
MOVE_FROM_KEY, MOVE_TO_KEY = "from", "to"
#: the record kinds (:attr:`Record.kind`), "unknown" aside
RECORD_KINDS = ("static", "turn", "rate", "pose", "move")
_HEADER_RE = re.compile(r"^imu-bench record v(?P<v>\d+)\s*$")
_META_RE = re.compile(r"^(?P<key>[^:]+?)\s*:\s?(?P<value>.*)$")
_KEY_OK_RE = re.compile(r"^[A-Za-z0-9_.\- ]+$")

#: printed decimals of the 8 columns (time, Ax, Ay, Az, Gx, Gy, Gz, temp)
DECIMALS = (1, 4, 4, 4, 3, 3, 3, 1)
#: decimals of the mean and std rows (7 columns, no time)
SUMMARY_DECIMALS = 4
#: how far a stored mean may be from the mean of the rows (rounding of rows and of the mean)
_MEAN_TOL = (2e-3, 2e-3, 2e-3, 2e-3, 2e-3, 2e-3, 0.06)


class RecordError(InputError):
    """A record file that cannot be read (message names the file and line)."""


def pose_name(number: int) -> str:
    """The name of the ``number``-th pose (1-based): ``pose_01``, … ``pose_100``."""
    if number < 1:
        raise ValueError(f"pose number {number}: poses are numbered from 1")
    return f"pose_{number:02d}"


def move_name(first: int, second: int) -> str:
    """The name of the move from pose ``first`` to pose ``second``: ``move_01_02``."""
    if first < 1 or second < 1 or first == second:
        raise ValueError(f"move {first} -> {second}: two different poses numbered from 1")
    return f"move_{first:02d}_{second:02d}"


def is_standard_name(name: str) -> bool:
    """A record name the bench or ``import`` gives: a face or turn (``x_up``, ``z_cw_2``), a
    pose (``pose_01``) or a move (``move_01_02``)."""
    return bool(RECORD_NAME_RE.match(name) or POSE_NAME_RE.match(name) or MOVE_NAME_RE.match(name))


@dataclass(frozen=True, eq=False)
class Record:
    """One measurement: a static attitude or a turn (method.md §6).

    Attributes: ``name`` (e.g. "x_up", "z_cw", "tilt_45_1"), ``t_ms`` (N,) ms since the start
    beep on the device clock, ``accel`` (N,3) m/s² (nominal conversion of counts, chip axes),
    ``gyro`` (N,3) °/s, ``temp`` (N,) °C, ``meta`` the ``# key: value`` header lines.

    Extra plans are described by meta: ``up: [ux, uy, uz]`` the up direction in chip axes
    (unit vector) for any static/turn record; ``kind: static|turn|rate|pose|move``;
    ``turns: n``; ``rate_dps`` and ``rate_axis`` (e.g. "+x" or "[0, 0, 1]") for rate-table
    records. A pose (``pose_01``) is a rest at an unknown attitude: it has no ``up``. A move
    (``move_01_02``) is the motion between two poses; ``from``/``to`` in its header (or its
    name) say which (:attr:`move_from`, :attr:`move_to`).
    """

    name: str
    t_ms: np.ndarray
    accel: np.ndarray
    gyro: np.ndarray
    temp: np.ndarray
    meta: dict[str, str] = field(default_factory=dict)

    def __post_init__(self) -> None:
        t = np.asarray(self.t_ms, dtype=np.float64).reshape(-1)
        n = t.shape[0]
        a = np.asarray(self.accel, dtype=np.float64).reshape(n, 3)
        g = np.asarray(self.gyro, dtype=np.float64).reshape(n, 3)
        tc = np.asarray(self.temp, dtype=np.float64).reshape(n)
        object.__setattr__(self, "t_ms", t)
        object.__setattr__(self, "accel", a)
        object.__setattr__(self, "gyro", g)
        object.__setattr__(self, "temp", tc)
        object.__setattr__(self, "meta", {str(k): str(v) for k, v in dict(self.meta).items()})

    # ---- classification -------------------------------------------------------------------
    @property
    def kind(self) -> str:
        """ "static" (gravity reference), "turn" (integral method), "rate" (rate table) or
        "unknown"."""
        k = self.meta.get("kind", "").strip().lower()
        if k in RECORD_KINDS:
            return k
        if POSE_NAME_RE.match(self.name):
            return "pose"
        if MOVE_NAME_RE.match(self.name):
            return "move"
        m = RECORD_NAME_RE.match(self.name)
        if m:
            return "static" if m.group("dir") in ("up", "dn") else "turn"
        if "rate_dps" in self.meta:
            return "rate"
        if "up" in self.meta:
            return "static"
        return "unknown"

    @property
    def up(self) -> np.ndarray:
        """Unit vector of the up direction in chip axes (from meta ``up`` or the name); a pose
        or a move has none (RecordError)."""
        if self.kind in ("pose", "move"):
            raise RecordError(
                f"record {self.name}: a {self.kind} has no up direction (its attitude is "
                "fitted, not set)"
            )
        if "up" in self.meta:
            return parse_vector(self.meta["up"], f"record {self.name}: meta 'up'")
        m = RECORD_NAME_RE.match(self.name)
        if not m:
            raise RecordError(f"record {self.name}: no up direction (name or meta 'up: [x,y,z]')")
        v = np.zeros(3)
        v[_AXES.index(m.group("axis"))] = -1.0 if m.group("dir") == "dn" else 1.0
        return v

    @property
    def axis(self) -> str:
        """'x'|'y'|'z': the axis that points up (static, turn) or the rate axis (rate)."""
        v = self._axis_vector()
        return _AXES[int(np.argmax(np.abs(v)))]

    @property
    def sign(self) -> int:
        """+1 for up / ccw (positive rate), -1 for dn / cw."""
        m = RECORD_NAME_RE.match(self.name)
        if self.kind == "turn":
            if m and "up" not in self.meta:
                return 1 if m.group("dir") == "ccw" else -1
            d = self.meta.get("direction", "").strip().lower()
            if d in ("ccw", "cw"):
                return 1 if d == "ccw" else -1
            if m:
                return 1 if m.group("dir") == "ccw" else -1
            raise RecordError(f"record {self.name}: turn direction unknown (meta 'direction')")
        if self.kind == "rate":
            return 1 if self.rate_dps >= 0 else -1
        v = self._axis_vector()
        return 1 if v[int(np.argmax(np.abs(v)))] > 0 else -1

    @property
    def move_from(self) -> str:
        """The pose a move starts from (header ``from:``, else its name: ``move_01_02`` ->
        ``pose_01``); RecordError for a record that is no move or names none."""
        return self._move_end(MOVE_FROM_KEY, "a")

    @property
    def move_to(self) -> str:
        """The pose a move ends at (header ``to:``, else its name: ``move_01_02`` ->
        ``pose_02``); RecordError for a record that is no move or names none."""
        return self._move_end(MOVE_TO_KEY, "b")

    def _move_end(self, key: str, group: str) -> str:
        if self.kind != "move":
            raise RecordError(f"record {self.name}: not a move, it has no {key!r} pose")
        text = self.meta.get(key, "").strip()
        if text:
            return text
        m = MOVE_NAME_RE.match(self.name)
        if m is None:
            raise RecordError(
                f"record {self.name}: a move names its poses in its header "
                f"('{MOVE_FROM_KEY}: pose_01', '{MOVE_TO_KEY}: pose_02')"
            )
        return pose_name(int(m.group(group)))

    @property
    def rate_dps(self) -> float:
        """Reference rate of a rate-table record, °/s (meta ``rate_dps``)."""
        try:
            return float(self.meta["rate_dps"])
        except (KeyError, ValueError) as exc:
            raise RecordError(f"record {self.name}: meta 'rate_dps' missing or bad") from exc

    @property
    def rate_axis(self) -> np.ndarray:
        """Unit vector of the rate-table axis in chip axes (meta ``rate_axis``)."""
        if "rate_axis" not in self.meta:
            raise RecordError(f"record {self.name}: meta 'rate_axis' missing")
        return parse_vector(self.meta["rate_axis"], f"record {self.name}: meta 'rate_axis'")

    @property
    def placement_heading_deg(self) -> float | None:
        """The cube's heading on the plate at the first sample, ° (meta :data:`HEADING_KEY`,
        counter-clockwise seen from above from the fence to the reference axis); None when the
        record does not say. RecordError when the header's value is not a finite number."""
        text = self.meta.get(HEADING_KEY)
        if text is None or not text.strip():
            return None
        try:
            value = float(text)
        except ValueError:
            value = math.nan
        if not math.isfinite(value):
            raise RecordError(
                f"record {self.name}: header {HEADING_KEY!r} is {text!r}, not a number of "
                "degrees (write e.g. '90', or delete the line when the heading is unknown)"
            )
        return value % 360.0

    def _axis_vector(self) -> np.ndarray:
        if self.kind == "rate":
            return self.rate_axis
        return self.up

    @property
    def duration_s(self) -> float:
        """Time between the first and the last sample, s."""
        return float(self.t_ms[-1] - self.t_ms[0]) / 1000.0 if len(self.t_ms) else 0.0

    def __len__(self) -> int:
        return int(self.t_ms.shape[0])


def parse_vector(text: str, what: str) -> np.ndarray:
    """'[0, 0.7071, 0.7071]' or '+x'/'-z' -> unit vector (normalised)."""
    s = text.strip().lower()
    if re.fullmatch(r"[+-]?[xyz]", s):
        v = np.zeros(3)
        v[_AXES.index(s[-1])] = -1.0 if s.startswith("-") else 1.0
        return v
    try:
        parts = [float(p) for p in s.strip("[]() ").replace(",", " ").split()]
    except ValueError:
        parts = []
    v = np.array(parts, dtype=np.float64)
    if v.shape != (3,) or not np.all(np.isfinite(v)) or np.linalg.norm(v) < 1e-9:
        raise RecordError(f"{what}: expected a vector like [0, 0, 1] or +z, got {text!r}")
    return v / float(np.linalg.norm(v))


# ---- writing ------------------------------------------------------------------------------
def _fmt(v: float, dec: int) -> str:
    s = f"{v:.{dec}f}"
    if s.startswith("-") and float(s) == 0.0:
        s = s[1:]
    return s


def name_problem(value: str) -> str | None:
    """What is wrong with ``value`` as a name kept in the records' header and the archive (an
    operator, a bench, a lot), or None. It must be printable text: an escape sequence or a line
    break in it would garble every listing that shows it."""
    bad = next((c for c in value if not c.isprintable()), None)
    if bad is None:
        return None
    return f"{value!r} holds a control character ({bad!r}); give printable text"


def format_record(record: Record) -> str:
    """The file text of a record (method.md §6), header first."""
    for k, v in record.meta.items():
        if not _KEY_OK_RE.match(k) or "\n" in v or "\r" in v:
            raise ValueError(f"meta key/value not writable: {k!r}: {v!r}")
    arrays = (record.t_ms, record.accel, record.gyro, record.temp)
    for a in arrays:
        if not np.all(np.isfinite(a)):
            raise ValueError(f"record {record.name}: non-finite sample values")
    lines = [f"# imu-bench record v{RECORD_FORMAT_VERSION}"]
    meta = dict(record.meta)
    meta["record"] = record.name
    for k, v in meta.items():
        lines.append(f"# {k}: {v}".rstrip())
    data = np.column_stack([record.t_ms, record.accel, record.gyro, record.temp])
    rows = format_rows(data, DECIMALS)
    if rows:
        lines.append(rows)
    lines.append("_" * 72)
    if rows:
        printed = np.loadtxt(rows.split("\n"), dtype=np.float64, comments=None, ndmin=2)
        mean = printed[:, 1:].mean(axis=0)
        std = printed[:, 1:].std(axis=0, ddof=1) if len(data) > 1 else np.zeros(7)
    else:
        mean = std = np.zeros(7)
    lines.append("mean\t" + "\t".join(_fmt(float(v), SUMMARY_DECIMALS) for v in mean))
    lines.append("std\t" + "\t".join(_fmt(float(v), SUMMARY_DECIMALS) for v in std))
    return "\n".join(lines) + "\n"


# ---- reading ------------------------------------------------------------------------------
def _numbers(fields: list[str]) -> list[float] | None:
    try:
        vals = [float(f) for f in fields]
    except ValueError:
        return None
    return vals


def _header_line(meta: dict[str, str], key: str, value: str, where: str) -> None:
    """Keep header ``key: value`` in ``meta``; RecordError when an earlier line gave ``key``
    another value (two ``# serial:`` lines: which one is the unit's?)."""
    if key in meta and meta[key] != value:
        raise RecordError(
            f"{where}: a second '{key}:' header line ({value!r}) contradicts the first "
            f"({meta[key]!r}); keep the one that is true"
        )
    meta[key] = value


def _check_times(t_ms: np.ndarray, meta: dict[str, str], source: str) -> None:
    """RecordError for time stamps no record has (:func:`host.session.rowtext.spacing_problem`)
    and for a session-time header (:data:`TIME_KEYS`) that is not a finite number of seconds."""
    for key in TIME_KEYS:
        try:
            v = float(meta.get(key, "0"))
        except ValueError:
            continue
        if not math.isfinite(v):
            raise RecordError(f"{source}: header '{key}: {meta[key]}' is not a finite number "
                              "of seconds; correct the line or remove it")  # fmt: skip
    problem = spacing_problem(t_ms)
    if problem:
        raise RecordError(f"{source}: {problem}")


@dataclass
class _RecordText:
    """A record file as it is read, line by line: its header (``meta``), the data rows, the
    mean and std rows after the underscores (``summary``), whether that line was passed and
    the last line that was not empty."""

    meta: dict[str, str] = field(default_factory=dict)
    rows: list[list[float]] = field(default_factory=list)
    summary: list[list[float]] = field(default_factory=list)
    in_summary: bool = False
    last_line: int = 0


def _comment_line(parsed: _RecordText, body: str, where: str) -> None:
    """A ``#`` line (``body`` after the ``#``): the format version, or a header line while no
    data row has come."""
    hm = _HEADER_RE.match(body)
    if hm:
        v = int(hm.group("v"))
        if v > RECORD_FORMAT_VERSION:
            raise RecordError(
                f"{where}: record format v{v} is newer than this program reads "
                f"(v{RECORD_FORMAT_VERSION}); update the host software"
            )
        return
    mm = _META_RE.match(body)
    if mm and not parsed.in_summary and not parsed.rows:
        _header_line(parsed.meta, mm.group("key").strip(), mm.group("value").strip(), where)


def _data_row(rows: list[list[float]], line: str, where: str) -> None:
    """One data row: eight finite numbers, its time not before the last row's."""
    vals = _numbers(line.split())
    if vals is None:
        raise RecordError(
            f"{where}: not a row of numbers ({line[:40]!r}); the file is damaged — "
            "re-measure this record"
        )
    if len(vals) != 8:
        raise RecordError(
            f"{where}: {len(vals)} columns, expected 8 (time, Ax, Ay, Az, Gx, Gy, Gz, "
            "temp); the file is truncated or damaged — re-measure this record"
        )
    if not all(math.isfinite(v) for v in vals):
        raise RecordError(f"{where}: non-finite value; re-measure this record")
    if rows and vals[0] < rows[-1][0]:
        raise RecordError(f"{where}: time goes backwards; the file is damaged")
    rows.append(vals)


def _summary_row(summary: list[list[float]], line: str, where: str) -> None:
    """The mean row, then the std row, after the underscores (labelled or not)."""
    fields = line.split()
    label_ok = fields[0].lower() in ("mean", "std")
    vals = _numbers(fields[1:] if label_ok else fields)
    if vals is None or len(vals) not in (7, 8) or len(summary) >= 2:
        raise RecordError(
            f"{where}: expected the mean and std rows after the underscores; the file is damaged"
        )
    if label_ok and fields[0].lower() != ("mean", "std")[len(summary)]:
        raise RecordError(f"{where}: expected the {('mean', 'std')[len(summary)]} row")
    summary.append(vals[-7:])


def _read_lines(lines: list[str], source: str) -> _RecordText:
    """Every line of a record file read into a :class:`_RecordText`, one at a time: the reader
    that names the first line that is wrong."""
    parsed = _RecordText()
    for lineno, raw in enumerate(lines, start=1):
        line = raw.strip()
        if not line:
            continue
        parsed.last_line = lineno
        where = f"{source}:{lineno}"
        if line.startswith("#"):
            _comment_line(parsed, line[1:].strip(), where)
        elif UNDERSCORES_RE.match(line):
            if parsed.in_summary:
                raise RecordError(f"{where}: a second line of underscores; the file is damaged")
            parsed.in_summary = True
        elif parsed.in_summary:
            _summary_row(parsed.summary, line, where)
        else:
            _data_row(parsed.rows, line, where)
    return parsed


def _read_whole(lines: list[str], source: str) -> tuple[_RecordText, np.ndarray] | None:
    """A well-formed record's lines read in one pass: its header line by line, its data rows
    at once (``np.loadtxt``), its mean and std rows; None when anything is out of the ordinary
    (then :func:`_read_lines` reads it line by line and names what is wrong)."""
    parsed = _RecordText()
    head = 0
    try:
        while head < len(lines) and (not lines[head].strip() or lines[head].lstrip()[0] == "#"):
            line = lines[head].strip()
            if line:
                _comment_line(parsed, line[1:].strip(), f"{source}:{head + 1}")
            head += 1
        bar = underscores_at_end(lines, head)
        if bar is None or not _summary_rows(parsed, lines, bar, source):
            return None
    except RecordError:
        return None
    data = read_rows(lines[head:bar], 8)
    if data is None:
        return None
    parsed.in_summary = True
    return parsed, data


def _summary_rows(parsed: _RecordText, lines: list[str], bar: int, source: str) -> bool:
    """The mean and std rows after the underscores at ``bar`` into ``parsed``: False when they
    are not just those two rows (and empty lines)."""
    for i in range(bar + 1, len(lines)):
        line = lines[i].strip()
        if line:
            if line[0] == "#" or UNDERSCORES_RE.match(line):
                return False
            _summary_row(parsed.summary, line, f"{source}:{i + 1}")
            parsed.last_line = i + 1
    return len(parsed.summary) == 2


def _check_complete(parsed: _RecordText, source: str) -> None:
    """The underscores, the mean and std rows and some data are there."""
    end = f"{source}:{parsed.last_line + 1}"
    if not parsed.in_summary:
        raise RecordError(
            f"{end}: no line of underscores after the data: the file is truncated "
            "(recording interrupted?) — re-measure this record"
        )
    if len(parsed.summary) < 2:
        raise RecordError(
            f"{end}: mean/std rows missing after the underscores: the file is "
            "truncated — re-measure this record"
        )
    if not parsed.rows:
        raise RecordError(f"{source}: no data rows; re-measure this record")


def _check_stored_mean(data: np.ndarray, stored: list[float], source: str) -> None:
    """The rows' mean of each column matches the stored mean row (:data:`_MEAN_TOL`)."""
    mean = data[:, 1:].mean(axis=0)
    bad = np.abs(mean - np.array(stored)) > np.array(_MEAN_TOL)
    if np.any(bad):
        col = ("Ax", "Ay", "Az", "Gx", "Gy", "Gz", "temp")[int(np.argmax(bad))]
        raise RecordError(
            f"{source}: the stored mean of {col} does not match the rows (rows missing or "
            "edited?); re-measure this record"
        )


def _record_name(meta: dict[str, str], name: str | None, source: str) -> str:
    """The record's name: ``name`` (from the file name), else its ``# record:`` line; the two
    agree when both are there."""
    rec_name = name or meta.get("record") or ""
    if not rec_name:
        raise RecordError(f"{source}: record name unknown (no '# record:' line, file name)")
    if "record" in meta and name and meta["record"] != name:
        raise RecordError(
            f"{source}: the header says record {meta['record']!r} but the file name says "
            f"{name!r}; rename the file"
        )
    return rec_name


def parse_record_text(text: str, source: str, name: str | None = None) -> Record:
    """Parse the text of a record file; ``source`` names it in messages (e.g. the path).

    Raises RecordError naming ``source:line`` for anything that is not a complete record.
    """
    lines = text.splitlines()
    fast = _read_whole(lines, source)
    if fast is not None:
        parsed, data = fast
    else:
        parsed = _read_lines(lines, source)
        _check_complete(parsed, source)
        data = np.array(parsed.rows, dtype=np.float64)
    _check_times(data[:, 0], parsed.meta, source)
    _check_stored_mean(data, parsed.summary[0], source)
    return Record(
        name=_record_name(parsed.meta, name, source),
        t_ms=data[:, 0],
        accel=data[:, 1:4],
        gyro=data[:, 4:7],
        temp=data[:, 7],
        meta=parsed.meta,
    )
