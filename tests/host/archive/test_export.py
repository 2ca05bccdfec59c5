"""The archive's values for the user's own analysis (host/archive/export.py): CSV that reads
back to the same numbers (a value not determined is an empty field), Parquet only with
pyarrow, any other suffix refused."""

from __future__ import annotations

import csv
import importlib.util
import math
from pathlib import Path

import numpy as np
import pytest

from host.archive.export import COLUMNS, write_values
from host.archive.store import ValueTable
from host.errors import UserError


def _table() -> ValueTable:
    def obj(*xs: str) -> np.ndarray:
        a = np.empty(len(xs), dtype=object)
        a[:] = xs
        return a

    return ValueTable(
        id=np.array([1, 1]), serial=obj("U,1", "U,1"), bench=obj("B1", "B1"),
        measured_at=obj("2026-01-01T00:00:00.000000Z", "2026-01-01T00:00:00.000000Z"),
        self_test=obj("", ""), verdict=obj("pass", "pass"),
        fit_verdict=obj("inadequate", "inadequate"), rms_z=np.array([8.35, 8.35]),
        name=obj("A0x", "Gzz"),
        value=np.array([0.1 + 0.2, math.nan]), stderr=np.array([1e-17, math.nan]),
        dof=np.array([6.0, math.inf]),
    )  # fmt: skip


def test_csv_reads_back_exactly(tmp_path: Path) -> None:
    p = tmp_path / "v.csv"
    assert write_values(_table(), p, {1: "L,7"}) == 2
    rows = list(csv.DictReader(p.open(encoding="utf-8")))
    assert tuple(rows[0]) == COLUMNS
    assert rows[0]["serial"] == "U,1"  # quoted, not split
    # every row names its unit, its lot and the unit of its value (method.md §7)
    assert [(r["serial"], r["lot"], r["unit"]) for r in rows] == [
        ("U,1", "L,7", "m/s²"),
        ("U,1", "L,7", "1"),
    ]
    # a conditional PASS stays one: the fit's verdict beside the archived verdict
    assert (rows[0]["verdict"], rows[0]["fit_verdict"]) == ("pass", "inadequate")
    assert float(rows[0]["value"]) == 0.1 + 0.2 and float(rows[0]["stderr"]) == 1e-17
    assert rows[1]["value"] == "" and rows[1]["stderr"] == ""
    # the σ's dof where it is itself estimated; an exact σ's is empty
    assert float(rows[0]["dof"]) == 6.0 and rows[1]["dof"] == ""


def test_other_formats(tmp_path: Path) -> None:
    with pytest.raises(UserError, match=r"write \.csv or \.parquet"):
        write_values(_table(), tmp_path / "v.xlsx")
    if importlib.util.find_spec("pyarrow") is None:
        with pytest.raises(UserError, match="Parquet needs pyarrow"):
            write_values(_table(), tmp_path / "v.parquet")
    else:
        import pyarrow.parquet as pq

        write_values(_table(), tmp_path / "v.parquet")
        assert pq.read_table(tmp_path / "v.parquet").num_rows == 2
