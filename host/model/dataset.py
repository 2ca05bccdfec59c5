"""The dataset: everything the fits need from a session — the records' reference signals, the
rows (:mod:`host.model.rows`: block means, turn integrals, still moments, moving blocks), their
noise (:mod:`host.model.noise`) and the whitening (:mod:`host.model.whitening`)."""

from __future__ import annotations

import functools
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from host.errors import UserError
from host.model.moves import add_moves
from host.model.noise import NoiseModel, session_floor
from host.model.plate import (
    plate_from_rests,
    resolve_placements,
    tilt_matrices,
    turn_circles,
    with_headings,
)
from host.model.poses import RecordLinks, first_estimates
from host.model.remeasured import leans_are_a_bias_change
from host.model.rows import (
    BlockMeans,
    RowTable,
    TurnAccel,
    TurnAccelValues,
    add_block_means,
    add_turn_accel,
    add_turn_integrals,
    apply_serial_correlation,
    block_means,
    hand_sigma,
    seating_sigma,
    turn_accel_rows,
    turn_accel_values,
    turn_tilt_columns,
)
from host.model.signals import RecordSignals
from host.model.turn_axis import resolve_turn_axes, turn_axes
from host.model.turning import sensed_lever_matrix
from host.model.variance import Component, TurnClosure, turn_angle_sigma, turn_wobble_sigma
from host.model.whitening import Group, GroupsBySize, Whitener, groups_by_size, whiten_rows
from host.session.directory import Session, read_session
from host.session.method import (
    DEFAULT_HEIGHT_M,
    DEFAULT_LATITUDE_DEG,
    RecordStats,
    local_gravity,
    record_stats,
    trapezoid_integral,
)
from host.session.observations import Observation, build_observations
from host.session.records import Record


@dataclass(frozen=True, eq=False)
class Dataset:
    """Everything the fits need from a session: signals, rows and the whitening.

    Rows (n): ``y`` measured block mean (unit of the channel) or turn integral (°), ``nominal``
    the ideal sensor's value (the aggregated reference input on the channel), ``span`` (n,2)
    within-record time span s. ``whiten``: W (n, n) with W·Cov·Wᵀ = I, block-diagonal, one
    block per group (:class:`~host.model.whitening.Whitener`).
    """

    signals: tuple[RecordSignals, ...]
    row_record: np.ndarray
    row_sensor: np.ndarray  # 0 accel, 1 gyro
    row_axis: np.ndarray
    row_integral: np.ndarray
    span: np.ndarray
    y: np.ndarray
    nominal: np.ndarray
    whiten: Whitener
    groups: tuple[Group, ...]
    aggregators: tuple[np.ndarray, ...]  # per record (B, N): block-mean or trapezoid weights
    rows_of: dict[tuple[int, str, int], np.ndarray]
    g: float
    notes: tuple[str, ...] = ()
    #: False: the records carry no power-on time (time = within-record, centred)
    time_known: bool = True
    #: the bias-instability floor of a record mean per sensor (m/s², °/s) this dataset uses
    floor: Mapping[str, float] = field(default_factory=dict)
    #: turns n of each turn record (record name -> n)
    turns_of: Mapping[str, int] = field(default_factory=dict)
    #: (record, sensor, axis) -> its own aggregator where it differs from the record's: the
    #: accelerometer of a turn record is read at the still moments (one row per still moment)
    #: and, on the horizontal axes, in the moving blocks (:mod:`host.model.turning`)
    sensor_aggregators: Mapping[tuple[int, str, int], np.ndarray] = field(default_factory=dict)
    #: the named variance components this dataset's rows carry (:mod:`host.model.variance`)
    components: tuple[Component, ...] = ()
    #: the turn-angle σ the turn integrals carry, ° (given, else measured)
    turn_angle_sigma_deg: float = 0.0
    #: the hand's wobble on the cross-axis turn integrals, ° (measured)
    turn_wobble_sigma_deg: float = 0.0
    #: the closures of the turns made both ways the turn-angle σ is measured from (empty when
    #: it is given): a candidate that moves them is tested against the σ of the others
    closures: tuple[TurnClosure, ...] = ()
    #: rows of other records that read a record's own unknowns (a move's rows read its two
    #: poses' attitudes): (term name, record name) -> [(row, coefficient per unknown)]
    record_links: RecordLinks = field(default_factory=dict)

    @property
    def n_rows(self) -> int:
        return int(self.y.shape[0])

    @functools.cached_property
    def group_means_whitened(self) -> np.ndarray:
        """(n_rows,) W⁻ᵀ·a_g for each group's mean a_g, each on its own group's rows (W is
        block-diagonal by group, so they do not overlap; :func:`residual_sigmas`), solved once
        per dataset (W does not change between fits)."""
        a = np.zeros(self.n_rows)
        for gr in self.groups:
            a[gr.rows] = 1.0 / len(gr.rows)
        return self.whiten.solve_t(a)

    @functools.cached_property
    def groups_by_size(self) -> GroupsBySize:
        """``groups`` gathered by their number of rows (:func:`host.model.whitening.
        group_means` takes every group's mean a size at a time)."""
        return groups_by_size(self.groups)

    @functools.cached_property
    def row_group(self) -> np.ndarray:
        """(n_rows,) the index in ``groups`` of each row's group."""
        out = np.zeros(self.n_rows, dtype=np.intp)
        for k, gr in enumerate(self.groups):
            out[gr.rows] = k
        return out

    def aggregator(self, record: int, sensor: str, axis: int) -> np.ndarray:
        """(B, N) weights turning record ``record``'s samples into its rows of ``sensor``'s
        channel ``axis``."""
        return self.sensor_aggregators.get((record, sensor, axis), self.aggregators[record])


def turn_heading(t_s: np.ndarray, rate_up_dps: np.ndarray) -> np.ndarray:
    """(N,) the angle turned about the up axis since the record began, ° (trapezoid rule over
    the reference rate ``rate_up_dps`` (N,) °/s at times ``t_s`` (N,) s; method.md §4)."""
    if len(t_s) < 2:
        return np.zeros(len(t_s))
    step = np.diff(t_s) * (rate_up_dps[1:] + rate_up_dps[:-1]) / 2.0
    return np.concatenate([[0.0], np.cumsum(step)])


def _turn_reference(
    rec_gyro: np.ndarray, t_ms: np.ndarray, up: np.ndarray, bias_dps: np.ndarray, want_deg: float
) -> np.ndarray:
    """(N,3) reference rate of a turn: the measured rate about the up axis (static bias
    removed), scaled so that its trapezoid integral is exactly ``want_deg``."""
    raw = (rec_gyro - bias_dps) @ up
    total = float(trapezoid_integral(t_ms, raw))
    if abs(total) < 1e-6:
        return np.zeros((len(t_ms), 3))
    return (raw * (want_deg / total))[:, None] * up[None, :]


def _record_signals(
    rec: Record,
    o: Observation,
    g: float,
    t0: float,
    t_rel: np.ndarray,
    gyro_bias: np.ndarray,
    temp_mean_c: float,
    accel_matrix: np.ndarray | None = None,
    gyro_scale: np.ndarray | None = None,
) -> RecordSignals:
    """The reference signals of one record (observation ``o``): gravity ``g`` m/s² along its up
    direction, the reference rate (a turn: its measured rate about up less the static
    ``gyro_bias`` (4, 3) (g-sensitivity rows, bias), scaled to the known turn; otherwise the
    observation's rate), the time ``t0`` + ``t_rel`` s and the heading."""
    n = len(rec)
    force = np.tile(g * o.up, (n, 1)) if o.kind != "rate" else np.tile(g * rec.up, (n, 1))
    if o.kind == "turn":
        bias_up = gyro_bias[:3].T @ o.up + gyro_bias[3]
        want = float(o.rate @ o.up)
        rate = _turn_reference(rec.gyro, rec.t_ms, o.up, bias_up, want)
        heading: np.ndarray | None = turn_heading(t_rel, rate @ o.up)
    else:  # rate table; statics: zero, or the vertical Earth rate
        rate = np.tile(o.rate, (n, 1))
        heading = None
    return RecordSignals(
        name=o.record, kind=o.kind, t_s=t0 + t_rel, temp_c=rec.temp.copy(), force=force,
        rate=rate, accel=rec.accel, gyro=rec.gyro, g=g, up=o.up, temp_mean_c=temp_mean_c,
        heading_deg=heading, placement_deg=rec.placement_heading_deg,
        accel_matrix=accel_matrix if o.kind in ("turn", "static") else None,
        gyro_scale=gyro_scale if o.kind in ("turn", "static") else None,
    )  # fmt: skip


def _preliminary_gyro_scale(
    turns: Sequence[tuple[Record, Observation]], gyro_bias: np.ndarray
) -> np.ndarray | None:
    """(3,) 1 + each gyro's scale on its own axis from the turn records before the fit: the
    measured integral about up (static ``gyro_bias`` (4, 3) removed) over the known turn, the
    mean of the turns about each axis (1 for an axis without turns); None without turns. It
    carries a face's lean into the gyro's columns (:data:`host.model.catalogue.face_error`)."""
    per: dict[int, list[float]] = {0: [], 1: [], 2: []}
    for rec, o in turns:
        want = float(o.rate @ o.up)
        bias = gyro_bias[:3].T @ o.up + gyro_bias[3]
        total = float(trapezoid_integral(rec.t_ms, (rec.gyro - bias) @ o.up))
        if abs(want) > 1e-6 and abs(total) > 1e-6:
            per[int(np.argmax(np.abs(o.up)))].append(total / want)
    if not any(per.values()):
        return None
    return np.array([float(np.mean(v)) if v else 1.0 for v in per.values()])


def _preliminary_accel_matrix(
    xs: np.ndarray, accel_means: np.ndarray, g: float
) -> np.ndarray | None:
    """(3, 3) how the accelerometer reads a specific force, from the static records before
    the fit: least squares of their means ``accel_means`` (S, 3) m/s² on ``xs`` (S, 4) (each
    one's reference force in units of the local gravity ``g`` m/s², and 1) — scale and
    misalignment to about 1e-3 on six faces; None unless the forces span all three axes. It
    carries the turning force into the lever arm's columns
    (:func:`host.model.turning.sensed_lever_matrix`)."""
    if len(xs) < 4 or np.linalg.matrix_rank(xs[:, :3], tol=0.1) < 3:
        return None
    sol, *_ = np.linalg.lstsq(xs, accel_means, rcond=None)
    return np.asarray(sol[:3].T) / g


def _static_blocks(
    table: RowTable, signals: list[RecordSignals]
) -> dict[str, list[tuple[np.ndarray, np.ndarray, int, np.ndarray]]]:
    """sensor -> per static record and channel (block means, their white-noise variances, the
    channel's axis, the blocks' mean temperature and time (B, 2)): what the records' own samples
    say about the bias wander (:func:`host.model.noise.wander_floor`)."""
    y = np.asarray(table.y)
    out: dict[str, list[tuple[np.ndarray, np.ndarray, int, np.ndarray]]] = {}
    for ch in table.channels:
        sig = signals[ch.record]
        if sig.kind == "turn" or len(ch.rows) < 2:
            continue
        counts = np.count_nonzero(ch.aggregator, axis=1).astype(float)
        w = ch.aggregator / ch.aggregator.sum(axis=1, keepdims=True)
        shapes = np.column_stack([w @ sig.temp_c, w @ sig.t_s])
        out.setdefault(ch.sensor, []).append((y[ch.rows], ch.white / counts, ch.axis, shapes))
    return out


def turn_pairs(signals: Sequence[RecordSignals], timed: bool) -> list[tuple[int, int, int]]:
    """(up axis, ccw record, cw record) for each pair of turns made both ways about an axis:
    its ccw turns paired with its cw turns in the order measured (the first with the first, the
    second with the second, …; by first sample time when ``timed``, else as the records are
    listed); a turn without a partner is left out."""
    by_dir: dict[tuple[int, int], list[tuple[float, int]]] = {}
    for r, sig in enumerate(signals):
        if sig.kind != "turn":
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


def _turn_closures(
    table: RowTable, signals: list[RecordSignals], rest: np.ndarray, timed: bool
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


@dataclass(eq=False)
class RecordWork:
    """What :func:`build_dataset` reads from a record alone, kept between builds of sessions
    that share records (the planner adds each candidate to the same measured records): each
    record's stats, and a static record's block means (:func:`host.model.rows.block_means`)
    under the reference input and blocks they were read with. Keyed by the record itself (a
    :class:`Record` is not changed once read); one per caller, dropped with it."""

    stats: dict[Record, RecordStats] = field(default_factory=dict)
    blocks: dict[tuple[object, ...], BlockMeans] = field(default_factory=dict)
    turns: dict[tuple[object, ...], tuple[TurnAccel | None, TurnAccelValues]] = field(
        default_factory=dict
    )
    levers: dict[tuple[object, ...], np.ndarray] = field(default_factory=dict)

    def record_stats(self, rec: Record) -> RecordStats:
        """:func:`host.session.method.record_stats` of ``rec``, read once."""
        if rec not in self.stats:
            self.stats[rec] = record_stats(rec)
        return self.stats[rec]

    def block_means(
        self, rec: Record, sig: RecordSignals, t_rel: np.ndarray, noise: NoiseModel
    ) -> BlockMeans:
        """:func:`host.model.rows.block_means` of static record ``rec`` (its signals ``sig``),
        read once per reference input and blocks."""
        key = (rec, noise.block_s, noise.max_blocks, sig.force.tobytes(), sig.rate.tobytes())
        if key not in self.blocks:
            self.blocks[key] = block_means(sig, t_rel, noise)
        return self.blocks[key]

    def turn_accel(
        self, rec: Record, sig: RecordSignals, t_rel: np.ndarray, gyro_sd_dps: float, moving: bool
    ) -> tuple[TurnAccel | None, TurnAccelValues]:
        """Turn record ``rec``'s accelerometer rows (:func:`host.model.rows.turn_accel_rows`,
        :func:`host.model.rows.turn_accel_values`), read once per reference input (its
        signals ``sig``), gyro noise and ``moving``."""
        key = (rec, sig.up.tobytes(), sig.rate.tobytes(), sig.force.tobytes(), gyro_sd_dps, moving)
        if key not in self.turns:
            turn = turn_accel_rows(sig, t_rel, gyro_sd_dps, moving)
            self.turns[key] = (turn, () if turn is None else turn_accel_values(sig, turn))
        return self.turns[key]

    def lever(self, rec: Record, sig: RecordSignals) -> np.ndarray:
        """:func:`host.model.turning.sensed_lever_matrix` of turn record ``rec`` (its signals
        ``sig``), read once per clock, reference rate and accelerometer matrix."""
        matrix = None if sig.lever_matrix is None else np.asarray(sig.lever_matrix).tobytes()
        key = (rec, sig.t_s.tobytes(), sig.rate.tobytes(), matrix)
        if key not in self.levers:
            lever = sensed_lever_matrix(sig.t_s, sig.rate, sig.lever_matrix)
            lever.flags.writeable = False  # several datasets may read it
            self.levers[key] = lever
        return self.levers[key]


def build_dataset(
    session: Session,
    *,
    noise: NoiseModel | None = None,
    latitude_deg: float = DEFAULT_LATITUDE_DEG,
    height_m: float = DEFAULT_HEIGHT_M,
    turns: int | None = None,
    earth_rate: bool = False,
    moving: bool = True,
    work: RecordWork | None = None,
) -> Dataset:
    """Check the records (:func:`host.session.observations.build_observations`) and build the
    rows.

    ``earth_rate``: the reference rate includes the vertical Earth rate (as
    :func:`~host.session.observations.build_observations`). ``moving``: the accelerometer's
    block means over the turning parts of the turn records are rows too
    (:mod:`host.model.turning`; the lever arm shows only there). ``work``: what earlier builds
    read from the same records (:class:`RecordWork`; None: read everything). UserError when
    there is nothing to fit (no static records, bad records).
    """
    nm = noise or NoiseModel()
    if not session.records:
        raise UserError("no records to fit")
    work = RecordWork() if work is None else work
    g = local_gravity(latitude_deg, height_m)
    stats = {n: work.record_stats(r) for n, r in session.records.items()}
    obs, notes = build_observations(
        session, g, turns=turns, stats=stats, earth_rate=earth_rate, latitude_deg=latitude_deg
    )
    obs_of = {o.record: o for o in obs}
    names = [n for n in session.records if n in obs_of]
    has_power = all("power_on_s" in session.records[n].meta for n in names)
    if not has_power:
        notes.append(
            "records carry no power-on time (meta power_on_s): time terms see only the time "
            "within each record (centred on its middle)"
        )
    first = first_estimates(obs_of, g)  # poses: their attitudes before the fit
    obs_of.update(first.observations)
    # preliminary static gyro bias + g-sensitivity (per channel), for the turn reference rate
    statics = [n for n in names if obs_of[n].kind in ("static", "rate", "pose")]
    xs = np.array([np.concatenate([obs_of[n].force, [1.0]]) for n in statics])
    ys = np.array([stats[n].gyro_mean - obs_of[n].rate for n in statics])
    pre, *_ = np.linalg.lstsq(xs, ys, rcond=None)
    first = first.with_moves(session.records, obs_of, pre)
    accel_matrix = _preliminary_accel_matrix(
        xs, np.array([stats[n].accel_mean for n in statics]), g
    )
    gyro_scale = _preliminary_gyro_scale(
        [(session.records[n], obs_of[n]) for n in names if obs_of[n].kind == "turn"], pre
    )
    # per-sample gyro noise (°/s) per axis: finds the still moments inside the turns
    gyro_sd = np.median([stats[n].gyro_std for n in statics], axis=0)

    pose_frame = not any(obs_of[n].kind in ("static", "turn", "rate") for n in names)
    temp_mean = float(np.mean([float(np.mean(session.records[n].temp)) for n in names]))
    signals: list[RecordSignals] = []
    aggs: list[np.ndarray] = []
    table = RowTable()
    sensor_aggs: dict[tuple[int, str, int], np.ndarray] = {}
    #: turn record -> how many of its accelerometer rows are still moments (the rest: moving)
    n_still: dict[int, int] = {}
    for ri, name in enumerate(names):
        rec = session.records[name]
        o = obs_of[name]
        t_rel = (rec.t_ms - rec.t_ms[0]) / 1000.0
        # without power-on times only the variation within a record is known: centre it
        t0 = float(rec.meta.get("power_on_s", "0") or 0.0) if has_power else -float(t_rel.mean())
        sig = _record_signals(rec, o, g, t0, t_rel, pre, temp_mean, accel_matrix, gyro_scale)
        if o.kind == "move":  # read against the first estimates; its rows come last
            sig = replace(sig, force=first.force(rec), rate=first.reference_rate(rec, pre))
        signals.append(replace(sig, pose_frame=pose_frame) if pose_frame else sig)
        if o.kind == "move":
            aggs.append(np.zeros((2, len(rec))))
            continue
        if o.kind != "turn":
            aggs.append(add_block_means(table, ri, work.block_means(rec, sig, t_rel, nm)))
            continue
        up_k = int(np.argmax(np.abs(o.up)))
        turn, values = work.turn_accel(rec, sig, t_rel, float(gyro_sd[up_k]), moving)
        if turn is not None:
            for ax in range(3):
                sensor_aggs[(ri, "accel", ax)] = turn.aggregators[ax]
            n_still[ri] = turn.n_still
            add_turn_accel(table, ri, turn, values)
        aggs.append(add_turn_integrals(table, ri, sig, rec.t_ms, t_rel))

    apply_serial_correlation(table, nm.max_lag)
    # the circles are drawn once: resolving the headings only places them in the room
    circles = turn_circles(signals)
    signals, plate_notes = resolve_placements(signals, g, plate_from_rests(circles))
    notes.extend(plate_notes)
    plate = plate_from_rests(with_headings(circles, signals))
    signals = tilt_matrices(signals, plate)
    # the turns' axes, read once: whether a bias change explains their leans, else which
    # turns were tilted
    axes = turn_axes(signals, plate)
    changed = leans_are_a_bias_change(signals, axes)
    signals, tilted = resolve_turn_axes(signals, [] if changed else axes)
    notes.extend(a.line() for a in tilted)
    if changed:
        notes.append(changed.line(g))
    moved = {i for i, s in enumerate(signals) if s.name in {a.record for a in tilted}}
    for ch in table.channels:  # the ideal sensor's value of a turn now about its measured axis
        if ch.record in moved:
            ref = ch.aggregator @ signals[ch.record].reference(ch.sensor)[:, ch.axis]
            for row, v in zip(ch.rows, ref, strict=True):
                table.nominal[row] = float(v)
    floors, floor_note = session_floor(_static_blocks(table, signals), nm)
    notes.append(floor_note)
    tilt_cols = turn_tilt_columns(signals, sensor_aggs)
    seat, seat_note = seating_sigma(signals, sensor_aggs, table.channels, n_still, tilt_cols)
    if seat_note:
        notes.append(seat_note)
    white_level = {
        k: float(np.mean([v * t for v, t in lv])) for k, lv in table.static_noise.items()
    }
    records = [session.records[n] for n in names]
    hand, hand_note = hand_sigma(
        signals, sensor_aggs, n_still, white_level, tilt_cols,
        lambda ri: work.lever(records[ri], signals[ri]),
    )  # fmt: skip
    if hand_note:
        notes.append(hand_note)
    closures = _turn_closures(table, signals, pre, has_power)
    wobble = turn_wobble_sigma([c for c in closures if c.axis != c.channel])
    if nm.turn_angle_sigma_deg is None:
        angle = turn_angle_sigma([c for c in closures if c.axis == c.channel])
        components: tuple[Component, ...] = (angle, wobble)
    else:
        absorbs = "the hand's angle error (given)"
        angle = Component("turn angle", float(nm.turn_angle_sigma_deg), 0.0, 0, "°", absorbs)
        components = (wobble,)
        notes.append(f"turn angle: {angle.value:g}° per turn (given)")
    notes.extend("a named variance component: " + c.describe() for c in components)
    turn_sigma = (angle.value, wobble.value)
    y_arr = np.array(table.y)
    whiten, groups = whiten_rows(
        table.channels, signals, y_arr, floors=floors, static_noise=table.static_noise,
        white_level=white_level, n_still=n_still, seat=seat, hand=hand, turn_sigma=turn_sigma,
        free_levels={(ri, ax) for ri in moved for ax in range(3)
                     if abs(float(signals[ri].up[ax])) < 0.5}, g=g,
    )  # fmt: skip
    for a in tilted:  # a corrected turn's integrals carry its measured axis's σ
        ri = next(i for i, s in enumerate(signals) if s.name == a.record)
        turned = abs(float(signals[ri].heading[-1]))  # rad
        # per component: the accelerometer's σ, and the plate's tilt at the statics' unknown
        # heading (up to ``bound`` in any direction: RMS bound/√2 per component)
        axis_sd = math.hypot(a.sd, a.bound / math.sqrt(2.0))
        for k, gr in enumerate(groups):
            if gr.record == ri and gr.sensor == "gyro":
                # across the axis the error moves the rate directly; along it by lean·δ
                across = abs(float(a.up[gr.axis])) < 0.5
                sd_rad = axis_sd if across else a.size * axis_sd
                sd = math.hypot(gr.sigma, math.degrees(sd_rad * turned))
                whiten = whiten.with_block(gr.rows, np.array([[1.0 / sd]]))
                groups[k] = replace(gr, sigma=sd)
    whiten, move_rows_of, move_aggs, links = add_moves(
        table, signals, records, white_level, whiten, groups
    )
    y_arr = np.array(table.y)
    sensor_aggs.update(move_aggs)
    rows_of: dict[tuple[int, str, int], np.ndarray] = {}
    for gr in groups:
        rows_of[(gr.record, gr.sensor, gr.axis)] = gr.rows
    rows_of.update(move_rows_of)  # a move's two rows, read by every gyro channel
    return Dataset(
        signals=tuple(signals),
        row_record=np.array(table.record, dtype=int),
        row_sensor=np.array(table.sensor, dtype=int),
        row_axis=np.array(table.axis, dtype=int),
        row_integral=np.array(table.integral, dtype=bool),
        span=np.column_stack([table.t0, table.t1]),
        y=y_arr,
        nominal=np.array(table.nominal),
        whiten=whiten,
        groups=tuple(groups),
        aggregators=tuple(aggs),
        rows_of=rows_of,
        g=g,
        notes=tuple(notes),
        time_known=has_power,
        floor=floors,
        turns_of={o.record: o.turns for o in obs if o.kind == "turn" and o.turns is not None},
        sensor_aggregators=sensor_aggs,
        components=components,
        turn_angle_sigma_deg=turn_sigma[0],
        turn_wobble_sigma_deg=turn_sigma[1],
        closures=tuple(c for c in closures if c.axis == c.channel)
        if nm.turn_angle_sigma_deg is None
        else (),
        record_links=links,
    )


def load_dataset(
    directory: str | Path,
    *,
    noise: NoiseModel | None = None,
    latitude_deg: float = DEFAULT_LATITUDE_DEG,
    height_m: float = DEFAULT_HEIGHT_M,
    serial: str | None = None,
) -> Dataset:
    """Read the session in ``directory`` (:func:`host.session.directory.read_session`) and
    build it."""
    session = read_session(directory, serial)
    return build_dataset(session, noise=noise, latitude_deg=latitude_deg, height_m=height_m)


def session_from_records(records: Mapping[str, object], serial: str = "SIM") -> Session:
    """A :class:`Session` of in-memory records (e.g. :func:`host.bench.plan.simulate_session`)."""
    recs = {k: v for k, v in records.items() if isinstance(v, Record)}
    return Session(serial=serial, records=recs)
