"""The dataset: everything the fits need from a session — the records' signals, the rows (block
means, turn integrals, still moments, moving blocks), their noise and the whitening."""

from __future__ import annotations

import functools
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from host.errors import UserError
from host.model import turning
from host.model.noise import (
    NoiseModel,
    hand_sigma,
    integrated_autocorrelation,
    resolution,
    seating_sigma,
    session_floor,
    still_runs,
)
from host.model.signals import SENSORS, RecordSignals
from host.session.directory import Session
from host.session.method import (
    DEFAULT_HEIGHT_M,
    DEFAULT_LATITUDE_DEG,
    local_gravity,
    record_stats,
    trapezoid_integral,
)
from host.session.observations import build_observations


# ---- dataset: rows, their noise and the whitening ------------------------------------------
@dataclass(frozen=True, eq=False)
class Group:
    """The rows of one record and channel: ``rows`` indices; ``sigma`` = std of their mean
    (static: block-mean average; turn: the integral); ``contrast_sigma`` = std of a block's
    deviation from the record's mean (NaN for one row)."""

    record: int
    sensor: str
    axis: int
    rows: np.ndarray
    sigma: float
    contrast_var: float


@dataclass(frozen=True, eq=False)
class Dataset:
    """Everything the fits need from a session: signals, rows and the whitening.

    Rows (n): ``y`` measured block mean (unit of the channel) or turn integral (°), ``nominal``
    the ideal sensor's value (the aggregated reference input on the channel), ``span`` (n,2)
    within-record time span s. ``whiten`` (n,n): W with W·Cov·Wᵀ = I.
    """

    signals: tuple[RecordSignals, ...]
    row_record: np.ndarray
    row_sensor: np.ndarray  # 0 accel, 1 gyro
    row_axis: np.ndarray
    row_integral: np.ndarray
    span: np.ndarray
    y: np.ndarray
    nominal: np.ndarray
    whiten: np.ndarray
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

    @property
    def n_rows(self) -> int:
        return int(self.y.shape[0])

    @functools.cached_property
    def group_means_whitened(self) -> np.ndarray:
        """(n_rows, groups) W⁻ᵀ·a for each group's mean a (:func:`residual_sigmas`), solved
        once per dataset (W does not change between fits)."""
        a = np.zeros((self.n_rows, len(self.groups)))
        for k, gr in enumerate(self.groups):
            a[gr.rows, k] = 1.0 / len(gr.rows)
        return np.asarray(np.linalg.solve(self.whiten.T, a))

    def aggregator(self, record: int, sensor: str, axis: int) -> np.ndarray:
        """(B, N) weights turning record ``record``'s samples into its rows of ``sensor``'s
        channel ``axis``."""
        return self.sensor_aggregators.get((record, sensor, axis), self.aggregators[record])

    def record_name(self, i: int) -> str:
        return self.signals[i].name


def _block_edges(n: int, duration_s: float, noise: NoiseModel) -> list[tuple[int, int]]:
    b = int(max(1, min(noise.max_blocks, round(duration_s / noise.block_s))))
    b = max(1, min(b, n // 8 if n >= 8 else 1))
    edges = np.linspace(0, n, b + 1).round().astype(int)
    return [(int(edges[i]), int(edges[i + 1])) for i in range(b)]


def _runs_of(agg: np.ndarray) -> list[tuple[int, int]]:
    """[start, stop) sample ranges of the rows of a still-moment aggregator."""
    out = []
    for row in agg:
        nz = np.flatnonzero(row)
        out.append((int(nz[0]), int(nz[-1]) + 1))
    return out


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


def _whiten_exact(
    whiten: np.ndarray,
    record: int,
    sensor: str,
    axis: int,
    idx: Sequence[int],
    cov: np.ndarray,
) -> Group:
    """Whiten the rows ``idx`` of one record and channel exactly when their variances differ
    or they are correlated (still moments and moving blocks of a turn): ``cov`` their
    covariance, W = L⁻¹ with L its Cholesky factor, written into ``whiten``; -> the
    :class:`Group`."""
    b = len(idx)
    if not np.all(np.diag(cov) > 0.0):
        raise UserError(
            f"record {record}: accel {'xyz'[axis]} reads the same value in every sample while "
            "turning (noise-free data): give a floor, e.g. --floor accel=1e-4,gyro=1e-3"
        )
    w = np.linalg.inv(np.linalg.cholesky(cov))
    whiten[np.ix_(list(idx), list(idx))] = w
    v_mean = float(np.sum(cov)) / b**2
    return Group(
        record, sensor, axis, np.array(idx), math.sqrt(v_mean), float(np.mean(np.diag(cov)))
    )


def build_dataset(
    session: Session,
    *,
    noise: NoiseModel | None = None,
    latitude_deg: float = DEFAULT_LATITUDE_DEG,
    height_m: float = DEFAULT_HEIGHT_M,
    turns: int | None = None,
    earth_rate: bool = False,
    moving: bool = True,
) -> Dataset:
    """Check the records (:func:`host.calibration.build_observations`) and build the rows.

    ``earth_rate``: the reference rate includes the vertical Earth rate (as
    :func:`~host.calibration.build_observations`). ``moving``: the accelerometer's block means
    over the turning parts of the turn records are rows too (:mod:`host.model.turning`;
    the lever arm shows only there). UserError when there is nothing to fit (no static
    records, bad records).
    """
    nm = noise or NoiseModel()
    if not session.records:
        raise UserError("no records to fit")
    g = local_gravity(latitude_deg, height_m)
    stats = {n: record_stats(r) for n, r in session.records.items()}
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
    # preliminary static gyro bias + g-sensitivity (per channel), for the turn reference rate
    statics = [n for n in names if obs_of[n].kind in ("static", "rate")]
    xs = np.array([np.concatenate([obs_of[n].force, [1.0]]) for n in statics])
    ys = np.array([stats[n].gyro_mean - obs_of[n].rate for n in statics])
    pre, *_ = np.linalg.lstsq(xs, ys, rcond=None)
    # per-sample gyro noise (°/s) per axis: finds the still moments inside the turns
    gyro_sd = np.median([stats[n].gyro_std for n in statics], axis=0)

    temp_mean = float(np.mean([float(np.mean(session.records[n].temp)) for n in names]))
    signals: list[RecordSignals] = []
    aggs: list[np.ndarray] = []
    rows: dict[str, list[float]] = {k: [] for k in ("rec", "sen", "ax", "int", "t0", "t1")}
    y_list: list[float] = []
    nom_list: list[float] = []
    groups_raw: list[tuple[int, str, int, list[int], np.ndarray, float]] = []
    # white-noise levels from the statics (for the turns): sensor -> axis -> (var, tau) lists
    static_noise: dict[tuple[str, int], list[tuple[float, float]]] = {}
    rec_noise: dict[tuple[int, str, int], tuple[float, float]] = {}
    sensor_aggs: dict[tuple[int, str, int], np.ndarray] = {}
    still_spans: dict[int, list[tuple[float, float]]] = {}
    #: turn record -> how many of its accelerometer rows are still moments (the rest: moving)
    n_still: dict[int, int] = {}

    for ri, name in enumerate(names):
        rec = session.records[name]
        o = obs_of[name]
        n = len(rec)
        t_rel = (rec.t_ms - rec.t_ms[0]) / 1000.0
        # without power-on times only the variation within a record is known: centre it
        t0 = float(rec.meta.get("power_on_s", "0") or 0.0) if has_power else -float(t_rel.mean())
        force = np.tile(g * o.up, (n, 1)) if o.kind != "rate" else np.tile(g * rec.up, (n, 1))
        if o.kind == "turn":
            bias_up = pre[:3].T @ o.up + pre[3]
            want = float(o.rate @ o.up)
            rate = _turn_reference(rec.gyro, rec.t_ms, o.up, bias_up, want)
            heading: np.ndarray | None = turn_heading(t_rel, rate @ o.up)
        else:  # rate table; statics: zero, or the vertical Earth rate
            rate = np.tile(o.rate, (n, 1))
            heading = None
        sig = RecordSignals(
            name=name, kind=o.kind, t_s=t0 + t_rel, temp_c=rec.temp.copy(), force=force,
            rate=rate, accel=rec.accel, gyro=rec.gyro, g=g, up=o.up, temp_mean_c=temp_mean,
            heading_deg=heading,
        )  # fmt: skip
        signals.append(sig)
        if o.kind == "turn":
            w = np.zeros(n)
            dt = np.diff(rec.t_ms) / 1000.0
            w[1:] += dt / 2
            w[:-1] += dt / 2
            agg = w[None, :]
            spans = [(0.0, float(t_rel[-1]))]
            sensors: tuple[str, ...] = ("gyro",)
            # the accelerometer at the still moments: gravity seen at several headings
            up_k = int(np.argmax(np.abs(o.up)))
            runs = still_runs(rate @ o.up, t_rel, float(gyro_sd[up_k]))
            # ... and while it turns (the lever arm): block means of the moving parts
            blocks = (
                turning.moving_blocks(rate @ o.up, t_rel, float(gyro_sd[up_k])) if moving else []
            )
            if runs or blocks:
                acc_agg = np.zeros((len(runs) + len(blocks), n))
                for b, (a, e) in enumerate([*runs, *blocks]):
                    acc_agg[b, a:e] = 1.0 / (e - a)
                for ax in range(3):
                    # the up channel reads no lever arm, only the hand pressing and tilting
                    # the cube (g·(1 − cos θ), one-signed): its moving blocks are left out
                    horizontal = abs(float(o.up[ax])) < 0.5
                    sensor_aggs[(ri, "accel", ax)] = acc_agg if horizontal else acc_agg[: len(runs)]
                still_spans[ri] = [
                    (float(t_rel[a]), float(t_rel[e - 1])) for a, e in [*runs, *blocks]
                ]
                n_still[ri] = len(runs)
                sensors = ("accel", "gyro")
        else:
            edges = _block_edges(n, float(t_rel[-1]) if n else 0.0, nm)
            agg = np.zeros((len(edges), n))
            for b, (a, e) in enumerate(edges):
                agg[b, a:e] = 1.0 / (e - a)
            spans = [(float(t_rel[a]), float(t_rel[e - 1])) for a, e in edges]
            sensors = SENSORS
        aggs.append(agg)
        for s in sensors:
            meas = sig.measured(s)
            ref = sig.reference(s)
            still = o.kind == "turn" and s == "accel"
            for ax in range(3):
                s_agg = sensor_aggs[(ri, s, ax)] if still else agg
                s_spans = still_spans[ri] if still else spans
                if not s_agg.shape[0]:
                    continue
                idx = list(range(len(y_list), len(y_list) + s_agg.shape[0]))
                yv = s_agg @ meas[:, ax]
                nv = s_agg @ ref[:, ax]
                y_list.extend(yv.tolist())
                nom_list.extend(nv.tolist())
                for b in range(s_agg.shape[0]):
                    rows["rec"].append(ri)
                    rows["sen"].append(SENSORS.index(s))
                    rows["ax"].append(ax)
                    rows["int"].append(o.kind == "turn" and not still)
                    rows["t0"].append(s_spans[b][0])
                    rows["t1"].append(s_spans[b][1])
                if o.kind == "turn" and not still:
                    groups_raw.append((ri, s, ax, idx, agg, 0.0))
                    continue
                if still:
                    # white noise of a still moment's mean from its own samples (NaN without
                    # still moments: the static records' level is taken below)
                    ns = n_still[ri]
                    if ns == 0:
                        groups_raw.append((ri, s, ax, idx, s_agg, math.nan))
                        continue
                    dev = np.concatenate(
                        [meas[a:e, ax] - meas[a:e, ax].mean() for a, e in _runs_of(s_agg[:ns])]
                    )
                    dof = max(len(dev) - ns, 1)
                    var = max(float(dev @ dev) / dof, resolution(meas[:, ax]) ** 2 / 12.0)
                    tau = integrated_autocorrelation(dev, nm.max_lag)
                    groups_raw.append((ri, s, ax, idx, s_agg, var * tau))
                    continue
                # white noise of a block mean from the record's own samples
                dev = np.concatenate([meas[a:e, ax] - meas[a:e, ax].mean() for a, e in edges])
                dof = max(len(dev) - len(edges), 1)
                var = max(float(dev @ dev) / dof, resolution(meas[:, ax]) ** 2 / 12.0)
                tau = integrated_autocorrelation(dev, nm.max_lag)
                static_noise.setdefault((s, ax), []).append((var, tau))
                rec_noise[(ri, s, ax)] = (var, tau)
                groups_raw.append((ri, s, ax, idx, agg, var * tau))

    floors, floor_note = session_floor(signals, rec_noise, nm)
    notes.append(floor_note)
    seat, seat_note = seating_sigma(signals, sensor_aggs, groups_raw, n_still)
    if seat_note:
        notes.append(seat_note)
    white_level = {k: float(np.mean([v * t for v, t in lv])) for k, lv in static_noise.items()}
    hand, hand_note = hand_sigma(signals, sensor_aggs, n_still, white_level)
    if hand_note:
        notes.append(hand_note)
    n_rows = len(y_list)
    whiten = np.zeros((n_rows, n_rows))
    groups: list[Group] = []
    # within-record wander: pooled excess scatter of block means over their prediction
    excess: dict[tuple[str, int], list[float]] = {}
    y_arr = np.array(y_list)
    for _ri, s, ax, idx, agg, var_tau in groups_raw:
        if len(idx) >= 2 and signals[_ri].kind != "turn":
            m = agg.sum(axis=1)  # ones
            counts = np.count_nonzero(agg, axis=1)
            v_b = var_tau / counts * m
            yb = y_arr[idx]
            chi = float(np.sum((yb - yb.mean()) ** 2 / v_b))
            excess.setdefault((s, ax), []).extend([chi, len(idx) - 1])
    inflate = {k: max(1.0, sum(v[0::2]) / max(sum(v[1::2]), 1.0)) for k, v in excess.items()}
    for ri, s, ax, idx, agg, var_tau in groups_raw:
        floor = floors[s]
        if signals[ri].kind == "turn" and s == "gyro":
            w = agg[0]
            levels = static_noise.get((s, ax), [(0.0, 1.0)])
            v_white = float(np.mean([v * t for v, t in levels]))
            T = float(w.sum())
            var = v_white * float(w @ w) + (floor * T) ** 2 + nm.turn_angle_sigma_deg**2
            whiten[idx[0], idx[0]] = 1.0 / math.sqrt(var)
            groups.append(Group(ri, s, ax, np.array(idx), math.sqrt(var), math.nan))
            continue
        counts = np.count_nonzero(agg, axis=1).astype(float)
        level = white_level.get((s, ax), 0.0)
        v_blocks = (var_tau if math.isfinite(var_tau) else level) / counts  # each block mean
        horizontal = abs(float(signals[ri].up[ax])) < 0.5
        ns = n_still.get(ri, len(idx)) if signals[ri].kind == "turn" else len(idx)
        if signals[ri].kind == "turn" and horizontal:
            v_blocks[:ns] = v_blocks[:ns] + seat**2  # a horizontal channel at a still moment
        if ns < len(idx):
            # moving blocks: the sensor's white noise (the static records' level) + the hand
            v_blocks[ns:] = level / counts[ns:]
            cov = np.diag(v_blocks) + floor**2
            cov[ns:, ns:] += turning.hand_covariance(hand[0], hand[1], len(idx) - ns)
            groups.append(_whiten_exact(whiten, ri, s, ax, idx, cov))
            continue
        b = len(idx)
        v_mean = float(np.sum(v_blocks)) / b**2 + floor**2
        if not v_mean > 0.0:
            raise UserError(
                f"{signals[ri].name}: {s} {'xyz'[ax]} reads the same value in every sample "
                "(noise-free data, or a stuck sensor): the fit weighs each record by its "
                "noise; give a floor, e.g. --floor accel=1e-4,gyro=1e-3 (m/s², °/s), or check "
                "the sensor"
            )
        whiten[idx[0], idx] = (1.0 / b) / math.sqrt(v_mean)
        turn = signals[ri].kind == "turn"  # still moments: their spread is the signal
        v_c = float(np.mean(v_blocks)) * (1.0 if turn else inflate.get((s, ax), 1.0))
        if not v_c > 0.0:  # noise-free samples (with a given floor): the only scale there is
            v_c = v_mean
        if b >= 2:
            # orthonormal Helmert contrasts of the b blocks
            for k in range(1, b):
                h = np.zeros(b)
                h[:k] = 1.0
                h[k] = -float(k)
                h /= np.linalg.norm(h)
                whiten[idx[k], idx] = h / math.sqrt(v_c)
        groups.append(Group(ri, s, ax, np.array(idx), math.sqrt(v_mean), v_c))
    rows_of: dict[tuple[int, str, int], np.ndarray] = {}
    for gr in groups:
        rows_of[(gr.record, gr.sensor, gr.axis)] = gr.rows
    return Dataset(
        signals=tuple(signals),
        row_record=np.array(rows["rec"], dtype=int),
        row_sensor=np.array(rows["sen"], dtype=int),
        row_axis=np.array(rows["ax"], dtype=int),
        row_integral=np.array(rows["int"], dtype=bool),
        span=np.column_stack([rows["t0"], rows["t1"]]),
        y=y_arr,
        nominal=np.array(nom_list),
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
    )


def load_dataset(
    directory: str | Path,
    *,
    noise: NoiseModel | None = None,
    latitude_deg: float = DEFAULT_LATITUDE_DEG,
    height_m: float = DEFAULT_HEIGHT_M,
    serial: str | None = None,
) -> Dataset:
    """Read the session in ``directory`` (:func:`host.records.read_session`) and build it."""
    from host.session.directory import read_session

    session = read_session(directory, serial)
    return build_dataset(session, noise=noise, latitude_deg=latitude_deg, height_m=height_m)


def session_from_records(records: Mapping[str, object], serial: str = "SIM") -> Session:
    """A :class:`Session` of in-memory records (e.g. :func:`host.sim.simulate_session`)."""
    from host.session.records import Record

    recs = {k: v for k, v in records.items() if isinstance(v, Record)}
    return Session(serial=serial, records=recs)
