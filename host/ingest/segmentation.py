"""Cutting a continuous stream into the plan's records (method.md §3-§4, §6), and timing quality.

A stream from anywhere (a logger's CSV, a capture) has no beeps: the records are found in it.

1. **Stillness** (:func:`find_still`): over a moving window of ``STILL_WINDOW_S`` the standard
   deviation of every channel and the mean rate (bias removed) are compared with thresholds
   tuned from the data's own noise: the noise floor of a channel is the ``NOISE_QUANTILE``
   quantile of its moving standard deviation (the quietest tenth of the stream), the threshold
   ``THRESHOLD_FACTOR`` times that (never below ``MIN_ACCEL_STD``, ``MIN_GYRO_STD``); the mean
   rate must stay within ``max(MIN_RATE_DPS, RATE_FACTOR · gyro noise)`` of the still bias.
   A sample is still when every window holding it is; still runs shorter than
   ``MIN_STILL_S`` are dropped.
2. **Attitude** of a still run from gravity: the axis nearest the mean specific force (up =
   +g on that axis, method.md §3), with the angle off it as its quality.
3. **Turns**: the rotation about the up axis (bias of the still run before removed) is summed
   over the motions between still runs of the same attitude; a still run at a whole number of
   turns (within ``TURN_HEADING_TOL_DEG``) ends a turn, so turns made in steps with pauses count
   as one; the sign gives the direction (ccw = positive about up, §4).
4. **Choice**: per attitude, the longest still run is the static record; other still runs and
   the moves between attitudes are left out (label ``-``). The table can be corrected with a
   labels file (:func:`read_labels`), which then defines the segments.

Every integral uses the true sample times (trapezoid rule over ``t``), never a nominal rate.

Length (over 600 lines): finding the records, checking them and the labels file that lets a user
correct the cut are one algorithm with its own input/output format; kept together so the labels
file cannot drift from what the cut produces.
"""

from __future__ import annotations

import math
import os
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from host.errors import UserError
from host.ingest.importing import Stream
from host.session.records import STATIC_NAMES, TURN_NAMES, Record

# ---- stated thresholds ----------------------------------------------------------------------
STILL_WINDOW_S = 0.5  #: moving window of the stillness detector, s (at least 5 samples)
NOISE_QUANTILE = 0.10  #: the quietest tenth of windows gives each channel's noise floor
THRESHOLD_FACTOR = 4.0  #: a window moves when a channel's std exceeds this × its noise floor
MIN_ACCEL_STD = 0.005  #: m/s², floor of the accel std threshold (quantised, very quiet data)
MIN_GYRO_STD = 0.02  #: °/s, floor of the gyro std threshold
MIN_RATE_DPS = 0.5  #: °/s, floor of the mean-rate threshold
RATE_FACTOR = 10.0  #: mean-rate threshold = this × the gyro noise floor (if above the floor)
MIN_STILL_S = 1.0  #: still runs shorter than this are not still periods, s
AXIS_TOL_DEG = 25.0  #: gravity within this of an axis labels the attitude (else tilted)
TURN_HEADING_TOL_DEG = 45.0  #: a pause within this of a whole turn ends the turn
TURN_PAD_S = 0.5  #: a turn record reaches this far into the still runs around it, s
MIN_SPACING_S = 20e-6  #: a median sample spacing outside these bounds means a wrong time unit
MAX_SPACING_S = 2.0

# timing quality
GAP_MIN_MS = 50.0  #: a spacing above max(GAP_MIN_MS, GAP_FACTOR × median) is a gap
GAP_FACTOR = 3.0
WARN_GAP_SHARE = 0.02  #: warn when more than this share of a record's time is inside gaps
WARN_WORST_FACTOR = 10.0  #: … or when the worst gap exceeds this × the median spacing

LABELS_HEADER = "# imu-bench segments v1"
_LABEL_RE = re.compile(r"^(?P<axis>[xyz])_(?P<dir>up|dn|ccw|cw)(?:_(?P<rep>[0-9A-Za-z]+))?$")


class SegmentationError(UserError):
    """The stream cannot be cut into records as asked (message names the file/segment)."""


# ---- timing quality -------------------------------------------------------------------------
@dataclass(frozen=True)
class TimingQuality:
    """Sample spacing of one record: ``median_ms``, ``worst_gap_ms`` (largest spacing),
    ``gap_share`` (fraction of the duration inside spacings above ``gap_limit_ms``) and
    ``warning`` (share above ``WARN_GAP_SHARE`` or worst gap above ``WARN_WORST_FACTOR`` ×
    median)."""

    n: int
    median_ms: float
    worst_gap_ms: float
    gap_share: float
    gap_limit_ms: float
    warning: bool

    def describe(self) -> str:
        """One line: 'median 2.1 ms, worst gap 252 ms, 23 % of the time in gaps > 50 ms'."""
        return (
            f"median spacing {self.median_ms:.3g} ms, worst gap {self.worst_gap_ms:.3g} ms, "
            f"{100 * self.gap_share:.1f} % of the time in gaps > {self.gap_limit_ms:.3g} ms"
        )

    def meta(self) -> dict[str, str]:
        """Record metadata lines."""
        return {
            "timing_median_ms": f"{self.median_ms:.4g}",
            "timing_worst_gap_ms": f"{self.worst_gap_ms:.4g}",
            "timing_gap_share": f"{self.gap_share:.4f}",
            "timing_gap_limit_ms": f"{self.gap_limit_ms:.4g}",
            "timing_warning": "yes" if self.warning else "no",
        }


def timing_quality(t_s: np.ndarray) -> TimingQuality:
    """Spacing statistics of sample times ``t_s`` (s), see :class:`TimingQuality`."""
    t = np.asarray(t_s, dtype=np.float64)
    if t.size < 2:
        return TimingQuality(int(t.size), math.nan, math.nan, 0.0, GAP_MIN_MS, False)
    dt_ms = np.diff(t) * 1000.0
    median = float(np.median(dt_ms))
    worst = float(dt_ms.max())
    limit = max(GAP_MIN_MS, GAP_FACTOR * median)
    total = float(dt_ms.sum())
    share = float(dt_ms[dt_ms > limit].sum() / total) if total > 0 else 0.0
    warn = share > WARN_GAP_SHARE or (median > 0 and worst > WARN_WORST_FACTOR * median)
    return TimingQuality(int(t.size), median, worst, share, limit, bool(warn))


def trapezoid(t_s: np.ndarray, values: np.ndarray) -> np.ndarray:
    """∫ values dt over the true times ``t_s`` (s) by the trapezoid rule (method.md §4);
    ``values`` (N,) or (N,k) -> (unit)·s."""
    t = np.asarray(t_s, dtype=np.float64)
    v = np.asarray(values, dtype=np.float64)
    if t.size < 2:
        return np.zeros(v.shape[1:])
    return np.asarray(np.tensordot(np.diff(t), 0.5 * (v[1:] + v[:-1]), axes=(0, 0)))


def uniform_rate_error_deg(t_s: np.ndarray, gyro_dps: np.ndarray) -> float:
    """How far the gyro integral (°, largest channel) moves if the samples are assumed evenly
    spaced over the same span instead of at their true times ``t_s`` (s)."""
    t = np.asarray(t_s, dtype=np.float64)
    if t.size < 2:
        return 0.0
    uniform = np.linspace(t[0], t[-1], t.size)
    diff = trapezoid(uniform, gyro_dps) - trapezoid(t, gyro_dps)
    return float(np.max(np.abs(diff)))


# ---- stillness ------------------------------------------------------------------------------
@dataclass(frozen=True)
class Thresholds:
    """The stillness detector's settings, tuned from the stream: window (samples, s), noise
    floors and thresholds per channel (accel m/s², gyro °/s), the mean-rate limit (°/s), the
    still bias (°/s) and the shortest still run (s)."""

    window: int
    window_s: float
    accel_noise: np.ndarray
    gyro_noise: np.ndarray
    accel_std: np.ndarray
    gyro_std: np.ndarray
    rate_dps: float
    bias_dps: np.ndarray
    min_still_s: float

    def text(self) -> str:
        """One line for the record metadata and the printed table."""
        f3 = lambda v: "/".join(f"{x:.3g}" for x in v)  # noqa: E731
        return (
            f"window {self.window} samples ({self.window_s:.2f} s); still when std < accel "
            f"{f3(self.accel_std)} m/s², gyro {f3(self.gyro_std)} °/s ({THRESHOLD_FACTOR:g}× "
            f"the noise floor) and |rate − bias| < {self.rate_dps:.3g} °/s for ≥ "
            f"{self.min_still_s:g} s"
        )


def _moving(values: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """Moving mean and std (ddof 0) over windows of k samples: (N−k+1, C) each."""
    v0 = np.asarray(values, dtype=np.float64)
    centre = v0.mean(axis=0)
    v = v0 - centre  # better conditioned sums
    c1 = np.concatenate([np.zeros((1, v.shape[1])), np.cumsum(v, axis=0)])
    c2 = np.concatenate([np.zeros((1, v.shape[1])), np.cumsum(v * v, axis=0)])
    s1 = c1[k:] - c1[:-k]
    s2 = c2[k:] - c2[:-k]
    mean = s1 / k
    var = np.maximum(s2 / k - mean * mean, 0.0)
    return mean + centre, np.sqrt(var)


def _erode(window_ok: np.ndarray, n: int, k: int) -> np.ndarray:
    """Sample i is still when every window of k samples holding it is still."""
    bad = np.concatenate([[0], np.cumsum(~window_ok)])
    i = np.arange(n)
    lo = np.clip(i - k + 1, 0, len(window_ok))
    hi = np.clip(i + 1, 0, len(window_ok))
    return np.asarray((bad[hi] - bad[lo]) == 0)


def find_still(
    t_s: np.ndarray, accel: np.ndarray, gyro: np.ndarray
) -> tuple[np.ndarray, Thresholds]:
    """Per-sample stillness of a stream (times s, accel m/s², gyro °/s) and the thresholds
    used, tuned from the stream's own noise (see the module docstring)."""
    t = np.asarray(t_s, dtype=np.float64)
    n = t.size
    dt = float(np.median(np.diff(t))) if n > 1 else 0.02
    k = max(5, int(round(STILL_WINDOW_S / dt))) if dt > 0 else 5
    if n < 2 * k:
        raise SegmentationError(
            f"the stream has {n} samples, too short to find still periods ({2 * k} needed)"
        )
    _, a_std = _moving(accel, k)
    g_mean, g_std = _moving(gyro, k)
    a_noise = np.quantile(a_std, NOISE_QUANTILE, axis=0)
    g_noise = np.quantile(g_std, NOISE_QUANTILE, axis=0)
    a_thr = np.maximum(THRESHOLD_FACTOR * a_noise, MIN_ACCEL_STD)
    g_thr = np.maximum(THRESHOLD_FACTOR * g_noise, MIN_GYRO_STD)
    quiet = np.all(a_std < a_thr, axis=1) & np.all(g_std < g_thr, axis=1)
    bias = np.median(g_mean[quiet], axis=0) if np.any(quiet) else np.median(g_mean, axis=0)
    rate = max(MIN_RATE_DPS, RATE_FACTOR * float(g_noise.max()))
    ok = quiet & np.all(np.abs(g_mean - bias) < rate, axis=1)
    still = _erode(ok, n, k)
    thr = Thresholds(k, k * dt, a_noise, g_noise, a_thr, g_thr, rate, bias, MIN_STILL_S)
    return still, thr


def still_runs(t_s: np.ndarray, still: np.ndarray, min_s: float = MIN_STILL_S) -> list[range]:
    """Index ranges of consecutive still samples lasting at least ``min_s`` s."""
    s = np.concatenate([[False], np.asarray(still, bool), [False]])
    edges = np.flatnonzero(np.diff(s.astype(np.int8)))
    out = []
    for a, b in zip(edges[::2], edges[1::2], strict=True):
        if b - a >= 2 and t_s[b - 1] - t_s[a] >= min_s:
            out.append(range(int(a), int(b)))
    return out


# ---- attitude -------------------------------------------------------------------------------
def attitude(accel_mean: np.ndarray) -> tuple[str, np.ndarray, float]:
    """Label of the axis nearest the mean specific force (``x_up`` … ``z_dn``, or ``tilted``),
    the up unit vector of that axis and the angle between them (°)."""
    a = np.asarray(accel_mean, dtype=np.float64)
    norm = float(np.linalg.norm(a))
    k = int(np.argmax(np.abs(a)))
    up = np.zeros(3)
    up[k] = 1.0 if a[k] > 0 else -1.0
    angle = math.degrees(math.acos(min(1.0, abs(a[k]) / norm))) if norm > 0 else 90.0
    label = f"{'xyz'[k]}_{'up' if a[k] > 0 else 'dn'}" if angle <= AXIS_TOL_DEG else "tilted"
    return label, up, angle


def _axis_text(up: np.ndarray) -> str:
    k = int(np.argmax(np.abs(up)))
    return ("+" if up[k] > 0 else "-") + "xyz"[k]


# ---- segments -------------------------------------------------------------------------------
@dataclass(frozen=True)
class Segment:
    """A found (or labelled) piece of the stream: samples ``start`` … ``stop − 1``.

    ``found``: what the detector saw ("still +X", "turn +720° about +X", "move");
    ``label``: the record it becomes (``x_up``, ``x_ccw``, … or ``-`` for none);
    ``quality``: a short human note; ``up`` the up vector; ``turns``/``direction`` of a turn."""

    start: int
    stop: int
    t0_s: float
    t1_s: float
    found: str
    label: str
    quality: str
    up: tuple[float, float, float] = (0.0, 0.0, 1.0)
    turns: int = 0
    direction: int = 0

    @property
    def duration_s(self) -> float:
        """End minus start, s."""
        return self.t1_s - self.t0_s


def _t3(v: np.ndarray) -> tuple[float, float, float]:
    return (float(v[0]), float(v[1]), float(v[2]))


def segment_stream(stream: Stream) -> tuple[list[Segment], Thresholds]:
    """Find still periods, their attitudes and the turns between them (module docstring);
    -> segments in time order (still runs, turns, moves) with proposed labels, thresholds."""
    t, acc, gyr = stream.t_s, stream.accel, stream.gyro
    check_time_unit(stream)
    still, thr = find_still(t, acc, gyr)
    runs = still_runs(t, still, thr.min_still_s)
    if not runs:
        raise SegmentationError(
            f"{stream.meta.get('source', 'stream')}: no still period of {MIN_STILL_S:g} s or "
            f"more found ({thr.text()}); is the time column in the right unit?"
        )
    info = []
    for r in runs:
        am = acc[r].mean(axis=0)
        label, up, angle = attitude(am)
        info.append((r, label, up, angle, am, acc[r].std(axis=0), gyr[r].mean(axis=0)))
    _check_gravity(stream, [float(np.linalg.norm(x[4])) for x in info])

    pad = TURN_PAD_S
    segs: list[Segment] = []
    # turns: walk the heading about the up axis over still runs of the same attitude
    anchor = 0
    heading = 0.0
    turn_spans: list[tuple[int, int, float]] = []  # (anchor run, end run, angle °)
    for j in range(1, len(info)):
        r_prev, lab_prev, up_prev, *_rest = info[j - 1]
        bias_prev = info[j - 1][6]
        r_j, lab_j = info[j][0], info[j][1]
        lo, hi = r_prev.stop - 1, r_j.start + 1
        rot = trapezoid(t[lo:hi], gyr[lo:hi] - bias_prev)
        if lab_j != info[anchor][1] or lab_j == "tilted":
            anchor, heading = j, 0.0
            continue
        heading += float(rot @ info[anchor][2])
        whole = round(heading / 360.0)
        if whole != 0 and abs(heading - 360.0 * whole) <= TURN_HEADING_TOL_DEG:
            turn_spans.append((anchor, j, heading))
            anchor, heading = j, 0.0
        elif abs(heading) <= TURN_HEADING_TOL_DEG:
            anchor, heading = j, 0.0
    inside = {k for a, b, _ in turn_spans for k in range(a + 1, b)}

    # still runs: the longest per attitude becomes the static record
    best: dict[str, int] = {}
    for i, (r, label, *_rest) in enumerate(info):
        if label == "tilted" or i in inside:
            continue
        if label not in best or len(r) > len(info[best[label]][0]):
            best[label] = i
    for i, (r, label, up, angle, am, astd, _gm) in enumerate(info):
        if i in inside:
            continue
        found = "still " + (_axis_text(up) if label != "tilted" else "tilted")
        q = (
            f"gravity {angle:.1f}° off {_axis_text(up)}, |a| {np.linalg.norm(am):.3f} m/s², "
            f"std a {astd.max():.3g} m/s², std g {gyr[r].std(axis=0).max():.3g} °/s"
        )
        chosen = best.get(label) == i
        if not chosen and label != "tilted":
            q += f"; rest (a longer still {_axis_text(up)} is the record)"
        segs.append(
            Segment(
                r.start, r.stop, float(t[r.start]), float(t[r.stop - 1]), found,
                label if chosen else "-", q, _t3(up),
            )
        )  # fmt: skip
    used: dict[str, int] = {}
    for a, b, angle in turn_spans:
        ra, rb = info[a][0], info[b][0]
        up = info[a][2]
        start = int(np.searchsorted(t, t[ra.stop - 1] - pad, side="left"))
        start = max(start, ra.start)
        stop = int(np.searchsorted(t, t[rb.start] + pad, side="right"))
        stop = min(stop, rb.stop)
        n = max(1, round(abs(angle) / 360.0))
        direction = 1 if angle > 0 else -1
        base = f"{'xyz'[int(np.argmax(np.abs(up)))]}_{'ccw' if direction > 0 else 'cw'}"
        used[base] = used.get(base, 0) + 1
        label = base if used[base] == 1 else f"{base}_{used[base]}"
        steps = b - a
        q = f"{n} turn{'s' if n > 1 else ''}, {angle:+.1f}° about {_axis_text(up)}"
        if steps > 1:
            q += f" in {steps} steps"
        segs.append(
            Segment(
                start, stop, float(t[start]), float(t[stop - 1]),
                f"turn {angle:+.0f}° about {_axis_text(up)}", label, q, _t3(up), n, direction,
            )
        )  # fmt: skip
    segs.sort(key=lambda s: s.start)
    return segs, thr


def _check_gravity(stream: Stream, norms: list[float]) -> None:
    """At rest the accelerometer must read about g: else the unit is wrong — say which."""
    if not norms:
        return
    m = float(np.median(norms))
    src = stream.meta.get("source", "the file")
    if 7.0 < m < 12.5:
        return
    hint = ""
    if 0.7 < m < 1.3:
        hint = " — it looks like g: add --units accel=g"
    elif m > 100:
        hint = " — it looks like raw counts: add --units accel=counts:LSB_PER_G"
    elif 700 < m < 1300:
        hint = " — it looks like mg"
    raise SegmentationError(
        f"{src}: at rest the accelerometer reads |a| = {m:.4g} m/s² after the unit conversion, "
        f"gravity is about 9.81{hint}"
    )


def check_time_unit(stream: Stream) -> None:
    """Sample spacing must be plausible for an IMU (``MIN_SPACING_S`` … ``MAX_SPACING_S``):
    else the time column's unit is wrong — say which one it looks like."""
    t = stream.t_s
    if t.size < 2:
        return
    dt = float(np.median(np.diff(t)))
    src = stream.meta.get("source", "the file")
    if dt > MAX_SPACING_S:
        raise SegmentationError(
            f"{src}: the samples are {dt:.4g} s apart after the unit conversion "
            f"({stream.meta.get('units', '')}): is the time column in ms or µs? "
            "add --units t=ms or t=us"
        )
    if 0 < dt < MIN_SPACING_S:
        raise SegmentationError(
            f"{src}: the samples are {dt * 1e6:.3g} µs apart after the unit conversion "
            f"({stream.meta.get('units', '')}): is the time column in s or ms? "
            "add --units t=s or t=ms"
        )


def gyro_unit_hint(stream: Stream, segments: list[Segment]) -> str | None:
    """When no turn was found but the rotation between two still periods of one attitude is
    close to a whole number of 2π, the gyro is probably in rad/s: the hint, else None."""
    if any(s.turns for s in segments):
        return None
    still = [s for s in segments if s.found.startswith("still")]
    t, gyr = stream.t_s, stream.gyro
    for a, b in zip(still, still[1:], strict=False):
        if a.found != b.found:
            continue
        bias = gyr[a.start : a.stop].mean(axis=0)
        lo, hi = a.stop - 1, b.start + 1
        angle = abs(float(trapezoid(t[lo:hi], gyr[lo:hi] - bias) @ np.asarray(a.up)))
        k = round(angle / (2 * math.pi))
        if k >= 1 and abs(angle - 2 * math.pi * k) < 0.15 * 2 * math.pi:
            return (
                f"between {a.t1_s:.1f} s and {b.t0_s:.1f} s the gyro integral about "
                f"{_axis_text(np.asarray(a.up))} is {angle:.2f}, close to {k}·2π, and no turn "
                "was found: is the gyro in rad/s? add --units gyro=rad/s"
            )
    return None


# ---- the table and the labels file ----------------------------------------------------------
def format_table(segments: list[Segment]) -> str:
    """The printed table: row, start, duration, found, label, quality."""
    lines = [f"{'#':>3} {'start s':>9} {'dur s':>7}  {'found':<24} {'label':<9} quality"]
    for i, s in enumerate(segments, start=1):
        lines.append(
            f"{i:>3} {s.t0_s:>9.2f} {s.duration_s:>7.2f}  {s.found:<24} {s.label:<9} {s.quality}"
        )
    return "\n".join(lines) + "\n"


def format_labels(segments: list[Segment], source: str) -> str:
    """The labels file (TSV) the user edits: one row per segment, times in s of the stream."""
    out = [
        f"{LABELS_HEADER} of {source}",
        "# Edit the label column (x_up … z_dn, x_ccw … z_cw, x_up_2 for a repeat, '-' to leave "
        "a row out),",
        "# or the start/end times; add rows for what was missed. Then run the same import with "
        "--labels THIS_FILE.",
        "# row\tstart_s\tend_s\tlabel\tfound\tquality",
    ]
    for i, s in enumerate(segments, start=1):
        out.append(f"{i}\t{s.t0_s:.3f}\t{s.t1_s:.3f}\t{s.label}\t{s.found}\t{s.quality}")
    return "\n".join(out) + "\n"


def valid_label(label: str) -> bool:
    """A record name the calibration understands (x_up … z_cw, optional _repeat suffix)."""
    return bool(_LABEL_RE.match(label))


def read_labels(path: str | os.PathLike[str], stream: Stream) -> list[Segment]:
    """Segments from a labels file (:func:`format_labels`, edited): each row's start/end
    times (s) and label; turns are measured from the stream (angle about the label's axis)."""
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except OSError as exc:
        raise SegmentationError(
            f"{p}: cannot read the labels file ({exc.strerror or exc})"
        ) from exc
    return parse_labels(text, str(p), stream)


def parse_labels(text: str, source: str, stream: Stream) -> list[Segment]:
    """The segments of a labels file's text (see :func:`read_labels`); ``source`` names it."""
    p = source
    t = stream.t_s
    segs: list[Segment] = []
    seen: dict[str, int] = {}
    for lineno, raw in enumerate(text.splitlines(), start=1):
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        where = f"{p}:{lineno}"
        f = line.split("\t") if "\t" in line else line.split()
        if len(f) < 4:
            raise SegmentationError(f"{where}: expected row, start_s, end_s, label")
        try:
            t0, t1 = float(f[1]), float(f[2])
        except ValueError:
            raise SegmentationError(f"{where}: start_s and end_s must be numbers") from None
        label = f[3].strip()
        if label == "-":
            continue
        if not valid_label(label):
            raise SegmentationError(
                f"{where}: label {label!r} is not a record name (x_up … z_dn, x_ccw … z_cw, "
                "x_up_2, or - to leave the row out)"
            )
        if label in seen:
            raise SegmentationError(
                f"{where}: label {label} is also on line {seen[label]}; name a repeat {label}_2"
            )
        seen[label] = lineno
        if not t1 > t0:
            raise SegmentationError(f"{where}: end_s must be after start_s")
        start = int(np.searchsorted(t, t0, side="left"))
        stop = int(np.searchsorted(t, t1, side="right"))
        if stop - start < 2:
            raise SegmentationError(
                f"{where}: {t0:g}..{t1:g} s holds fewer than 2 samples (the stream spans "
                f"{t[0]:.3f}..{t[-1]:.3f} s)"
            )
        m = _LABEL_RE.match(label)
        assert m
        axis, d = m.group("axis"), m.group("dir")
        up = np.zeros(3)
        if d in ("up", "dn"):
            up["xyz".index(axis)] = 1.0 if d == "up" else -1.0
            segs.append(
                Segment(start, stop, float(t[start]), float(t[stop - 1]), "labelled", label,
                        "from the labels file", _t3(up))
            )  # fmt: skip
            continue
        seg = _turn_from_label(stream, start, stop, label, axis, d, where)
        segs.append(seg)
    if not segs:
        raise SegmentationError(f"{p}: no labelled rows (every label is '-')")
    segs.sort(key=lambda s: s.start)
    return segs


def _turn_from_label(
    stream: Stream, start: int, stop: int, label: str, axis: str, d: str, where: str
) -> Segment:
    t, acc, gyr = stream.t_s, stream.accel, stream.gyro
    k = "xyz".index(axis)
    sign_up = 1.0 if acc[start:stop, k].mean() >= 0 else -1.0
    up = np.zeros(3)
    up[k] = sign_up
    angle = float(trapezoid(t[start:stop], gyr[start:stop]) @ up)
    n = max(1, round(abs(angle) / 360.0))
    direction = 1 if d == "ccw" else -1
    if angle * direction < 0:
        raise SegmentationError(
            f"{where}: {label} turned {angle:+.0f}° about {_axis_text(up)}, the other way: "
            f"label it {axis}_{'cw' if d == 'ccw' else 'ccw'}"
        )
    q = f"{n} turn{'s' if n > 1 else ''}, {angle:+.1f}° about {_axis_text(up)} (labelled)"
    return Segment(
        start, stop, float(t[start]), float(t[stop - 1]), "labelled", label, q, _t3(up), n,
        direction,
    )  # fmt: skip


# ---- records --------------------------------------------------------------------------------
def _up_text(up: tuple[float, float, float]) -> str:
    return _axis_text(np.asarray(up))


def build_records(
    stream: Stream, segments: list[Segment], thresholds: Thresholds | None, serial: str
) -> dict[str, Record]:
    """Records (method.md §6) for every labelled segment: time since the segment's first sample
    (ms, from the stream's true times), the data, and metadata — source, column map, units,
    segmentation thresholds, the segment's place in the stream and its timing quality."""
    out: dict[str, Record] = {}
    for s in segments:
        if s.label == "-":
            continue
        sl = slice(s.start, s.stop)
        t = stream.t_s[sl]
        tq = timing_quality(t)
        meta = {"serial": serial, **stream.meta}
        turn = s.turns > 0 or s.label.split("_")[1] in ("ccw", "cw")
        meta["kind"] = "turn" if turn else "static"
        meta["up"] = _up_text(s.up)
        if turn:
            meta["turns"] = str(max(1, s.turns))
            meta["direction"] = "ccw" if s.direction > 0 else "cw"
        meta["segment_s"] = f"{s.t0_s:.3f}..{s.t1_s:.3f} of the stream"
        meta["segment_found"] = s.found
        if thresholds is not None:
            meta["segmentation"] = thresholds.text()
        meta.update(tq.meta())
        out[s.label] = Record(
            name=s.label,
            t_ms=(t - t[0]) * 1000.0,
            accel=stream.accel[sl],
            gyro=stream.gyro[sl],
            temp=stream.temp[sl],
            meta=meta,
        )
    return out


def format_timing(records: dict[str, Record]) -> str:
    """Per-record timing table: samples, median spacing, worst gap, share of time in gaps."""
    lines = [f"{'record':<9} {'samples':>7} {'median ms':>9} {'worst gap ms':>12} {'in gaps':>8}"]
    for name, rec in records.items():
        q = timing_quality(rec.t_ms / 1000.0)
        flag = "  irregular" if q.warning else ""
        lines.append(
            f"{name:<9} {q.n:>7} {q.median_ms:>9.3g} {q.worst_gap_ms:>12.4g} "
            f"{100 * q.gap_share:>7.1f}%{flag}"
        )
    return "\n".join(lines) + "\n"


def plan_summary(records: dict[str, Record]) -> str:
    """Which records of the standard plan (6 statics, 6 turns) were found and which not."""
    have_s = [n for n in STATIC_NAMES if n in records]
    have_t = [n for n in TURN_NAMES if n in records]
    miss = [n for n in STATIC_NAMES + TURN_NAMES if n not in records]
    extra = [n for n in records if n not in STATIC_NAMES + TURN_NAMES]
    txt = f"{len(have_s)} of 6 static records, {len(have_t)} of 6 turn records"
    if miss:
        txt += f"; not found: {', '.join(miss)}"
    if extra:
        txt += f"; also: {', '.join(extra)}"
    return txt
