"""Named sources of scatter that are not the sensor's noise, each measured with its own degrees
of freedom (never a constant, never the misfit of the model under test).

- the hand's turn-angle error (:func:`turn_angle_sigma`): from the closure of the repeated turns
  about one axis. A turn's gyro integral (method.md §4) is (1 + s)·θ + b·T + (1 + s)·e with the
  hand's angle error e; the counter-clockwise and clockwise turns about one axis have θ = ∓360°·n,
  so their sum less the static bias over both durations is (1 + s)·(e₁ + e₂) + white noise — the
  scale cancels, and with K axes turned both ways σ_e² = Σ(c² − w)/(2K), K degrees of freedom.
  A gyro scale asymmetry (a rate-dependent scale, one sign per direction) gives the same closure:
  on this plan the two cannot be told apart, and the note says so (a turn of another angle,
  e.g. 180°, or a rate table separates them).

The closures are read from a dataset's rows (:func:`turn_pairs`, :func:`turn_closures`), and
:func:`turn_sigmas` gives the components a dataset's turn integrals carry. The cube's seating at
the still moments and the hand while the cube turns are estimated beside the rows
(:func:`host.model.rows.seating_sigma`, :func:`host.model.rows.hand_sigma`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from host.model.noise import NoiseModel
from host.model.rows import RowTable
from host.model.signals import RecordSignals
from host.model.stats import beyond_white


@dataclass(frozen=True)
class TurnClosure:
    """One pair of turns about ``axis`` (a ccw turn and the cw turn paired with it, in the
    order measured; an axis turned in several pairs gives one closure per pair): gyro
    ``channel``'s two integrals ``integrals_deg`` (ccw, cw) °, the static gyro reading of that
    attitude on that channel ``rest_dps`` °/s, the turns' durations ``durations_s`` s and
    ``white_var`` the variance the white noise gives their sum (°²)."""

    axis: int
    channel: int
    integrals_deg: tuple[float, float]
    rest_dps: float
    durations_s: tuple[float, float]
    white_var: float

    @property
    def closure_deg(self) -> float:
        """ccw + cw less the static reading over both durations, °: the hand's two angle
        errors (and any asymmetry of the gyro scale)."""
        return sum(self.integrals_deg) - self.rest_dps * sum(self.durations_s)


@dataclass(frozen=True)
class Component:
    """A named variance component: its ``value`` (std, ``unit``), ``sigma`` (the standard error
    of that std), ``dof``, ``absorbs`` (what scatter it takes up) and ``plausible`` ('' or why
    not)."""

    name: str
    value: float
    sigma: float
    dof: int
    unit: str
    absorbs: str
    plausible: str = ""

    def describe(self) -> str:
        """One line: value ± σ, dof, what it absorbs, the plausibility check."""
        if self.dof == 0:
            return f"{self.name}: not measured ({self.absorbs})"
        warn = f"; IMPLAUSIBLE: {self.plausible}" if self.plausible else ""
        return (
            f"{self.name}: {self.value:.2g} ± {self.sigma:.1g} {self.unit} ({self.dof} dof; "
            f"absorbs {self.absorbs}){warn}"
        )


#: a hand that turns a cube against a stop rarely misses by more than this, °
TURN_ANGLE_PLAUSIBLE_DEG = 3.0
#: a hand's wobble (a degree or two of tilt) moves a cross-axis integral by far less, °
TURN_WOBBLE_PLAUSIBLE_DEG = 0.5
#: a unit held still by hand creeps by a degree in ten seconds at most, °/s (a pose's gyro mean)
POSE_RATE_PLAUSIBLE_DPS = 0.1
#: a hand settling into a pose or out of it moves the rest's ends by less than this from the
#: rest's mean attitude, ° (a move's rows)
POSE_HOLD_PLAUSIBLE_DEG = 0.5


def turn_angle_sigma(closures: Sequence[TurnClosure]) -> Component:
    """The hand's turn-angle error, ° (module docstring), from the up channels' ``closures``."""
    absorbs = (
        "the scatter of the turn integrals about the model: the hand's angle error, and a gyro "
        "scale asymmetry alike (a turn of another angle or a rate table tells them apart)"
    )
    why = "a turn short or long by a step, or a gyro scale asymmetry"
    return _closure_component("turn angle", closures, absorbs, TURN_ANGLE_PLAUSIBLE_DEG, why)


def turn_wobble_sigma(closures: Sequence[TurnClosure]) -> Component:
    """The hand's wobble as the cross-axis gyro integrals see it, °, from their ``closures``:
    a cube tilted back and forth while it turns adds the same to both directions (the
    misalignment, odd in the direction, cancels)."""
    absorbs = (
        "the part of the cross-axis turn integrals that is the same in both directions: the "
        "hand tilting the cube while it turns (and any other even effect: a tilted turn axis)"
    )
    why = "more than a hand's wobble gives: a systematic tilt of the turns"
    return _closure_component("turn wobble", closures, absorbs, TURN_WOBBLE_PLAUSIBLE_DEG, why)


def _closure_component(
    name: str, closures: Sequence[TurnClosure], absorbs: str, most: float, why: str
) -> Component:
    """σ² = Σ(c² − w)/(2K) of the ``closures``, 0 unless their scatter is beyond the white
    noise (:func:`host.model.stats.beyond_white`; a clipped 0 ± se would widen the yardstick
    under the null); its standard error from K dof;
    implausible above ``most`` (°, ``why``)."""
    k = len(closures)
    if k == 0:
        return Component(name, 0.0, math.nan, 0, "°", absorbs)
    c = np.array([cl.closure_deg for cl in closures])
    w = np.array([cl.white_var for cl in closures])
    var = float(np.sum(c * c - w)) / (2.0 * k)
    # standard error of var under the estimate itself: var(c²) = 2·(w + 2σ²)²
    se_var = math.sqrt(float(np.sum(2.0 * (w + 2.0 * max(var, 0.0)) ** 2))) / (2.0 * k)
    if beyond_white(float(c @ c), float(np.sum(w)), 2.0 * float(w @ w)):
        value = math.sqrt(var)
    else:
        value = 0.0
    sigma = se_var / (2.0 * value) if value > 0 else math.sqrt(se_var)
    plausible = f"{value:.2g}° over {most:g}°: {why}" if value > most else ""
    return Component(name, value, sigma, k, "°", absorbs, plausible)


def turn_pairs(signals: Sequence[RecordSignals], timed: bool) -> list[tuple[int, int, int]]:
    """(up axis, ccw record, cw record) for each pair of turns made both ways about an axis:
    its ccw turns paired with its cw turns in the order measured (the first with the first, the
    second with the second, …; by first sample time when ``timed``, else as the records are
    listed); a turn without a partner, or in motion at an end (its angle unknown), is left
    out."""
    by_dir: dict[tuple[int, int], list[tuple[float, int]]] = {}
    for r, sig in enumerate(signals):
        if sig.kind != "turn" or sig.angle_column is not None:  # in motion: no closure
            continue
        k = int(np.argmax(np.abs(sig.up)))
        turned = float(np.sum(sig.rate[:, k]))
        if turned != 0.0:
            start = float(sig.t_s[0]) if timed and len(sig.t_s) else 0.0
            by_dir.setdefault((k, int(np.sign(turned))), []).append((start, r))
    out: list[tuple[int, int, int]] = []
    for k in range(3):
        ccw = [r for _, r in sorted(by_dir.get((k, 1), []))]
        cw = [r for _, r in sorted(by_dir.get((k, -1), []))]
        out.extend((k, a, b) for a, b in zip(ccw, cw, strict=False))
    return out


def turn_closures(
    table: RowTable, signals: Sequence[RecordSignals], rest: np.ndarray, timed: bool
) -> list[TurnClosure]:
    """Per pair of turns made both ways about an axis (:func:`turn_pairs`) and gyro channel,
    the two integrals and what the static records say the gyro reads at rest there (``rest``
    (4, 3): the gyro's g-sensitivity per g and bias from the statics), each with its own white
    noise: :func:`host.model.variance.turn_angle_sigma`."""
    statics = [len(sig.t_s) for sig in signals if sig.kind != "turn"]
    n_static = float(np.median(statics)) if statics else 1.0
    got: dict[tuple[int, int], tuple[float, float, float, float]] = {}
    for ch in table.channels:
        sig = signals[ch.record]
        if sig.kind != "turn" or ch.sensor != "gyro":
            continue
        w = ch.aggregator[0]
        at_rest = float(np.concatenate([sig.up, [1.0]]) @ rest[:, ch.axis])  # force in g
        got[(ch.record, ch.axis)] = (table.y[ch.rows[0]], at_rest, float(w.sum()), float(w @ w))
    out = []
    for k, ccw, cw in turn_pairs(signals, timed):
        for ax in range(3):
            if (ccw, ax) not in got or (cw, ax) not in got:
                continue
            levels = table.static_noise.get(("gyro", ax), [(0.0, 1.0)])
            v = float(np.mean([a * t for a, t in levels]))
            (i1, r1, t1, ww1), (i2, _, t2, ww2) = got[(ccw, ax)], got[(cw, ax)]
            # the white noise of both integrals, and of the rest reading (about one static
            # record's mean) carried over both durations
            white = v * (ww1 + ww2) + v / n_static * (t1 + t2) ** 2
            out.append(TurnClosure(k, ax, (i1, i2), r1, (t1, t2), white))
    return out


@dataclass(frozen=True, eq=False)
class TurnSigmas:
    """The turns' named variance components (``components``), the turn-angle σ and the
    wobble they give the turn integrals (°), the closures the angle was measured from
    (empty when it is given) and what was said of them."""

    components: tuple[Component, ...]
    angle_deg: float
    wobble_deg: float
    closures: tuple[TurnClosure, ...]
    notes: list[str]


def turn_sigmas(
    table: RowTable, signals: Sequence[RecordSignals], rest: np.ndarray, timed: bool,
    nm: NoiseModel,
) -> TurnSigmas:  # fmt: skip
    """The hand's turn-angle error (measured from the closures of the turns made both ways,
    unless ``nm`` gives it) and its wobble on the cross axes (:mod:`host.model.variance`)."""
    closures = turn_closures(table, signals, rest, timed)
    wobble = turn_wobble_sigma([c for c in closures if c.axis != c.channel])
    notes = []
    if nm.turn_angle_sigma_deg is None:
        angle = turn_angle_sigma([c for c in closures if c.axis == c.channel])
        components: tuple[Component, ...] = (angle, wobble)
        kept = tuple(c for c in closures if c.axis == c.channel)
    else:
        absorbs = "the hand's angle error (given)"
        angle = Component("turn angle", float(nm.turn_angle_sigma_deg), 0.0, 0, "°", absorbs)
        components, kept = (wobble,), ()
        notes.append(f"turn angle: {angle.value:g}° per turn (given)")
    notes.extend("a named variance component: " + c.describe() for c in components)
    return TurnSigmas(components, angle.value, wobble.value, kept, notes)
