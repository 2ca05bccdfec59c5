"""Plan the next measurement from the fit's own information.

Given the records measured so far, a model and the method's tolerances (method.md §7), every
record the operator could measure next — a face again, a 45° attitude (an edge of the cube up),
a pair of turns about an axis — is added to the session as it would be measured (the sensor as
fitted so far, its measured noise, the session's sample rate and record length), the model is
fitted again, and the records are ranked by how much each shrinks the worst standard error
relative to its tolerance per minute of the operator's time (placing, settling, measuring,
turning: :class:`OperatorTime`).

Only the information matters, not the values drawn: a record's σ in a weighted least-squares
fit depends on where it puts the cube and how long, not on its noise's draw. Where a channel's
fit is poor its standard errors are widened (the Birge ratio of :func:`host.model.stats.
stderr_scale`) — the ranking keeps the widening the records measured so far show.
"""

from __future__ import annotations

import dataclasses
import math
import zlib
from collections import defaultdict
from collections.abc import Callable, Collection, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from host.bench.plan import tilted_45
from host.model.dataset import build_dataset
from host.model.fit import Fit, fit_model
from host.model.noise import NoiseModel
from host.model.rows import RecordWork
from host.model.spec import ModelTerm
from host.session.checks import turn_in_motion
from host.session.directory import Session
from host.session.method import (
    DEFAULT_HEIGHT_M,
    DEFAULT_LATITUDE_DEG,
    TOLERANCES,
    local_gravity,
    names_to_gsens,
    names_to_matrix,
    record_stats,
)
from host.session.records import HEADING_KEY, STATIC_NAMES, Record, turn_window_s


@dataclass(frozen=True)
class OperatorTime:
    """What a record costs the operator, s: ``place`` the cube on a face against the fence,
    ``place_tilted`` on an edge (a 45° wedge), ``settle`` before the start beep, ``turn_ready``
    the 'get ready' before each turn and the return against the ruler after it, ``soak`` the
    wait until the chip has settled at another temperature (another room, a warm box) and its
    warm-up. The record's own length (accumulation time, or the fixed turn window of method.md
    §4) is added."""

    place: float = 15.0
    place_tilted: float = 40.0
    settle: float = 3.0
    turn_ready: float = 8.0
    soak: float = 1800.0


#: the operator's times when nobody says otherwise
OPERATOR_TIME = OperatorTime()


@dataclass(frozen=True)
class Candidate:
    """One record (or pair of turns) the operator could measure next.

    ``records``: the records it adds (name, up vector in chip axes, kind, seconds, turns,
    direction +1 ccw / -1 cw); ``operator_s``: what it costs the operator, s; ``pace``: turns
    made this many times as fast as the operator's own (1: the same hand);
    ``temp_offset_c``: its records at this many °C from the session's mean chip temperature
    (a sitting at another temperature); ``headings``: the placement heading the operator
    records for each record, ° (:data:`HEADING_KEY`; empty or None: as the session's records
    carry it)."""

    label: str
    records: tuple[tuple[str, tuple[float, float, float], str, float, int, int], ...]
    operator_s: float
    pace: float = 1.0
    temp_offset_c: float = 0.0
    headings: tuple[float | None, ...] = ()


@dataclass(frozen=True)
class Ranked:
    """A candidate with what it does: ``worst_after`` the worst σ/tolerance with it added (and
    the name of the value that is then worst), ``sigma_after`` name -> σ, ``determines`` the
    values now undetermined that it would determine, ``gain_per_min`` the worst σ/tolerance
    it removes per minute of operator time (∞ when it determines a value; with a target, the
    :func:`excess` over the target it removes per minute)."""

    candidate: Candidate
    worst_after: float
    worst_name: str
    sigma_after: Mapping[str, float]
    determines: tuple[str, ...]
    gain_per_min: float


@dataclass(frozen=True)
class NextPlan:
    """The planner's answer: the worst σ/tolerance now (and whose), the σ of every value with
    a tolerance now, and the candidates ranked best first."""

    worst_now: float
    worst_name: str
    sigma_now: Mapping[str, float]
    ranked: tuple[Ranked, ...]
    notes: tuple[str, ...] = ()
    #: name -> the σ the model's misfit sets (:func:`misfit_sigmas`): the part of
    #: ``sigma_now`` no record lowers (0 where the channel fits)
    misfit: Mapping[str, float] = dataclasses.field(default_factory=dict)

    def misfit_worst(
        self, tolerances: Mapping[str, float | None] = TOLERANCES
    ) -> tuple[float, str]:
        """The largest σ/tolerance the model's misfit alone sets, and whose (0, '': none)."""
        return worst_ratio(self.misfit, tolerances)


def _scales(fit: Fit) -> dict[tuple[str, str], float]:
    """(sensor, axis letter or '') -> the factor its standard errors were widened by."""
    out: dict[tuple[str, str], float] = {}
    for c in fit.channels:
        out[(c.sensor, c.axis)] = c.se_scale
        out[(c.sensor, "")] = max(out.get((c.sensor, ""), 1.0), c.se_scale)
    return out


def unscaled_sigmas(fit: Fit, widen: Fit | None = None) -> dict[str, float]:
    """Parameter name -> its standard error from the noise model alone (σ/σ-widening of
    ``fit``), times the widening ``widen`` shows (None: none). NaN where undetermined."""
    own, other = _scales(fit), _scales(widen) if widen is not None else {}
    out: dict[str, float] = {}
    for p in fit.parameters:
        key = (p.sensor, p.axis)
        mine = fit.se_scales.get(p.name, own.get(key, 1.0))
        theirs = widen.se_scales.get(p.name, other.get(key, 1.0)) if widen is not None else 1.0
        out[p.name] = p.stderr / mine * theirs
    return out


#: the misfit a channel shows beyond doubt: its χ²/dof beyond 1 by more than this many
#: standard deviations of χ²/dof under the noise model (√(2/dof)) — a chance excess of white
#: noise (the Birge widening at p < 0.01 of 1 % of channels) sets no floor
MISFIT_MARGIN_SD = 4.0


def _misfit_factors(fit: Fit) -> dict[tuple[str, str], float]:
    """(sensor, axis letter or '') -> √(χ²/dof − 1 − margin), the misfit's σ in units of the
    noise model's (0 where the channel fits or its excess may be chance:
    :data:`MISFIT_MARGIN_SD`)."""
    out: dict[tuple[str, str], float] = {}
    for c in fit.channels:
        excess_var = 0.0
        if c.se_scale > 1.0 and c.dof > 0 and math.isfinite(c.chi2):
            excess_var = c.chi2 / c.dof - 1.0 - MISFIT_MARGIN_SD * math.sqrt(2.0 / c.dof)
        f = math.sqrt(max(excess_var, 0.0))
        out[(c.sensor, c.axis)] = f
        out[(c.sensor, "")] = max(out.get((c.sensor, ""), 0.0), f)
    return out


def misfit_sigmas(fit: Fit) -> dict[str, float]:
    """Parameter name -> the σ the model's misfit sets: the part of its widened σ (the noise
    model's σ_n times the channel's Birge ratio, :func:`host.model.stats.stderr_scale`) that
    the misfit shows beyond doubt, σ_n·√(χ²/dof − 1 − margin) (:data:`MISFIT_MARGIN_SD`; 0
    where the channel fits). A record measured next lowers σ_n; the planner holds this part
    as it is — an effect the model lacks moves the values the same way in every record of a
    kind, and no record averages it away (issue 46). 0 where the value is not determined
    yet."""
    own, factor = _scales(fit), _misfit_factors(fit)
    out: dict[str, float] = {}
    for p in fit.parameters:
        key = (p.sensor, p.axis)
        sigma = p.stderr / own.get(key, 1.0) * factor.get(key, 0.0)
        out[p.name] = sigma if math.isfinite(sigma) else 0.0  # undetermined: none known yet
    return out


def with_misfit(noise: Mapping[str, float], misfit: Mapping[str, float]) -> dict[str, float]:
    """The σ a value will have: its noise part ``noise`` (lowered by the records to come)
    and the ``misfit`` part (:func:`misfit_sigmas`, held), added in quadrature."""
    return {n: math.hypot(s, misfit.get(n, 0.0)) for n, s in noise.items()}


def excess(
    sigmas: Mapping[str, float],
    target: float,
    tolerances: Mapping[str, float | None] = TOLERANCES,
) -> float:
    """Σ over the values with a tolerance of how far σ/tolerance lies above ``target`` (0 when
    every value meets it; ∞ when one is not determined): what an adaptive plan drives to 0."""
    total = 0.0
    for n, s in sigmas.items():
        tol = tolerances.get(n)
        if tol:
            total += max(0.0, s / tol - target) if math.isfinite(s) else math.inf
    return total


def unique_name(base: str, taken: Collection[str]) -> str:
    """``base`` if no record has it, else ``base_2``, ``base_3`` … (a record measured again)."""
    if base not in taken:
        return base
    k = 2
    while f"{base}_{k}" in taken:
        k += 1
    return f"{base}_{k}"


def worst_ratio(
    sigmas: Mapping[str, float], tolerances: Mapping[str, float | None] = TOLERANCES
) -> tuple[float, str]:
    """The largest σ/tolerance over the values that have a tolerance, and its name (∞ for a
    value the records do not determine)."""
    worst, name = 0.0, ""
    for n, s in sigmas.items():
        tol = tolerances.get(n)
        if not tol:
            continue
        r = s / tol if math.isfinite(s) else math.inf
        if r > worst:
            worst, name = r, n
    return worst, name


def _values(fit: Fit) -> dict[str, float]:
    """The base model's values as fitted (0 where not in the model or undetermined)."""
    out = {p.name: p.value for p in fit.parameters if math.isfinite(p.value)}
    return out


def _sensor(
    values: Mapping[str, float],
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Ma, A0, Mg, GA, G0 of method.md §2 from fitted values (0 where absent)."""

    v = defaultdict(float, values)
    a0 = np.array([v["A0x"], v["A0y"], v["A0z"]])
    g0 = np.array([v["G0x"], v["G0y"], v["G0z"]])
    return names_to_matrix("A", v), a0, names_to_matrix("G", v), names_to_gsens(v), g0


def synthetic_record(
    name: str,
    up: Sequence[float],
    kind: str,
    seconds: float,
    *,
    g: float,
    values: Mapping[str, float],
    accel_sd: np.ndarray,
    gyro_sd: np.ndarray,
    dt_s: float,
    temp_c: float,
    turns: int = 0,
    direction: int = 0,
    meta: Mapping[str, str] | None = None,
    rng: np.random.Generator | None = None,
    profile: np.ndarray | None = None,
) -> Record:
    """A record as the sensor fitted so far would measure it (method.md §2 with ``values``):
    ``kind`` 'static' (``seconds`` of rest with ``up``, a unit vector in chip axes, pointing
    away from the Earth) or 'turn' (``turns`` whole turns about ``up``, ``direction`` +1 ccw,
    -1 cw, in a window of ``seconds``: the hand's rate ``profile`` (°/s, ≥ 0, one value a
    sample, e.g. a turn the operator made) scaled to 360°·turns, else a smooth turn with 1 s of
    rest at each end); white noise of ``accel_sd`` (m/s²) and ``gyro_sd`` (°/s) per axis, one
    sample every ``dt_s`` s."""
    rng = rng or np.random.default_rng(0)
    u = np.asarray(up, dtype=float)
    u = u / np.linalg.norm(u)
    t_s = np.arange(0.0, seconds, dt_s)
    n = len(t_s)
    rate = np.zeros(n)
    if kind == "turn" and profile is not None and len(profile) > 1:
        rate = np.interp(t_s, np.arange(len(profile)) * dt_s, np.abs(profile), right=0.0)
    elif kind == "turn":
        rest = min(1.0, seconds / 5.0)
        moving = (t_s >= rest) & (t_s <= seconds - rest)
        phase = (t_s - rest) / max(seconds - 2 * rest, dt_s)
        rate = np.where(moving, 1.0 - np.cos(2 * np.pi * phase), 0.0)
    if kind == "turn":
        area = float(np.trapezoid(rate, t_s)) if n > 1 else 1.0
        rate *= direction * 360.0 * turns / area
    ma, a0, mg, ga, g0 = _sensor(values)
    force = np.tile(g * u, (n, 1))
    omega = rate[:, None] * u[None, :]
    accel = force @ (np.eye(3) + ma).T + a0 + rng.normal(0.0, 1.0, (n, 3)) * accel_sd
    gyro = omega @ (np.eye(3) + mg).T + (force / g) @ ga.T + g0
    gyro = gyro + rng.normal(0.0, 1.0, (n, 3)) * gyro_sd
    m = {"kind": kind, "up": "[" + ", ".join(f"{x:.6g}" for x in u) + "]"}
    if kind == "turn":
        m.update({"turns": str(turns), "direction": "ccw" if direction > 0 else "cw"})
    m.update(meta or {})
    return Record(name, t_s * 1000.0, accel, gyro, np.full(n, temp_c), m)


def _face_up(name: str) -> tuple[float, float, float]:
    v = [0.0, 0.0, 0.0]
    v["xyz".index(name[0])] = -1.0 if name.endswith("_dn") else 1.0
    return (v[0], v[1], v[2])


def candidates(
    static_s: float | Sequence[float],
    turns: int,
    time: OperatorTime = OPERATOR_TIME,
    *,
    tilted: bool = True,
    paces: Sequence[float] = (1.0,),
    temperatures: Sequence[float] = (),
) -> list[Candidate]:
    """The records the operator could measure next: each face again (for each length in
    ``static_s``, s), each 45° attitude of :func:`host.bench.plan.tilted_45` (``tilted``; the
    first length), a pair of turns (ccw and cw, ``turns`` each, the method's window)
    about each axis at each of ``paces`` (×2: twice as fast as the operator turned; a slower
    pace in a longer window, :func:`paced_window_s`), and for
    each of ``temperatures`` (°C from the session's mean chip temperature) a sitting there:
    the six faces again after ``time.soak``. Record names are the plan's (``x_up``,
    ``tilt_45_3``, ``x_ccw``)."""
    lengths = [float(static_s)] if isinstance(static_s, int | float) else list(static_s)
    out: list[Candidate] = []
    for seconds in lengths:
        for face in STATIC_NAMES:
            rec = (face, _face_up(face), "static", seconds, 0, 0)
            label = f"{face} again" if len(lengths) == 1 else f"{face} again, {seconds:g} s"
            out.append(Candidate(label, (rec,), time.place + time.settle + seconds))
    for name, up in tilted_45() if tilted else ():
        rec = (name, up, "static", lengths[0], 0, 0)
        label = f"{name} (up {_format_up(up)})"
        out.append(Candidate(label, (rec,), time.place_tilted + time.settle + lengths[0]))
    for ax in "xyz":
        up = _face_up(f"{ax}_up")
        for pace in paces:
            window = paced_window_s(turns, pace)
            pair = tuple(
                (f"{ax}_{d}", up, "turn", window, turns, s) for d, s in (("ccw", 1), ("cw", -1))
            )
            cost = 2 * (time.place + time.turn_ready + window)
            label = f"{ax} turns, {turns} each way"
            label += "" if pace == 1.0 else f", {pace:g}× as fast"
            out.append(Candidate(label, pair, cost, pace))
    seconds = lengths[0]
    faces = tuple((f, _face_up(f), "static", seconds, 0, 0) for f in STATIC_NAMES)
    for dt in temperatures:
        label = f"6 faces at {dt:+g} °C, {seconds:g} s"  # a sitting at another temperature
        cost = time.soak + len(faces) * (time.place + time.settle + seconds)
        out.append(Candidate(label, faces, cost, temp_offset_c=float(dt)))
    return out


def paced_window_s(turns: int, pace: float) -> float:
    """The recording window of ``turns`` whole turns made ``pace`` times as fast as the
    operator's own, s: the method's window (method.md §4), ``1/pace`` times as long for a
    slower turn (the same turns at half the rate take twice as long; a faster one fits the
    method's window)."""
    return turn_window_s(turns) / min(pace, 1.0)


#: a sitting at another temperature: this far from the session's, °C (a room or a warm box)
OTHER_TEMPERATURE_C = 15.0


def has_temperature_term(model: Sequence[ModelTerm]) -> bool:
    """Whether ``model`` has a term of the chip temperature (only a sitting at another
    temperature determines it well)."""
    return any("temperature" in mt.term.name for mt in model)


def _format_up(up: Sequence[float]) -> str:
    parts = []
    for k, c in zip("xyz", up, strict=True):
        if abs(c) > 1e-9:
            parts.append(("+" if c > 0 else "−") + k)
    return "".join(parts)


class Augmenter:
    """The session with a candidate's records added as the sensor fitted so far (``values``,
    method.md §2) would measure them: the noise measured in its static records, its sample
    rate, mean chip temperature, power-on time and placement header; the same draw for the
    same record name and ``seed``. ``static_s``/``turns``: the session's own record length
    and turns."""

    def __init__(self, session: Session, values: Mapping[str, float], g: float, seed: int = 0):
        recs = list(session.records.values())
        stats = [record_stats(r) for r in recs]
        statics = [s for s in stats if s.kind in ("static", "pose")]  # the rests
        self.session, self.values, self.g, self.seed = session, values, g, seed
        self.accel_sd = np.median([s.accel_std for s in statics], axis=0)
        self.gyro_sd = np.median([s.gyro_std for s in statics], axis=0)
        self.dt_s = float(np.median([s.dt_s for s in stats if s.dt_s > 0]))
        self.temp_c = float(np.mean([float(np.mean(r.temp)) for r in recs]))
        self.static_s = float(np.median([s.duration_s for s in statics]))
        ns = [int(r.meta["turns"]) for r in recs if r.meta.get("turns", "").strip().isdigit()]
        self.turns = ns[0] if ns else _turns_made(recs)
        self.meta: dict[str, str] = {}
        if all("power_on_s" in r.meta for r in recs):
            end = max(float(r.meta["power_on_s"]) + r.duration_s for r in recs)
            self.meta["power_on_s"] = f"{end + 60.0:.3f}"
        if any(HEADING_KEY in r.meta for r in recs):
            self.meta[HEADING_KEY] = "0"
        #: up axis -> the hand's rate profile of a turn the operator made about it (°/s), at
        #: rest at both ends (one in motion would make every candidate turn start in motion)
        self.profiles: dict[int, np.ndarray] = {}
        rest_bias = np.median([s.gyro_mean for s in statics], axis=0)
        for r in recs:
            if r.kind == "turn" and len(r) > 10 and not turn_in_motion(r, rest_bias):
                k = int(np.argmax(np.abs(r.up)))
                rate = r.gyro[:, k] * float(np.sign(r.up[k]))
                self.profiles.setdefault(k, np.abs(rate - np.median(rate[:5])))

    def _profile(self, axis: int, pace: float) -> np.ndarray | None:
        """The operator's rate profile about ``axis`` made ``pace`` times as fast (°/s, one
        value every ``dt_s``), or None (a smooth turn) when no turn about it was measured."""
        p = self.profiles.get(axis)
        if p is None or pace == 1.0:
            return p
        t = np.arange(len(p)) * self.dt_s
        t_new = np.arange(math.ceil(len(p) / pace)) * self.dt_s  # all of it, slower or faster
        return pace * np.interp(pace * t_new, t, p, right=0.0)

    def fits_range(self, cand: Candidate, limit_dps: float = 240.0) -> bool:
        """False when the candidate's turns would leave the gyro's range (±250 °/s)."""
        for _, up, kind, *_ in cand.records:
            p = self._profile(int(np.argmax(np.abs(up))), cand.pace)
            if kind == "turn" and p is not None and float(np.max(p)) > limit_dps:
                return False
        return True

    def with_candidate(self, cand: Candidate) -> Session:
        """The session with ``cand``'s records added (each under a name no record has). A
        turn made at the operator's own rate profile lasts its window, or the profile's whole
        length when that is longer (a session whose turns took longer than the window the
        candidate names: it still ends at rest)."""
        records = dict(self.session.records)
        for i, (base, up, kind, seconds, n_turns, direction) in enumerate(cand.records):
            name = unique_name(base, records)
            heading = cand.headings[i] if i < len(cand.headings) else None
            meta = self.meta if heading is None else {**self.meta, HEADING_KEY: f"{heading:g}"}
            profile = self._profile(int(np.argmax(np.abs(up))), cand.pace)
            if kind == "turn" and profile is not None:
                seconds = max(seconds, (len(profile) + 1) * self.dt_s)
            records[name] = synthetic_record(
                name, up, kind, seconds, g=self.g, values=self.values, accel_sd=self.accel_sd,
                gyro_sd=self.gyro_sd, dt_s=self.dt_s, temp_c=self.temp_c + cand.temp_offset_c,
                turns=n_turns,
                direction=direction, meta=meta,
                rng=np.random.default_rng([self.seed, zlib.crc32(name.encode())]),
                profile=profile,
            )  # fmt: skip
        return Session(self.session.serial, records)


def _turns_made(records: Sequence[Record]) -> int:
    """The whole turns per turn record, read from the turns themselves when their headers do
    not say (the integral of the gyro about the up axis, in turns; 1 without a turn)."""
    for r in records:
        if r.kind == "turn" and len(r) > 10:
            k = int(np.argmax(np.abs(r.up)))
            t_s = r.t_ms / 1000.0
            angle = abs(float(np.trapezoid(r.gyro[:, k] - np.median(r.gyro[:5, k]), t_s)))
            return max(1, round(angle / 360.0))
    return 1


def plan_next(
    session: Session,
    model: Sequence[ModelTerm],
    *,
    noise: NoiseModel | None = None,
    tolerances: Mapping[str, float | None] = TOLERANCES,
    time: OperatorTime = OPERATOR_TIME,
    latitude_deg: float = DEFAULT_LATITUDE_DEG,
    height_m: float = DEFAULT_HEIGHT_M,
    only: Sequence[Candidate] | None = None,
    progress: Callable[[int, int, str], None] | None = None,
    seed: int = 0,
    target: float | None = None,
    temperature: bool | None = None,
) -> NextPlan:
    """Rank the records the operator could measure next (:func:`candidates`, with a sitting
    at another temperature when ``temperature`` — None: when the model has a temperature term
    (:func:`has_temperature_term`) — or ``only``) by
    how much each shrinks the worst σ/tolerance of ``model`` per minute of operator time —
    or, with a ``target`` σ/tolerance, the :func:`excess` over it of all values (several
    values near the worst are then shrunk together, not one at a time). With a target the σ
    a record leaves is its noise part after it with the misfit part held
    (:func:`with_misfit`): a record is ranked for what it can lower.

    ``progress(done, total, label)`` is called before each candidate is tried. UserError
    (from the engine) when the session cannot be fitted at all."""
    nm = noise or NoiseModel()
    # the measured records are read once for every candidate added to them
    kw = {"noise": nm, "latitude_deg": latitude_deg, "height_m": height_m, "work": RecordWork()}
    fit = fit_model(build_dataset(session, **kw), model)  # type: ignore[arg-type]
    now = _Now(fit, tolerances, target)
    hand = Augmenter(session, _values(fit), local_gravity(latitude_deg, height_m), seed)
    todo = _menu(only, hand, model, time, temperature)
    ranked: list[Ranked] = []
    for i, cand in enumerate(todo):
        if progress is not None:
            progress(i, len(todo), cand.label)
        aug = fit_model(build_dataset(hand.with_candidate(cand), **kw), model)  # type: ignore[arg-type]
        ranked.append(now.rank(cand, aug))
    if progress is not None:
        progress(len(todo), len(todo), "")
    ranked.sort(key=lambda r: (-len(r.determines), -r.gain_per_min, r.candidate.operator_s))
    notes = () if any(c.temp_offset_c for c in todo) else (
        "a sitting at another temperature is ranked only for a model with a temperature term "
        "(or plan --separate with one)",
    )  # fmt: skip
    return NextPlan(now.worst, now.worst_name, now.sigma, tuple(ranked), notes, misfit_sigmas(fit))


def _menu(
    only: Sequence[Candidate] | None,
    hand: Augmenter,
    model: Sequence[ModelTerm],
    time: OperatorTime,
    temperature: bool | None,
) -> list[Candidate]:
    """The candidates :func:`plan_next` ranks: ``only``, else :func:`candidates` of the
    session's own record length and turns (a sitting at another temperature when
    ``temperature``, None: when the model has a temperature term)."""
    if only is not None:
        return list(only)
    if temperature is None:
        temperature = has_temperature_term(model)
    temps = (OTHER_TEMPERATURE_C,) if temperature else ()
    return candidates(hand.static_s, hand.turns, time, temperatures=temps)


class _Now:
    """The fit of the records measured so far, and how a candidate's fit is ranked against
    it (:func:`plan_next`)."""

    def __init__(
        self, fit: Fit, tolerances: Mapping[str, float | None], target: float | None
    ) -> None:
        self.fit, self.tolerances, self.target = fit, tolerances, target
        self.sigma = unscaled_sigmas(fit, fit)
        self.worst, self.worst_name = worst_ratio(self.sigma, tolerances)
        self.undetermined = {n for n, s in self.sigma.items() if not math.isfinite(s)}
        self.misfit = misfit_sigmas(fit) if target is not None else {}

    def after(self, aug: Fit) -> dict[str, float]:
        """The σ of every value once the candidate fitted in ``aug`` is measured."""
        if self.target is None:
            return unscaled_sigmas(aug, self.fit)  # widened as the records so far show
        return with_misfit(unscaled_sigmas(aug), self.misfit)

    def rank(self, cand: Candidate, aug: Fit) -> Ranked:
        """``cand`` with what it does (its fit: ``aug``)."""
        sigma = self.after(aug)
        worst, name = worst_ratio(sigma, self.tolerances)
        determines = tuple(
            sorted(n for n in self.undetermined if math.isfinite(sigma.get(n, math.nan)))
        )
        minutes = cand.operator_s / 60.0
        if determines:
            gain = math.inf
        elif self.target is not None:
            gain = excess(self.sigma, self.target, self.tolerances)
            gain = (gain - excess(sigma, self.target, self.tolerances)) / minutes
        elif math.isfinite(self.worst):
            gain = (self.worst - worst) / minutes
        else:  # the worst stays undetermined: nothing gained on it
            gain = 0.0
        return Ranked(cand, worst, name, sigma, determines, gain)
