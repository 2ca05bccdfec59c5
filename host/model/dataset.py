"""The dataset: everything the fits need from a session — the records' reference signals, the
rows (:mod:`host.model.rows`: block means, turn integrals, still moments, moving blocks), their
noise (:mod:`host.model.noise`) and the whitening (:mod:`host.model.whitening`)."""

from __future__ import annotations

import functools
import math
from collections.abc import Mapping
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
from host.model.poses import FirstEstimates, RecordLinks, first_estimates
from host.model.remeasured import leans_are_a_bias_change, leans_are_an_unseen_step
from host.model.rows import (
    RecordWork,
    RowTable,
    add_block_means,
    add_turn_accel,
    add_turn_integrals,
    apply_serial_correlation,
    hand_sigma,
    seating_sigma,
    turn_tilt_columns,
)
from host.model.signals import RecordSignals, record_signals
from host.model.turn_angle import preliminary_gyro_scale, turn_reads
from host.model.turn_axis import TurnAxis, resolve_turn_axes, turn_axes
from host.model.variance import Component, TurnClosure, TurnSigmas, turn_sigmas
from host.model.whitening import (
    Group,
    GroupsBySize,
    RowNoise,
    Whitener,
    groups_by_size,
    whiten_rows,
)
from host.session.directory import Session, read_session
from host.session.method import (
    DEFAULT_HEIGHT_M,
    DEFAULT_LATITUDE_DEG,
    RecordStats,
    local_gravity,
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
        if (ch.record, ch.sensor, ch.axis) in table.inner_steps:
            continue  # a step inside the record: an effect, not the bias's wander
        counts = np.count_nonzero(ch.aggregator, axis=1).astype(float)
        w = ch.aggregator / ch.aggregator.sum(axis=1, keepdims=True)
        shapes = np.column_stack([w @ sig.temp_c, w @ sig.t_s])
        out.setdefault(ch.sensor, []).append((y[ch.rows], ch.white / counts, ch.axis, shapes))
    return out


@dataclass(frozen=True, eq=False)
class _Observed:
    """The records as the model reads them, before any row: ``obs`` each one's observation
    (:func:`~host.session.observations.build_observations`) and ``of`` the same by record
    name, the poses with their first attitudes (``first``: :func:`~host.model.poses.
    first_estimates`); ``names`` the records observed, in the session's order; ``stats`` per
    record; ``has_power``: every one carries its power-on time; ``notes`` so far."""

    obs: list[Observation]
    of: dict[str, Observation]
    names: list[str]
    stats: dict[str, RecordStats]
    first: FirstEstimates
    has_power: bool
    notes: list[str]


def _observe(
    session: Session, g: float, turns: int | None, earth_rate: bool, latitude_deg: float,
    work: RecordWork,
) -> _Observed:  # fmt: skip
    """Check the records and observe each one (gravity ``g`` m/s²; ``turns``, ``earth_rate``
    and ``latitude_deg`` as :func:`~host.session.observations.build_observations` takes them);
    the poses' attitudes first estimated."""
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
    return _Observed(obs, obs_of, names, stats, first, has_power, notes)


@dataclass(frozen=True, eq=False)
class _BeforeFit:
    """What the records say before the fit, for their reference signals: ``rest`` (4, 3) the
    gyro's g-sensitivity per g and bias from the static records (least squares per channel),
    ``first`` the first estimates with the moves, ``accel_matrix`` and ``gyro_scale``
    (:func:`_preliminary_accel_matrix`, :func:`host.model.turn_angle.preliminary_gyro_scale`),
    ``reads`` what each gyro channel reads of a turn about each axis
    (:func:`host.model.turn_angle.turn_reads`), ``gyro_sd`` (3,) the per-sample gyro noise °/s
    per axis (it finds the still moments inside the turns)."""

    rest: np.ndarray
    first: FirstEstimates
    accel_matrix: np.ndarray | None
    gyro_scale: np.ndarray | None
    reads: dict[int, np.ndarray]
    gyro_sd: np.ndarray


def _before_the_fit(session: Session, observed: _Observed, g: float) -> _BeforeFit:
    """The static records' gyro bias and g-sensitivity, the moves' first estimates, the
    accelerometer's matrix and the gyro's scale read before the fit (gravity ``g`` m/s²)."""
    of, stats, names = observed.of, observed.stats, observed.names
    statics = [n for n in names if of[n].kind in ("static", "rate", "pose")]
    xs = np.array([np.concatenate([of[n].force, [1.0]]) for n in statics])
    ys = np.array([stats[n].gyro_mean - of[n].rate for n in statics])
    pre, *_ = np.linalg.lstsq(xs, ys, rcond=None)
    first = observed.first.with_moves(session.records, of, pre)
    accel_matrix = _preliminary_accel_matrix(
        xs, np.array([stats[n].accel_mean for n in statics]), g
    )
    turns = [(session.records[n], of[n]) for n in names if of[n].kind == "turn"]
    gyro_scale = preliminary_gyro_scale(turns, pre)
    gyro_sd = np.median([stats[n].gyro_std for n in statics], axis=0)
    return _BeforeFit(pre, first, accel_matrix, gyro_scale, turn_reads(turns, pre), gyro_sd)


@dataclass(frozen=True, eq=False)
class _Rows:
    """Each record's signals and rows, in the order of :attr:`_Observed.names`: ``signals``
    and ``aggregators`` per record, the rows themselves (``table``), a turn's accelerometer
    aggregators (``sensor_aggs``) and ``n_still``: turn record -> how many of its
    accelerometer rows are still moments (the rest: moving)."""

    signals: list[RecordSignals] = field(default_factory=list)
    aggregators: list[np.ndarray] = field(default_factory=list)
    table: RowTable = field(default_factory=RowTable)
    sensor_aggs: dict[tuple[int, str, int], np.ndarray] = field(default_factory=dict)
    n_still: dict[int, int] = field(default_factory=dict)


def _signals_of(
    rec: Record, o: Observation, g: float, t_rel: np.ndarray, observed: _Observed,
    before: _BeforeFit, temp_mean_c: float,
) -> RecordSignals:  # fmt: skip
    """Record ``rec``'s reference signals (:func:`~host.model.signals.record_signals`;
    ``t_rel`` (N,) s since its first sample); a move's read against the first estimates."""
    # without power-on times only the variation within a record is known: centre it
    if observed.has_power:
        t0 = float(rec.meta.get("power_on_s", "0") or 0.0)
    else:
        t0 = -float(t_rel.mean())
    sig = record_signals(rec, o, g, t0, t_rel, before.rest, temp_mean_c, before.accel_matrix,
                          before.gyro_scale, before.reads)  # fmt: skip
    if o.kind == "move":  # read against the first estimates; its rows come last
        sig = replace(sig, force=before.first.force(rec),
                      rate=before.first.reference_rate(rec, before.rest))  # fmt: skip
    return sig


def _record_rows(
    session: Session, observed: _Observed, before: _BeforeFit, g: float, nm: NoiseModel,
    moving: bool, work: RecordWork,
) -> _Rows:  # fmt: skip
    """Every record's signals and rows, one builder per kind (:mod:`host.model.rows`; a move
    has none until the others are whitened), the rows' serial correlation applied."""
    names, of = observed.names, observed.of
    pose_frame = not any(of[n].kind in ("static", "turn", "rate") for n in names)
    temp_mean = float(np.mean([float(np.mean(session.records[n].temp)) for n in names]))
    out = _Rows()
    for ri, name in enumerate(names):
        rec, o = session.records[name], of[name]
        t_rel = (rec.t_ms - rec.t_ms[0]) / 1000.0
        sig = _signals_of(rec, o, g, t_rel, observed, before, temp_mean)
        out.signals.append(replace(sig, pose_frame=pose_frame) if pose_frame else sig)
        if o.kind == "move":
            out.aggregators.append(np.zeros((2, len(rec))))
        elif o.kind != "turn":
            out.aggregators.append(
                add_block_means(out.table, ri, work.block_means(rec, sig, t_rel, nm))
            )
        else:
            gyro_sd = float(before.gyro_sd[int(np.argmax(np.abs(o.up)))])
            turn, values = work.turn_accel(rec, sig, t_rel, gyro_sd, moving)
            if turn is not None:
                for ax in range(3):
                    out.sensor_aggs[(ri, "accel", ax)] = turn.aggregators[ax]
                out.n_still[ri] = turn.n_still
                add_turn_accel(out.table, ri, turn, values)
            out.aggregators.append(add_turn_integrals(out.table, ri, sig, rec.t_ms, t_rel))
    apply_serial_correlation(out.table, nm.max_lag)
    return out


@dataclass(frozen=True, eq=False)
class _Placed:
    """The records placed on the plate: their ``signals`` with headings, tilt matrices and
    each tilted turn about its measured axis; the ``tilted`` turns, the indices of their
    records (``moved``) and what was said of it (``notes``)."""

    signals: list[RecordSignals]
    tilted: list[TurnAxis]
    moved: set[int]
    notes: list[str]


def _place_on_the_plate(signals: list[RecordSignals], g: float) -> _Placed:
    """The plate's tilt from the turns' circles, each record placed in the room, and the
    turns' axes, read once: whether a bias change explains their leans, else which turns were
    tilted (those then about their measured axes)."""
    # the circles are drawn once: resolving the headings only places them in the room
    circles = turn_circles(signals)
    signals, notes = resolve_placements(signals, g, plate_from_rests(circles))
    plate = plate_from_rests(with_headings(circles, signals))
    signals = tilt_matrices(signals, plate)
    axes = turn_axes(signals, plate)
    changed = leans_are_a_bias_change(signals, axes) or leans_are_an_unseen_step(signals, axes)
    signals, tilted = resolve_turn_axes(signals, [] if changed else axes)
    notes = [*notes, *(a.line() for a in tilted)]
    if changed:
        notes.append(changed.line(g))
    moved = {i for i, s in enumerate(signals) if s.name in {a.record for a in tilted}}
    return _Placed(signals, tilted, moved, notes)


def _nominal_about_measured_axes(table: RowTable, placed: _Placed) -> None:
    """The ideal sensor's value of each row of a tilted turn, now about its measured axis."""
    for ch in table.channels:
        if ch.record in placed.moved:
            ref = ch.aggregator @ placed.signals[ch.record].reference(ch.sensor)[:, ch.axis]
            for row, v in zip(ch.rows, ref, strict=True):
                table.nominal[row] = float(v)


@dataclass(frozen=True, eq=False)
class _SensorNoise:
    """The rows' noise beyond each sample's white noise: the ``floors`` per sensor, the white
    level per (sensor, axis) (variance·τ of one sample, from the static records), the seating
    and the hand's scatter (m/s², :func:`host.model.rows.seating_sigma`,
    :func:`host.model.rows.hand_sigma`) and what was said of them."""

    floors: dict[str, float]
    white_level: dict[tuple[str, int], float]
    seat: float
    hand: tuple[float, float]
    notes: list[str]


def _sensor_noise(
    rows: _Rows, signals: list[RecordSignals], records: list[Record], nm: NoiseModel,
    work: RecordWork,
) -> _SensorNoise:  # fmt: skip
    """The floor from the static records' block means (or as given in ``nm``), the seating
    at the turns' still moments and the hand while they turn."""
    table, sensor_aggs, n_still = rows.table, rows.sensor_aggs, rows.n_still
    floors, floor_note = session_floor(_static_blocks(table, signals), nm)
    notes = [floor_note]
    tilt_cols = turn_tilt_columns(signals, sensor_aggs)
    seat, seat_note = seating_sigma(signals, sensor_aggs, table.channels, n_still, tilt_cols)
    if seat_note:
        notes.append(seat_note)
    white_level = {
        k: float(np.mean([v * t for v, t in lv])) for k, lv in table.static_noise.items()
    }
    hand, hand_note = hand_sigma(
        signals, sensor_aggs, n_still, white_level, tilt_cols,
        lambda ri: work.lever(records[ri], signals[ri]),
    )  # fmt: skip
    if hand_note:
        notes.append(hand_note)
    return _SensorNoise(floors, white_level, seat, hand, notes)


def _tilted_turn_sigmas(
    whiten: Whitener, groups: list[Group], signals: list[RecordSignals], tilted: list[TurnAxis]
) -> Whitener:
    """A corrected turn's gyro integrals carry its measured axis's σ (``groups`` changed in
    place, the whitener returned)."""
    for a in tilted:
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
    return whiten


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
    observed = _observe(session, g, turns, earth_rate, latitude_deg, work)
    before = _before_the_fit(session, observed, g)
    rows = _record_rows(session, observed, before, g, nm, moving, work)
    placed = _place_on_the_plate(rows.signals, g)
    _nominal_about_measured_axes(rows.table, placed)
    records = [session.records[n] for n in observed.names]
    sensor = _sensor_noise(rows, placed.signals, records, nm, work)
    turn = turn_sigmas(rows.table, placed.signals, before.rest, observed.has_power, nm)
    signals = placed.signals
    row_noise = RowNoise(
        floors=sensor.floors, static_noise=rows.table.static_noise,
        white_level=sensor.white_level, n_still=rows.n_still, seat=sensor.seat,
        hand=sensor.hand, turn_sigma=(turn.angle_deg, turn.wobble_deg),
        free_levels={(ri, ax) for ri in placed.moved for ax in range(3)
                     if abs(float(signals[ri].up[ax])) < 0.5}, g=g,
    )  # fmt: skip
    whiten, groups = whiten_rows(rows.table.channels, signals, np.array(rows.table.y), row_noise)
    whiten = _tilted_turn_sigmas(whiten, groups, signals, placed.tilted)
    whiten, move_rows_of, move_aggs, links = add_moves(
        rows.table, signals, records, sensor.white_level, whiten, groups, sensor.floors["gyro"]
    )
    rows.sensor_aggs.update(move_aggs)
    notes = [*observed.notes, *placed.notes, *sensor.notes, *turn.notes]
    return _assemble(observed, rows, signals, whiten, groups, move_rows_of, links, g,
                     notes, sensor, turn)  # fmt: skip


def _assemble(
    observed: _Observed, rows: _Rows, signals: list[RecordSignals], whiten: Whitener,
    groups: list[Group], move_rows_of: Mapping[tuple[int, str, int], np.ndarray],
    links: RecordLinks, g: float, notes: list[str], sensor: _SensorNoise, turn: TurnSigmas,
) -> Dataset:  # fmt: skip
    """The :class:`Dataset` of the rows built (a move's two rows read by every gyro channel)."""
    table = rows.table
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
        y=np.array(table.y),
        nominal=np.array(table.nominal),
        whiten=whiten,
        groups=tuple(groups),
        aggregators=tuple(rows.aggregators),
        rows_of=rows_of,
        g=g,
        notes=tuple(notes),
        time_known=observed.has_power,
        floor=sensor.floors,
        turns_of={o.record: o.turns for o in observed.obs
                  if o.kind == "turn" and o.turns is not None},
        sensor_aggregators=rows.sensor_aggs,
        components=turn.components,
        turn_angle_sigma_deg=turn.angle_deg,
        turn_wobble_sigma_deg=turn.wobble_deg,
        closures=turn.closures,
        record_links=links,
    )  # fmt: skip


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
