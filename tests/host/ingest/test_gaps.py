"""Cuts that never cross a gap in time, and rows out of any sensor's range (issue 41, item 4):
property tests on continuous sessions from the simulator written apart from host/bench/."""

from __future__ import annotations

from functools import lru_cache

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from host.__main__ import main
from host.ingest.gaps import MAX_ACCEL_MS2, MAX_GYRO_DPS, gap_between, gap_starts
from host.ingest.importing import ForeignFileError, Stream, parse_column_text, parse_columns
from host.ingest.reading import Segment
from host.ingest.segmentation import segment_stream
from host.session.records import TURN_NAMES
from tests.host.ingest.continuous_sessions import OPERATORS, ContinuousSession, make_session

COLUMNS = parse_columns("t,ax,ay,az,gx,gy,gz")
FAST = settings(max_examples=20, deadline=None, suppress_health_check=[HealthCheck.too_slow])


@lru_cache(maxsize=1)
def _session() -> ContinuousSession:
    return make_session(5, OPERATORS[0])  # fast turns: 115 s at 50 Hz


def _stream(t: np.ndarray, gyro: np.ndarray | None = None) -> Stream:
    cs = _session()
    return Stream(t, cs.accel, cs.gyro if gyro is None else gyro, cs.temp, {"source": "s.csv"})


def _csv(t: np.ndarray, accel: np.ndarray, gyro: np.ndarray) -> str:
    rows = ["t,ax,ay,az,gx,gy,gz"]
    rows += [f"{a:.4f},{b[0]:.5f},{b[1]:.5f},{b[2]:.5f},{c[0]:.5g},{c[1]:.5g},{c[2]:.5g}"
             for a, b, c in zip(t, accel, gyro, strict=True)]  # fmt: skip
    return "\n".join(rows) + "\n"


def _spans_gap(s: Segment, gaps: np.ndarray) -> bool:
    return gap_between(gaps, s.start, s.stop - 1)


@FAST
@given(where=st.floats(0.02, 0.98), gap_s=st.floats(2.0, 1e6))
def test_no_rest_or_turn_spans_a_gap_and_the_gap_is_named(where: float, gap_s: float) -> None:
    """Was: a 1-hour jump in the time column integrated into a '+130257° move'."""
    cs = _session()
    t = cs.t.copy()
    i = int(where * t.size)
    t[i:] += gap_s
    segs, _, _ = segment_stream(_stream(t))
    gaps = gap_starts(t)
    assert gaps.tolist() == [i]
    named = [s for s in segs if s.found.startswith("gap of")]
    assert len(named) == 1 and named[0].label == "-" and named[0].start == i - 1
    assert "nothing is integrated across it" in named[0].reason
    others = [s for s in segs if s is not named[0]]
    assert not [s for s in others if _spans_gap(s, gaps)]
    for s in others:  # no motion grows by the gap's time × the bias
        if s.found.startswith("turn"):
            assert abs(float(s.found.split()[1].rstrip("°"))) < 1500.0, s.found
        if s.found.startswith("move"):
            assert abs(float(s.quality.split()[0].rstrip("°"))) < 1500.0, s.quality
    # the turns away from the gap are found as without it
    hit = {n for n, (a, b) in cs.motions.items() if a - 2.5 <= t[i - 1] <= b + 2.5}
    found = {s.label for s in segs if s.label in TURN_NAMES}
    assert set(TURN_NAMES) - hit <= found


@settings(FAST, max_examples=12)
@given(
    name=st.sampled_from(TURN_NAMES),
    frac=st.floats(0.2, 0.8),
    channel=st.integers(0, 5),
    value=st.one_of(st.just(1e300), st.floats(2.5e4, 1e308), st.floats(-1e308, -2.5e4)),
)
@pytest.mark.slow
def test_a_value_out_of_range_is_named_and_its_turn_kept(
    name: str, frac: float, channel: int, value: float
) -> None:
    cs = _session()
    m0, m1 = cs.motions[name]
    k = int(np.searchsorted(cs.t, m0 + frac * (m1 - m0)))
    accel, gyro = cs.accel.copy(), cs.gyro.copy()
    (accel if channel < 3 else gyro)[k, channel % 3] = value
    text = _csv(cs.t, accel, gyro)
    stream = parse_column_text(text, "log.csv", COLUMNS)
    assert len(stream) == cs.t.size - 1
    assert len(stream.notes) == 1 and stream.notes[0].startswith(f"log.csv:{k + 2}: ")
    assert "left out" in stream.notes[0] and stream.meta["rows_left_out"].startswith("1 ")
    segs, _, _ = segment_stream(stream)
    turn = next(s for s in segs if s.label == name)
    assert turn.t0_s <= m0 + 0.2 and turn.t1_s >= m1 - 0.2
    # one sample of a 360°/s turn left out: the trapezoid bridges it
    assert abs(_angle(turn) - _clean_angles()[name]) <= 1.0


def _angle(s: Segment) -> float:
    return float(s.found.split()[1].rstrip("°"))


@lru_cache(maxsize=1)
def _clean_angles() -> dict[str, float]:
    cs = _session()
    segs, _, _ = segment_stream(parse_column_text(_csv(cs.t, cs.accel, cs.gyro), "c", COLUMNS))
    return {s.label: _angle(s) for s in segs if s.label in TURN_NAMES}


def test_rows_out_of_range_are_counted_beyond_the_first_three() -> None:
    cs = _session()
    gyro = cs.gyro.copy()
    gyro[100:110, 0] = 3 * MAX_GYRO_DPS
    stream = parse_column_text(_csv(cs.t, cs.accel, gyro), "log.csv", COLUMNS)
    (note,) = stream.notes
    assert "log.csv:102: gx 6e+04 °/s" in note and "and 7 more rows" in note
    assert note.count("\n") == 0


def test_every_row_out_of_range_is_one_line() -> None:
    text = "".join(f"{i * 0.01},{3 * MAX_ACCEL_MS2},0,0,0,0,0\n" for i in range(50))
    with pytest.raises(ForeignFileError) as exc:
        parse_column_text(text, "all.csv", COLUMNS)
    msg = str(exc.value)
    assert "\n" not in msg and "every row" in msg and "--units" in msg


def test_the_import_warns_of_gaps_and_rows_left_out(tmp_path, capsys) -> None:
    cs = _session()
    t, gyro = cs.t.copy(), cs.gyro.copy()
    t[3000:] += 3600.0
    gyro[4000, 1] = 1e300
    f = tmp_path / "log.csv"
    f.write_text(_csv(t, cs.accel, gyro))
    argv = ["import", str(f), "--columns", "t,ax,ay,az,gx,gy,gz", "--serial", "G1"]
    assert main([*argv, "--out", str(tmp_path / "o")]) == 0
    err = capsys.readouterr().err
    assert "log.csv: gap of 3600 s in the time column" in err
    assert "line 3001 to line 3002" in err
    assert f"log.csv:{4000 + 2}: gy 1e+300 °/s" in err
    tsv = (tmp_path / "o" / "G1_segments.tsv").read_text()
    assert "gap of 3600 s" in tsv
