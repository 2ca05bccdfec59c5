"""Which records a resumed session keeps, and in what order (issues 30, 31):
:func:`host.session.directory.record_names` lists every record of a unit that
:func:`host.session.directory.read_session` would read, the repeats (``x_ccw_2``) too, and
:func:`host.session.directory.measured_order` puts records back in the order they were measured
from their headers, across sittings."""

from __future__ import annotations

import random
from datetime import datetime, timedelta, timezone
from pathlib import Path

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from host.session.directory import (
    measured_order,
    read_session,
    record_names,
    record_path,
    write_record,
)
from host.session.records import Record

START = datetime(2026, 11, 27, 3, 0, tzinfo=timezone(timedelta(hours=1)))


def _record(name: str, serial: str = "S1", **meta: str) -> Record:
    z = np.zeros((2, 3))
    return Record(name, np.array([0.0, 20.0]), z, z, np.zeros(2), {"serial": serial, **meta})


def test_every_record_of_the_unit_is_listed_and_nothing_else(tmp_path: Path) -> None:
    names = ["x_up", "x_ccw_2", "x_up_3", "z_cw_10", "tilt_45_1"]
    for n in names:
        write_record(record_path(tmp_path, "S1", n), _record(n))
    write_record(record_path(tmp_path, "S1_B", "x_dn"), _record("x_dn", "S1_B"))
    write_record(record_path(tmp_path, "S1", "warmup"), _record("warmup"))
    for other in ("S1_result.txt", "S1_result.json", "S1_session.cap", "S1_thermal.json"):
        (tmp_path / other).write_text("not a record")
    assert sorted(record_names(tmp_path, "S1")) == sorted(names)
    assert sorted(record_names(tmp_path, "S1")) == sorted(read_session(tmp_path, "S1").records)
    assert record_names(tmp_path, "S1_B") == ["x_dn"]
    assert record_names(tmp_path / "none", "S1") == []


@settings(max_examples=60, deadline=None)
@given(
    sizes=st.lists(st.integers(1, 6), min_size=1, max_size=4),
    gaps=st.lists(st.floats(0.01, 5000.0), min_size=30, max_size=30),
    seed=st.integers(0, 2**32 - 1),
)
def test_records_come_back_in_the_order_they_were_measured(
    sizes: list[int], gaps: list[float], seed: int
) -> None:
    """Sittings (each its own capture, its clock ``session_s`` from 0 again) of records whose
    names say nothing of their order; the dict handed over is shuffled."""
    rng = random.Random(seed)
    names = [f"{a}_{d}_{k}" for k in range(2, 9) for a in "xyz" for d in ("up", "ccw")]
    rng.shuffle(names)
    truth: list[str] = []
    recs: dict[str, Record] = {}
    wall = START
    caps = rng.sample(range(2, 40), len(sizes))  # capture names not in time order
    for sitting, size in enumerate(sizes):
        session_s = rng.uniform(0.0, 30.0)
        for _ in range(size):
            gap = gaps[len(truth)]
            wall, session_s = wall + timedelta(seconds=gap), session_s + gap
            name = names[len(truth)]
            truth.append(name)
            recs[name] = _record(
                name, capture=f"S1_session_{caps[sitting]}.cap", session_s=f"{session_s:.3f}",
                start_time=wall.isoformat(timespec="milliseconds"),
            )  # fmt: skip
    shuffled = list(recs.items())
    rng.shuffle(shuffled)
    assert measured_order(dict(shuffled)) == truth
