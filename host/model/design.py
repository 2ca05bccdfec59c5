"""The design matrix: each model term's columns over the dataset's rows (block means, turn
integrals, still moments, moving blocks), built from its column function (user code, maybe:
errors become one line naming the term)."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from host.errors import UserError
from host.model.dataset import Dataset
from host.model.signals import RecordSignals
from host.model.spec import ModelTerm
from host.model.terms import Term

#: the largest magnitude a term's column may take: its square, summed over the rows, stays
#: far inside float64 (a column of 1e150 made the fit's SVD fail)
MAX_COLUMN = 1e100


# ---- design matrix --------------------------------------------------------------------------
def aggregate(
    agg: np.ndarray, per_sample: np.ndarray, scale: float | np.ndarray | None = None
) -> np.ndarray:
    """Rows of one record from per-sample values: ``agg`` (B,N) @ ``per_sample`` (N,…), with
    round-off (below 1e-9 of the largest per-sample value, ``scale`` where the caller has
    it already, or per column: (…,) the largest of each) set to exactly 0."""
    out = agg @ per_sample
    if scale is None:
        scale = float(np.abs(per_sample).max()) if per_sample.size else 0.0
    out[np.abs(out) < 1e-9 * scale] = 0.0
    return out


def _call_term(
    t: Term, what: str, sig: RecordSignals, fn: Callable[[], Any]
) -> tuple[np.ndarray, float]:
    """Call a term's function (user code, maybe): any exception or a non-finite value becomes
    one UserError naming the term, the function and the record. -> (its values, their
    largest magnitude)."""
    try:
        raw = fn()
        if np.iscomplexobj(raw):  # its real part alone would be taken, with a warning
            raise UserError(
                f"term {t.name}: {what}() returned complex numbers for record {sig.name}; it "
                "must give real ones"
            )
        x = np.asarray(raw, dtype=np.float64)
    except UserError:
        raise
    except (Exception, SystemExit) as exc:  # noqa: BLE001 - a term's error: one line
        raise UserError(
            f"term {t.name}: {what}() raised {type(exc).__name__}: {exc} (record {sig.name})"
        ) from None
    big = float(np.abs(x).max()) if x.size else 0.0  # NaN (or inf) if any value is not finite
    if not math.isfinite(big):
        raise UserError(
            f"term {t.name}: {what}() returned {int(np.count_nonzero(~np.isfinite(x)))} "
            f"non-finite values (NaN or inf) for record {sig.name}; it must give finite numbers"
        )
    if big > MAX_COLUMN:  # the fit's squares overflow: 'SVD did not converge', a traceback
        raise UserError(
            f"term {t.name}: {what}() returned values up to {big:.3g} for record {sig.name}, "
            f"beyond the fit's range (±{MAX_COLUMN:g}); scale the term to the records' units"
        )
    return x, big


def _regressors(
    t: Term,
    sig: RecordSignals,
    sensor: str,
    axis: int,
    twin: bool = False,
    every: dict[int, Sequence[np.ndarray]] | None = None,
    record: int = -1,
) -> tuple[np.ndarray, float]:
    """(N, k) a term's per-sample regressors on one channel of one record, their largest
    magnitude. ``every``: record -> its three channels' columns, where the term gives them at
    once (:attr:`Term.columns_all`), filled on the record's first channel."""
    columns = t.twin_columns if twin else t.columns
    assert columns is not None
    what = "twin_columns" if twin else "columns"
    all_axes = t.columns_all if not twin and every is not None else None
    if all_axes is None:
        x, big = _call_term(t, what, sig, lambda: columns(sig, sensor, axis))
    else:
        assert every is not None

        def channel() -> np.ndarray:
            if record not in every:
                every[record] = all_axes(sig, sensor)
            return every[record][axis]

        x, big = _call_term(t, what, sig, channel)
    if x.ndim == 1:
        x = x[:, None]
    if x.shape != (len(sig.t_s), len(t.params)):
        raise UserError(
            f"term {t.name}: {what}() returned shape {x.shape}, expected "
            f"({len(sig.t_s)}, {len(t.params)})"
        )
    return x, big


def term_columns(
    ds: Dataset, mt: ModelTerm, theta: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Design columns (n_rows, n_params) of a model term and its offset (n_rows,).

    Linear terms: offset 0. Nonlinear terms: the Jacobian at ``theta`` (parameters in the
    order axis-major) and offset value(θ) − J·θ, so that value ≈ offset + J·θ'. A shared
    term (:attr:`Term.shared`, linear only) has one set of k columns: each channel's rows hold
    that channel's regressors. A term with a twin (:attr:`Term.twin_columns`) puts the same
    parameters on the twin sensor's rows of the same axis. The unknowns of records that carry
    their own follow (:func:`record_columns`).
    """
    own = record_columns(ds, mt)
    if mt.term.shared:
        if mt.term.nonlinear:
            raise UserError(f"term {mt.term.name}: a shared term must be linear (columns())")
        return np.column_stack([_shared_columns(ds, mt), own]), np.zeros(ds.n_rows)
    if mt.term.nonlinear:
        cols, offset = _linearised_columns(ds, mt, theta)
    else:
        cols, offset = _linear_columns(ds, mt), np.zeros(ds.n_rows)
    return np.column_stack([cols, own]), offset


def _shared_columns(ds: Dataset, mt: ModelTerm) -> np.ndarray:
    """(n_rows, k) a shared term's one set of columns: each channel's rows hold that
    channel's regressors."""
    cols = np.zeros((ds.n_rows, len(mt.term.params)))
    every: dict[int, Sequence[np.ndarray]] = {}  # a record's channels, built at once
    for ax in mt.axes:
        for ri, sig in enumerate(ds.signals):
            rows = ds.rows_of.get((ri, mt.sensor, ax))
            if rows is not None:
                cols[rows] = aggregate(
                    ds.aggregator(ri, mt.sensor, ax),
                    *_regressors(mt.term, sig, mt.sensor, ax, every=every, record=ri),
                )
    return cols


def _linear_columns(ds: Dataset, mt: ModelTerm) -> np.ndarray:
    """(n_rows, k·axes) a linear term's columns, k per axis, on its sensor's rows and on its
    twin sensor's rows of the same axis (:attr:`Term.twin_columns`)."""
    k = len(mt.term.params)
    cols = np.zeros((ds.n_rows, k * len(mt.axes)))
    every: dict[int, Sequence[np.ndarray]] = {}  # a record's channels, built at once
    for j, ax in enumerate(mt.axes):
        for ri, sig in enumerate(ds.signals):
            rows = ds.rows_of.get((ri, mt.sensor, ax))
            if rows is not None:
                cols[rows, j * k : (j + 1) * k] = aggregate(
                    ds.aggregator(ri, mt.sensor, ax),
                    *_regressors(mt.term, sig, mt.sensor, ax, every=every, record=ri),
                )
    if mt.term.twin_columns is not None:
        twin = mt.term.twin_sensor
        for j, ax in enumerate(mt.axes):
            for ri, sig in enumerate(ds.signals):
                rows = ds.rows_of.get((ri, twin, ax))
                if rows is not None:
                    cols[rows, j * k : (j + 1) * k] = aggregate(
                        ds.aggregator(ri, twin, ax), *_regressors(mt.term, sig, twin, ax, True)
                    )
    return cols


def _linearised_columns(
    ds: Dataset, mt: ModelTerm, theta: np.ndarray | None
) -> tuple[np.ndarray, np.ndarray]:
    """A nonlinear term's Jacobian columns (n_rows, k·axes) at ``theta`` (its initial values
    when None) and the offset value(θ) − J·θ (n_rows,)."""
    k = len(mt.term.params)
    cols = np.zeros((ds.n_rows, k * len(mt.axes)))
    offset = np.zeros(ds.n_rows)
    th = np.tile(np.array(mt.term.initial), len(mt.axes)) if theta is None else theta
    for j, ax in enumerate(mt.axes):
        p = np.asarray(th[j * k : (j + 1) * k], dtype=np.float64)
        for ri, sig in enumerate(ds.signals):
            rows = ds.rows_of.get((ri, mt.sensor, ax))
            if rows is None:
                continue
            v0, jac = _value_and_jacobian(mt, sig, ax, p)
            agg = ds.aggregator(ri, mt.sensor, ax)
            cols[rows, j * k : (j + 1) * k] = agg @ jac
            offset[rows] = agg @ (v0 - jac @ p)
    return cols, offset


def _value_and_jacobian(
    mt: ModelTerm, sig: RecordSignals, ax: int, p: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """A nonlinear term's per-sample value (N,) on channel ``ax`` of one record at its
    parameters ``p`` (k,), and its Jacobian (N, k) by central differences (step 1e-6 of
    each parameter, at least 1e-6)."""
    value = mt.term.value
    assert value is not None

    def at(pp: np.ndarray) -> np.ndarray:
        return _call_term(mt.term, "value", sig, lambda: value(sig, mt.sensor, ax, pp))[0]

    k = len(p)
    v0 = at(p)
    jac = np.zeros((len(sig.t_s), k))
    for q in range(k):
        h = 1e-6 * max(1.0, abs(p[q]))
        dp = np.zeros(k)
        dp[q] = h
        jac[:, q] = (at(p + dp) - at(p - dp)) / (2 * h)
    return v0, jac


def record_columns(ds: Dataset, mt: ModelTerm) -> np.ndarray:
    """(n_rows, Σk) the columns of the unknowns of the records that carry their own
    (:meth:`Term.own_params`, k of each record, in :meth:`ModelTerm.slots` order): each
    record's columns are non-zero on its own rows only, on every channel of the term."""
    t = mt.term
    owners = t.owners(ds.signals, mt.sensor)
    widths = [len(t.own_params(ds.signals[ri])) for ri in owners]
    out = np.zeros((ds.n_rows, sum(widths)))
    if not owners:
        return out
    fn = t.record_columns
    if fn is None or t.nonlinear:
        raise UserError(f"term {t.name}: a record's own unknowns need record_columns()")
    start = 0
    for ri, k in zip(owners, widths, strict=True):
        sig = ds.signals[ri]
        start += k
        for ax in mt.axes:
            rows = ds.rows_of.get((ri, mt.sensor, ax))
            if rows is None:
                continue
            x, big = _call_term(t, "record_columns", sig, lambda: fn(sig, mt.sensor, ax))  # noqa: B023
            if x.shape != (len(sig.t_s), k):
                raise UserError(
                    f"term {t.name}: record_columns() returned shape {x.shape}, expected "
                    f"({len(sig.t_s)}, {k})"
                )
            out[rows, start - k : start] = aggregate(ds.aggregator(ri, mt.sensor, ax), x, big)
        for row, coef in ds.record_links.get((t.name, sig.name), ()):
            out[row, start - k : start] = coef  # another record's row reads these unknowns
    return out


def same_records(a: Dataset, b: Dataset) -> bool:
    """Whether ``a`` and ``b`` hold the same records' signals, rows, aggregators and clock (one
    a copy of the other with other measured values or another whitening): every term's
    columns on one are its columns on the other."""
    return (
        a.signals is b.signals
        and a.rows_of is b.rows_of
        and a.aggregators is b.aggregators
        and a.sensor_aggregators is b.sensor_aggregators
        and a.time_known == b.time_known
    )


class BuiltColumns:
    """The columns of linear model terms over ONE dataset's rows, each term's built once and
    reused by every design on those rows (:func:`design`'s ``built``): the fits and predictions
    of one call that weigh several models, or one model against several ``y``, on the same
    records. A design reads the records' signals, rows and aggregators, never the measured
    values or the whitening, so a copy of the dataset with another ``y`` (or whitening) shares
    them; any other dataset builds its own. Made inside a call and dropped with it."""

    def __init__(self, ds: Dataset) -> None:
        self._ds = ds
        self._columns: dict[ModelTerm, tuple[np.ndarray, np.ndarray]] = {}

    def of(self, ds: Dataset, mt: ModelTerm, theta: np.ndarray | None = None) -> (
        tuple[np.ndarray, np.ndarray]
    ):  # fmt: skip
        """:func:`term_columns` of ``mt`` on ``ds`` (built the first time; a nonlinear term's
        depend on ``theta``: built every time)."""
        if mt.term.nonlinear or not same_records(ds, self._ds):
            return term_columns(ds, mt, theta)
        if mt not in self._columns:
            self._columns[mt] = term_columns(ds, mt, theta)
        return self._columns[mt]


def design(
    ds: Dataset,
    model: Sequence[ModelTerm],
    thetas: Sequence[np.ndarray | None] = (),
    built: BuiltColumns | None = None,
) -> tuple[np.ndarray, np.ndarray, list[tuple[int, int]]]:
    """(X (n_rows, P), offset (n_rows,), per model term (start, stop) columns); ``built``: the
    columns already built on these rows (:class:`BuiltColumns`), else each term's are built."""
    blocks: list[np.ndarray] = []
    offset = np.zeros(ds.n_rows)
    spans: list[tuple[int, int]] = []
    col = 0
    for i, mt in enumerate(model):
        th = thetas[i] if i < len(thetas) else None
        c, off = term_columns(ds, mt, th) if built is None else built.of(ds, mt, th)
        blocks.append(c)
        offset += off
        spans.append((col, col + c.shape[1]))
        col += c.shape[1]
    x = np.column_stack(blocks) if blocks else np.zeros((ds.n_rows, 0))
    return x, offset, spans


def select_columns(xw: np.ndarray, tol: float = 1e-9) -> tuple[np.ndarray, np.ndarray]:
    """Greedy Gram-Schmidt: (mask of columns independent of the earlier ones, orthonormal
    basis (n, r) of their span)."""
    n, p = xw.shape
    q = np.zeros((n, 0))
    keep = np.zeros(p, dtype=bool)
    for j in range(p):
        v = xw[:, j]
        norm = float(np.linalg.norm(v))
        if norm == 0.0:
            continue
        r = v - q @ (q.T @ v)
        r = r - q @ (q.T @ r)
        rn = float(np.linalg.norm(r))
        if rn > tol * norm and rn > 1e-300:
            keep[j] = True
            q = np.column_stack([q, r / rn])
    return keep, q
