"""The questions of ``python3 -m host archive``, answered from the store with :mod:`stats`:
trend, repeat, drift, lot, control charts and the bench check. Each returns plain values (the
text and the page render them elsewhere); ``alpha`` is the family-wise false-alarm rate of the
run (:mod:`host.archive.stats`)."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from host.archive import stats
from host.archive.entry import conditional_pass
from host.archive.store import Archive, ValueTable
from host.calib.decision import expanded_uncertainty
from host.errors import UserError
from host.session.method import TOLERANCES


@dataclass(frozen=True)
class Grid:
    """Values arranged as (group, parameter, session): ``groups`` the group keys, ``names``
    the parameters (in the order they first appear), sessions in time order (NaN: none);
    ``times``/``benches``/``ids`` of each session (group, session) from the first parameter
    seen; ``dofs`` the degrees of freedom of each σ (inf: exact)."""

    groups: list[tuple[str, ...]]
    names: list[str]
    values: np.ndarray
    sigmas: np.ndarray
    dofs: np.ndarray
    times: np.ndarray
    benches: np.ndarray
    ids: np.ndarray


def grid(t: ValueTable, by: Sequence[str]) -> Grid:
    """Arrange ``t`` by the columns ``by`` (e.g. ('serial', 'bench'))."""
    if len(t) == 0:
        e = np.zeros((0, 0, 0))
        return Grid([], [], e, e, e, e.astype(object), e.astype(object), e.astype(np.int64))
    cols = [getattr(t, c).astype(str) for c in by]
    key = cols[0].astype(object)
    for c in cols[1:]:
        key = key + "\x1f" + c.astype(object)
    gkeys, gi = np.unique(key.astype(str), return_inverse=True)
    first: dict[str, int] = {}
    for n in t.name:
        first.setdefault(n, len(first))
    names = list(first)
    ni = np.array([first[n] for n in t.name], dtype=np.int64)
    p = len(names)
    # a session = one calibration id within the group, numbered in time order (the rows come
    # ordered by serial, time, id)
    seen: dict[tuple[int, int], int] = {}
    counts: dict[int, int] = {}
    si = np.empty(len(t), dtype=np.int64)
    for r, k in enumerate(zip(gi.tolist(), t.id.tolist(), strict=True)):
        if k not in seen:
            seen[k] = counts.get(k[0], 0)
            counts[k[0]] = seen[k] + 1
        si[r] = seen[k]
    s = int(si.max()) + 1
    g = len(gkeys)
    values = np.full((g, p, s), np.nan)
    sigmas = np.full((g, p, s), np.nan)
    values[gi, ni, si] = t.value
    sigmas[gi, ni, si] = t.stderr
    dofs = np.full((g, p, s), np.inf)
    dofs[gi, ni, si] = t.dof
    times = np.full((g, s), "", dtype=object)
    benches = np.full((g, s), "", dtype=object)
    ids = np.full((g, s), -1, dtype=np.int64)
    times[gi, si] = t.measured_at
    benches[gi, si] = t.bench
    ids[gi, si] = t.id
    groups = [tuple(k.split("\x1f")) for k in gkeys]
    return Grid(groups, names, values, sigmas, dofs, times, benches, ids)


# ---- trend -----------------------------------------------------------------------------------
@dataclass(frozen=True)
class TrendPoint:
    """One session of a trend: UTC time, bench, value and 1-σ ``stderr`` in the parameter's
    unit, read on ``dof`` degrees of freedom (inf: from the noise model alone)."""

    measured_at: str
    bench: str
    value: float
    stderr: float
    dof: float = math.inf

    @property
    def expanded(self) -> float:
        """U at 95 % coverage, as the certificate gives it
        (:func:`host.calib.decision.expanded_uncertainty`)."""
        return expanded_uncertainty(self.stderr, self.dof)


def nothing_selected(archive: Archive, selection: str, names: Sequence[str] | None) -> UserError:
    """The one-line error of a question whose selection holds no calibration: the parameter
    names the archive does not know (and those it does), else the ``selection`` in words."""
    if names:
        known = sorted(set(archive.values().name.tolist()))  # on the error's path only
        unknown = [n for n in names if n not in known]
        if unknown:
            return UserError(
                f"--param {', '.join(unknown)}: no such parameter in the archive (it has "
                f"{', '.join(known) or 'none'})"
            )
    what = f"the archive has no calibration {selection}".rstrip()
    return UserError(f"{what} (python3 -m host archive list shows what it holds)")


def trend(
    archive: Archive, serial: str, names: Sequence[str] | None = None
) -> dict[str, list[TrendPoint]]:
    """Each parameter of ``serial`` against time (every session, in time order)."""
    t = archive.values(names, serial=serial)
    if len(t) == 0 and names and len(archive.values(None, serial=serial)):
        raise nothing_selected(archive, f"of {serial}", names)
    if len(t) == 0:
        raise UserError(f"{serial}: no calibration of this serial in the archive")
    out: dict[str, list[TrendPoint]] = {}
    for i in range(len(t)):
        out.setdefault(str(t.name[i]), []).append(
            TrendPoint(str(t.measured_at[i]), str(t.bench[i]), float(t.value[i]),
                       float(t.stderr[i]), float(t.dof[i]))
        )  # fmt: skip
    return out


# ---- repeat ----------------------------------------------------------------------------------
@dataclass(frozen=True)
class RepeatRow:
    """One parameter of one unit (on one bench unless pooled): the statistics of
    :func:`host.archive.stats.repeatability` (``nu``: Welch's second dof, inf when every σ is
    exact) and whether it ``failed`` the family-wise test."""

    serial: str
    bench: str
    name: str
    n: int
    mean: float
    scatter: float
    predicted: float
    chi2: float
    dof: int
    p: float
    cv: float
    failed: bool
    nu: float = math.inf


def repeat(
    archive: Archive,
    serial: str | None = None,
    *,
    alpha: float = stats.DEFAULT_ALPHA,
    across_benches: bool = False,
    lot: str | None = None,
) -> list[RepeatRow]:
    """Repeatability of ``serial`` (every unit when None) from its sessions on each bench
    (``across_benches``: all its sessions pooled — reproducibility). A parameter fails when
    its p-value (χ², or Welch's F where a σ is estimated: :func:`host.archive.stats.welch_p`)
    is below alpha / (number of parameters tested in this run)."""
    t = archive.values(serial=serial, lot=lot)
    if serial is not None and len(t) == 0:
        raise UserError(f"{serial}: no calibration of this serial in the archive")
    g = grid(t, ("serial",) if across_benches else ("serial", "bench"))
    r = stats.repeatability(g.values, g.sigmas, g.dofs)
    m = int(np.count_nonzero(r.dof >= 1))
    limit = alpha / max(m, 1)
    rows = []
    for gi, key in enumerate(g.groups):
        for pi, name in enumerate(g.names):
            if r.n[gi, pi] == 0:
                continue
            p = float(r.p[gi, pi])
            rows.append(
                RepeatRow(
                    key[0], "(all)" if across_benches else key[1], name, int(r.n[gi, pi]),
                    float(r.mean[gi, pi]), float(r.scatter[gi, pi]), float(r.predicted[gi, pi]),
                    float(r.chi2[gi, pi]), int(r.dof[gi, pi]), p, float(r.cv[gi, pi]),
                    bool(p < limit), float(r.nu[gi, pi]),
                )
            )  # fmt: skip
    return rows


@dataclass(frozen=True)
class IdenticalRepeat:
    """A session of a unit that is an earlier one of the same unit over again, bit for bit:
    calibration ids ``earlier`` and ``later``, and ``what`` is the same (every value and σ,
    or the named record file): a copy, or the same simulated noise, never a repeat."""

    serial: str
    bench: str
    earlier: int
    later: int
    what: str


def identical_repeats(
    archive: Archive,
    serial: str | None = None,
    *,
    across_benches: bool = False,
    lot: str | None = None,
) -> list[IdenticalRepeat]:
    """The sessions :func:`repeat` compares that are no repeat: every parameter's value and σ
    equal to an earlier session's of the unit (on its bench unless ``across_benches``), or a
    record file (its SHA-256) archived in an earlier session of other records."""
    g = grid(archive.values(serial=serial, lot=lot), ("serial",) if across_benches else
             ("serial", "bench"))  # fmt: skip
    out: list[IdenticalRepeat] = []
    for gi, key in enumerate(g.groups):
        seen: dict[bytes, int] = {}
        for si in range(g.ids.shape[1]):
            cid = int(g.ids[gi, si])
            if cid < 0:
                continue
            k = np.concatenate([g.values[gi, :, si], g.sigmas[gi, :, si]]).tobytes()
            if k in seen:
                bench = "(all)" if across_benches else key[1]
                out.append(IdenticalRepeat(key[0], bench, seen[k], cid, "every value and σ"))
            seen.setdefault(k, cid)
    kept = {int(i) for i in g.ids.ravel() if i >= 0}
    named = {(r.earlier, r.later) for r in out}
    for unit, bench, earlier, later, name in archive.shared_records(serial=serial, lot=lot):
        if earlier in kept and later in kept and (earlier, later) not in named:
            named.add((earlier, later))
            where = "(all)" if across_benches else bench
            out.append(IdenticalRepeat(unit, where, earlier, later, f"the record {name}"))
    return sorted(out, key=lambda r: (r.serial, r.later))


# ---- drift -----------------------------------------------------------------------------------
@dataclass(frozen=True)
class DriftRow:
    """A parameter of a unit between its last two calibrations: ``before``/``after`` values,
    ``delta``, ``z``, when, and whether it ``moved`` beyond k·σ or the tolerance."""

    serial: str
    name: str
    before_at: str
    after_at: str
    before: float
    after: float
    delta: float
    z: float
    moved: bool


def drift(
    archive: Archive,
    *,
    alpha: float = stats.DEFAULT_ALPHA,
    k: float | None = None,
    tolerances: Mapping[str, float] | None = None,
    serial: str | None = None,
    lot: str | None = None,
) -> tuple[list[DriftRow], float]:
    """Every unit's change between its last two sessions; returns the rows and the k used
    (``k`` None: the family-wise k of ``alpha`` over every (unit, parameter) compared)."""
    g = grid(archive.values(serial=serial, lot=lot, with_simulated=False), ("serial",))
    # the last two sessions that determined each parameter (a session without it is skipped)
    at = np.where(np.isfinite(g.values), np.arange(g.values.shape[-1]), -1)
    last = at.max(axis=-1, initial=-1)
    prev = np.where(at < last[..., None], at, -1).max(axis=-1, initial=-1)
    has = prev >= 0
    m = int(np.count_nonzero(has))
    kk = stats.family_z(alpha, m) if k is None else k

    def pick(a: np.ndarray, i: np.ndarray) -> np.ndarray:
        return np.take_along_axis(a, np.maximum(i, 0)[..., None], axis=-1)[..., 0]

    a, b = pick(g.values, last), pick(g.values, prev)
    z = stats.drift_z(b, pick(g.sigmas, prev), a, pick(g.sigmas, last))
    tol = np.array([(tolerances or {}).get(nm, math.inf) for nm in g.names])
    moved = stats.drifted(z, a - b, kk, tol) & has
    rows = []
    for gi, key in enumerate(g.groups):
        for pi, name in enumerate(g.names):
            if not has[gi, pi]:
                continue
            rows.append(
                DriftRow(key[0], name, str(g.times[gi, prev[gi, pi]]),
                         str(g.times[gi, last[gi, pi]]), float(b[gi, pi]), float(a[gi, pi]),
                         float(a[gi, pi] - b[gi, pi]), float(z[gi, pi]), bool(moved[gi, pi]))
            )  # fmt: skip
    return rows, kk


# ---- lot -------------------------------------------------------------------------------------
@dataclass(frozen=True)
class LotRow:
    """One parameter over the lot (each unit's latest session): the summary and the outlier
    units with their values."""

    name: str
    summary: stats.LotSummary
    outliers: tuple[tuple[str, float], ...]


#: the lot table's mark of a parameter (its ``within``) and what it means, in words
LOT_MARKS: dict[bool | None, tuple[str, str]] = {
    True: ("within", "mean ± 3·spread inside the datasheet limit"),
    False: ("OUTSIDE", "mean ± 3·spread of this lot past the datasheet limit: a wide lot to "
            "watch, no unit's FAIL"),
    None: ("-", "no datasheet limit"),
}  # fmt: skip


def lot_mark(row: LotRow) -> tuple[str, str]:
    """(the mark, what it means) of one parameter of the lot table; an outlier is named."""
    mark, means = LOT_MARKS[row.summary.within]
    if row.outliers:
        names = ", ".join(u for u, _ in row.outliers)
        means += f"; outlier {names}: unusual for this lot, not a failure"
    return mark, means


@dataclass(frozen=True)
class LotReport:
    rows: list[LotRow]
    units: int
    failing: tuple[tuple[str, str], ...]  # (serial, why) of units whose latest session failed
    #: (serial, RMS z) of units whose latest session is a conditional PASS: every value within
    #: tolerance, on a model that does not fit (not a clean pass)
    conditional: tuple[tuple[str, float], ...] = ()


def lot_report(
    archive: Archive,
    lot: str | None = None,
    *,
    alpha: float = stats.DEFAULT_ALPHA,
    names: Sequence[str] | None = None,
    limits: Mapping[str, float | None] | None = None,
) -> LotReport:
    """Per parameter over each unit's latest session: mean, spread, mean ± 3·spread against
    the datasheet limit (``limits``, default the method's §7 tolerances), and the outlier
    units (Grubbs at alpha / number of parameters); the units whose latest session failed,
    and those whose PASS is conditional (the model does not fit their records)."""
    t = archive.values(names, lot=lot, latest_per_unit=True, with_simulated=False)
    lim = TOLERANCES if limits is None else limits
    g = grid(t, ("serial",))
    x = g.values[..., 0] if g.values.size else np.zeros((0, 0))
    a = alpha / max(len(g.names), 1)
    rows = []
    for pi, name in enumerate(g.names):
        col = x[:, pi]
        out = stats.grubbs_outliers(col, a)
        rows.append(
            LotRow(
                name, stats.lot_summary(col, lim.get(name)),
                tuple((g.groups[i][0], float(col[i])) for i in out),
            )
        )  # fmt: skip
    failing: dict[str, str] = {}
    conditional: dict[str, float] = {}
    for i in range(len(t)):
        s = str(t.serial[i])
        if t.self_test[i] == "fail":
            failing[s] = "self-test failed"
        elif t.verdict[i] != "pass":
            failing.setdefault(s, "FAIL in its report")
        elif conditional_pass(str(t.verdict[i]), str(t.fit_verdict[i])):
            conditional[s] = float(t.rms_z[i])
    return LotReport(
        rows, len(g.groups), tuple(sorted(failing.items())),
        tuple(sorted((s, z) for s, z in conditional.items() if s not in failing)),
    )  # fmt: skip


# ---- control charts --------------------------------------------------------------------------
@dataclass(frozen=True)
class Chart:
    """An individuals chart of one parameter on one bench: points in time order, centre and σ
    from the baseline, and the rules (numbers 1–4) that fire at each point."""

    bench: str
    name: str
    times: list[str]
    serials: list[str]
    values: np.ndarray
    centre: float
    sigma: float
    fired: list[tuple[int, ...]]


def control_charts(
    archive: Archive,
    *,
    serial: str | None = None,
    bench: str | None = None,
    names: Sequence[str] | None = None,
    baseline: int = 20,
) -> list[Chart]:
    """One chart per bench and parameter: every session on the bench (of ``serial`` only when
    given, e.g. the reference unit) in time order."""
    t = archive.values(names, serial=serial, bench=bench, with_simulated=False)
    charts = []
    for b in sorted(set(t.bench.tolist())):
        on = t.where(t.bench == b)
        order = np.lexsort((on.id, on.measured_at.astype(str)))
        on = on.where(order)
        for name in dict.fromkeys(on.name.tolist()):
            c = on.where(on.name == name)
            ok = np.isfinite(c.value)
            c = c.where(ok)
            centre, sigma = stats.individuals_limits(c.value, baseline)
            fired: list[tuple[int, ...]] = [()] * len(c)
            if math.isfinite(sigma) and sigma > 0:
                hits = stats.run_rules(c.value, centre, sigma)
                fired = [tuple(int(r) + 1 for r in np.flatnonzero(h)) for h in hits]
            charts.append(
                Chart(b, name, c.measured_at.astype(str).tolist(), c.serial.astype(str).tolist(),
                      c.value, centre, sigma, fired)
            )  # fmt: skip
    return charts


# ---- bench check -----------------------------------------------------------------------------
@dataclass(frozen=True)
class BenchRow:
    """One parameter on one bench for the reference unit (see
    :class:`host.archive.stats.BenchComparison`)."""

    bench: str
    name: str
    sessions: int
    mean: float
    u: float
    ref: float
    u_ref: float
    z: float
    en: float
    flagged: bool


def check_bench(
    archive: Archive, reference: str, *, alpha: float = stats.DEFAULT_ALPHA
) -> tuple[list[BenchRow], float]:
    """The reference unit's calibrations on every bench compared; returns the rows and the
    family-wise k over benches × parameters."""
    g = grid(archive.values(serial=reference), ("bench",))
    if len(g.groups) < 2:
        raise UserError(
            f"{reference}: calibrated on {len(g.groups)} bench(es) in the archive; the bench "
            "check needs the reference unit calibrated on at least two"
        )
    mean, u = stats.bench_means(g.values, g.sigmas)  # (B, P)
    k = stats.family_z(alpha, int(np.count_nonzero(np.isfinite(mean))))
    cmp = stats.compare_benches(mean.T, u.T, k)  # (P, B)
    n = np.isfinite(g.values).sum(axis=-1)
    rows = [
        BenchRow(
            g.groups[bi][0], name, int(n[bi, pi]), float(cmp.mean[pi, bi]), float(cmp.u[pi, bi]),
            float(cmp.ref[pi, bi]), float(cmp.u_ref[pi, bi]), float(cmp.z[pi, bi]),
            float(cmp.en[pi, bi]), bool(cmp.flagged[pi, bi]),
        )
        for bi in range(len(g.groups))
        for pi, name in enumerate(g.names)
    ]  # fmt: skip
    return rows, k
