"""The labels file carries the cube's placement heading (issue 25): a ``heading_deg`` column
read into every record's ``placement_heading_deg``; files without the column (v1) carry none."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from host.ingest.importing import Stream
from host.ingest.labels import format_labels, parse_labels
from host.ingest.segmentation import build_records
from host.ingest.stillness import SegmentationError
from host.session.records import HEADING_KEY, Record

G = 9.81


def _stream() -> Stream:
    """20 s at 50 Hz: x up for 10 s, then y up for 10 s, still."""
    t = np.arange(1000) / 50.0
    accel = np.zeros((1000, 3))
    accel[:500, 0] = G
    accel[500:, 1] = G
    return Stream(t, accel, np.zeros((1000, 3)), np.full(1000, 25.0), {"source": "s.csv"})


V1 = (
    "# imu-bench segments v1 of s.csv\n"
    "# row\tstart_s\tend_s\tlabel\tfound\tquality\treason\n"
    "1\t1.0\t9.0\tx_up\tstill +x\tok\tfirst\n"
    "2\t11.0\t19.0\ty_up\tstill +y\tok\tsecond\n"
)


def _v2(x_heading: str, y_heading: str) -> str:
    return (
        "# imu-bench segments v2 of s.csv\n"
        "# row\tstart_s\tend_s\tlabel\theading_deg\tfound\tquality\treason\n"
        f"1\t1.0\t9.0\tx_up\t{x_heading}\tstill +x\tok\tfirst\n"
        f"2\t11.0\t19.0\ty_up\t{y_heading}\tstill +y\tok\tsecond\n"
    )


def _read_back(rec: Record) -> float | None:
    """The heading as the model reads it from the record's header."""
    return Record(rec.name, rec.t_ms, rec.accel, rec.gyro, rec.temp, dict(rec.meta)) \
        .placement_heading_deg  # fmt: skip


def test_the_heading_column_goes_into_the_records() -> None:
    stream = _stream()
    segs = parse_labels(_v2("90", "-"), "l.tsv", stream)
    assert [s.heading_deg for s in segs] == [90.0, None]
    records = build_records(stream, segs, None, "U1")
    assert records["x_up"].meta[HEADING_KEY] == "90" and _read_back(records["x_up"]) == 90.0
    # not known: not written, so the model treats it as an unknown (never 0)
    assert HEADING_KEY not in records["y_up"].meta and _read_back(records["y_up"]) is None


def test_a_file_without_the_column_carries_no_heading() -> None:
    segs = parse_labels(V1, "l.tsv", _stream())
    assert [s.label for s in segs] == ["x_up", "y_up"]
    assert all(s.heading_deg is None for s in segs)


@pytest.mark.parametrize("bad", ["east", "nan", "inf", "9O"])
def test_a_heading_that_is_not_a_number_is_one_line_naming_the_column(bad: str) -> None:
    with pytest.raises(SegmentationError) as e:
        parse_labels(_v2(bad, "0"), "l.tsv", _stream())
    msg = str(e.value)
    assert "\n" not in msg and "l.tsv:3" in msg and "heading_deg" in msg and bad in msg


@settings(max_examples=60, deadline=None)
@given(
    st.one_of(st.none(), st.floats(-1e4, 1e4, allow_nan=False)),
    st.one_of(st.none(), st.sampled_from([0.0, 90.0, 180.0, 270.0])),
)
def test_written_and_read_back_the_heading_survives(x: float | None, y: float | None) -> None:
    stream = _stream()
    segs = parse_labels(_v2("-", "-"), "l.tsv", stream)
    segs = [type(s)(**{**s.__dict__, "heading_deg": h}) for s, h in zip(segs, (x, y), strict=True)]
    again = parse_labels(format_labels(segs, "s.csv"), "l.tsv", stream)
    for h, s in zip((x, y), again, strict=True):
        if h is None:
            assert s.heading_deg is None
        else:
            assert s.heading_deg is not None and 0.0 <= s.heading_deg < 360.0
            d = (s.heading_deg - h + 180.0) % 360.0 - 180.0
            assert abs(d) <= 1e-3 * max(1.0, abs(h)), (h, s.heading_deg)  # printed with :g
    records = build_records(stream, again, None, "U1")
    for h, name in zip((x, y), ("x_up", "y_up"), strict=True):
        got = _read_back(records[name])
        assert (got is None) == (h is None)
        if got is not None and h is not None:
            assert math.isclose(math.cos(math.radians(got)), math.cos(math.radians(h)),
                                abs_tol=1e-3)  # fmt: skip
