"""A face measured twice (the plan's closing ``x_up_2``): how far the accelerometer's bias moved
between the two, and whether that change is what the turns' accelerometers show.

A turn's axis is read against the static of the same face (:func:`host.model.turn_axis.turn_axes`):
the turn's horizontal accelerometers against the static's. A bias step or drift between the two
records moves them exactly as a seat tilted by Δb/g does: a 0.05 m/s² step is a 5 mrad lean, the
size a hand's re-seating is allowed (:data:`host.model.turn_axis.SEAT_TOL_RAD`). Taken for tilted
axes, such turns get their reference rate turned by the lean, which the gyro then shows as
structure of its own (a false "(rate y)²"), and the step itself is absorbed on the accelerometer.

The time pattern tells them apart: a bias change moves the same channel in every turn after it
(turns about different axes alike) and shows between the two measurements of one face; a seat
tilt belongs to its turns alone. :func:`leans_are_a_bias_change` tries each bias history the
re-measured face allows (a step at any gap between records between its two measurements, or a
drift linear in time across them) and says whether one of them leaves no turn tilted.

Where no static record follows the turns (a plan without the closing face), nothing measures
the bias after them: a step of the accelerometer's bias before the first tilted turn and a
seat tilted by Δb/g in every turn after it are the same records.
:func:`leans_are_an_unseen_step` tries that step (one change for every turn after it, on the
channels each has level, up to :data:`UNSEEN_STEP_MAX_RAD`) and, when it leaves no turn tilted,
the turns keep their nominal axes: the step then shows as misfit of their still moments for
the scan to name, and the note says a step there could not be told from a tilted seat.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from host.model.signals import RecordSignals
from host.model.turn_axis import SEAT_TOL_RAD, TurnAxis

#: a change between the two measurements of a face counts beyond this many standard errors
CHANGE_SIGMAS = 5.0
#: the largest lean an unseen step is tried for, rad (0.2 m/s² of bias: a MEMS bias steps by a
#: fraction of its zero-g tolerance, ±0.5 m/s² on the MPU-6000); a seat a few degrees off its
#: face (a hand pressing one edge) leans beyond it
UNSEEN_STEP_MAX_RAD = 0.02


@dataclass(frozen=True)
class BiasChange:
    """The accelerometer's reading of one face at ``first`` and at ``last`` (static records,
    times ``t0_s``, ``t1_s`` s): ``change`` (3,) m/s², last less first, and its ``sd`` (3,)."""

    first: str
    last: str
    t0_s: float
    t1_s: float
    change: np.ndarray
    sd: np.ndarray

    @property
    def seen(self) -> bool:
        """The change shows beyond the noise on some channel (:data:`CHANGE_SIGMAS`)."""
        return bool(np.any(np.abs(self.change) > CHANGE_SIGMAS * self.sd))

    def line(self, g: float) -> str:
        """The reader's sentence."""
        moved = ", ".join(
            f"{'xyz'[i]} {self.change[i]:+.4f}" for i in range(3)
            if abs(self.change[i]) > CHANGE_SIGMAS * self.sd[i]
        )  # fmt: skip
        return (
            f"the accelerometer read {self.first} and {self.last} apart by {moved} m/s² (a bias "
            f"step or drift between them): the turns' accelerometers show that change (up to "
            f"{1e3 * float(np.max(np.abs(self.change))) / g:.1f} mrad), not tilted turn axes, "
            "so their reference rates are left along the nominal axes"
        )


def bias_change(signals: Sequence[RecordSignals]) -> BiasChange | None:
    """The largest accelerometer change between the first and the last static record of one
    face (None when no face was measured twice)."""
    best: BiasChange | None = None
    statics = sorted((s for s in signals if s.kind == "static"), key=lambda s: float(s.t_s[0]))
    for i, first in enumerate(statics):
        later = [s for s in statics[i + 1 :] if np.allclose(s.up, first.up)]
        if not later or any(np.allclose(s.up, first.up) for s in statics[:i]):
            continue
        last = later[-1]
        change = last.accel.mean(axis=0) - first.accel.mean(axis=0)
        sd = np.sqrt(
            first.accel.var(axis=0) / len(first.t_s) + last.accel.var(axis=0) / len(last.t_s)
        )
        made = BiasChange(
            first.name, last.name, float(first.t_s[0]), float(last.t_s[-1]), change, sd
        )
        if best is None or np.max(np.abs(change) / sd) > np.max(np.abs(best.change) / best.sd):
            best = made
    return best


def _histories(
    ch: BiasChange, signals: Sequence[RecordSignals]
) -> list[Callable[[float], np.ndarray]]:
    """The bias (3,) m/s² at a time, for each history the change allows: a step at each gap
    between records inside [t0, t1], and a drift linear across it."""
    starts = sorted(float(s.t_s[0]) for s in signals if ch.t0_s < float(s.t_s[0]) <= ch.t1_s)
    ends = sorted(float(s.t_s[-1]) for s in signals)

    def step(cut: float) -> Callable[[float], np.ndarray]:
        return lambda x: ch.change * float(x > cut)

    def drift(x: float) -> np.ndarray:
        span = max(ch.t1_s - ch.t0_s, 1e-9)
        return ch.change * min(max((x - ch.t0_s) / span, 0.0), 1.0)

    cuts = [0.5 * (max((e for e in ends if e < t), default=t) + t) for t in starts]
    return [*(step(c) for c in cuts), drift]


def _untilted(a: TurnAxis, lean: np.ndarray) -> bool:
    """``lean`` (3,) rad within what :attr:`TurnAxis.tilted` allows ``a``."""
    return bool(np.linalg.norm(lean) <= a.bound + max(SEAT_TOL_RAD, 3.0 * a.sd))


def leans_are_a_bias_change(
    signals: Sequence[RecordSignals], axes: Sequence[TurnAxis]
) -> BiasChange | None:
    """The change a re-measured face shows, when it explains the turns' leans ``axes``
    (:func:`host.model.turn_axis.turn_axes`; module docstring): some tilted turn, and a history of
    that change (a step or a drift) under which no turn is tilted any more; else None."""
    if not any(a.tilted for a in axes):
        return None
    ch = bias_change(signals)
    if ch is None or not ch.seen:
        return None
    when = {s.name: s for s in signals}
    for bias in _histories(ch, signals):
        ok = True
        for a in axes:
            turn = when[a.record]
            seat = np.mean([bias(float(np.mean(when[n].t_s))) for n in a.statics], axis=0)
            moved = (bias(float(np.mean(turn.t_s))) - seat) / turn.g
            moved[np.abs(a.up) > 0.5] = 0.0  # the up channel carries no lean
            if not _untilted(a, a.lean - moved):
                ok = False
                break
        if ok:
            return ch
    return None


@dataclass(frozen=True)
class UnseenStep:
    """A step of the accelerometer's bias by ``change`` (3,) m/s² (0 on a channel no turn after
    it has level) in the gap before the turn record ``before``, which the leans of the turns
    ``turns`` (all after the last static record) equally are."""

    before: str
    turns: tuple[str, ...]
    change: np.ndarray
    #: the largest of the turns' lean σ, rad: a channel's change within 3 of it is not named
    sd: float

    def line(self, g: float) -> str:
        """The reader's sentence."""
        seen = [i for i in range(3) if abs(self.change[i]) > 3.0 * self.sd * g] or [
            int(np.argmax(np.abs(self.change)))
        ]
        moved = ", ".join(f"{'xyz'[i]} {self.change[i]:+.4f}" for i in seen)
        return (
            f"the turns {', '.join(self.turns)} lean as a bias step of the accelerometer by "
            f"{moved} m/s² before {self.before} would move them (up to "
            f"{1e3 * float(np.max(np.abs(self.change))) / g:.1f} mrad): no static record after "
            "them, so a step there could not be told from the turns made on a tilted seat; "
            "their reference rates are left along the nominal axes, a step shows as their "
            "misfit (measure a face again after the turns to tell)"
        )


def leans_are_an_unseen_step(
    signals: Sequence[RecordSignals], axes: Sequence[TurnAxis]
) -> UnseenStep | None:
    """The step no static record sees that explains the turns' leans ``axes`` (module
    docstring): with some turn tilted and every tilted one after the last static record, the
    change each channel's leans after a gap show on average (the turns after it that have the
    channel level), tried at each gap from the first tilted turn back to the last static; the
    first under which no turn is tilted. None otherwise."""
    tilted = [a for a in axes if a.tilted]
    when = {s.name: float(s.t_s[0]) for s in signals}
    last_static = max((float(s.t_s[-1]) for s in signals if s.kind == "static"), default=None)
    if not tilted or last_static is None:
        return None
    first = min(when[a.record] for a in tilted)
    if first < last_static:
        return None
    by_time = sorted(axes, key=lambda a: when[a.record])
    for k in range(len(by_time) - 1, -1, -1):
        if when[by_time[k].record] > first:
            continue
        after = by_time[k:]
        change = _mean_lean(after) * signals[0].g
        if float(np.max(np.abs(change))) > UNSEEN_STEP_MAX_RAD * signals[0].g:
            continue
        if all(_untilted(a, a.lean - _level(a, change) / signals[0].g) for a in after):
            sd = max(a.sd for a in after)
            return UnseenStep(after[0].record, tuple(a.record for a in after), change, sd)
    return None


def _level(a: TurnAxis, change: np.ndarray) -> np.ndarray:
    """``change`` (3,) on the channels turn ``a`` has level (0 on its up channel)."""
    out = np.array(change, dtype=float)
    out[np.abs(a.up) > 0.5] = 0.0
    return out


def _mean_lean(axes: Sequence[TurnAxis]) -> np.ndarray:
    """(3,) each channel's mean lean over the turns that have it level (0 where none has)."""
    level = np.array([np.abs(a.up) <= 0.5 for a in axes], dtype=float)
    leans = np.array([a.lean for a in axes]) * level
    n = level.sum(axis=0)
    return np.divide(leans.sum(axis=0), n, out=np.zeros(3), where=n > 0)
