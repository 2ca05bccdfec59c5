"""Reading a session as a person would: visits to faces, turns, and the plan's records.

A stream from anywhere (a logger's CSV, a capture, record files joined end to end) has no beeps:
the records are found in it, in the words of method.md §3-§5.

1. **Rests** (:func:`host.ingest.stillness.rests`) and their attitude from gravity.
2. **Visits**: consecutive rests on the same face with the cube never leaving that face in
   between (gravity never more than ``FACE_LEAVE_DEG`` off its axis) are one visit; a
   re-orientation starts the next.
3. **Turns** inside a visit: the rotation about the up axis (gyro bias removed, over the true
   sample times) from rest to rest. A turn ends at a rest where it has reached a whole number of
   turns (within ``TURN_HEADING_TOL_DEG``), started from the latest rest that makes it whole
   (an aborted start that was turned back is left out); steps with pauses in between count as
   one turn (four 90° steps are one turn), and a pause shorter than ``TURN_MERGE_REST_S`` at a
   whole turn with the motion going on the same way is part of a longer turn; rests within
   ``SAME_STOP_DEG`` and ``SAME_STOP_ACCEL`` of each other around a turn's start or end (a slow
   hand leaves and reaches its rest in pieces) are one opening or closing rest. A turn record
   starts at the end of the rest before its motion and ends at the start of the rest after it,
   with one sample interval of each (its last two samples, the first two of the closing rest:
   the detector's last quiet sample may already move); of a stop in pieces, the last piece
   before and the first piece after that lasts ``TURN_REST_MIN_S`` (a re-seat's settling
   before the turn is not part of it). Rests
   inside a turn belong to it. No visit spans a gap in time (:mod:`host.ingest.gaps`).
4. **The plan** picks the statics: visits without turns, with a rest of at least
   ``MIN_STATIC_S``, are matched to the plan's faces (x_up, x_dn, y_up, y_dn, z_up, z_dn) in
   order, keeping as many as the order allows (when two visits could serve a face, the later
   one: the operator placed it again); the record is the visit's longest rest. A visit before
   the plan's first static whose temperature rises by ``WARMUP_RISE_C`` or more is the warm-up
   (record ``warmup``, kept apart); a static visit after the last turn on a face already
   measured is a repeat (``x_up_2``: the closing check). Every other rest is left out with its
   reason, and the ones that could have been chosen are named as alternatives.
"""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass, field

import numpy as np

from host.ingest.gaps import gap_between, gap_starts
from host.ingest.stillness import Rest, Thresholds, attitude, axis_text, rests
from host.session.records import STATIC_NAMES, WARMUP_NAME
from host.session.spacing import cumulative_trapezoid

FACE_LEAVE_DEG = 45.0  #: gravity this far off a face's axis means the cube left the face
SMOOTH_S = 0.1  #: the accelerometer is averaged over this long to follow gravity, s
TURN_HEADING_TOL_DEG = 45.0  #: a rest within this of a whole number of turns ends a turn
TURN_MERGE_REST_S = 1.5  #: a shorter pause at a whole turn, motion going on the same way: one turn
SAME_STOP_DEG = 5.0  #: rests this close in heading are one stop of the hand (a slow start or end)
SAME_STOP_ACCEL = 0.2  #: … and this close in specific force, m/s² (≈ 1°: not the next attitude)
BACKSTEP_DEG = 20.0  #: a turn may step back this far between its rests (a hand correcting)
TURN_REST_MIN_S = 0.1  #: a turn starts and ends at a rest at least this long (shorter: motion), s
MIN_STATIC_S = 1.0  #: a rest shorter than this is not a static record, s
WARMUP_RISE_C = 0.2  #: a rise of the temperature this large before the plan: the warm-up, °C
ABORTED_MIN_DEG = 30.0  #: a rotation about up this large that is no whole turn is named, °


@dataclass(frozen=True)
class Segment:
    """A found (or labelled) piece of the stream: samples ``start`` … ``stop − 1``.

    ``found``: what the detector saw ("still +x", "turn +720° about +x", "move");
    ``label``: the record it becomes (``x_up``, ``x_ccw``, ``warmup`` … or ``-`` for none);
    ``quality``: a short human note; ``reason``: why this label (the plan's choice);
    ``up`` the up vector; ``turns``/``direction`` of a turn; ``heading_deg`` the cube's
    placement heading on the plate, ° (the labels file's column; None: not known)."""

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
    reason: str = ""
    heading_deg: float | None = None

    @property
    def duration_s(self) -> float:
        """End minus start, s."""
        return self.t1_s - self.t0_s


@dataclass
class _Visit:
    """Consecutive rests on one face; ``yaw`` (°) about its up axis per sample of the stream
    from the first rest on, ``turns`` as (opening rest, closing rest, angle °) indices."""

    face: str
    up: np.ndarray
    rests: list[Rest]
    yaw: np.ndarray
    offset: int
    means: list[np.ndarray] = field(default_factory=list)
    turns: list[tuple[int, int, float]] = field(default_factory=list)
    aborted: list[tuple[int, int, float]] = field(default_factory=list)

    def yaw_at(self, i: int) -> float:
        return float(self.yaw[i - self.offset])


def _t3(v: np.ndarray) -> tuple[float, float, float]:
    return (float(v[0]), float(v[1]), float(v[2]))


def _visits(
    t: np.ndarray, acc: np.ndarray, gyr: np.ndarray, bias: np.ndarray, found: list[Rest]
) -> tuple[list[_Visit], list[Rest]]:
    """Group the rests into visits (module docstring item 2); -> visits, tilted rests."""
    dt = float(np.median(np.diff(t))) if t.size > 1 else 0.01
    k = max(1, int(round(SMOOTH_S / dt)))
    c = np.concatenate([np.zeros((1, 3)), np.cumsum(acc, axis=0)])
    lo = np.clip(np.arange(len(t)) - k // 2, 0, len(t) - 1)
    hi = np.clip(lo + k, 1, len(t))
    smooth = (c[hi] - c[lo]) / (hi - lo)[:, None]
    norm = np.maximum(np.linalg.norm(smooth, axis=1), 1e-9)
    cos_leave = math.cos(math.radians(FACE_LEAVE_DEG))
    gaps = gap_starts(t)
    visits: list[_Visit] = []
    tilted: list[Rest] = []
    for r in found:
        label, up, _ = attitude(acc[r.start : r.stop].mean(axis=0))
        if label == "tilted":
            tilted.append(r)
            continue
        v = visits[-1] if visits else None
        if (
            v is not None
            and v.face == label
            and not gap_between(gaps, v.rests[-1].stop - 1, r.start)
        ):
            between = slice(v.rests[-1].stop, r.start)
            stays = smooth[between] @ v.up / norm[between]
            if stays.size == 0 or float(stays.min()) > cos_leave:
                v.rests.append(r)
                continue
        visits.append(_Visit(label, up, [r], np.zeros(0), r.start))
    for v in visits:
        v.means = [acc[r.start : r.stop].mean(axis=0) for r in v.rests]
        a, b = v.rests[0].start, v.rests[-1].stop
        v.yaw = cumulative_trapezoid(t[a:b], (gyr[a:b] - bias[a:b]) @ v.up)
    return visits, tilted


def _whole(angle: float) -> int:
    n = round(angle / 360.0)
    return n if n != 0 and abs(angle - 360.0 * n) <= TURN_HEADING_TOL_DEG else 0


def _find_turns(v: _Visit, t: np.ndarray) -> None:
    """Turns of a visit (module docstring item 3), into ``v.turns``/``v.aborted``."""
    rs = v.rests
    k = len(rs)
    start_yaw = [v.yaw_at(r.stop - 1) for r in rs]
    end_yaw = [v.yaw_at(r.start) for r in rs]

    def steady(i: int, j: int, sign: float) -> bool:
        """No step from rest i to rest j goes back more than BACKSTEP_DEG."""
        return all(sign * (end_yaw[m + 1] - start_yaw[m]) > -BACKSTEP_DEG for m in range(i, j))

    first = 0
    j = 1
    while j < k:
        begin = None
        for i in range(j - 1, first - 1, -1):
            d = end_yaw[j] - start_yaw[i]
            if _whole(d) and steady(i, j, math.copysign(1.0, d)):
                begin = i
                break
        if begin is None:
            j += 1
            continue
        opening = begin
        while begin > first and _same_stop(v, begin - 1, begin, start_yaw, end_yaw):
            begin -= 1  # a slow start breaks the opening rest into pieces: its first piece
        end = j
        n = _whole(end_yaw[j] - start_yaw[begin])
        while end < k - 1 and t[rs[end].stop - 1] - t[rs[end].start] < TURN_MERGE_REST_S:
            more = None
            for j2 in range(end + 1, k):
                d2 = end_yaw[j2] - start_yaw[begin]
                if not steady(begin, j2, math.copysign(1.0, n)):
                    break
                n2 = _whole(d2)
                if n2 * n > 0 and abs(n2) > abs(n):
                    more = (j2, n2)
                    break
            if more is None:
                break
            end, n = more
        closing = end
        while end < k - 1 and _same_stop(v, end, end + 1, start_yaw, end_yaw):
            end += 1  # … and a slow end its closing rest: up to its last piece
        if begin > first:
            _aborted(v, first, begin, start_yaw, end_yaw)
        a, b = _opening(v, t, begin, opening), _closing(v, t, closing, end)
        v.turns.append((a, b, end_yaw[b] - start_yaw[a]))
        first = end
        j = end + 1
    _aborted(v, first, k - 1, start_yaw, end_yaw)


def _lasts(v: _Visit, t: np.ndarray, m: int) -> bool:
    r = v.rests[m]
    return float(t[r.stop - 1] - t[r.start]) >= TURN_REST_MIN_S


def _opening(v: _Visit, t: np.ndarray, first: int, last: int) -> int:
    """The rest a turn starts from, of the pieces ``first`` … ``last`` of its opening stop:
    the last that lasts ``TURN_REST_MIN_S`` (the motion starts at its last sample), else the
    first piece (a slow hand's start is all motion)."""
    return next((m for m in range(last, first - 1, -1) if _lasts(v, t, m)), first)


def _closing(v: _Visit, t: np.ndarray, first: int, last: int) -> int:
    """The rest a turn ends at, of the pieces ``first`` … ``last`` of its closing stop: the
    first that lasts ``TURN_REST_MIN_S``, else the last piece."""
    return next((m for m in range(first, last + 1) if _lasts(v, t, m)), last)


def _same_stop(v: _Visit, a: int, b: int, start_yaw: list[float], end_yaw: list[float]) -> bool:
    """Rests a and b (consecutive) are one stop of the hand: the same heading (within
    ``SAME_STOP_DEG``) and the same attitude (accelerometer within ``SAME_STOP_ACCEL``)."""
    same_heading = abs(end_yaw[b] - start_yaw[a]) < SAME_STOP_DEG
    return same_heading and float(np.max(np.abs(v.means[b] - v.means[a]))) < SAME_STOP_ACCEL


def _aborted(v: _Visit, a: int, b: int, start_yaw: list[float], end_yaw: list[float]) -> None:
    """Rotations about up between rests a … b that are no whole turn (named, not records)."""
    for m in range(a, b):
        d = end_yaw[m + 1] - start_yaw[m]
        if abs(d) >= ABORTED_MIN_DEG:
            v.aborted.append((m, m + 1, d))


def _rise(temp: np.ndarray) -> float:
    """Temperature change over a span (°C): mean of its last tenth − mean of its first tenth."""
    n = max(1, temp.size // 10)
    return float(temp[-n:].mean() - temp[:n].mean())


def _plan_match(faces: list[str]) -> dict[int, str]:
    """Visit index -> static name: the longest match of ``faces`` to the plan's order, the
    later visit when two could serve a face."""
    m, p = len(faces), len(STATIC_NAMES)
    dp = np.zeros((m + 1, p + 1), dtype=int)
    for i in range(m - 1, -1, -1):
        for j in range(p - 1, -1, -1):
            best = max(dp[i + 1, j], dp[i, j + 1])
            if faces[i] == STATIC_NAMES[j]:
                best = max(best, 1 + dp[i + 1, j + 1])
            dp[i, j] = best
    out: dict[int, str] = {}
    i = j = 0
    while i < m and j < p:
        if dp[i + 1, j] == dp[i, j]:
            i += 1
        elif faces[i] == STATIC_NAMES[j] and dp[i, j] == 1 + dp[i + 1, j + 1]:
            out[i] = STATIC_NAMES[j]
            i += 1
            j += 1
        else:
            j += 1
    return out


@dataclass
class _Stream:
    """The stream read: times s, accel m/s², gyro °/s, temperature °C (recorded or not)."""

    t: np.ndarray
    acc: np.ndarray
    gyr: np.ndarray
    temp: np.ndarray
    temp_recorded: bool

    def dur(self, r: Rest) -> float:
        """How long a rest lasts, s."""
        return float(self.t[r.stop - 1] - self.t[r.start])


@dataclass
class _Statics:
    """The static visits (indices into the visits), each one's longest rest, the names chosen
    for them with the reason, and every record name taken so far."""

    visits: list[int]
    best: dict[int, Rest]
    chosen: dict[int, str]
    why: dict[int, str] = field(default_factory=dict)
    used: set[str] = field(default_factory=set)


def read_session(
    t: np.ndarray, acc: np.ndarray, gyr: np.ndarray, temp: np.ndarray, temp_recorded: bool
) -> tuple[list[Segment], Thresholds, list[str]]:
    """Segments of a stream (times s, accel m/s², gyro °/s, temperature °C) with labels and
    reasons, the stillness thresholds, and notes on ambiguous choices (module docstring)."""
    s = _Stream(t, acc, gyr, temp, temp_recorded)
    found, thr, bias = rests(t, acc, gyr)
    visits, tilted = _visits(t, acc, gyr, bias, found)
    for v in visits:
        _find_turns(v, t)
    notes: list[str] = []
    st = _match_statics(s, visits)
    _name_after_plan(s, visits, st)
    _explain_left_out(s, visits, st, notes)
    segs: list[Segment] = []
    for i, v in enumerate(visits):
        segs.extend(_visit_segments(s, v, i, st, notes))
    for r in tilted:
        if s.dur(r) >= MIN_STATIC_S:
            segs.append(_rest_segment(s, r, None, "-", "gravity is on no axis"))
    segs.sort(key=lambda g: g.start)
    return segs, thr, notes


def _rest_segment(s: _Stream, r: Rest, v: _Visit | None, label: str, reason: str) -> Segment:
    """A rest as a segment, its quality in words (attitude, |a|, spreads)."""
    am = s.acc[r.start : r.stop].mean(axis=0)
    _, up, angle = attitude(am)
    q = (
        f"gravity {angle:.1f}° off {axis_text(up)}, |a| {np.linalg.norm(am):.3f} m/s², "
        f"std a {s.acc[r.start : r.stop].std(axis=0).max():.3g} m/s², "
        f"std g {s.gyr[r.start : r.stop].std(axis=0).max():.3g} °/s"
    )
    what = f"still {axis_text(up)}" if v is not None else "still tilted"
    return Segment(r.start, r.stop, float(s.t[r.start]), float(s.t[r.stop - 1]), what, label, q,
                   _t3(up), reason=reason)  # fmt: skip


def _match_statics(s: _Stream, visits: list[_Visit]) -> _Statics:
    """Visits without turns, longest rest each, matched to the plan's faces in order; and a
    visit whose turns follow a rest long enough, on a face no visit without turns rests on
    (the adaptive dialogue's order: the up face, then its turns without placing the cube
    again), with that rest as its static."""
    best = {i: max(v.rests, key=s.dur) for i, v in enumerate(visits) if not v.turns}
    best = {i: r for i, r in best.items() if s.dur(r) >= MIN_STATIC_S}
    alone = {visits[i].face for i in best}
    for i, v in enumerate(visits):
        first = v.rests[v.turns[0][0]] if v.turns else None  # the rest before its first turn
        if first is not None and v.face not in alone and s.dur(first) >= MIN_STATIC_S:
            best[i] = first
    static_v = sorted(best)
    best = {i: best[i] for i in static_v}
    match = _plan_match([visits[i].face for i in static_v])
    chosen: dict[int, str] = {static_v[k]: name for k, name in match.items()}
    st = _Statics(static_v, best, chosen, used=set(chosen.values()))
    for i in static_v:
        if i in chosen:
            st.why[i] = (
                f"{chosen[i]}: the plan's {STATIC_NAMES.index(chosen[i]) + 1}. face in order"
            )
    return st


def _name_after_plan(s: _Stream, visits: list[_Visit], st: _Statics) -> None:
    """Name the static visits the plan's order left: the warm-up before it, a face after the
    turns (a repeat ``x_up_2`` when the face is taken)."""
    first_static = min(st.chosen) if st.chosen else len(visits)
    turn_v = [i for i, v in enumerate(visits) if v.turns]
    last_turn = max(turn_v) if turn_v else -1
    planned = set(st.chosen)
    visits_to = Counter(visits[i].face for i in st.visits)
    for i in st.visits:
        if i in planned:
            continue
        v = visits[i]
        a, b = st.best[i].start, st.best[i].stop
        rise = _rise(s.temp[v.rests[0].start : v.rests[-1].stop]) if s.temp_recorded else 0.0
        if visits_to[v.face] == 1 and v.face not in st.used:  # e.g. the adaptive order
            st.chosen[i] = v.face
            st.used.add(v.face)
            st.why[i] = f"{v.face}: the only visit to {axis_text(v.up)}, out of the plan's order"
        elif i < first_static and rise >= WARMUP_RISE_C and WARMUP_NAME not in st.used:
            st.chosen[i] = WARMUP_NAME
            st.used.add(WARMUP_NAME)
            st.why[i] = (f"warm-up: before the plan's first static, temperature {rise:+.1f} °C "
                         f"over {s.t[b - 1] - s.t[a]:.0f} s")  # fmt: skip
        elif i > last_turn >= 0 and v.face in st.used:
            name = f"{v.face}_2"
            k = 2
            while name in st.used:
                k += 1
                name = f"{v.face}_{k}"
            st.chosen[i] = name
            st.used.add(name)
            st.why[i] = f"{name}: {v.face} again after the turns, a repeat (the closing check)"
        elif i > last_turn >= 0 and v.face not in st.used:
            st.chosen[i] = v.face
            st.used.add(v.face)
            st.why[i] = f"{v.face}: after the turns, the only visit to {axis_text(v.up)}"


def _explain_left_out(s: _Stream, visits: list[_Visit], st: _Statics, notes: list[str]) -> None:
    """The reason each static visit left unnamed is left out; an alternative is also a note."""
    first_static = min(st.chosen) if st.chosen else len(visits)
    for i in st.visits:
        if i in st.chosen:
            continue
        v = visits[i]
        owner = next((j for j, n in st.chosen.items() if n == v.face), None)
        if i < first_static:
            st.why[i] = "before the plan's first static" + (
                " (its temperature does not rise: not a warm-up)" if s.temp_recorded else ""
            )
        elif owner is not None:
            t_owner, t_here = s.t[st.best[owner].start], s.t[st.best[i].start]
            st.why[i] = (f"alternative for {v.face}: another visit to {axis_text(v.up)}, the "
                         f"plan's order chose the one at {t_owner:.1f} s")  # fmt: skip
            notes.append(f"{v.face}: visits at {t_owner:.1f} s (chosen) and "
                         f"{t_here:.1f} s (alternative)")  # fmt: skip
        else:
            st.why[i] = f"{axis_text(v.up)} out of the plan's order"


def _visit_segments(s: _Stream, v: _Visit, i: int, st: _Statics, notes: list[str]) -> list[Segment]:
    """The segments of one visit: its rests (named or with the reason they are left out), its
    turns, and its aborted turns."""
    segs: list[Segment] = []
    turn_spans = [(v.rests[a].stop, v.rests[b].start) for a, b, _ in v.turns]
    for r in v.rests:
        if s.dur(r) < MIN_STATIC_S or any(a <= r.start and r.stop <= e for a, e in turn_spans):
            continue  # a pause inside a turn, or too short to be a static
        if v.turns and not (i in st.chosen and r is st.best.get(i)):
            segs.append(_rest_segment(s, r, v, "-", f"a rest on {axis_text(v.up)} between turns, "
                                      "belongs to the turns"))  # fmt: skip
        elif v.turns:  # the rest before its turns, on a face no other visit rests on
            why = st.why.get(i, "") + " (the rest before its turns: no other visit rests on it)"
            segs.append(_rest_segment(s, r, v, st.chosen[i], why))
        elif r is st.best[i]:
            segs.append(_rest_segment(s, r, v, st.chosen.get(i, "-"), st.why.get(i, "")))
        else:
            reason = _shorter_rest(s, r, st.best[i], st.chosen.get(i), notes)
            segs.append(_rest_segment(s, r, v, "-", reason))
    segs.extend(_turn_segments(v, s.t, st.used))
    for a, b, d in v.aborted:
        m0, m1 = v.rests[a].stop - 1, v.rests[b].start + 1
        about = axis_text(v.up)
        segs.append(Segment(m0, m1, float(s.t[m0]), float(s.t[m1 - 1]), f"move about {about}",
                            "-", f"{d:+.0f}° about {about}", _t3(v.up),
                            reason="no whole turn (an aborted turn?)"))  # fmt: skip
    return segs


def _shorter_rest(s: _Stream, r: Rest, ref: Rest, lab: str | None, notes: list[str]) -> str:
    """Why a rest shorter than its visit's longest is left out; a long one is a note."""
    reason = f"a shorter rest of the same visit ({s.dur(r):.1f} s < {s.dur(ref):.1f} s)"
    if lab:
        reason += f"; alternative for {lab}"
        if s.dur(r) > 0.5 * s.dur(ref):
            notes.append(
                f"{lab}: rests of {s.dur(ref):.1f} s (chosen) and "
                f"{s.dur(r):.1f} s at {s.t[r.start]:.1f} s (alternative)"
            )
    return reason


def _turn_segments(v: _Visit, t: np.ndarray, used: set[str]) -> list[Segment]:
    out = []
    for a, b, angle in v.turns:
        ra, rb = v.rests[a], v.rests[b]
        n = round(abs(angle) / 360.0)
        # the motion and one sample interval of each rest around it (a rest of one sample: it)
        start, stop = max(ra.start, ra.stop - 2), min(rb.stop, rb.start + 2)
        direction = 1 if angle > 0 else -1
        base = f"{'xyz'[int(np.argmax(np.abs(v.up)))]}_{'ccw' if direction > 0 else 'cw'}"
        label, k = base, 1
        while label in used:
            k += 1
            label = f"{base}_{k}"
        used.add(label)
        steps = sum(
            1 for m in range(a, b)
            if abs(v.yaw_at(v.rests[m + 1].start) - v.yaw_at(v.rests[m].stop - 1)) > 10.0
        )  # fmt: skip
        q = f"{n} turn{'s' if n > 1 else ''}, {angle:+.1f}° about {axis_text(v.up)}"
        if steps > 1:
            q += f" in {steps} steps"
        reason = (
            f"{label}: {angle:+.0f}° about {axis_text(v.up)} is {n} whole turn"
            + ("s" if n > 1 else "")
            + ", cut at its own rests"
        )
        out.append(Segment(start, stop, float(t[start]), float(t[stop - 1]),
                           f"turn {angle:+.0f}° about {axis_text(v.up)}", label, q, _t3(v.up),
                           n, direction, reason))  # fmt: skip
    return out
