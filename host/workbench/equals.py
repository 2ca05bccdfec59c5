"""Groups of equals: explanations the measured plan cannot tell apart (issue 24, item 3).

A missing effect can have more than one explanation that fits the records as well as the
others: a fixture term and a sensor term (the faces ±z leaning toward x, or accelerometer x
reading the square of the specific force along z: on the six faces both put the same value on
the ±z faces and nothing elsewhere), two sensor terms (a gyro scale asymmetry and a quadratic
scale on turns made at one rate), temperature, time and g² when the plan measured them in the
same order. Recommending one of them would be a guess.

Which explanations are equal is decided from the data, never from a list of pairs. Each
explanation is a set of whitened columns orthogonal to the model: a candidate term of
:mod:`host.workbench.candidates` (the catalogue's and a user's term file alike) or a signal of
:mod:`host.workbench.scan` on one channel (an off-catalogue shape: (f_z/g)², |f_z|, dT/dt, a
step in time, …), built through the same aggregation as a term's columns. Two are equal when
each explains the misfit significantly and neither adds significantly to the other: the Δχ²
of one given the other below the candidates' Bonferroni level, both ways. A group names its
members, says in words that the data cannot tell them apart, and names the records that would:
each term's ``needs`` and, for a signal, the record that varies its input alone (a 45°
attitude for f² and |f|, a sitting at another temperature, turns at another rate, …).
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from host.model.dataset import Dataset
from host.model.fit import Fit
from host.model.signals import AXES
from host.model.spec import ModelTerm
from host.model.stats import chi2_sf
from host.model.terms import Term
from host.workbench.candidates import (
    ALPHA,
    NEAR_FACTOR,
    Candidate,
    Tried,
    conditional_delta,
    json_number,
    try_term,
)
from host.workbench.scan import ScanHit, signal_function

#: what record varies a signal's input apart from the others' (the first key found in the
#: signal's name wins; the order puts the specific ones first)
SEPARATES: tuple[tuple[str, str], ...] = (
    ("step in time", "the first attitude measured again at the end, or the attitudes in "
     "another order (a step stays, an attitude effect moves with the attitude)"),
    ("dT/dt", "a sitting at steady temperature beside one while the chip warms (dT/dt "
     "differs, the temperature need not)"),
    ("temperature", "a sitting at another temperature (or records spread over the warm-up)"),
    ("time", "the attitudes measured in another order, or again later at the same "
     "temperature"),
    ("specific force", "45° attitudes (tilt_45_*: (f/g)², |f|/g and a face lean differ "
     "there), or the board turned 90° in the fixture (a sensor effect turns with the board)"),
    ("rate", "turns at another rate (a rate table, or turns made faster and slower)"),
)  # fmt: skip


#: the record kinds of a session without a cube (hand-held poses and the moves between them)
POSE_KINDS = frozenset({"pose", "move"})

#: the advice's cube phrases and their form for a session of poses and moves, which has no
#: faces, turns or tilt_45_* (:func:`advice`; the longer phrases first)
POSE_FORMS: tuple[tuple[str, str], ...] = (
    ("45° attitudes (tilt_45_*: (f/g)², |f|/g and a face lean differ there), or the board "
     "turned 90° in the fixture (a sensor effect turns with the board)",
     "poses with gravity between two axes, about 45° from each ((f/g)² and |f|/g differ "
     "there; python3 -m host plan DIR names the next pose the planner values most)"),
    ("attitudes that are not the six faces (the 45° attitudes tilt_45_*), or the same faces "
     "measured again after turning the board 90° in the fixture (a fixture error moves with "
     "the fixture, a sensor effect with the sensor)",
     "poses with gravity between two axes, about 45° from each"),
    ("the accelerometer at several headings on the plate (the still moments inside the turn "
     "records, a quarter turn or more apart), or static attitudes beyond the six faces "
     "(tilt_45_*)", "poses with gravity between two axes, about 45° from each"),
    ("the 45° attitudes tilt_45_*", "poses with gravity between two axes, about 45° from each"),
    ("±1 g faces; CW and CCW turns about the axis",
     "poses with the axis up and with it down; moves both ways about the axis"),
    ("turns at another rate (a rate table, or turns made faster and slower)",
     "moves at another rate (moves about the axis made faster and slower)"),
    ("turns at several rates", "moves about the axis at several rates"),
    ("turns about at least two axes", "moves about at least two axes"),
    ("turns about them", "moves about them"),
    ("each turn sees", "each move sees"),
    ("(±1 g, turns)", "(the axis up and down, moves)"),
    ("static records", "poses"),
)  # fmt: skip


def pose_session(ds: Dataset) -> bool:
    """Is ``ds`` a session without a cube: every record a pose or a move?"""
    kinds = {s.kind for s in ds.signals}
    return bool(kinds) and kinds <= POSE_KINDS


def advice(text: str, ds: Dataset) -> str:
    """The records that would tell explanations apart (``text``, in a cube's words) as the
    session's user can make them: unchanged on a cube session, in poses and moves
    (:data:`POSE_FORMS`) on a session without a cube."""
    if not pose_session(ds):
        return text
    for cube, poses in POSE_FORMS:
        text = text.replace(cube, poses)
    return text


@dataclass(frozen=True)
class Equals:
    """A group of explanations the records cannot tell apart, strongest first.

    ``members``: the candidates' labels (``face_error:accel:y``) and the signals' names
    (``accel y follows (specific force z)²``); ``terms``: the members a model can add;
    ``delta_chi2``: each member's drop of χ² alone; ``separate``: the records that would tell
    them apart, in words.
    """

    members: tuple[str, ...]
    terms: tuple[str, ...]
    delta_chi2: tuple[float, ...]
    separate: tuple[str, ...]
    #: the members that are a signal, not a term (off the catalogue): (sensor, axis, signal)
    signals: tuple[tuple[str, str, str], ...] = ()

    def describe(self) -> str:
        """One sentence for people."""
        whats = ", ".join(
            f"{m} (Δχ² = {d:.1f})" for m, d in zip(self.members, self.delta_chi2, strict=True)
        )
        return (
            f"the records cannot tell apart {whats}: each explains the misfit and none adds "
            "to another, so none is recommended alone"
        )

    def to_dict(self) -> dict[str, Any]:
        return {
            "members": list(self.members), "terms": list(self.terms),
            "signals": [{"sensor": se, "axis": ax, "signal": sg} for se, ax, sg in self.signals],
            "delta_chi2": [json_number(d) for d in self.delta_chi2],
            "separate": list(self.separate), "text": self.describe(),
        }  # fmt: skip


@dataclass(frozen=True, eq=False)
class _Explanation:
    label: str
    sensor: str
    axes: str
    delta: float
    tried: Tried
    separate: str
    #: None for a candidate term; (sensor, axis, signal) for a signal of the scan
    signal: tuple[str, str, str] | None = None


def signal_label(h: ScanHit) -> str:
    """How a group names a signal of the scan: 'accel y follows (specific force z)²'."""
    return f"{h.sensor} {h.axis} follows {h.signal}"


def signal_term(name: str, sensor: str, ds: Dataset) -> Term | None:
    """The scan's signal ``name`` as a one-parameter term (its columns aggregated like any
    term's); None when the scan has no such signal."""
    fn = signal_function(ds, sensor, name)
    if fn is None:
        return None
    return Term(
        name=f"signal {name}", doc=name, sensors=(sensor,), params=("coefficient",),
        units=("{u}",), columns=lambda sig, sen, a: fn(sig, sen, a)[:, None],
    )  # fmt: skip


def _separates(name: str) -> str:
    for key, words in SEPARATES:
        if key in name:
            return words
    return "records in which this signal varies apart from the others"


def _overlap(a: _Explanation, b: _Explanation) -> bool:
    return a.sensor == b.sensor and bool(set(a.axes) & set(b.axes))


class EqualsFinder:
    """The groups of equals of one diagnosis: the candidates and the scan's signals of a fit,
    made comparable; :meth:`group` gives the group of one candidate. A signal is tried (its
    columns built) only on the channels a group is asked for."""

    def __init__(
        self,
        ds: Dataset,
        fit: Fit,
        candidates: Sequence[Candidate],
        tried: Sequence[Tried],
        hits: Sequence[ScanHit],
        catalogue: Mapping[str, Term],
        alpha: float = ALPHA,
    ) -> None:
        m = max(sum(1 for c in candidates if c.identifiable), 1)
        #: the level at which one explanation adds to another (the candidates' Bonferroni)
        self.level = alpha / m
        self._ds, self._fit, self._hits = ds, fit, list(hits)
        self._signals: dict[tuple[str, str], list[_Explanation]] = {}
        self._pool: list[_Explanation] = []
        for c, t in zip(candidates, tried, strict=True):
            near = c.identifiable and c.p_value <= NEAR_FACTOR * self.level
            if (c.significant or near) and not c.implausible:
                needs = catalogue[c.term].needs if c.term in catalogue else c.needs
                self._pool.append(
                    _Explanation(c.label, c.sensor, c.axes, c.delta_chi2, t,
                                 advice(needs or "records in which its input varies apart", ds))
                )  # fmt: skip

    def _channel_signals(self, sensor: str, axis: str) -> list[_Explanation]:
        """The scan's significant signals on one channel, tried like terms (cached)."""
        key = (sensor, axis)
        if key not in self._signals:
            out = []
            for h in self._hits:
                if (h.sensor, h.axis) != key:
                    continue
                term = signal_term(h.signal, h.sensor, self._ds)
                if term is None:
                    continue
                mt = ModelTerm(term, h.sensor, (AXES.index(h.axis),))
                t = try_term(self._ds, self._fit, mt)
                if not t.reason:
                    out.append(
                        _Explanation(signal_label(h), h.sensor, h.axis, t.delta, t,
                                     advice(_separates(h.signal), self._ds),
                                     (h.sensor, h.axis, h.signal))
                    )  # fmt: skip
            self._signals[key] = out
        return self._signals[key]

    def _adds(self, given: _Explanation, extra: _Explanation) -> bool:
        """Does ``extra`` add significantly to a model that holds ``given``?"""
        d = conditional_delta(given.tried, extra.tried)
        return chi2_sf(d, extra.tried.cw_perp.shape[1]) <= self.level

    def _per_channel(self, anchor: _Explanation) -> list[_Explanation]:
        """For a term shared by several channels (a plate tilt): the strongest other term on
        each of those channels, when at least two have one (together they may explain what
        the shared term does, though none does alone)."""
        if len(anchor.axes) < 2:
            return []
        out = []
        for ax in anchor.axes:
            on = [e for e in self._pool if e.signal is None and e.sensor == anchor.sensor
                  and e.axes == ax and e.tried.ds is anchor.tried.ds]  # fmt: skip
            if on:
                out.append(max(on, key=lambda e: e.delta))
        return out if len(out) > 1 else []

    def group(self, candidate: Candidate) -> Equals | None:
        """The group of equals of ``candidate`` (it first, then the others strongest first),
        None when no other explanation is its equal.

        A signal that is the candidate's own shape (its one column is the signal's) is the
        candidate, and a signal of the same input (its square, its magnitude: ``family``) a
        variant of it, not another explanation."""
        anchor = next(
            (e for e in self._pool if e.signal is None and e.label == candidate.label), None
        )
        if anchor is None:
            return None
        signals = [e for ax in anchor.axes for e in self._channel_signals(anchor.sensor, ax)]
        own = {family(e.signal[2]) for e in signals if e.signal and _same_shape(anchor, e)}
        others = [e for e in signals if e.signal and family(e.signal[2]) not in own]
        equal = self._equals_of(anchor, [*self._pool, *others])
        parts = [e for e in self._per_channel(anchor) if e not in equal]
        if parts:
            both = _Explanation(" + ".join(e.label for e in parts), anchor.sensor, anchor.axes,
                                math.nan, _combined([e.tried for e in parts]), "")  # fmt: skip
            if not self._adds(anchor, both) and not self._adds(both, anchor):
                equal += parts
        return _make(anchor, equal)

    def _equals_of(self, anchor: _Explanation, pool: Sequence[_Explanation]) -> list[_Explanation]:
        """The explanations of ``pool`` that overlap ``anchor``, explain the misfit about as well
        (Δχ² within the level) and neither adds significantly to the other."""
        return [
            e for e in pool
            if e is not anchor and _overlap(anchor, e) and math.isfinite(e.delta)
            and chi2_sf(e.delta, e.tried.cw_perp.shape[1]) <= NEAR_FACTOR * self.level
            and not self._adds(anchor, e) and not self._adds(e, anchor)
        ]  # fmt: skip

    def signal_group(self, hit: ScanHit) -> Equals | None:
        """The group of equals of a signal the scan found and no term explains (temperature²,
        dT/dt and time when the plan measured them together), None when it has no equal. The
        other signals of its own input (its square, another step) are variants of it."""
        signals = self._channel_signals(hit.sensor, hit.axis)
        anchor = next((e for e in signals if e.signal == (hit.sensor, hit.axis, hit.signal)),
                      None)  # fmt: skip
        if anchor is None or anchor.signal is None:
            return None
        mine = family(anchor.signal[2])
        others = [e for e in signals if e.signal and family(e.signal[2]) != mine]
        equal = self._equals_of(anchor, [*self._pool, *others])
        return _make(anchor, equal)


def _make(anchor: _Explanation, equal: Sequence[_Explanation]) -> Equals | None:
    """The group of ``anchor`` and its ``equal`` explanations (None when there are none)."""
    if not equal:
        return None
    members = [anchor]
    seen = {family(anchor.signal[2])} if anchor.signal else set()
    for e in sorted(equal, key=lambda e: -e.delta):
        if e.signal is not None:  # one signal of each input: its strongest form
            if family(e.signal[2]) in seen:
                continue
            seen.add(family(e.signal[2]))
        members.append(e)
    separate: list[str] = []
    for e in members:
        if e.separate not in separate:
            separate.append(e.separate)
    return Equals(
        tuple(e.label for e in members),
        tuple(e.label for e in members if e.signal is None),
        tuple(e.delta for e in members),
        tuple(separate),
        tuple(e.signal for e in members if e.signal is not None),
    )


def _combined(parts: Sequence[Tried]) -> Tried:
    """Several terms tried together on one fit (the same yardstick): their columns side by
    side, fitted jointly."""
    cw = np.column_stack([t.cw_perp for t in parts])
    r = parts[0].r
    beta, *_ = np.linalg.lstsq(cw, r, rcond=None)
    after = r - cw @ beta
    cov = np.full((cw.shape[1], cw.shape[1]), np.nan)
    delta = float(r @ r - after @ after)
    return Tried(parts[0].mt, parts[0].ds, parts[0].fit, cw, r, beta, cov, delta, "")


#: |cos| between two one-column explanations from which they are the same shape
SAME_SHAPE = 1.0 - 1e-6


def _same_shape(a: _Explanation, b: _Explanation) -> bool:
    """Are ``a`` and ``b`` one column each, and the same column (up to a factor)?"""
    ta, tb = a.tried, b.tried
    if ta.ds is not tb.ds:  # on one yardstick
        ta = try_term(tb.ds, tb.fit, ta.mt)
    if ta.cw_perp.shape[1] != 1 or tb.cw_perp.shape[1] != 1:
        return False
    u, v = ta.cw_perp[:, 0], tb.cw_perp[:, 0]
    nu, nv = float(np.linalg.norm(u)), float(np.linalg.norm(v))
    return nu > 0 and nv > 0 and abs(float(u @ v)) / (nu * nv) >= SAME_SHAPE


def family(signal: str) -> str:
    """The input a scan signal follows, whatever its power: '(rate x)²', '|rate x|' and
    'rate x' are 'rate x'; 'temperature²' is 'temperature'; a step is its own."""
    name = signal.split(" / ")[0]
    if name.startswith("a step in time"):
        return "step"
    return re.sub(r"[()|²]", "", name).strip()
