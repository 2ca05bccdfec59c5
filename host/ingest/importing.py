"""Foreign data in: column files, imucal sessions and the project's captures as one stream.

Everything here turns a file into a :class:`Stream` — true sample times (s), specific force
(m/s²), rate (°/s) and temperature (°C) in the project's chip axes — and names the user's file,
line and column in every message. Cutting the stream into records is
:mod:`host.ingest.segmentation`'s job; nothing here assumes the data came from the bench.

Options of ``python3 -m host import`` (spellings fixed by issue 15):

- ``--columns t,ax,ay,az,gx,gy,gz,temp``: what each column of the file is, in order; ``skip``
  ignores a column; ``t`` and ``temp`` are optional (without ``t``, ``--rate HZ`` gives the
  nominal sample rate).
- ``--units t=ms,accel=m/s2,gyro=deg/s``: ``t`` in ``s|ms|us``; ``accel`` in ``m/s2|g`` or
  ``counts:LSB_PER_G``; ``gyro`` in ``deg/s|rad/s`` or ``counts:LSB_PER_DPS``; ``temp`` in ``C``.
  ``g`` is standard gravity 9.80665 m/s² (what loggers mean by g).
- ``--axes x,-y,z``: entry i is the file's axis (with sign) that becomes our axis i, for both
  sensors: ``--axes y,x,-z`` makes our x the file's y, our y the file's x, our z minus the
  file's z (e.g. NED body axes to the chip's).
"""

from __future__ import annotations

import json
import math
import os
import re
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from host.errors import UserError
from host.ingest.gaps import out_of_range, out_of_range_text

#: standard gravity, m/s²: the "g" of a logger that writes accelerations in g
STANDARD_G = 9.80665
#: filled into the temperature column when the file has none (the record format needs one);
#: meta ``temperature: not recorded`` says it is not a measurement
NO_TEMPERATURE_C = 25.0

COLUMN_NAMES = ("t", "ax", "ay", "az", "gx", "gy", "gz", "temp", "skip")
_REQUIRED = ("ax", "ay", "az", "gx", "gy", "gz")
_TIME_UNITS = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "µs": 1e-6}
_ACCEL_UNITS = {"m/s2": 1.0, "m/s^2": 1.0, "mps2": 1.0, "g": STANDARD_G}
_GYRO_UNITS = {"deg/s": 1.0, "dps": 1.0, "°/s": 1.0, "rad/s": 180.0 / math.pi}
_COUNTS_RE = re.compile(r"^counts:(?P<scale>[0-9.eE+-]+)$")
_AXIS_RE = re.compile(r"^(?P<sign>[+-]?)(?P<axis>[xyz])$")


class ForeignFileError(UserError):
    """A foreign file that cannot be read as asked (message names the file, line, column)."""


@dataclass(frozen=True, eq=False)
class Stream:
    """A continuous stream of samples in the project's units and chip axes.

    ``t_s`` (N,) true sample times in s (from the file's clock; non-decreasing), ``accel``
    (N,3) m/s², ``gyro`` (N,3) °/s, ``temp`` (N,) °C (``NO_TEMPERATURE_C`` when not recorded,
    see ``meta['temperature']``), ``meta`` how it was read (source, column map, units, axes),
    ``lines`` (N,) the file's line number of each sample (None: not from a text file) and
    ``notes`` what was left out of the file, one line each (rows out of range).
    """

    t_s: np.ndarray
    accel: np.ndarray
    gyro: np.ndarray
    temp: np.ndarray
    meta: dict[str, str] = field(default_factory=dict)
    lines: np.ndarray | None = None
    notes: tuple[str, ...] = ()

    def __len__(self) -> int:
        return int(self.t_s.shape[0])


@dataclass(frozen=True)
class Units:
    """Scale factors from the file's units to s, m/s², °/s (multiply)."""

    t: float = 1.0
    accel: float = 1.0
    gyro: float = 1.0
    text: str = "t=s,accel=m/s2,gyro=deg/s"


# ---- option parsing -------------------------------------------------------------------------
def parse_columns(text: str) -> tuple[str, ...]:
    """``'t,ax,ay,az,gx,gy,gz,temp'`` -> names; UserError on an unknown or repeated name or a
    missing sensor axis."""
    names = tuple(p.strip().lower() for p in text.split(",") if p.strip())
    for n in names:
        if n not in COLUMN_NAMES:
            raise ForeignFileError(
                f"--columns: unknown column name {n!r}; use {', '.join(COLUMN_NAMES)}"
            )
    dup = sorted({n for n in names if n != "skip" and names.count(n) > 1})
    if dup:
        raise ForeignFileError(f"--columns: {', '.join(dup)} named twice")
    missing = [n for n in _REQUIRED if n not in names]
    if missing:
        raise ForeignFileError(f"--columns: no column for {', '.join(missing)} (name every axis)")
    return names


def _counts_scale(value: str, what: str, per: str) -> float | None:
    m = _COUNTS_RE.match(value)
    if not m:
        return None
    try:
        lsb = float(m.group("scale"))
    except ValueError:
        lsb = math.nan
    if not math.isfinite(lsb) or lsb <= 0:
        raise ForeignFileError(f"--units {what}=counts:N: N is counts per {per}, e.g. counts:16384")
    return 1.0 / lsb


def parse_units(text: str | None) -> Units:
    """``'t=ms,accel=g,gyro=rad/s'`` -> :class:`Units` (unnamed quantities keep s, m/s², °/s)."""
    t, a, g = 1.0, 1.0, 1.0
    given: dict[str, str] = {"t": "s", "accel": "m/s2", "gyro": "deg/s"}
    for part in (text or "").split(","):
        part = part.strip()
        if not part:
            continue
        key, sep, value = part.partition("=")
        key, value = key.strip().lower(), value.strip().lower()
        if not sep or not value:
            raise ForeignFileError(f"--units: {part!r} is not QUANTITY=UNIT (e.g. t=ms)")
        if key == "t":
            if value not in _TIME_UNITS:
                raise ForeignFileError(f"--units t={value}: use t=s, t=ms or t=us")
            t = _TIME_UNITS[value]
        elif key == "accel":
            c = _counts_scale(value, "accel", "g")
            if c is not None:
                a = c * STANDARD_G
            elif value in _ACCEL_UNITS:
                a = _ACCEL_UNITS[value]
            else:
                raise ForeignFileError(f"--units accel={value}: use m/s2, g or counts:LSB_PER_G")
        elif key == "gyro":
            c = _counts_scale(value, "gyro", "°/s")
            if c is not None:
                g = c
            elif value in _GYRO_UNITS:
                g = _GYRO_UNITS[value]
            else:
                raise ForeignFileError(
                    f"--units gyro={value}: use deg/s, rad/s or counts:LSB_PER_DPS"
                )
        elif key == "temp":
            if value not in ("c", "degc", "°c"):
                raise ForeignFileError(f"--units temp={value}: only °C (temp=C) is read")
        else:
            raise ForeignFileError(f"--units: unknown quantity {key!r}; use t, accel, gyro, temp")
        given[key] = value
    text_out = ",".join(f"{k}={v}" for k, v in given.items())
    return Units(t=t, accel=a, gyro=g, text=text_out)


def parse_axes(text: str | None) -> np.ndarray:
    """``'x,-y,z'`` -> the 3×3 signed permutation P with ours = P · file's (row i: our axis i).

    Each of x, y, z must appear once; a sign flips that axis."""
    if not text:
        return np.eye(3)
    parts = [p.strip().lower() for p in text.split(",")]
    if len(parts) != 3:
        raise ForeignFileError(f"--axes {text}: give three axes, e.g. x,-y,z")
    p = np.zeros((3, 3))
    for i, part in enumerate(parts):
        m = _AXIS_RE.match(part)
        if not m:
            raise ForeignFileError(f"--axes {text}: {part!r} is not an axis like x or -y")
        p[i, "xyz".index(m.group("axis"))] = -1.0 if m.group("sign") == "-" else 1.0
    if not np.allclose(np.abs(p).sum(axis=0), 1.0):
        raise ForeignFileError(f"--axes {text}: each of x, y and z must appear exactly once")
    return p


# ---- column files ---------------------------------------------------------------------------
def _is_number(s: str) -> bool:
    try:
        float(s)
    except ValueError:
        return False
    return True


def _split(line: str, delim: str | None) -> list[str]:
    fields = line.split(delim) if delim else line.split()
    if delim and fields and fields[-1].strip() == "":
        fields = fields[:-1]  # a trailing separator
    return [f.strip() for f in fields]


def _choose_delimiter(line: str, n_columns: int) -> str | None:
    """The separator that splits ``line`` into ``n_columns`` fields: ';', tab, ',' or
    whitespace, tried in that order; else the first one present."""
    candidates = [d for d in (";", "\t", ",") if d in line] + [None]
    for d in candidates:
        if len(_split(line, d)) == n_columns:
            return d
    return candidates[0]


def _delimiter_name(d: str | None) -> str:
    return {";": "';'", "\t": "tabs", ",": "','"}.get(d or "", "spaces")


def parse_column_text(
    text: str,
    source: str,
    columns: tuple[str, ...],
    units: Units | None = None,
    axes: np.ndarray | None = None,
    rate_hz: float | None = None,
) -> Stream:
    """Parse a column file (CSV/TSV/whitespace, optional header line, ``#`` comments).

    Raises :class:`ForeignFileError` naming ``source``, the line and the column for anything that
    does not match ``columns``. Times must not go backwards (equal times are allowed: bursty
    host time stamps); without a ``t`` column ``rate_hz`` gives t = n / rate.
    """
    units = units or Units()
    axes = np.eye(3) if axes is None else axes
    if "t" not in columns and not rate_hz:
        raise ForeignFileError(
            f"{source}: --columns has no time column t; give the sample rate with --rate HZ"
        )
    if rate_hz is not None and (not math.isfinite(rate_hz) or rate_hz <= 0):
        raise ForeignFileError(f"--rate {rate_hz}: must be a positive number of samples per second")
    lines, linenos, delim, header = _data_lines(text, source, columns)
    data = _fast_rows(lines, delim, len(columns))
    if data is None:  # something is wrong: find the first bad line and say what
        data = np.array(
            [_row(ln, no, delim, columns, source) for ln, no in zip(lines, linenos, strict=True)],
            dtype=np.float64,
        )
    col = {name: k for k, name in enumerate(columns) if name != "skip"}
    if "t" in col:
        t_s = _times(data[:, col["t"]], units.t, linenos, source)
    else:
        assert rate_hz is not None
        t_s = np.arange(len(lines), dtype=np.float64) / rate_hz
    accel = data[:, [col["ax"], col["ay"], col["az"]]] * units.accel @ axes.T
    gyro = data[:, [col["gx"], col["gy"], col["gz"]]] * units.gyro @ axes.T
    meta = {
        "source": Path(source).name,
        "importer": "columns",
        "columns": ",".join(columns),
        "units": units.text,
        "axes": axes_text(axes),
    }
    if header is not None:
        meta["header"] = ",".join(header)[:200]
    if "t" not in col:
        meta["rate_hz"] = f"{rate_hz:g}"
    if "temp" in col:
        temp = data[:, col["temp"]]
    else:
        temp = np.full(len(lines), NO_TEMPERATURE_C)
        meta["temperature"] = f"not recorded (column filled with {NO_TEMPERATURE_C:g})"
    stream = Stream(t_s, accel, gyro, temp, meta, np.asarray(linenos, dtype=np.int64))
    return _without_out_of_range(stream, source)


def _without_out_of_range(stream: Stream, source: str) -> Stream:
    """The stream without its rows out of any IMU's range (:mod:`host.ingest.gaps`), each
    named in ``notes``; ForeignFileError when no row is left."""
    bad = out_of_range(stream.accel, stream.gyro)
    if not np.any(bad):
        return stream
    assert stream.lines is not None
    note = out_of_range_text(source, stream.lines, stream.accel, stream.gyro, bad)
    if np.all(bad) or np.count_nonzero(~bad) < 2:
        raise ForeignFileError(f"{note.split(': out of')[0]}: out of any IMU's range in every "
                               "row; check the --units and --columns")  # fmt: skip
    keep = ~bad
    meta = dict(stream.meta)
    meta["rows_left_out"] = f"{int(np.count_nonzero(bad))} (out of range)"
    return Stream(stream.t_s[keep], stream.accel[keep], stream.gyro[keep], stream.temp[keep],
                  meta, stream.lines[keep], (*stream.notes, note))  # fmt: skip


def _data_lines(
    text: str, source: str, columns: tuple[str, ...]
) -> tuple[list[str], list[int], str | None, list[str] | None]:
    """A column file's rows of numbers, their line numbers, the separator and the header line
    (None: none); ForeignFileError for a header of the wrong width or no rows at all."""
    n_col = len(columns)
    delim: str | None = None
    header: list[str] | None = None
    lines: list[str] = []
    linenos: list[int] = []
    for lineno, raw in enumerate(text.splitlines(), start=1):
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        if not linenos and header is None:
            delim = _choose_delimiter(line, n_col)
            fields = _split(line, delim)
            numbers = [_is_number(f) for f, c in zip(fields, columns, strict=False) if c != "skip"]
            if not all(numbers):
                header = fields
                if len(fields) != n_col:
                    raise ForeignFileError(
                        f"{source}:{lineno}: the header has {len(fields)} columns (separated by "
                        f"{_delimiter_name(delim)}) but --columns names {n_col}"
                    )
                continue
        lines.append(line)
        linenos.append(lineno)
    if not lines:
        raise ForeignFileError(f"{source}: no rows of numbers in this file")
    return lines, linenos, delim, header


def _times(raw: np.ndarray, scale: float, linenos: list[int], source: str) -> np.ndarray:
    """The time column in s; ForeignFileError naming the line where it goes backwards, or when
    it does not advance."""
    t_s = raw * scale
    back = np.flatnonzero(np.diff(t_s) < 0)
    if back.size:
        i = int(back[0]) + 1
        raise ForeignFileError(
            f"{source}:{linenos[i]}: time goes backwards ({raw[i - 1]:g} then {raw[i]:g}); sort "
            "the file by time or name the right column t"
        )
    if t_s[-1] <= t_s[0] and len(t_s) > 1:
        raise ForeignFileError(f"{source}: the time column t does not advance")
    return np.asarray(t_s)


def _fast_rows(lines: list[str], delim: str | None, n_col: int) -> np.ndarray | None:
    """All rows at once (numpy's C parser); None when any line is not ``n_col`` finite
    numbers — then :func:`_row` finds the first bad one and names it."""
    try:
        vals = np.loadtxt(lines, delimiter=delim, dtype=np.float64, ndmin=2, comments=None)
    except ValueError:
        return None
    if vals.shape != (len(lines), n_col) or not np.all(np.isfinite(vals)):
        return None
    return np.asarray(vals)


def _row(
    line: str, lineno: int, delim: str | None, columns: tuple[str, ...], source: str
) -> list[float]:
    """One line's numbers (``skip`` columns read as 0), or ForeignFileError naming the line and
    the column."""
    fields = _split(line, delim)
    n_col = len(columns)
    if len(fields) != n_col:
        raise ForeignFileError(
            f"{source}:{lineno}: {len(fields)} columns (separated by "
            f"{_delimiter_name(delim)}), but --columns names {n_col} "
            f"({','.join(columns)}); fix --columns or the line"
        )
    vals: list[float] = []
    for k, f in enumerate(fields):
        if columns[k] == "skip":
            vals.append(0.0)
            continue
        try:
            v = float(f)
        except ValueError:
            raise ForeignFileError(
                f"{source}:{lineno}: column {k + 1} ({columns[k]}) is not a number: {f[:30]!r}"
            ) from None
        if not math.isfinite(v):
            raise ForeignFileError(
                f"{source}:{lineno}: column {k + 1} ({columns[k]}) is not a finite number: "
                f"{f[:30]!r}"
            )
        vals.append(v)
    return vals


def axes_text(axes: np.ndarray) -> str:
    """The ``--axes`` spelling of a signed permutation matrix (``x,-y,z``)."""
    out = []
    for row in np.asarray(axes):
        k = int(np.argmax(np.abs(row)))
        out.append(("-" if row[k] < 0 else "") + "xyz"[k])
    return ",".join(out)


def read_text(path: str | os.PathLike[str]) -> str:
    """UTF-8 (or Latin-1) text of a user's file; ForeignFileError naming it when unreadable."""
    p = Path(path)
    try:
        raw = p.read_bytes()
    except FileNotFoundError:
        raise ForeignFileError(f"{p}: no such file") from None
    except OSError as exc:
        raise ForeignFileError(f"{p}: cannot read ({exc.strerror or exc})") from exc
    if b"\x00" in raw[:4096]:
        raise ForeignFileError(
            f"{p}: a binary file, not columns of text (a capture must end in .cap)"
        )
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError:
        return raw.decode("latin-1")


# ---- imucal sessions ------------------------------------------------------------------------
#: imucal's section names -> ours (p: axis parallel to gravity's reaction = up, a: antiparallel)
IMUCAL_SECTIONS = {
    "x_p": "x_up",
    "x_a": "x_dn",
    "y_p": "y_up",
    "y_a": "y_dn",
    "z_p": "z_up",
    "z_a": "z_dn",
    "x_rot": "x_turn",
    "y_rot": "y_turn",
    "z_rot": "z_turn",
}
#: the columns imucal's session CSV holds (its first column is the sample number n_samples)
IMUCAL_COLUMNS = ("acc_x", "acc_y", "acc_z", "gyr_x", "gyr_y", "gyr_z")


def looks_like_imucal(text: str) -> bool:
    """True when the first line is an imucal session header (acc_x … gyr_z by name)."""
    first = next((ln for ln in text.splitlines() if ln.strip()), "")
    names = [f.strip().lower() for f in first.split(",")]
    return all(c in names for c in IMUCAL_COLUMNS)


def parse_imucal_stream(text: str, source: str, rate_hz: float | None) -> Stream:
    """imucal's session CSV (header with ``acc_x … gyr_z``, m/s² and °/s, no time column) ->
    the stream, t = n / ``rate_hz`` (s)."""
    if not rate_hz:
        raise ForeignFileError(
            f"{source}: imucal sessions have no time column; give the sampling rate with "
            "--rate HZ (imucal's sampling_rate_hz)"
        )
    lines = [ln for ln in text.splitlines() if ln.strip()]
    header = [f.strip().lower() for f in lines[0].split(",")]
    columns = tuple(
        {
            "acc_x": "ax",
            "acc_y": "ay",
            "acc_z": "az",
            "gyr_x": "gx",
            "gyr_y": "gy",
            "gyr_z": "gz",
        }.get(h, "skip")
        for h in header
    )
    stream = parse_column_text(text, source, columns, rate_hz=rate_hz)
    meta = dict(stream.meta)
    meta["importer"] = "imucal session"
    meta.pop("header", None)
    return replace(stream, meta=meta)


def parse_imucal_session(
    text: str, sections_text: str, source: str, sections_source: str, rate_hz: float | None
) -> tuple[Stream, list[tuple[str, int, int]]]:
    """imucal's session CSV (:func:`parse_imucal_stream`) and its section list JSON
    (``{"x_p": {"start": i, "end": j}, …}``, j exclusive) -> the stream (t = n / rate) and the
    sections as (our label, start, stop) sample indices."""
    stream = parse_imucal_stream(text, source, rate_hz)
    meta = dict(stream.meta)
    meta["sections"] = Path(sections_source).name
    try:
        raw = json.loads(sections_text)
    except ValueError as exc:
        raise ForeignFileError(f"{sections_source}: not valid JSON ({exc})") from exc
    if not isinstance(raw, dict):
        raise ForeignFileError(f"{sections_source}: expected an object of sections like x_p")
    out: list[tuple[str, int, int]] = []
    row = np.rint(stream.t_s * float(rate_hz or 1.0)).astype(np.int64)  # the file's sample n
    n = int(row[-1]) + 1
    for key, span in raw.items():
        label = IMUCAL_SECTIONS.get(str(key))
        if label is None:
            raise ForeignFileError(
                f"{sections_source}: unknown section {key!r}; imucal's are "
                f"{', '.join(IMUCAL_SECTIONS)}"
            )
        try:
            start, stop = int(span["start"]), int(span["end"])
        except (KeyError, TypeError, ValueError):
            raise ForeignFileError(
                f"{sections_source}: section {key} needs integer start and end"
            ) from None
        if not 0 <= start < stop <= n:
            raise ForeignFileError(
                f"{sections_source}: section {key} spans samples {start}..{stop}, but "
                f"{Path(source).name} has {n} samples"
            )
        # rows left out (out of range) shift the samples after them
        out.append((label, int(np.searchsorted(row, start)), int(np.searchsorted(row, stop))))
    return replace(stream, meta=meta), out


# ---- the project's captures -----------------------------------------------------------------
def read_capture_stream(path: str | os.PathLike[str]) -> Stream:
    """A ``.cap`` capture (raw bytes or IMUCAP01) -> its samples on the device clock.

    Times are the device's µs time stamps (unwrapped); if the board was reset during the
    capture the pieces are joined on the host clock when the capture has arrival times, else
    only the longest piece is kept (with a note in ``meta``). Without a reset ``meta`` holds
    ``device_clock_s_at_t0``, the device clock (s since power-on) at t = 0: the records then
    carry their power-on time as the dialogue's do."""
    from host.timing.timeline import build_timeline
    from host.wire import sensor
    from host.wire.bulk import (
        baud_from_hello,
        decode_file,
        full_scale_from_hello,
        product_id_from_hello,
        samples_to_physical,
        unreadable,
    )
    from host.wire.frames import bus_meta

    p = Path(path)
    result, arrivals = decode_file(p)
    if (stop := unreadable(result)) is not None:  # no scale to read its samples by
        raise ForeignFileError(f"{p}: byte {stop[0]}: {stop[1]}; its samples cannot be scaled "
                               "as they were measured: nothing imported")  # fmt: skip
    s = result.samples
    if s.size < 2:
        raise ForeignFileError(f"{p}: no IMU samples decoded from this capture")
    timeline = build_timeline(s, arrivals, baud=baud_from_hello(result.others))
    product_id = product_id_from_hello(result.others)
    phys = samples_to_physical(s, *full_scale_from_hello(result.others), product_id)
    meta = {"source": p.name, "importer": "capture", "units": "device counts (HELLO full scale)"}
    meta |= sensor.identity_meta(None, product_id)
    statuses = [f for _, f in result.others if f.name == "STATUS"]
    meta |= bus_meta(int(statuses[-1].fields["flags"]) if statuses else None)
    sel = slice(0, s.size)
    if len(timeline.segments) == 1:
        t_s = (timeline.device_us - timeline.device_us[0]) / 1e6
        meta["device_clock_s_at_t0"] = f"{timeline.device_us[0] / 1e6:.6f}"
    elif np.all(np.isfinite(timeline.host_ns)):
        t_s = (timeline.host_ns - timeline.host_ns[0]) / 1e9
        meta["clock"] = f"{len(timeline.segments)} board resets joined on the host clock"
    else:
        seg = max(timeline.segments, key=lambda g: g.stop - g.start)
        sel = slice(seg.start, seg.stop)
        t_s = (timeline.device_us[sel] - timeline.device_us[seg.start]) / 1e6
        meta["clock"] = (
            f"{len(timeline.segments)} pieces between board resets; kept the longest "
            f"({seg.stop - seg.start} samples)"
        )
    accel = np.column_stack([phys[k][sel] for k in ("ax", "ay", "az")])
    gyro = np.column_stack([phys[k][sel] for k in ("gx", "gy", "gz")])
    order = np.argsort(t_s, kind="stable")
    return Stream(
        t_s=np.asarray(t_s)[order],
        accel=accel[order],
        gyro=gyro[order],
        temp=np.asarray(phys["temp"][sel])[order],
        meta=meta,
    )
