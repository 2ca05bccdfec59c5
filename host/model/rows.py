"""The rows of a dataset, one small builder per kind of row (:func:`add_block_means`,
:func:`add_turn_integrals`, :func:`add_turn_accel`), each with the white noise its record shows:

* a static or rate-table record: each channel's block means (blocks of ``NoiseModel.block_s``);
* a turn record: each gyro channel's trapezoid integral (method.md §4), in °;
* a turn record's accelerometer: one row per still moment (gravity at another heading) and, on
  the horizontal channels, one per moving block (:mod:`host.model.turning`).

The turn records' accelerometer rows have noise of their own beyond the sensor's: the cube's
seating at the still moments (:func:`seating_sigma`) and the hand while it turns
(:func:`hand_sigma`), both measured from the rows themselves. What the builders read from a
record alone is kept between builds of sessions that share records (:class:`RecordWork`).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Hashable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from host.model import turning
from host.model.catalogue import plate_tilt
from host.model.noise import (
    NoiseModel,
    inner_step,
    integrated_autocorrelation,
    resolution,
    still_runs,
)
from host.model.signals import SENSORS, RecordSignals
from host.session.method import RecordStats, record_stats
from host.session.records import Record


@dataclass(frozen=True, eq=False)
class ChannelRows:
    """The rows of one record and channel as they are built, before the whitening.

    ``rows``: their indices in the dataset; ``aggregator`` (B, N): the weights turning the
    record's N samples into its B rows; ``white``: variance·τ of one sample of the channel
    measured from the record's own samples (NaN: not measured there, the static records' level
    is taken; 0: a turn integral, whose white noise comes from the static records)."""

    record: int
    sensor: str
    axis: int
    rows: list[int]
    aggregator: np.ndarray
    white: float


@dataclass(eq=False)
class RowTable:
    """The rows as the builders add them: per row its record, sensor (0 accel, 1 gyro), axis,
    whether it is a turn integral, its time span within the record (s), the measured value and
    the ideal sensor's (``nominal``); per record and channel a :class:`ChannelRows`; and the
    white-noise levels the static records measured (``static_noise``: (sensor, axis) -> their
    (variance, τ) in record order; ``record_noise``: (record, sensor, axis) -> (variance, τ)).
    ``deviations``: (sensor, axis) -> each measured run's samples about its mean, static records
    first (what the serial correlation is read from, :func:`apply_serial_correlation`); until
    then every τ is 1. ``inner_steps``: (record, sensor, axis) -> the time a step inside that
    static record starts at, s since its first sample (:class:`BlockMeans`)."""

    record: list[int] = field(default_factory=list)
    sensor: list[int] = field(default_factory=list)
    axis: list[int] = field(default_factory=list)
    integral: list[bool] = field(default_factory=list)
    t0: list[float] = field(default_factory=list)
    t1: list[float] = field(default_factory=list)
    y: list[float] = field(default_factory=list)
    nominal: list[float] = field(default_factory=list)
    channels: list[ChannelRows] = field(default_factory=list)
    static_noise: dict[tuple[str, int], list[tuple[float, float]]] = field(default_factory=dict)
    record_noise: dict[tuple[int, str, int], tuple[float, float]] = field(default_factory=dict)
    deviations: dict[tuple[str, int], list[np.ndarray]] = field(default_factory=dict)
    static_deviations: dict[tuple[str, int], list[np.ndarray]] = field(default_factory=dict)
    inner_steps: dict[tuple[int, str, int], float] = field(default_factory=dict)

    def add(
        self,
        record: int,
        sig: RecordSignals,
        sensor: str,
        axis: int,
        agg: np.ndarray,
        spans: Sequence[tuple[float, float]],
        integral: bool,
    ) -> list[int]:
        """Add the rows ``agg`` (B, N) @ samples of channel ``axis`` of ``sensor``, with their
        time spans ``spans`` (B, s); returns their indices."""
        y = (agg @ sig.measured(sensor)[:, axis]).tolist()
        nominal = (agg @ sig.reference(sensor)[:, axis]).tolist()
        return self.add_values(record, sensor, axis, y, nominal, spans, integral)

    def add_values(
        self,
        record: int,
        sensor: str,
        axis: int,
        y: Sequence[float],
        nominal: Sequence[float],
        spans: Sequence[tuple[float, float]],
        integral: bool,
    ) -> list[int]:
        """Add the rows of channel ``axis`` of ``sensor`` whose measured and ideal values are
        ``y`` and ``nominal`` (B,), with their time spans ``spans`` (B, s); returns their
        indices."""
        b = len(y)
        idx = list(range(len(self.y), len(self.y) + b))
        self.y.extend(y)
        self.nominal.extend(nominal)
        self.record.extend([record] * b)
        self.sensor.extend([SENSORS.index(sensor)] * b)
        self.axis.extend([axis] * b)
        self.integral.extend([integral] * b)
        self.t0.extend(span[0] for span in spans[:b])
        self.t1.extend(span[1] for span in spans[:b])
        return idx


def white_variance(
    meas: np.ndarray, runs: Sequence[tuple[int, int]]
) -> tuple[float, list[np.ndarray]]:
    """(variance of one sample of ``meas`` (N,) from its deviations about each run's mean, at
    least the quantisation step²/12; those deviations per run)."""
    devs = [meas[a:e] - meas[a:e].mean() for a, e in runs]
    dev = np.concatenate(devs)
    dof = max(len(dev) - len(runs), 1)
    return max(float(dev @ dev) / dof, resolution(meas) ** 2 / 12.0), devs


def apply_serial_correlation(table: RowTable, max_lag: int) -> dict[tuple[str, int], float]:
    """Multiply every measured white variance of ``table`` by its channel's integrated
    autocorrelation time τ (:func:`host.model.noise.integrated_autocorrelation`), read from
    the static records' deviations of that channel pooled (the sensor's filter is the same in
    every record; one record's few hundred samples alone would leave τ noisy and biased high),
    else from every run measured; -> τ per (sensor, axis)."""
    taus: dict[tuple[str, int], float] = {}
    for key, devs in table.deviations.items():
        taus[key] = integrated_autocorrelation(table.static_deviations.get(key) or devs, max_lag)
    table.channels[:] = [
        dataclasses.replace(ch, white=ch.white * taus.get((ch.sensor, ch.axis), 1.0))
        if math.isfinite(ch.white) and ch.white > 0
        else ch
        for ch in table.channels
    ]
    for key, levels in table.static_noise.items():
        table.static_noise[key] = [(v, taus.get(key, 1.0)) for v, _ in levels]
    for (ri, s, ax), (v, _) in list(table.record_noise.items()):
        table.record_noise[(ri, s, ax)] = (v, taus.get((s, ax), 1.0))
    return taus


def block_edges(n: int, duration_s: float, noise: NoiseModel) -> list[tuple[int, int]]:
    """[start, stop) sample ranges of the blocks a static record of ``n`` samples and
    ``duration_s`` s is cut into (about ``noise.block_s`` each, at most ``noise.max_blocks``)."""
    b = int(max(1, min(noise.max_blocks, round(duration_s / noise.block_s))))
    b = max(1, min(b, n // 8 if n >= 8 else 1))
    edges = np.linspace(0, n, b + 1).round().astype(int)
    return [(int(edges[i]), int(edges[i + 1])) for i in range(b)]


def means_of(ranges: Sequence[tuple[int, int]], n: int) -> np.ndarray:
    """(len(ranges), n) weights of the mean over each [start, stop) sample range."""
    agg = np.zeros((len(ranges), n))
    for b, (a, e) in enumerate(ranges):
        agg[b, a:e] = 1.0 / (e - a)
    return agg


def trapezoid_weights(t_ms: np.ndarray) -> np.ndarray:
    """(1, N) weights of the trapezoid integral over the sample times ``t_ms`` (ms), in s."""
    w = np.zeros(len(t_ms))
    dt = np.diff(t_ms) / 1000.0
    w[1:] += dt / 2
    w[:-1] += dt / 2
    return w[None, :]


@dataclass(frozen=True, eq=False)
class BlockMeans:
    """A static or rate-table record's rows, from its own samples alone (:func:`block_means`):
    ``aggregator`` (B, N) the weights of the block means, ``spans`` their time spans (s), and
    per channel (sensor, axis, the block means and the ideal sensor's (B,) in the channel's
    unit, the white variance of one sample and the deviations it is read from,
    :func:`white_variance`). ``inner``: (sensor, axis) -> the time (s since the record's first
    sample) a step inside the record starts at where its samples show one
    (:func:`host.model.noise.inner_step`; the deviations are then read about its two levels).
    Its arrays are not changed once made (several datasets may hold them)."""

    aggregator: np.ndarray
    spans: tuple[tuple[float, float], ...]
    channels: tuple[tuple[str, int, list[float], list[float], float, list[np.ndarray]], ...]
    inner: Mapping[tuple[str, int], float] = field(default_factory=dict)


def block_means(sig: RecordSignals, t_rel: np.ndarray, noise: NoiseModel) -> BlockMeans:
    """Every channel's block means of a static or rate-table record and their white noise from
    the record's own samples (``t_rel`` (N,) s since its first sample). Where a channel's
    samples show a step inside a static record (:func:`host.model.noise.inner_step`; not a
    hand-held pose, which creeps while it settles: :mod:`host.model.components`) the blocks are
    cut there, at least two either side (:func:`stepped_edges`): the rows then show the step's
    size from the record alone, also where the fit takes the record's level (the first record,
    whose level the pair's scale and the misalignments absorb)."""
    n = len(t_rel)
    inner: dict[tuple[str, int], float] = {}
    cuts: set[int] = set()
    for s in SENSORS if sig.kind == "static" else ():  # a hand's pose creeps as it settles
        for ax in range(3):
            cut = inner_step(sig.measured(s)[:, ax], noise.max_lag)
            if cut is not None:
                inner[(s, ax)] = float(t_rel[cut])
                cuts.add(cut)
    edges = block_edges(n, float(t_rel[-1]) if n else 0.0, noise)
    edges = stepped_edges(t_rel, sorted(cuts), noise) if cuts else edges
    agg = means_of(edges, n)
    agg.flags.writeable = False
    spans = tuple((float(t_rel[a]), float(t_rel[e - 1])) for a, e in edges)
    channels = []
    for s in SENSORS:
        meas, ref = sig.measured(s), sig.reference(s)
        for ax in range(3):
            if not agg.shape[0]:
                continue
            var, devs = white_variance(meas[:, ax], edges)
            y, nominal = (agg @ meas[:, ax]).tolist(), (agg @ ref[:, ax]).tolist()
            channels.append((s, ax, y, nominal, var, devs))
    return BlockMeans(agg, spans, tuple(channels), inner)


def stepped_edges(
    t_rel: np.ndarray, cuts: Sequence[int], noise: NoiseModel
) -> list[tuple[int, int]]:
    """[start, stop) sample ranges of the blocks of a static record (times ``t_rel`` (N,) s)
    cut at the samples ``cuts`` where a step starts: each piece between two cuts is cut into
    blocks of about ``noise.block_s`` and at least two (one block a side would leave the step's
    size and its place inside the block one unknown), each of at least 8 samples."""
    n = len(t_rel)
    bounds = [0, *cuts, n]
    out: list[tuple[int, int]] = []
    for a, e in zip(bounds[:-1], bounds[1:], strict=True):
        if e - a < 8:
            if out and e > a:
                out[-1] = (out[-1][0], e)  # too short for a block: joins the one before
            elif e > a:
                out.append((a, e))
            continue
        dur = float(t_rel[e - 1] - t_rel[a])
        b = int(min(noise.max_blocks, max(2, round(dur / noise.block_s)), (e - a) // 8 or 1))
        edges = np.linspace(a, e, b + 1).round().astype(int)
        out.extend((int(edges[i]), int(edges[i + 1])) for i in range(b))
    return out


def add_block_means(table: RowTable, record: int, means: BlockMeans) -> np.ndarray:
    """A static or rate-table record's rows (:func:`block_means`) into ``table``. Returns its
    aggregator."""
    agg = means.aggregator
    for s, ax, y, nominal, var, devs in means.channels:
        idx = table.add_values(record, s, ax, y, nominal, means.spans, integral=False)
        table.deviations.setdefault((s, ax), []).extend(devs)
        table.static_deviations.setdefault((s, ax), []).extend(devs)
        table.static_noise.setdefault((s, ax), []).append((var, 1.0))
        table.record_noise[(record, s, ax)] = (var, 1.0)
        table.channels.append(ChannelRows(record, s, ax, idx, agg, var))
    for (s, ax), at in means.inner.items():
        table.inner_steps[(record, s, ax)] = at
    return agg


def add_turn_integrals(
    table: RowTable, record: int, sig: RecordSignals, t_ms: np.ndarray, t_rel: np.ndarray
) -> np.ndarray:
    """A turn record: each gyro channel's trapezoid integral over the sample times ``t_ms``
    (ms), in °; its white noise comes from the static records. Returns its aggregator."""
    agg = trapezoid_weights(t_ms)
    spans = [(0.0, float(t_rel[-1]))]
    for ax in range(3):
        idx = table.add(record, sig, "gyro", ax, agg, spans, integral=True)
        table.channels.append(ChannelRows(record, "gyro", ax, idx, agg, 0.0))
    return agg


@dataclass(frozen=True, eq=False)
class TurnAccel:
    """Where a turn record's accelerometer is read: ``aggregators`` per axis (B, N) — the still
    moments, then (horizontal axes only) the moving blocks —, their time ``spans`` (s) and how
    many of the rows are still moments (``n_still``)."""

    aggregators: tuple[np.ndarray, ...]
    spans: tuple[tuple[float, float], ...]
    n_still: int
    #: [start, stop) sample ranges of the still moments (the first ``n_still`` rows)
    still: tuple[tuple[int, int], ...] = ()


def turn_accel_rows(
    sig: RecordSignals, t_rel: np.ndarray, gyro_sd_dps: float, moving: bool
) -> TurnAccel | None:
    """The still moments of a turn record (gravity at several headings) and, with ``moving``,
    the blocks of its turning parts (the lever arm), found from the reference rate about up
    and the gyro's per-sample noise ``gyro_sd_dps`` (°/s); None when it has neither."""
    rate_up = sig.rate @ sig.up
    runs = still_runs(rate_up, t_rel, gyro_sd_dps)
    blocks = turning.moving_blocks(rate_up, t_rel, gyro_sd_dps) if moving else []
    if not (runs or blocks):
        return None
    acc_agg = means_of([*runs, *blocks], len(t_rel))
    acc_agg.flags.writeable = False  # several datasets may hold it
    # the up channel reads no lever arm, only the hand pressing and tilting the cube
    # (g·(1 − cos θ), one-signed): its moving blocks are left out
    aggs = tuple(
        acc_agg if abs(float(sig.up[ax])) < 0.5 else acc_agg[: len(runs)] for ax in range(3)
    )
    spans = tuple((float(t_rel[a]), float(t_rel[e - 1])) for a, e in [*runs, *blocks])
    return TurnAccel(aggs, spans, len(runs), tuple(runs))


#: per accelerometer axis with rows: (axis, the rows' means and the ideal sensor's (B,), m/s²,
#: the white variance of one sample from the still moments (NaN without), its deviations)
TurnAccelValues = tuple[tuple[int, list[float], list[float], float, list[np.ndarray]], ...]


def turn_accel_values(sig: RecordSignals, turn: TurnAccel) -> TurnAccelValues:
    """A turn record's accelerometer rows (:func:`turn_accel_rows`) read from its samples: the
    white noise of a still moment's mean from the still moments' own samples (NaN without
    still moments: the static records' level is taken)."""
    out: list[tuple[int, list[float], list[float], float, list[np.ndarray]]] = []
    for ax in range(3):
        agg = turn.aggregators[ax]
        if not agg.shape[0]:
            continue
        y, nominal = (agg @ sig.accel[:, ax]).tolist(), (agg @ sig.force[:, ax]).tolist()
        if turn.n_still == 0:
            out.append((ax, y, nominal, math.nan, []))
            continue
        var, devs = white_variance(sig.accel[:, ax], turn.still)
        out.append((ax, y, nominal, var, devs))
    return tuple(out)


def add_turn_accel(table: RowTable, record: int, turn: TurnAccel, values: TurnAccelValues) -> None:
    """A turn record's accelerometer rows (:func:`turn_accel_rows`, :func:`turn_accel_values`)
    into ``table``."""
    for ax, y, nominal, var, devs in values:
        agg = turn.aggregators[ax]
        idx = table.add_values(record, "accel", ax, y, nominal, turn.spans, integral=False)
        if turn.n_still:
            table.deviations.setdefault(("accel", ax), []).extend(devs)
        table.channels.append(ChannelRows(record, "accel", ax, idx, agg, var))


def turn_tilt_columns(
    signals: Sequence[RecordSignals], sensor_aggs: Mapping[tuple[int, str, int], np.ndarray]
) -> dict[tuple[int, int], np.ndarray]:
    """(record, axis) -> the plate tilt's columns (N, 2) (:func:`plate_tilt`, m/s² per rad) on
    each turn record's horizontal accelerometer that has rows of its own (``sensor_aggs``):
    what :func:`seating_sigma` and :func:`hand_sigma` take out, computed once for both."""
    out: dict[tuple[int, int], np.ndarray] = {}
    for ri, sig in enumerate(signals):
        if sig.kind != "turn":
            continue
        for ax in range(3):
            if abs(float(sig.up[ax])) > 0.5 or (ri, "accel", ax) not in sensor_aggs:
                continue
            cols = plate_tilt.columns(sig, "accel", ax) if plate_tilt.columns else None
            assert cols is not None
            out[(ri, ax)] = cols
    return out


def seating_sigma(
    signals: Sequence[RecordSignals],
    sensor_aggs: Mapping[tuple[int, str, int], np.ndarray],
    channels: Sequence[ChannelRows],
    n_still: Mapping[int, int],
    tilt: Mapping[tuple[int, int], np.ndarray],
) -> tuple[float, str]:
    """How far the cube's attitude at a still moment of a hand turn departs from resting flat,
    as specific force on a horizontal accelerometer, m/s² (and a note; 0 and '' without the
    data). The hand holds or presses the cube between pushes, so each still moment is a new
    seating. Measured from the still moments themselves: per turn and horizontal channel a
    constant (bias, face error, misalignment: all fixed in the body) plus ONE plate tilt for
    the session, g·(t_e·e(ψ) + t_n·n(ψ)) (:func:`plate_tilt`); the scatter beyond each mean's
    white noise, Σ(r² − w)/dof, is the seating variance (method.md §8: repeatability;
    :func:`host.model.turning.excess_scatter`). ``tilt``: :func:`turn_tilt_columns`."""
    keys: list[tuple[int, int]] = []
    ys: list[float] = []
    cols_l: list[np.ndarray] = []
    ws: list[float] = []
    for ch in channels:
        ri, s, ax, agg, var_tau = ch.record, ch.sensor, ch.axis, ch.aggregator, ch.white
        sig = signals[ri]
        if s != "accel" or sig.kind != "turn" or abs(float(sig.up[ax])) > 0.5:
            continue
        if (ri, "accel", ax) not in sensor_aggs:
            continue
        cols = tilt[(ri, ax)]
        for b in range(n_still.get(ri, 0)):
            m = float(np.count_nonzero(agg[b]))
            keys.append((ri, ax))
            ys.append(float(agg[b] @ sig.accel[:, ax]))
            cols_l.append(agg[b] @ cols)
            ws.append(var_tau / m)
    if not ys or len(ys) <= len(set(keys)) + 2:
        return 0.0, ""
    sigma, dof = turning.excess_scatter(np.array(ys), keys, np.array(cols_l), np.array(ws))
    if dof <= 0:
        return 0.0, ""
    return sigma, (
        f"seating of the cube at the still moments of the turns: {sigma:.2g} m/s² on a "
        f"horizontal accelerometer ({1000 * sigma / 9.8:.2g} mrad), from {len(ys)} still "
        f"moments ({dof} dof beyond one plate tilt and a constant per turn and channel)"
    )


def hand_sigma(
    signals: Sequence[RecordSignals],
    sensor_aggs: Mapping[tuple[int, str, int], np.ndarray],
    n_still: Mapping[int, int],
    white_level: Mapping[tuple[str, int], float],
    tilt: Mapping[tuple[int, int], np.ndarray],
    lever_of: Callable[[int], np.ndarray],
) -> tuple[tuple[float, float], str]:
    """The hand's scatter on a horizontal accelerometer while the cube turns, m/s²: (of a
    moving block's mean about its turn's level, of that level about the turn's level at rest)
    and a note ('' without moving blocks): beyond a constant per turn and channel, the lever arm
    and the plate tilt, and beyond the sensor's white noise (``white_level`` (sensor, axis) ->
    variance·τ of one sample, from the static records) —
    :func:`host.model.turning.hand_scatter`, module docstring there. ``tilt``:
    :func:`turn_tilt_columns`; ``lever_of``: a turn record's
    :func:`host.model.turning.sensed_lever_matrix` by its index."""
    keys: list[tuple[int, int]] = []
    ys: list[float] = []
    cl: list[np.ndarray] = []
    ws: list[float] = []
    rest: dict[Hashable, tuple[float, float, np.ndarray]] = {}
    for ri, sig in enumerate(signals):
        if sig.kind != "turn":
            continue
        lever: np.ndarray | None = None
        for ax in range(3):
            agg = sensor_aggs.get((ri, "accel", ax))
            if agg is None or n_still.get(ri, 0) >= agg.shape[0]:
                continue
            moving = agg[n_still[ri] :]
            counts = np.count_nonzero(moving, axis=1).astype(float)
            tilt0 = tilt[(ri, ax)]
            if n_still[ri]:
                # the same turn and channel at rest: the still moments' mean
                still = agg[: n_still[ri]]
                m_still = still.mean(axis=0)
                # the average of the still moments' means: Σ w/n_b / B² (not w/Σn_b)
                inv_n = float(np.sum(1.0 / np.count_nonzero(still, axis=1))) / len(still) ** 2
                rest[(ri, ax)] = (
                    float(m_still @ sig.accel[:, ax]),
                    white_level.get(("accel", ax), 0.0) * inv_n,
                    np.concatenate([np.zeros(3), m_still @ tilt0]),
                )
            if lever is None:
                lever = lever_of(ri)
            keys.extend([(ri, ax)] * len(moving))
            ys.extend((moving @ sig.accel[:, ax]).tolist())
            cl.extend(moving @ np.column_stack([lever[:, ax, :], tilt0]))
            ws.extend((white_level.get(("accel", ax), 0.0) / counts).tolist())
    if not ys:
        return (0.0, 0.0), ""
    block, level, dof = turning.hand_scatter(np.array(ys), keys, np.array(cl), np.array(ws),
                                             rest)  # fmt: skip
    return (block, level), (
        f"the hand while the cube turns: {block:.2g} m/s² on a horizontal accelerometer's "
        f"block mean ({turning.BLOCK_S:g} s) about the turn's level, from {len(ys)} moving "
        f"blocks ({dof} dof beyond a constant per turn and channel, the lever arm and the "
        f"plate tilt); a turn's level while moving departs from its level at rest by {level:.2g}"
    )


@dataclass(eq=False)
class RecordWork:
    """What :func:`host.model.dataset.build_dataset` reads from a record alone, kept between
    builds of sessions that share records (the planner adds each candidate to the same
    measured records): each record's stats, and a static record's block means (:func:`block_means`)
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
            lever = turning.sensed_lever_matrix(sig.t_s, sig.rate, sig.lever_matrix)
            lever.flags.writeable = False  # several datasets may read it
            self.levers[key] = lever
        return self.levers[key]
