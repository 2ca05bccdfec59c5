"""Record text read and written in one pass (``host.session.records``): every variant of the
format docs/formats.md allows reads to the values its text holds (the oracle: Python's own
``float`` of each printed field), a value written reads back as its printed decimals, and a
damaged line anywhere in the rows still gives the one-line error naming the file and line."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from host.session.records import (
    DECIMALS,
    Record,
    RecordError,
    format_record,
    parse_record_text,
)

_COLS = ("Ax", "Ay", "Az", "Gx", "Gy", "Gz", "temp")


@st.composite
def record_texts(draw: st.DrawFn) -> tuple[str, list[list[str]], dict[str, str]]:
    """A record file written here, field by field, in one of the allowed layouts: with or
    without the header and the 'mean'/'std' labels, tabs or spaces, blank lines, CRLF."""
    n = draw(st.integers(2, 20))
    t = np.cumsum(draw(st.lists(st.floats(1.0, 50.0), min_size=n, max_size=n)))
    vals = draw(
        st.lists(st.lists(st.floats(-2000, 2000), min_size=7, max_size=7), min_size=n, max_size=n)
    )
    decimals = [draw(st.integers(1, 3)), *draw(st.lists(st.integers(0, 6), min_size=7, max_size=7))]
    rows = [
        [f"{v:.{d}f}" for v, d in zip([float(ti), *vi], decimals, strict=True)]
        for ti, vi in zip(t, vals, strict=True)
    ]
    sep = draw(st.sampled_from(["\t", " ", "  ", " \t"]))
    meta = draw(st.sampled_from([{}, {"serial": "S1"}, {"serial": "S1", "turns": "2"}]))
    lines = ["# imu-bench record v1"] if draw(st.booleans()) else []
    lines += [f"# {k}: {v}" for k, v in meta.items()]
    body = [sep.join(r) for r in rows]
    if draw(st.booleans()):
        body.insert(draw(st.integers(0, len(body))), "")
    lines += body + ["_" * draw(st.integers(3, 80))]
    printed = np.array([[float(f) for f in r[1:]] for r in rows])
    labels = ("mean\t", "std\t") if draw(st.booleans()) else ("", "")
    for label, row in zip(labels, (printed.mean(axis=0), printed.std(axis=0, ddof=1)), strict=True):
        lines.append(label + "\t".join(f"{v:.4f}" for v in row))
    newline = draw(st.sampled_from(["\n", "\r\n"]))
    return newline.join(lines) + newline * draw(st.integers(0, 2)), rows, meta


@given(record_texts())
@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
def test_every_layout_reads_to_the_printed_values(case: tuple) -> None:
    text, rows, meta = case
    rec = parse_record_text(text, "S1_x_up.txt", name="x_up")
    got = np.column_stack([rec.t_ms, rec.accel, rec.gyro, rec.temp])
    want = np.array([[float(f) for f in r] for r in rows])
    assert got.tobytes() == want.tobytes()
    assert rec.meta == meta


@st.composite
def damaged(draw: st.DrawFn) -> tuple[str, int, str]:
    """A good record's text with one data row damaged: the text, its line and the words."""
    n = draw(st.integers(3, 40))
    rec = Record("x_up", np.arange(n) * 10.0, np.ones((n, 3)), np.zeros((n, 3)), np.full(n, 30.0))
    lines = format_record(rec).split("\n")
    first = next(i for i, line in enumerate(lines) if not line.startswith("#"))
    k = draw(st.integers(1, n - 1))
    fields = lines[first + k].split("\t")
    kind = draw(st.sampled_from(["short", "word", "nan", "back", "comma"]))
    if kind == "short":
        lines[first + k], words = "\t".join(fields[:-1]), "7 columns"
    elif kind == "word":
        fields[draw(st.integers(0, 7))] = draw(st.sampled_from(["x", "1.2.3", "--1", "0x1"]))
        lines[first + k], words = "\t".join(fields), "not a row of numbers"
    elif kind == "nan":
        fields[draw(st.integers(1, 7))] = draw(st.sampled_from(["nan", "inf", "-inf"]))
        lines[first + k], words = "\t".join(fields), "non-finite"
    elif kind == "back":
        lines[first + k], words = "\t".join(["-5.0", *fields[1:]]), "time goes backwards"
    else:
        lines[first + k], words = ",".join(fields), "not a row of numbers"
    return "\n".join(lines), first + k + 1, words


@given(damaged())
@settings(max_examples=60, deadline=None)
def test_a_damaged_row_is_named_by_file_and_line(case: tuple[str, int, str]) -> None:
    text, line, words = case
    with pytest.raises(RecordError) as err:
        parse_record_text(text, "S1_x_up.txt")
    msg = str(err.value)
    assert msg.startswith(f"S1_x_up.txt:{line}: "), msg
    assert words in msg and "\n" not in msg


def _small_values(rng: np.random.Generator, n: int) -> np.ndarray:
    """(n, 7) values many of which round to zero at their column's decimals, of either sign."""
    scale = np.array([10.0**-d for d in DECIMALS[1:]])
    vals = rng.normal(0.0, 1.0, (n, 7)) * scale * rng.choice([0.3, 3.0, 3000.0], (n, 7))
    vals[rng.random((n, 7)) < 0.05] = -0.0
    return vals


@pytest.mark.parametrize("seed", range(6))
def test_written_values_read_back_as_their_printed_decimals(seed: int) -> None:
    rng = np.random.default_rng(seed)
    n = int(rng.integers(2, 400))
    vals = _small_values(rng, n)
    t = np.cumsum(rng.uniform(0.01, 30.0, n)) - rng.uniform(0.0, 0.2)
    rec = Record("y_dn", t, vals[:, :3], vals[:, 3:6], vals[:, 6], {"serial": "S9"})
    text = format_record(rec)
    back = parse_record_text(text, "S9_y_dn.txt")
    cols = np.column_stack([t, vals])
    got = np.column_stack([back.t_ms, back.accel, back.gyro, back.temp])
    for j, d in enumerate(DECIMALS):
        want = [float(f"{v:.{d}f}") + 0.0 for v in cols[:, j]]
        assert np.array_equal(got[:, j], want), j
    assert not re.search(r"(^|\t)-0(\.0*)?(\t|$)", text, re.MULTILINE), "a minus zero printed"
    mean_line = next(line for line in text.splitlines() if line.startswith("mean\t"))
    stored = [float(f) for f in mean_line.split("\t")[1:]]
    means = got[:, 1:].mean(axis=0)
    assert all(math.isclose(s, m, abs_tol=0.6e-4) for s, m in zip(stored, means, strict=True))
