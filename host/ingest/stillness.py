"""Where a stream rests: the stillness detector and the attitude of a rest (method.md §3).

1. **Noise floors** (:func:`find_still`): over a moving window of ``STILL_WINDOW_S`` the
   standard deviation of every channel; a channel's noise floor is the ``NOISE_QUANTILE``
   quantile of its moving standard deviation (the quietest tenth of the stream), a window is
   still when every channel stays under ``THRESHOLD_FACTOR`` times that (never below
   ``MIN_ACCEL_STD``, ``MIN_GYRO_STD``) and its mean rate within the rate limit of the bias.
2. **Gyro bias over time**: the median rate of the still windows in blocks of ``BIAS_BLOCK_S``,
   interpolated (a warm-up moves the bias).
3. **Rests** (:func:`rests`): runs of samples whose every gyro channel is within
   ``max(MIN_QUIET_DPS, QUIET_SIGMAS · noise floor)`` of the bias and whose accelerometer does
   not jump (``ACCEL_JUMP_SIGMAS`` noise floors, at least ``MIN_ACCEL_JUMP``: record files
   joined end to end jump from one face to the next without any rotation). Sample-exact, so a
   rest of two samples between the steps of a fast turn is found, and a static ends where the
   cube starts to move. Where record files were joined (the accelerometer steps by
   ``JOIN_STEP`` while the gyro turns slower than ``JOIN_RATE_DPS``) the samples on either side
   are one-sample rests: a record that ends while the cube still settles ends there. A rest's
   end samples whose accelerometer is ``ACCEL_DEV_SIGMAS`` noise floors off the samples just
   inside them are not part of it (the cube starts to tilt before the gyro shows it). No rest
   spans a gap in time (:mod:`host.ingest.gaps`): the pieces either side are two rests.
4. **Attitude** of a rest from gravity: the axis nearest the mean specific force (up = +g on
   that axis, method.md §3), with the angle off it as its quality.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from host.errors import UserError
from host.ingest.gaps import gap_starts

STILL_WINDOW_S = 0.5  #: moving window of the noise-floor detector, s (at least 5 samples)
NOISE_QUANTILE = 0.10  #: the quietest tenth of windows gives each channel's noise floor
THRESHOLD_FACTOR = 4.0  #: a window moves when a channel's std exceeds this × its noise floor
MIN_ACCEL_STD = 0.005  #: m/s², floor of the accel std threshold (quantised, very quiet data)
MIN_GYRO_STD = 0.02  #: °/s, floor of the gyro std threshold
MIN_RATE_DPS = 0.5  #: °/s, floor of a still window's mean-rate limit
RATE_FACTOR = 10.0  #: mean-rate limit = this × the gyro noise floor (if above the floor)
BIAS_BLOCK_S = 20.0  #: the gyro bias is followed in blocks of this many seconds
QUIET_SIGMAS = 6.0  #: a resting sample's rate is within this many noise floors of the bias …
MIN_QUIET_DPS = 0.3  #: … or within this many °/s (quantised gyros, g-sensitivity per face)
ACCEL_JUMP_SIGMAS = 10.0  #: an accelerometer step above this many noise floors ends a rest …
MIN_ACCEL_JUMP = 0.5  #: … when it is also above this, m/s²
JOIN_STEP = 3.0  #: m/s²: an accelerometer step this large between two samples …
JOIN_RATE_DPS = 10.0  #: … turning slower than this (°/s) is a join of record files: a boundary
ACCEL_DEV_SIGMAS = 6.0  #: a rest's end samples this many accel noise floors off the rest go
MERGE_GAP_SAMPLES = 2  #: rests this close (samples) are one rest (a single noisy sample)
AXIS_TOL_DEG = 25.0  #: gravity within this of an axis labels the attitude (else tilted)


class SegmentationError(UserError):
    """The stream cannot be cut into records as asked (message names the file/segment)."""


@dataclass(frozen=True)
class Thresholds:
    """The stillness detector's settings, tuned from the stream: window (samples, s), noise
    floors and thresholds per channel (accel m/s², gyro °/s), the still windows' mean-rate
    limit (°/s), the median bias (°/s), a resting sample's rate limit per channel (°/s) and
    the accelerometer step that ends a rest (m/s²)."""

    window: int
    window_s: float
    accel_noise: np.ndarray
    gyro_noise: np.ndarray
    accel_std: np.ndarray
    gyro_std: np.ndarray
    rate_dps: float
    bias_dps: np.ndarray
    quiet_dps: np.ndarray
    accel_jump: float

    def text(self) -> str:
        """One line for the record metadata and the printed table."""
        f3 = lambda v: "/".join(f"{x:.3g}" for x in v)  # noqa: E731
        return (
            f"noise floor from {self.window}-sample windows ({self.window_s:.2f} s): accel "
            f"{f3(self.accel_noise)} m/s², gyro {f3(self.gyro_noise)} °/s; at rest when every "
            f"gyro channel is within {f3(self.quiet_dps)} °/s of its bias and the "
            f"accelerometer steps less than {self.accel_jump:.3g} m/s²"
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
    """Per-sample stillness of a stream (times s, accel m/s², gyro °/s) by moving windows, and
    the thresholds tuned from the stream's own noise (see the module docstring)."""
    still, thr, _ = _windows(t_s, accel, gyro)
    return still, thr


def _windows(
    t_s: np.ndarray, accel: np.ndarray, gyro: np.ndarray
) -> tuple[np.ndarray, Thresholds, np.ndarray]:
    """Still samples, thresholds and the gyro bias per sample (°/s, (N,3))."""
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
    bias_t = _bias_track(t[k // 2 : k // 2 + len(ok)], g_mean, ok, bias, t)
    quiet_dps = np.maximum(QUIET_SIGMAS * g_noise, MIN_QUIET_DPS)
    jump = max(MIN_ACCEL_JUMP, ACCEL_JUMP_SIGMAS * float(a_noise.max()))
    thr = Thresholds(k, k * dt, a_noise, g_noise, a_thr, g_thr, rate, bias, quiet_dps, jump)
    return still, thr, bias_t


def _bias_track(
    t_win: np.ndarray, g_mean: np.ndarray, ok: np.ndarray, bias: np.ndarray, t: np.ndarray
) -> np.ndarray:
    """Gyro bias per sample (°/s): block medians of the still windows' means, interpolated."""
    if not np.any(ok):
        return np.tile(bias, (t.size, 1))
    blocks = np.floor((t_win - t[0]) / BIAS_BLOCK_S).astype(int)
    centres, values = [], []
    for b in np.unique(blocks[ok]):
        sel = ok & (blocks == b)
        centres.append(float(np.median(t_win[sel])))
        values.append(np.median(g_mean[sel], axis=0))
    v = np.asarray(values)
    return np.column_stack([np.interp(t, centres, v[:, c]) for c in range(3)])


@dataclass(frozen=True)
class Rest:
    """Samples ``start`` … ``stop − 1`` where the cube rests (see :func:`rests`)."""

    start: int
    stop: int

    def __len__(self) -> int:
        return self.stop - self.start


def rests(
    t_s: np.ndarray, accel: np.ndarray, gyro: np.ndarray
) -> tuple[list[Rest], Thresholds, np.ndarray]:
    """The rests of a stream (module docstring, item 3) in time order, the thresholds and the
    gyro bias per sample (°/s, (N,3))."""
    acc = np.asarray(accel, dtype=np.float64)
    gyr = np.asarray(gyro, dtype=np.float64)
    _, thr, bias_t = _windows(t_s, acc, gyr)
    quiet = np.all(np.abs(gyr - bias_t) < thr.quiet_dps, axis=1)
    step = np.zeros(len(acc), dtype=bool)
    step[1:] = np.max(np.abs(np.diff(acc, axis=0)), axis=1) > thr.accel_jump
    out: list[Rest] = []
    i, n = 0, len(quiet)
    while i < n:
        if not quiet[i]:
            i += 1
            continue
        j = i + 1
        while j < n and not step[j] and (quiet[j] or _gap_ok(quiet, step, j, n)):
            j += 1
        while j > i + 1 and not quiet[j - 1]:
            j -= 1
        out.append(_settled(Rest(i, j), acc, thr))
        i = j
    slow = np.all(np.abs(gyr - bias_t) < JOIN_RATE_DPS, axis=1)
    big = np.zeros(len(acc), dtype=bool)
    big[1:] = np.max(np.abs(np.diff(acc, axis=0)), axis=1) > JOIN_STEP
    starts = {r.start for r in out}
    stops = {r.stop for r in out}
    for join in np.flatnonzero(big & slow & np.roll(slow, 1)).tolist():
        if join not in stops:  # the last sample before a join ends what came before
            out.append(Rest(join - 1, join))
        if join not in starts:
            out.append(Rest(join, join + 1))
    out.sort(key=lambda r: r.start)
    return _split_at_gaps(out, gap_starts(t_s)), thr, bias_t


def _split_at_gaps(found: list[Rest], gaps: np.ndarray) -> list[Rest]:
    """The rests with none spanning a gap in time (:mod:`host.ingest.gaps`): each piece apart."""
    if gaps.size == 0:
        return found
    out: list[Rest] = []
    for r in found:
        cuts = [int(g) for g in gaps.tolist() if r.start < g < r.stop]
        edges = [r.start, *cuts, r.stop]
        out.extend(Rest(a, b) for a, b in zip(edges, edges[1:], strict=False))
    return out


def _settled(r: Rest, acc: np.ndarray, thr: Thresholds) -> Rest:
    """A rest without its end samples whose accelerometer is off the median of the window
    just inside them by more than ``ACCEL_DEV_SIGMAS`` noise floors (the cube starts to tilt
    before the gyro shows it); at most one window is cut at each end (a drift over a long
    warm-up is no tilt)."""
    w = thr.window
    if len(r) < 3 * w:
        return r
    limit = np.maximum(ACCEL_DEV_SIGMAS * thr.accel_noise, MIN_ACCEL_STD)
    a, b = r.start, r.stop
    while b > r.stop - w and np.any(
        np.abs(acc[b - 1] - np.median(acc[b - 1 - w : b - 1], axis=0)) > limit
    ):
        b -= 1
    while a < r.start + w and np.any(
        np.abs(acc[a] - np.median(acc[a + 1 : a + 1 + w], axis=0)) > limit
    ):
        a += 1
    return Rest(a, b)


def _gap_ok(quiet: np.ndarray, step: np.ndarray, j: int, n: int) -> bool:
    """A short non-quiet gap inside a rest (noise): quiet again within MERGE_GAP_SAMPLES."""
    end = min(n, j + MERGE_GAP_SAMPLES + 1)
    for m in range(j + 1, end):
        if step[m]:
            return False
        if quiet[m]:
            return True
    return False


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


def axis_text(up: np.ndarray | tuple[float, float, float]) -> str:
    """'+x', '-z' … of an up vector."""
    u = np.asarray(up, dtype=np.float64)
    k = int(np.argmax(np.abs(u)))
    return ("+" if u[k] > 0 else "-") + "xyz"[k]
