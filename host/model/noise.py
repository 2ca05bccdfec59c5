"""How uncertain each row is: the noise model (:class:`NoiseModel`, method.md §8 "residual mean
near 0") and the noise levels a session measures of itself.

The rows of one record and channel share one covariance ``v·I + f²·11ᵀ``: ``v`` = variance of a
block mean from the record's own samples (pooled within-block variance × integrated
autocorrelation time, at least the quantisation step²/12), ``f`` = the bias-instability floor:
the slow Gauss-Markov wander of a MEMS bias moves each record's mean by an amount the record
itself cannot show (:func:`repeat_floor`, :func:`session_floor`). Turn integrals: white noise
integrated + (floor·T)² + the hand's angle error (``turn_angle_sigma_deg``, as
:mod:`host.calib.calibration`). The still moments of a turn add the cube's seating, its moving
blocks the hand (:mod:`host.model.rows`, :mod:`host.model.turning`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from host.model.signals import SENSORS, UNIT, RecordSignals
from host.session.method import (
    TURN_ANGLE_SIGMA_DEG,
)


# ---- noise model ----------------------------------------------------------------------------
@dataclass(frozen=True)
class NoiseModel:
    """How uncertain each row is (see the module docstring).

    ``block_s``: length of the blocks static records are cut into, s (at most ``max_blocks``);
    ``floor``: bias-instability floor per sensor (m/s², °/s): the std of a record's mean bias
    wander between records that its own samples cannot show. Not given: measured from the
    session itself by :func:`repeat_floor` (the same attitude measured again minutes later);
    ``turn_angle_sigma_deg``: the hand's angle error per turn (method.md §4).
    """

    block_s: float = 5.0
    max_blocks: int = 6
    #: per sensor; a sensor not given is measured from the records (:func:`repeat_floor`)
    floor: Mapping[str, float] = field(default_factory=dict)
    turn_angle_sigma_deg: float = TURN_ANGLE_SIGMA_DEG
    max_lag: int = 30


#: a still moment inside a turn record lasts at least this long, s, after :data:`STILL_TRIM_S`
#: is cut at each end (the hand letting go / taking hold)
STILL_MIN_S = 0.1
STILL_TRIM_S = 0.05
#: the floor (:func:`repeat_floor`) compares still moments with static records: it keeps only
#: long, settled ones (a hand letting go rocks the cube for a moment)
FLOOR_MIN_S = 0.2
FLOOR_TRIM_S = 0.15


def still_runs(
    rate_up_dps: np.ndarray,
    t_s: np.ndarray,
    sigma_dps: float,
    *,
    trim_s: float | None = None,
    min_s: float | None = None,
) -> list[tuple[int, int]]:
    """[start, stop) index ranges where the cube rests inside a turn record: the rate about the
    up axis ``rate_up_dps`` (N,) °/s (static bias removed) stays within 4·``sigma_dps`` (the
    gyro's per-sample noise, °/s) of zero; ``trim_s`` (default :data:`STILL_TRIM_S`) s cut at
    each end, at least ``min_s`` (:data:`STILL_MIN_S`) s left (times ``t_s`` (N,) s)."""
    trim = STILL_TRIM_S if trim_s is None else trim_s
    least = STILL_MIN_S if min_s is None else min_s
    still = np.abs(rate_up_dps) < 4.0 * max(sigma_dps, 1e-6)
    out: list[tuple[int, int]] = []
    i, n = 0, len(still)
    while i < n:
        if not still[i]:
            i += 1
            continue
        j = i
        while j < n and still[j]:
            j += 1
        a = int(np.searchsorted(t_s, t_s[i] + trim))
        b = int(np.searchsorted(t_s, t_s[j - 1] - trim, side="right"))
        if b - a >= 4 and t_s[b - 1] - t_s[a] >= least:
            out.append((a, b))
        i = j
    return out


def repeat_floor(
    differences: np.ndarray,
    white_var: np.ndarray,
    channel: np.ndarray | None = None,
    explain: np.ndarray | None = None,
) -> float | None:
    """Bias-instability floor from repeated attitudes: ``differences`` (K,) between two means
    of the same channel in the same attitude measured at different times (a still moment of a
    turn against the static record of that face), ``white_var`` (K,) the variance their white
    noise alone gives the difference. Each record mean wanders by f around the session's
    bias, so E[d²] = w + 2·f²: f² = Σ(d² − w)/(2·dof) (≥ 0), in the channel's unit.

    A bias that follows time or temperature is an effect for the model to find, not noise:
    with ``channel`` (K,) ids and ``explain`` (K, m) the differences of those signals (elapsed
    time, temperature change), each channel's d is first regressed on them (dof = K − the
    columns used). None without any difference left (then nothing measures the floor). A
    floor the differences cannot resolve (f² below its standard error) is given as that
    bound, not as 0."""
    d = np.asarray(differences, dtype=np.float64)
    w = np.asarray(white_var, dtype=np.float64)
    if d.size == 0:
        return None
    ch = np.zeros(d.size, dtype=int) if channel is None else np.asarray(channel)
    x = np.zeros((d.size, 0)) if explain is None else np.asarray(explain, dtype=np.float64)
    resid = d.copy()
    used = 0
    for c in np.unique(ch):
        m = ch == c
        xc = x[m]
        keep = [j for j in range(xc.shape[1]) if np.ptp(xc[:, j]) > 0 or np.any(xc[:, j])]
        if keep and m.sum() > len(keep) + 1:
            beta, _, rank, _ = np.linalg.lstsq(xc[:, keep], d[m], rcond=None)
            resid[m] = d[m] - xc[:, keep] @ beta
            used += int(rank)
    dof = d.size - used
    if dof <= 0:
        return None
    f2 = float(np.sum(resid * resid - w)) / (2.0 * dof)
    # its standard error with no wander (var d² = 2·w²): a floor below it is not resolved by
    # these repeats, and 0 would claim a precision the data do not have — take that bound
    resolved = math.sqrt(float(np.sum(2.0 * w * w))) / (2.0 * dof)
    return math.sqrt(max(f2, resolved))


def resolution(x: np.ndarray) -> float:
    """Smallest step between distinct values of ``x`` (its quantisation), 0 if constant."""
    u = np.unique(x)
    if len(u) < 2:
        return 0.0
    d = np.diff(u)
    return float(np.min(d[d > 1e-12])) if np.any(d > 1e-12) else 0.0


def integrated_autocorrelation(dev: np.ndarray, max_lag: int) -> float:
    """1 + 2·Σρ_k of the deviations ``dev`` (N,), summed until ρ_k first drops to ≤ 0;
    the variance of a mean of m samples is σ²·τ/m (clipped to 1 … 50)."""
    n = len(dev)
    var = float(dev @ dev) / max(n, 1)
    if n < 4 or var <= 0:
        return 1.0
    tau = 1.0
    for k in range(1, min(max_lag, n // 4) + 1):
        rho = float(dev[k:] @ dev[:-k]) / (n * var)
        if rho <= 0:
            break
        tau += 2.0 * rho
    return float(min(max(tau, 1.0), 50.0))


def session_floor(
    signals: Sequence[RecordSignals],
    rec_noise: Mapping[tuple[int, str, int], tuple[float, float]],
    nm: NoiseModel,
) -> tuple[dict[str, float], str]:
    """The floor per sensor (``nm.floor`` where given, else :func:`repeat_floor` over the still
    moments of the turn records against the static record of the same face — every gyro
    channel and the accelerometer on the up axis, whose readings do not depend on the
    heading — and over static records of the same attitude, e.g. a repeated ``x_up_2``, every
    channel) and a note saying where it came from. (A slow effect that differs between the
    two measurements, e.g. a drift, inflates it: a noise file, ``--noise``, does not.)"""
    diffs: dict[str, tuple[list[float], list[float]]] = {s: ([], []) for s in SENSORS}

    for sig in signals:
        if sig.kind != "turn":
            continue
        match = next(
            (j for j, o in enumerate(signals) if o.kind == "static" and np.allclose(o.up, sig.up)),
            None,
        )
        if match is None:
            continue
        ref = signals[match]
        up_axis = int(np.argmax(np.abs(sig.up)))
        sd = math.sqrt(rec_noise[(match, "gyro", up_axis)][0])
        for a, b in still_runs(sig.rate @ sig.up, sig.t_s, sd, trim_s=FLOOR_TRIM_S,
                               min_s=FLOOR_MIN_S):  # fmt: skip
            m = b - a
            # back at the placement heading (a whole number of turns: the record's start and
            # end) every accelerometer axis repeats the static attitude; elsewhere only the up
            # axis does (a plate tilt moves the horizontal ones with the heading)
            turned = float(np.mean(sig.heading_deg[a:b])) if sig.heading_deg is not None else 0.0
            home = abs(turned - 360.0 * round(turned / 360.0)) < 5.0
            for s, axes in (("gyro", (0, 1, 2)), ("accel", (0, 1, 2) if home else (up_axis,))):
                for ax in axes:
                    var, tau = rec_noise[(match, s, ax)]
                    d = float(np.mean(sig.measured(s)[a:b, ax]) - np.mean(ref.measured(s)[:, ax]))
                    diffs[s][0].append(d)
                    diffs[s][1].append(var * min(tau, m) / m + var * tau / len(ref.t_s))

    # static records of the same attitude (the closing check): every channel
    for j, sj in enumerate(signals):
        for i in range(j):
            si = signals[i]
            if not (sj.kind == si.kind == "static" and np.allclose(sj.up, si.up)):
                continue
            for s in SENSORS:
                for ax in range(3):
                    vi, ti = rec_noise[(i, s, ax)]
                    vj, tj = rec_noise[(j, s, ax)]
                    d = float(np.mean(sj.measured(s)[:, ax]) - np.mean(si.measured(s)[:, ax]))
                    diffs[s][0].append(d)
                    diffs[s][1].append(vi * ti / len(si.t_s) + vj * tj / len(sj.t_s))
    out: dict[str, float] = {}
    said: list[str] = []
    for s in SENSORS:
        if s in nm.floor:
            out[s] = float(nm.floor[s])
            said.append(f"{s} {out[s]:.2g} {UNIT[s]} (given)")
            continue
        f = repeat_floor(np.array(diffs[s][0]), np.array(diffs[s][1]))
        out[s] = f if f is not None else 0.0
        said.append(
            f"{s} {out[s]:.2g} {UNIT[s]} from {len(diffs[s][0])} repeated attitudes (still "
            "moments of turns and static records against a static record of the same face)"
            if f is not None
            else f"{s} 0 (no attitude measured twice: only each record's own noise)"
        )
    return out, "noise floor of a record mean: " + "; ".join(said)
