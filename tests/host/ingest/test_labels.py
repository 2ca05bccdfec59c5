"""The labels file carries the cube's placement heading (issue 25): a ``heading_deg`` column
read into every record's ``placement_heading_deg``; files without the column (v1) carry none."""

from __future__ import annotations

import math
from pathlib import Path

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


def _rows(*rows: str, version: str = "v2") -> str:
    return (
        f"# imu-bench segments {version} of s.csv\n"
        "# row\tstart_s\tend_s\tlabel\theading_deg\tfound\tquality\treason\n"
        + "".join(f"{i}\t{r}\t-\t-\t-\t-\n" for i, r in enumerate(rows, start=1))
    )


def _turning_stream() -> Stream:
    """30 s at 50 Hz, x up: still 10 s, two turns ccw about x in 10 s, still 10 s."""
    t = np.arange(1500) / 50.0
    accel = np.zeros((1500, 3))
    accel[:, 0] = G
    gyro = np.zeros((1500, 3))
    gyro[500:1000, 0] = 72.0  # °/s for 10 s: 720°
    return Stream(t, accel, gyro, np.full(1500, 25.0), {"source": "s.csv"})


@pytest.mark.parametrize(
    "text, words",
    [
        # times past the stream: was a 20 s x_up over both faces, exit 0
        (_rows("1.0\t1e9\tx_up"), "reaches past the stream, which spans 0.000..19.980 s"),
        (_rows("-50\t9.0\tx_up"), "-50..9 s reaches past the stream"),
        (_rows("1.0\tinf\tx_up"), "reaches past the stream"),
        # a face where gravity is along another axis, or none: was a record of the wrong face
        (_rows("11.0\t19.0\tx_up"), "x_up on 11..19 s, but there gravity is along y_up"),
        (_rows("5.0\t15.0\tz_dn"), "gravity is along no face's axis"),
        # two statics on one sample: was two records sharing samples, exit 0
        (_rows("1.0\t9.0\tx_up", "2.0\t8.0\tx_up_2"), "x_up (1.000..9.000 s) and x_up_2"),
        # a file of a version this program does not know: was read as if v2
        (_rows("1.0\t9.0\tx_up", version="v9"), "labels file v9; this program reads v1 and v2"),
        # a repeat suffix the disk refuses as a file name: was an OSError 'File name too long'
        (_rows("1.0\t9.0\tx_up_" + "a" * 300), "is not a record name"),
    ],
)
def test_a_row_that_cannot_be_a_record_is_one_line(text: str, words: str) -> None:
    with pytest.raises(SegmentationError, match=words.replace("(", r"\(").replace(")", r"\)")):
        parse_labels(text, "l.tsv", _stream())


def test_a_rest_labelled_as_a_turn_is_refused_and_a_turn_is_read() -> None:
    """Was: a rest labelled x_ccw became a turn record of one turn (n = max(1, …))."""
    s = _turning_stream()
    with pytest.raises(SegmentationError, match=r"x_ccw turned \+0° about \+x: no turn"):
        parse_labels(_rows("1.0\t9.0\tx_ccw"), "l.tsv", s)
    (seg,) = parse_labels(_rows("9.0\t21.0\tx_ccw"), "l.tsv", s)
    assert (seg.turns, seg.direction) == (2, 1)
    # a turn's window may reach into the rests around it (the import's own cut does)
    segs = parse_labels(_rows("1.0\t9.5\tx_up", "9.0\t21.0\tx_ccw"), "l.tsv", s)
    assert [x.label for x in segs] == ["x_up", "x_ccw"]


def test_an_editors_byte_order_mark_is_not_text(tmp_path: Path) -> None:
    """Was: 'line 1: start_s and end_s must be numbers' for a file saved with a BOM."""
    from host.ingest.labels import read_labels

    p = tmp_path / "l.tsv"
    p.write_bytes(b"\xef\xbb\xbf" + _v2("90", "-").replace("\n", "\r\n").encode())
    assert [s.label for s in read_labels(p, _stream())] == ["x_up", "y_up"]


_cells = st.one_of(
    st.sampled_from(["x_up", "y_up", "x_ccw", "x_cw", "x_up_2", "warmup", "-", "", "nan", "inf",
                     "-1", "0", "9", "21", "1e9", "1.5", "90", "abc", "# imu-bench segments v2",
                     "\ufeff", " ", "x_up_" + "a" * 20]),
    st.text(max_size=6),
)  # fmt: skip
_row = st.lists(_cells, min_size=0, max_size=8).map("\t".join)


@settings(max_examples=100, deadline=None)
@given(st.lists(_row, max_size=6).map("\n".join))
@pytest.mark.slow
def test_any_labels_text_is_segments_or_one_line(text: str) -> None:
    """Whatever a labels file holds: the segments it names, each within the stream, on the
    face or turn it names, none sharing samples with another of its kind — or one
    SegmentationError naming the line; never another exception."""
    s = _turning_stream()
    try:
        segs = parse_labels(text, "l.tsv", s)
    except SegmentationError as exc:
        assert "\n" not in str(exc)
        return
    for g in segs:
        assert 0 <= g.start < g.stop <= len(s.t_s)
    statics = sorted((g for g in segs if g.label != "warmup" and g.label[2:4] in ("up", "dn")),
                     key=lambda g: g.start)  # fmt: skip
    assert all(b.start >= a.stop for a, b in zip(statics, statics[1:], strict=False))
