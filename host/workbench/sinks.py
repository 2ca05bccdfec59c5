"""An implausible variance component is a finding, not a sink (issue 39, item 2).

The hand's turn-angle error and its wobble (:mod:`host.model.components`) take up whatever
scatter of the turn integrals the model leaves. A hand gives a degree or two of wobble and
misses a stop by a step: a component beyond its plausible range
(:data:`host.model.variance.TURN_WOBBLE_PLAUSIBLE_DEG`, ``TURN_ANGLE_PLAUSIBLE_DEG``) has taken
up something else — a bias step between two turn records reaches only the cross-axis integrals
of the turns after it, which the wobble then holds as the hand's. A unit held by hand in poses
creeps and settles (``POSE_RATE_PLAUSIBLE_DPS`` on the poses' gyro means,
``POSE_HOLD_PLAUSIBLE_DEG`` on the moves' rows): beyond that, a gyro step or an unmodelled
effect of the moves is more likely than the hand. Such a diagnosis is never
``adequate``; the residuals are scanned again on the yardstick without the component (its rows
at their white noise), and the strongest signals found are each put into the model in turn
with the components estimated jointly again: the first with which every component is
plausible is what it absorbed, named as an unexplained signal of its channel.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from host.model.components import fit_with_components, without_components
from host.model.dataset import Dataset
from host.model.design import BuiltColumns
from host.model.fit import fit_model
from host.model.noise import still_runs
from host.model.signals import AXES, RecordSignals, true_runs
from host.model.spec import ModelTerm
from host.model.stats import chi2_sf
from host.model.variance import Component
from host.workbench.equals import signal_term
from host.workbench.scan import ScanHit, scan_signals
from host.workbench.steps import STEP, Placed

#: how many of the strongest signals (one per channel) are tried as what a component absorbed
TRIED = 4
#: the components whose plausibility is checked (estimated jointly with the fit)
CHECKED = ("turn angle", "turn wobble", "pose rate", "pose hold")


@dataclass(frozen=True)
class Absorbed:
    """What implausible ``components`` took up: ``hit`` the signal (found on the yardstick
    without them; None when no signal of the scan makes them plausible) and ``after`` the
    components estimated jointly with it in the model."""

    components: tuple[Component, ...]
    hit: ScanHit | None
    after: tuple[Component, ...] = ()
    #: the terms the diagnosis recommends take it up (no signal needed)
    by_terms: str = ""

    def describe(self) -> str:
        """One sentence for people."""
        what = "; ".join(f"{c.name} {c.value:.2g}{c.unit} ({c.plausible})" for c in self.components)
        now = ", ".join(f"{c.name} {c.value:.2g}{c.unit}" for c in self.after if c.name in CHECKED)
        if self.by_terms:
            return f"{what}: it absorbed what {self.by_terms} explains (with it: {now})"
        if self.hit is None:
            return (
                f"{what}: a variance component beyond what a hand gives is a finding, not "
                "noise; no signal of the scan takes it up (a tilted turn axis, an unmodelled "
                "effect of the turns?), so the model is not called adequate"
            )
        return (
            f"{what}: it absorbed {self.hit.sensor} {self.hit.axis} following "
            f"{self.hit.signal} (Δχ² = {self.hit.delta_chi2:.1f} with the component at 0); "
            f"with that in the model the components read {now}"
        )


def implausible(ds: Dataset) -> tuple[Component, ...]:
    """The checked components of ``ds`` beyond their plausible range."""
    return tuple(c for c in ds.components if c.name in CHECKED and c.plausible and c.dof > 0)


def what_absorbed(
    ds: Dataset,
    model: Sequence[ModelTerm],
    alpha: float,
    built: BuiltColumns | None = None,
    recommended: Sequence[ModelTerm] = (),
) -> Absorbed | None:
    """What the implausible components of ``ds`` (a dataset of a joint fit,
    :func:`host.model.components.fit_with_components`) took up (module docstring); None when
    every component is plausible. The ``recommended`` terms are tried first: when they make
    every component plausible, they explain what it took."""
    bad = implausible(ds)
    if not bad:
        return None
    if recommended:
        joint = fit_with_components(ds, [*model, *recommended], built=built)
        if not implausible(joint.dataset):
            label = ",".join(mt.label for mt in recommended)
            return Absorbed(bad, None, joint.components, by_terms=label)
    free = without_components(ds, [c.name for c in bad])
    hits = scan_signals(free, fit_model(free, model, built=built), alpha)
    tried: set[tuple[str, str]] = set()
    for h in hits:
        if (h.sensor, h.axis) in tried or len(tried) >= TRIED:
            continue
        tried.add((h.sensor, h.axis))
        term = signal_term(h.signal, h.sensor, ds)
        if term is None:
            continue
        mt = ModelTerm(term, h.sensor, (AXES.index(h.axis),))
        joint = fit_with_components(ds, [*model, mt], built=built)
        if not implausible(joint.dataset):
            return Absorbed(bad, h, joint.components)
    return Absorbed(bad, None)


# ---- the gyro at a turn's rests ---------------------------------------------------------------
#: a turn record's rests are read where the cube is still at least this long, s
REST_MIN_S = 0.3
#: a change between a turn's first and last rest is a step only beyond this many σ: a hand's
#: settling leaves the last rest's samples less white than the face's (|z| 3.7 with no gyro
#: step, on an independent session; steps of 0.05–0.5 °/s read 12–60)
INNER_Z_MIN = 5.0


@dataclass(frozen=True)
class RestChange:
    """A bias change the gyro reads at a turn's rests: ``record`` the turn, ``since`` what it is
    compared with (the static of the same face, or the turn's own rest before it turned),
    ``change`` °/s (later less earlier) ± ``sigma``, between the times ``lo_s`` and ``hi_s``."""

    record: str
    since: str
    axis: str
    change: float
    sigma: float
    lo_s: float
    hi_s: float

    @property
    def z(self) -> float:
        return self.change / self.sigma


def _rests(sig: RecordSignals, sd: float) -> list[tuple[int, int]]:
    """The turn's rests, each slow stretch (under 2 °/s about up) read about its own level: a
    bias step between two rests moves the later one's, and it is still a rest."""
    t = sig.t_s - sig.t_s[0]
    rate = sig.rate @ sig.up
    level = np.zeros_like(rate)
    for i, j in true_runs(np.abs(rate) < 2.0):
        level[i:j] = float(np.median(rate[i:j]))
    runs = still_runs(rate - level, t, sd)
    return [(a, b) for a, b in runs if t[b - 1] - t[a] >= REST_MIN_S]


def _face_static(ds: Dataset, turn: RecordSignals) -> RecordSignals | None:
    """The static record of the turn's up face measured nearest before it (else after)."""
    same = [s for s in ds.signals if s.kind == "static" and float(s.up @ turn.up) > 0.99]
    before = [s for s in same if s.t_s[-1] <= turn.t_s[0]]
    pick = before or same
    return min(pick, key=lambda s: abs(float(s.t_s[-1] - turn.t_s[0])), default=None)


def rest_changes(ds: Dataset) -> list[RestChange]:
    """Every turn record's gyro at its first rest against the static of its face (a bias change
    between them), and at its last rest against its first (a change inside the turn), per
    channel: the means' σ from the static's own per-sample scatter (white) and the floor (the
    unit's wander, which moves two rests of one turn apart as it moves two records). The last
    rest is read on its second half: the hand's settling at the end of a turn moved its whole
    mean by 4σ of the white noise on a drift session."""
    out: list[RestChange] = []
    floor = float(ds.floor.get("gyro", 0.0)) if ds.floor else 0.0
    for sig in ds.signals:
        face = _face_static(ds, sig) if sig.kind == "turn" else None
        if face is None or len(face.t_s) < 8:
            continue
        sd = np.std(face.gyro, axis=0, ddof=1)
        runs = _rests(sig, float(np.median(sd)))
        if not runs:
            continue
        first = runs[0]
        out += _changes(sig, first, face.gyro, sd, face.name, float(face.t_s[-1]), floor)
        if len(runs) > 1:
            a, b = runs[-1]
            last = ((a + b) // 2, b)
            t0 = float(sig.t_s[first[1] - 1])
            out += _changes(sig, last, sig.gyro[first[0] : first[1]], sd,
                            f"the first rest of {sig.name}", t0, floor)  # fmt: skip
    return out


def _changes(
    sig: RecordSignals,
    rest: tuple[int, int],
    earlier: np.ndarray,
    sd: np.ndarray,
    since: str,
    since_s: float,
    floor: float,
) -> list[RestChange]:
    """The gyro's mean over ``rest`` of turn ``sig`` less the mean of ``earlier`` (M, 3) °/s,
    per channel, σ from the per-sample scatter ``sd`` (3,) °/s and the ``floor`` °/s."""
    n = rest[1] - rest[0]
    t = float(sig.t_s[rest[0]])
    out = []
    for a in range(3):
        m = float(np.mean(sig.gyro[rest[0] : rest[1], a])) - float(np.mean(earlier[:, a]))
        v = float(sd[a]) ** 2
        s = math.sqrt(v / n + v / len(earlier) + 2 * floor**2)
        out.append(RestChange(sig.name, since, AXES[a], m, s, since_s, t))
    return out


def rest_hits(ds: Dataset, alpha: float) -> list[ScanHit]:
    """The significant bias changes at the turns' rests (:func:`rest_changes`, Bonferroni over
    them at ``alpha``), the strongest per gyro channel, as a step the scan would name."""
    changes = rest_changes(ds)
    m = max(len(changes), 1)
    best: dict[str, RestChange] = {}  # per channel the earliest significant change
    for c in sorted(changes, key=lambda c: c.lo_s):
        inner = c.since.startswith("the first rest")
        if inner and abs(c.z) < INNER_Z_MIN:
            continue
        if c.axis not in best and chi2_sf(c.z**2, 1) * m <= alpha:
            best[c.axis] = c
    out = []
    for c in best.values():
        where = (
            f"inside {c.record}, between its first rest and its last"
            if c.since.startswith("the first rest")
            else f"between {c.since} and the rest of {c.record}"
        )
        name = f"{STEP} {where} (the gyro at rest, {c.change:+.3g} ± {c.sigma:.1g} °/s)"
        d2 = c.z**2
        placed = Placed(0.5 * (c.lo_s + c.hi_s), c.lo_s, c.hi_s, c.change, c.sigma, d2, d2)
        out.append(ScanHit("gyro", c.axis, name, math.copysign(1.0, c.change), d2,
                           chi2_sf(d2, 1), True, math.nan, (placed,)))  # fmt: skip
    return out
