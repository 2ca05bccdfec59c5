"""imu_tk's test data (``../shared/data/imutk-xsens``: real Xsens samples, 100 Hz, 38 rests at
arbitrary attitudes) as pose and move records, for the tests of the poses engine.

The conversion is the README's: nominal factors 415 counts per m/s² and 4770 counts per rad/s
about 32768. The rests are found as imu_tk finds them (Tedaldi et al. §IV-A): the accelerometer's
variance over a window of ±0.5 s, as the norm of its three axes' variances, under a multiple of
that of the first 50 s (the first rest); runs of at least 1 s. A move runs from the last sample
of the rest before to the first sample of the rest after."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from host.session.directory import Session
from host.session.records import Record, move_name, pose_name

#: the data beside the clone (named REAL so that a clone without it skips its tests)
REAL = Path(__file__).resolve().parents[4] / "shared" / "data" / "imutk-xsens"
COUNTS_PER_MS2 = 415.0
COUNTS_PER_RAD_S = 4770.0
#: the window's half width (samples), the first rest (s), the threshold's multiple
_HALF = 50
_INIT_S = 50.0
_MULTIPLE = 8.0


def _rolling_variance(x: np.ndarray) -> np.ndarray:
    v = sliding_window_view(x, 2 * _HALF + 1, axis=0).var(axis=-1)
    out = np.full(x.shape, np.inf)
    out[_HALF:-_HALF] = v
    return out


def rests(t: np.ndarray, accel: np.ndarray) -> list[tuple[int, int]]:
    """[start, stop) sample ranges of the rests in ``accel`` (N, 3) at times ``t`` (N,) s."""
    level = np.sqrt((_rolling_variance(accel) ** 2).sum(axis=1))
    base = math.sqrt(float((accel[t < _INIT_S].var(axis=0) ** 2).sum()))
    still = np.concatenate([[0], (level < _MULTIPLE * base).astype(np.int8), [0]])
    edges = np.flatnonzero(np.diff(still))
    return [(int(a), int(b)) for a, b in zip(edges[::2], edges[1::2], strict=True) if b - a >= 100]


def read_xsens() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(t (N,) s, accel (N, 3) m/s², gyro (N, 3) °/s) at the README's nominal factors."""
    acc = np.loadtxt(REAL / "xsens_acc.mat")
    gyr = np.loadtxt(REAL / "xsens_gyro.mat")
    accel = (acc[:, 1:] - 32768.0) / COUNTS_PER_MS2
    gyro = np.degrees((gyr[:, 1:] - 32768.0) / COUNTS_PER_RAD_S)
    return acc[:, 0], accel, gyro


def xsens_session(moves: bool = True) -> tuple[Session, list[tuple[int, int]], np.ndarray]:
    """(the session of pose records and, with ``moves``, the moves between them; the rests'
    sample ranges; the accelerometer (N, 3) m/s²)."""
    t, accel, gyro = read_xsens()
    found = rests(t, accel)
    records: dict[str, Record] = {}

    def rec(name: str, a: int, b: int, meta: dict[str, str]) -> Record:
        meta = {**meta, "power_on_s": f"{t[a]:.3f}", "importer": "test"}
        t_ms = (t[a:b] - t[a]) * 1000.0
        return Record(name, t_ms, accel[a:b], gyro[a:b], np.full(b - a, 25.0), meta)

    for i, (a, b) in enumerate(found, start=1):
        records[pose_name(i)] = rec(pose_name(i), a, b, {})
        if moves and i < len(found):
            nxt = found[i][0]
            meta = {"from": pose_name(i), "to": pose_name(i + 1)}
            records[move_name(i, i + 1)] = rec(move_name(i, i + 1), b - 1, nxt + 1, meta)
    return Session(serial="XSENS", records=records), found, accel
