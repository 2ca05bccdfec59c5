"""The archive's values for the user's own analysis: one row per (calibration, parameter) as
CSV, or as Parquet when pyarrow is installed (it is not a dependency: ~40 MB for one format):
the unit (``serial``) and its production ``lot`` on every row, the value and σ with their
``unit`` (method.md §7), and the σ's ``dof`` where it is itself estimated (empty: exact)."""

from __future__ import annotations

import csv
import io
import math
import os
from collections.abc import Mapping
from pathlib import Path

from host.archive.charts import param_unit
from host.archive.store import ValueTable
from host.errors import UserError
from host.session.atomic import write_text_atomic

COLUMNS = (
    "calibration_id", "serial", "lot", "bench", "measured_at", "self_test", "verdict",
    "fit_verdict", "parameter", "value", "stderr", "unit", "dof",
)  # fmt: skip
#: the header of an export written before the lot and unit columns (replaced like any export)
EARLIER_COLUMNS = (
    "calibration_id", "serial", "bench", "measured_at", "self_test", "verdict", "fit_verdict",
    "parameter", "value", "stderr",
)  # fmt: skip


def _columns(t: ValueTable, lots: Mapping[int, str]) -> dict[str, list[object]]:
    return {
        "calibration_id": [int(x) for x in t.id], "serial": list(t.serial),
        "lot": [lots.get(int(x), "") for x in t.id],
        "bench": list(t.bench), "measured_at": list(t.measured_at),
        "self_test": list(t.self_test), "verdict": list(t.verdict),
        "fit_verdict": list(t.fit_verdict), "parameter": list(t.name),
        "value": [float(x) for x in t.value], "stderr": [float(x) for x in t.stderr],
        "unit": [param_unit(str(n)) for n in t.name],
        "dof": [float(x) if math.isfinite(x) else math.nan for x in t.dof],
    }  # fmt: skip


def _cell(v: object) -> object:
    if isinstance(v, float):
        return repr(v) if math.isfinite(v) else ""
    return v


def write_csv(
    t: ValueTable, path: str | os.PathLike[str], lots: Mapping[int, str] | None = None
) -> int:
    """Write ``t`` as CSV (header :data:`COLUMNS`; a value not determined, and the dof of an
    exact σ, is an empty field;
    ``lots``: each calibration id's lot, '' when not given); returns the number of rows."""
    cols = _columns(t, lots or {})
    f = io.StringIO(newline="")
    w = csv.writer(f)
    w.writerow(COLUMNS)
    for i in range(len(t)):
        w.writerow(_cell(cols[c][i]) for c in COLUMNS)
    write_text_atomic(path, f.getvalue())  # a file that cannot be written: one line
    return len(t)


def write_parquet(
    t: ValueTable, path: str | os.PathLike[str], lots: Mapping[int, str] | None = None
) -> int:
    """Write ``t`` as Parquet (needs pyarrow; columns as :func:`write_csv`'s); returns the
    number of rows."""
    try:
        import pyarrow as pa
        import pyarrow.parquet as pq
    except ImportError:
        raise UserError(
            f"{path}: Parquet needs pyarrow (pip install pyarrow), or write .csv instead"
        ) from None
    pq.write_table(pa.table(_columns(t, lots or {})), str(path))
    return len(t)


def write_values(
    t: ValueTable, path: str | os.PathLike[str], lots: Mapping[int, str] | None = None
) -> int:
    """CSV or Parquet by the file's suffix (.csv, .parquet); UserError for another."""
    suffix = Path(path).suffix.lower()
    if suffix == ".csv":
        return write_csv(t, path, lots)
    if suffix in (".parquet", ".pq"):
        return write_parquet(t, path, lots)
    raise UserError(f"{path}: write .csv or .parquet")
