"""Records that stop when they have enough (issue 30, item 2).

A static record ends when the σ of its mean, from its own samples, reaches the σ the values the
six faces determine need: a face and its opposite give a sensor's scale, misalignment and bias
(accelerometer) and its g-sensitivity (gyro) as half their difference or sum, so a record mean
of σ gives them σ/√2 (per g for a scale). The σ of a mean counts the samples' serial
correlation as the fit's noise model does (:func:`host.model.noise.integrated_autocorrelation`,
at least the quantisation step²/12 a sample): σ² = s²·τ/N. It is looked at once a second of
device time, never before the method's minimum (:data:`STATIC_MIN_S`) and never after the
record's maximum. The second face of an axis may ask the face pair instead of itself: its
g-sensitivities from both faces, counting the rest the turns made on it will add
(:meth:`StaticRule.gyro_pair_sigma`) — the faces then balance, as the least-time plan does
(:mod:`host.workbench.least_time`).

Turns continue, a pair (one each way) at a time about an axis, until the σ of that axis's gyro
scale in the fit of the records so far meets its target (:func:`turn_scale_ratio`), at most
:data:`TURN_PAIRS_MAX` pairs an axis.

Each record says why it stopped, in its header (:data:`host.session.records.STOPPED_KEY`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from host.model.dataset import build_dataset
from host.model.fit import fit_model
from host.model.noise import NoiseModel, integrated_autocorrelation
from host.model.rows import white_variance
from host.model.spec import ModelTerm
from host.session.directory import Session
from host.session.method import (
    ACCEL_BIAS_NAMES,
    ACCEL_MIS_NAMES,
    ACCEL_SCALE_NAMES,
    DEFAULT_HEIGHT_M,
    DEFAULT_LATITUDE_DEG,
    GYRO_GSENS_NAMES,
    TOLERANCES,
)
from host.workbench.planner import misfit_sigmas, unscaled_sigmas

#: the method's shortest accumulation time of a face, s (method.md §5 step 5: "10 … several
#: hundred")
STATIC_MIN_S = 10.0
#: the longest a face is measured when nothing else says, s
STATIC_MAX_S = 300.0
#: how often a static record looks at its own σ, s of device time
CHECK_EVERY_S = 1.0
#: turn pairs about one axis at most (the method's one pair, and two more)
TURN_PAIRS_MAX = 3


def mean_sigma(x: np.ndarray, max_lag: int = NoiseModel().max_lag) -> np.ndarray:
    """σ of the mean of each column of ``x`` (N, k), in ``x``'s unit, from its own samples:
    √(s²·τ/N), s² the sample variance (at least the quantisation step²/12), τ the integrated
    autocorrelation time the fit's noise model uses. ∞ with fewer than 4 samples."""
    x = np.asarray(x, dtype=float).reshape(len(x), -1)
    n = x.shape[0]
    out = np.full(x.shape[1], math.inf)
    if n < 4:
        return out
    for k in range(x.shape[1]):
        var, (dev,) = white_variance(x[:, k], [(0, n)])
        out[k] = math.sqrt(var * integrated_autocorrelation(dev, max_lag) / n)
    return out


def _tightest(names: Sequence[str], tolerances: Mapping[str, float | None]) -> float:
    tols = [t for n in names if (t := tolerances.get(n))]
    return min(tols) if tols else math.inf


@dataclass(frozen=True)
class StaticRule:
    """When a static record has enough: the σ of its mean on every accelerometer axis at most
    ``accel_sigma`` (m/s²) and on every gyro axis at most ``gyro_sigma`` (°/s), after at least
    ``min_s`` and at most ``max_s`` s."""

    accel_sigma: float
    gyro_sigma: float
    min_s: float = STATIC_MIN_S
    max_s: float = STATIC_MAX_S

    @classmethod
    def for_target(
        cls,
        target: float,
        g: float,
        *,
        min_s: float = STATIC_MIN_S,
        max_s: float = STATIC_MAX_S,
        tolerances: Mapping[str, float | None] = TOLERANCES,
    ) -> StaticRule:
        """The rule that gives every value the faces determine σ ≤ ``target``·tolerance
        (``g``: local gravity, m/s²): accelerometer scale and misalignment (σ/(√2·g)) and
        bias (σ/√2), gyro g-sensitivity (σ/√2 per g)."""
        r2 = target * math.sqrt(2.0)
        accel = min(
            r2 * g * _tightest(ACCEL_SCALE_NAMES + ACCEL_MIS_NAMES, tolerances),
            r2 * _tightest(ACCEL_BIAS_NAMES, tolerances),
        )
        gyro = r2 * _tightest(GYRO_GSENS_NAMES, tolerances)
        return cls(accel, gyro, min_s, max(max_s, min_s))

    def sigmas(self, accel: np.ndarray, gyro: np.ndarray) -> tuple[float, float]:
        """The largest σ of the mean over the axes of ``accel`` (N, 3) m/s² and ``gyro``
        (N, 3) °/s."""
        return float(np.max(mean_sigma(accel))), float(np.max(mean_sigma(gyro)))

    def gyro_pair_sigma(
        self, gyro: np.ndarray, elapsed_s: float, opposite: np.ndarray, extra_rest_s: float
    ) -> float:
        """σ (°/s) a face's gyro mean would need to have alone for its g-sensitivities to be
        as well known as the rule asks of a face pair, with the opposite face measured
        already (σ of its mean per gyro axis ``opposite``, °/s, as it will be once the rest
        still to come on it is counted) and ``extra_rest_s`` s of rest on this face still to
        come (the windows of the turns made on it: a turn about the
        vertical keeps the face up), the largest over the axes: GA = (up − down)/2 has
        σ² = (σ_up² + σ_down²)/4, σ_up² shrunk by T/(T + extra) for the rest to come."""
        own = mean_sigma(gyro) ** 2 * elapsed_s / max(elapsed_s + extra_rest_s, 1e-9)
        pair = own + np.asarray(opposite, dtype=float) ** 2
        return float(np.sqrt(np.max(pair) / 2.0))

    def stop(
        self,
        accel: np.ndarray,
        gyro: np.ndarray,
        elapsed_s: float,
        *,
        opposite: np.ndarray | None = None,
        extra_rest_s: float = 0.0,
    ) -> str | None:
        """Why the record stops now (its header's ``stopped``), or None: go on.
        ``elapsed_s``: device time since its first sample, s. With ``opposite`` (σ of the
        opposite face's mean per gyro axis, °/s) the gyro asks the face pair's g-sensitivity,
        counting ``extra_rest_s`` s of rest still to come on this face
        (:meth:`gyro_pair_sigma`), not this face alone."""
        if elapsed_s < self.min_s - 1e-9:
            return None
        sa, sg = self.sigmas(accel, gyro)
        if opposite is not None:
            sg = self.gyro_pair_sigma(gyro, elapsed_s, opposite, extra_rest_s)
        met = sa <= self.accel_sigma and sg <= self.gyro_sigma
        if not met and elapsed_s < self.max_s - 1e-9:
            return None
        what = "σ of the mean met its target" if met else "the maximum, target not met"
        pair = (
            "" if opposite is None
            else f" with the opposite face and {extra_rest_s:g} s of turns to come"
        )  # fmt: skip
        return (
            f"{what} at {elapsed_s:.0f} s: gyro {sg:.2g} °/s{pair} (target "
            f"{self.gyro_sigma:.2g}), accel {sa:.2g} m/s² (target {self.accel_sigma:.2g}); "
            f"bounds {self.min_s:g}-{self.max_s:g} s"
        )


def stop_index(
    rule: StaticRule,
    t_s: np.ndarray,
    accel: np.ndarray,
    gyro: np.ndarray,
    *,
    opposite: np.ndarray | None = None,
    extra_rest_s: float = 0.0,
) -> tuple[int, str]:
    """Where a static record of samples at ``t_s`` (N,) s would stop under ``rule``, looked at
    once every :data:`CHECK_EVERY_S` s, as the live measurement does: (number of samples kept,
    the reason). The record's end when it never says stop. ``opposite``, ``extra_rest_s``:
    as :meth:`StaticRule.stop`."""
    t = np.asarray(t_s, dtype=float) - float(t_s[0])
    rate = (len(t) - 1) / t[-1] if len(t) > 1 and t[-1] > 0 else 1.0
    every = max(1, round(rate * CHECK_EVERY_S))
    for n in range(every, len(t) + 1, every):
        why = rule.stop(accel[:n], gyro[:n], n / rate, opposite=opposite, extra_rest_s=extra_rest_s)
        if why is not None:
            return n, why
    return len(t), f"the record ended at {len(t) / rate:.0f} s"


def turn_scale_ratio(
    session: Session,
    model: Sequence[ModelTerm],
    axis: str,
    *,
    noise: NoiseModel | None = None,
    tolerances: Mapping[str, float | None] = TOLERANCES,
    latitude_deg: float = DEFAULT_LATITUDE_DEG,
    height_m: float = DEFAULT_HEIGHT_M,
) -> tuple[float, float]:
    """σ/tolerance of the gyro scale about ``axis`` ('x', 'y', 'z') in the fit of ``session``
    with ``model`` (the planner's σ: from the noise model, widened as the fit's misfit
    shows; ∞ when the records do not determine it), and the part of it the model's misfit
    sets (:func:`host.workbench.planner.misfit_sigmas`: no further pair lowers it)."""
    name = f"G{axis}{axis}"
    ds = build_dataset(session, noise=noise or NoiseModel(), latitude_deg=latitude_deg,
                       height_m=height_m)  # fmt: skip
    fit = fit_model(ds, model)
    s = unscaled_sigmas(fit, fit).get(name, math.nan)
    tol = tolerances.get(name)
    if not tol or not math.isfinite(s):
        return math.inf, 0.0
    return s / tol, misfit_sigmas(fit).get(name, 0.0) / tol


def turns_stop(ratio: float, target: float, pairs: int, misfit: float = 0.0) -> str | None:
    """Why the turns about an axis stop after ``pairs`` pairs with the gyro scale's
    σ/tolerance ``ratio`` (``misfit`` of it set by the model's misfit), or None: one more
    pair."""
    if ratio <= target:
        return f"gyro scale σ/tolerance {ratio:.3g} met the target {target:g} after {pairs} pair(s)"
    if misfit > target:
        return (
            f"the model's misfit sets gyro scale σ/tolerance {misfit:.3g}, above the target "
            f"{target:g}: another pair does not lower it ({ratio:.3g} after {pairs} pair(s))"
        )
    if pairs >= TURN_PAIRS_MAX:
        return (
            f"the maximum of {TURN_PAIRS_MAX} pairs; gyro scale σ/tolerance {ratio:.3g} "
            f"above the target {target:g}"
        )
    return None
