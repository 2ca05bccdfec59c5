"""Record files (method.md §6): writing, reading, damaged files, sessions."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from host.errors import UserError
from host.session.directory import (
    read_record,
    read_session,
    record_path,
    split_file_name,
    write_record,
)
from host.session.records import (
    DECIMALS,
    STATIC_NAMES,
    TURN_NAMES,
    Record,
    RecordError,
    format_record,
    parse_record_text,
)

# shared/ sits beside the checkout (as in CI)
REAL = Path(__file__).resolve().parents[4] / "shared" / "data" / "imucal-example"
DATA = Path(__file__).resolve().parents[2] / "data"


def _rec(n: int = 5, name: str = "x_up", meta: dict[str, str] | None = None) -> Record:
    rng = np.random.default_rng(3)
    t = np.cumsum(rng.uniform(15, 25, n)) - 15
    return Record(
        name,
        t,
        rng.normal(0, 5, (n, 3)),
        rng.normal(0, 50, (n, 3)),
        30 + rng.normal(0, 1, n),
        meta if meta is not None else {"serial": "S1", "turns": "2"},
    )


def _assert_printed_equal(a: Record, b: Record) -> None:
    cols_a = np.column_stack([a.t_ms, a.accel, a.gyro, a.temp])
    cols_b = np.column_stack([b.t_ms, b.accel, b.gyro, b.temp])
    assert cols_a.shape == cols_b.shape
    for i, d in enumerate(DECIMALS):
        assert np.all(np.abs(cols_a[:, i] - cols_b[:, i]) <= 0.5 * 10.0**-d + 1e-9), i


def test_round_trip(tmp_path: Path) -> None:
    rec = _rec(50)
    p = record_path(tmp_path, "S1", "x_up")
    assert p == tmp_path / "S1_x_up.txt"
    write_record(p, rec)
    back = read_record(p)
    assert back.name == "x_up"
    _assert_printed_equal(rec, back)
    assert back.meta == {**rec.meta, "record": "x_up"}
    # writing what was read reproduces the file byte for byte
    assert format_record(back) == p.read_text(encoding="utf-8")
    assert [q.name for q in tmp_path.iterdir()] == ["S1_x_up.txt"]  # no temp file left


def test_file_layout(tmp_path: Path) -> None:
    p = tmp_path / "S1_z_cw.txt"
    write_record(p, _rec(3, "z_cw"))
    lines = p.read_text(encoding="utf-8").splitlines()
    assert lines[0] == "# imu-bench record v1"
    assert "# record: z_cw" in lines
    rows = [ln for ln in lines if not ln.startswith("#")]
    assert len(rows) == 6 and set(rows[3]) == {"_"}
    assert rows[4].startswith("mean\t") and rows[5].startswith("std\t")
    fields = rows[0].split("\t")
    assert len(fields) == 8
    assert [len(f.split(".")[1]) for f in fields] == list(DECIMALS)


def test_read_real_file() -> None:
    rec = read_record(REAL / "REAL_x_up.txt")
    assert rec.name == "x_up" and len(rec) == 731
    assert rec.kind == "static" and rec.axis == "x" and rec.sign == 1
    assert rec.meta["source"].startswith("imucal example")
    assert rec.t_ms[1] == pytest.approx(9.8)
    assert rec.accel[0] == pytest.approx([10.3177, -0.5556, 0.4982])
    assert rec.gyro[0] == pytest.approx([-0.610, -0.366, 0.061])
    assert np.all(rec.temp == 25.0)


def test_no_header_no_labels() -> None:
    text = (
        "0.0\t0.1\t0.2\t9.8\t0.01\t0.02\t0.03\t30.0\n20.0\t0.1\t0.2\t9.8\t0.01\t0.02\t0.03\t30.0\n"
    )
    text += "_" * 40 + "\n0.1\t0.2\t9.8\t0.01\t0.02\t0.03\t30.0\n0\t0\t0\t0\t0\t0\t0\n"
    rec = parse_record_text(text, "S1_y_dn.txt", name="y_dn")
    assert len(rec) == 2 and rec.meta == {}
    assert rec.kind == "static" and rec.axis == "y" and rec.sign == -1
    assert rec.up.tolist() == [0.0, -1.0, 0.0]


def test_fixture_file() -> None:
    rec = read_record(DATA / "FIX1_z_ccw.txt")
    assert rec.kind == "turn" and rec.axis == "z" and rec.sign == 1
    assert rec.meta["turns"] == "1"


VALID = format_record(_rec(4))


@pytest.mark.parametrize(
    ("text", "line", "words"),
    [
        (VALID.split("____")[0], 9, "no line of underscores"),
        (VALID.replace("\nstd\t", "\nxx\t"), 11, "damaged"),
        ("\n".join(VALID.splitlines()[:-1]), 11, "mean/std rows missing"),
        (VALID.replace(VALID.splitlines()[4], "1.0\t2.0\t3.0"), 5, "3 columns"),
        (VALID.replace(VALID.splitlines()[5], "1.0\tabc\t3"), 6, "not a row of numbers"),
        (VALID.replace(VALID.splitlines()[5], "\t".join(["nan"] * 8)), 6, "non-finite"),
    ],
)
def test_damaged_files(text: str, line: int, words: str) -> None:
    with pytest.raises(RecordError) as ei:
        parse_record_text(text, "dir/S1_x_up.txt", name="x_up")
    msg = str(ei.value)
    assert msg.startswith(f"dir/S1_x_up.txt:{line}:"), msg
    assert words in msg
    assert isinstance(ei.value, UserError)


def test_mean_row_checked() -> None:
    lines = VALID.splitlines()
    lines[-2] = "mean\t" + "\t".join(["99.0"] * 7)
    with pytest.raises(RecordError, match="stored mean of Ax does not match"):
        parse_record_text("\n".join(lines), "f.txt", name="x_up")


def test_time_backwards_and_newer_version() -> None:
    lines = VALID.splitlines()
    lines[5], lines[6] = lines[6], lines[5]
    with pytest.raises(RecordError, match=r"f.txt:7: time goes backwards"):
        parse_record_text("\n".join(lines), "f.txt", name="x_up")
    with pytest.raises(RecordError, match="v2 is newer"):
        parse_record_text(VALID.replace("record v1", "record v2"), "f.txt", name="x_up")


def test_name_conflict_and_unreadable(tmp_path: Path) -> None:
    p = tmp_path / "S1_x_dn.txt"
    p.write_text(VALID, encoding="utf-8")  # header says x_up
    with pytest.raises(RecordError, match="header says record 'x_up'"):
        read_record(p)
    q = tmp_path / "S1_y_up.txt"
    q.write_bytes(b"\xff\xfe\x00garbage")
    with pytest.raises(RecordError, match="not a UTF-8"):
        read_record(q)
    with pytest.raises(RecordError, match="cannot read"):
        read_record(tmp_path / "S1_missing_up.txt")


def test_record_properties() -> None:
    for nm in STATIC_NAMES:
        r = _rec(2, nm)
        assert (r.kind, r.axis, r.sign) == ("static", nm[0], 1 if nm.endswith("up") else -1)
    for nm in TURN_NAMES:
        r = _rec(2, nm)
        assert (r.kind, r.axis, r.sign) == ("turn", nm[0], 1 if nm.endswith("ccw") else -1)
    r = _rec(2, "x_ccw_2")
    assert (r.kind, r.axis, r.sign) == ("turn", "x", 1)
    tilt = _rec(2, "tilt_45_1", {"up": "[0, 1, 1]"})
    assert tilt.kind == "static" and tilt.axis == "y"
    assert tilt.up == pytest.approx([0, 2**-0.5, 2**-0.5])
    rate = _rec(2, "rate_z_m50", {"rate_dps": "-50", "rate_axis": "+z", "up": "+z"})
    assert (rate.kind, rate.axis, rate.sign, rate.rate_dps) == ("rate", "z", -1, -50.0)
    assert _rec(2, "notes", {}).kind == "unknown"
    with pytest.raises(RecordError, match="expected a vector"):
        _ = _rec(2, "t", {"up": "[1, 2]"}).up


def test_split_file_name() -> None:
    assert split_file_name("S1_x_up.txt") == ("S1", "x_up")
    assert split_file_name("A_B_z_cw.txt") == ("A_B", "z_cw")
    assert split_file_name("S1_x_ccw_2.txt") == ("S1", "x_ccw_2")
    assert split_file_name("S1_tilt_45.txt") == ("S1", "tilt_45")
    assert split_file_name("README.md") is None
    assert split_file_name("LICENSE.txt") is None


def test_read_session(tmp_path: Path) -> None:
    for nm in ("x_up", "x_dn"):
        write_record(record_path(tmp_path, "S1", nm), _rec(3, nm, {}))
    (tmp_path / "S1_result.txt").write_text("TEST REPORT\n", encoding="utf-8")
    (tmp_path / "notes.md").write_text("hello\n", encoding="utf-8")
    s = read_session(tmp_path)
    assert s.serial == "S1" and sorted(s.records) == ["x_dn", "x_up"]
    assert s.path_of("x_up") == "S1_x_up.txt"
    write_record(record_path(tmp_path, "S2", "x_up"), _rec(3, "x_up", {}))
    with pytest.raises(RecordError, match=r"several units \(S1, S2\).*--serial"):
        read_session(tmp_path)
    assert sorted(read_session(tmp_path, "S1").records) == ["x_dn", "x_up"]
    with pytest.raises(RecordError, match="no records of serial 'S3'"):
        read_session(tmp_path, "S3")
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(RecordError, match="no record files"):
        read_session(empty)
    with pytest.raises(RecordError, match="no such directory; give the directory that holds"):
        read_session(tmp_path / "nope")
    (tmp_path / "a_file").write_text("x")
    with pytest.raises(RecordError, match="a_file: not a directory; give"):
        read_session(tmp_path / "a_file")


def test_read_session_serial_mismatch(tmp_path: Path) -> None:
    write_record(record_path(tmp_path, "S1", "x_up"), _rec(3, "x_up", {"serial": "OTHER"}))
    with pytest.raises(RecordError, match="header says serial 'OTHER'"):
        read_session(tmp_path)


def test_read_real_session() -> None:
    s = read_session(REAL)
    assert s.serial == "REAL"
    assert sorted(s.records) == sorted(STATIC_NAMES + ("x_cw", "y_cw", "z_cw"))


# ---- properties ---------------------------------------------------------------------------
_finite = st.floats(min_value=-3e4, max_value=3e4, allow_nan=False, allow_infinity=False)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    n=st.integers(min_value=1, max_value=12),
    seed=st.integers(min_value=0, max_value=2**31),
    scale=_finite,
    meta=st.dictionaries(
        st.from_regex(r"[A-Za-z][A-Za-z0-9_.\-]{0,10}", fullmatch=True).filter(
            lambda k: k != "record"
        ),
        st.text(alphabet=st.characters(blacklist_categories=("Cs", "Cc")), max_size=20).map(
            str.strip
        ),
        max_size=4,
    ),
)
@pytest.mark.slow
def test_round_trip_property(n: int, seed: int, scale: float, meta: dict[str, str]) -> None:
    rng = np.random.default_rng(seed)
    t = np.cumsum(rng.uniform(0.0, 30.0, n))
    vals = rng.uniform(-1, 1, (n, 7)) * scale
    rec = Record("y_ccw", t, vals[:, 0:3], vals[:, 3:6], vals[:, 6], meta)
    back = parse_record_text(format_record(rec), "S_y_ccw.txt", name="y_ccw")
    _assert_printed_equal(rec, back)
    assert back.meta == {**{k: v for k, v in meta.items()}, "record": "y_ccw"}


@settings(max_examples=200, deadline=None)
@given(st.text(max_size=400))
def test_garbage_raises_only_record_error(text: str) -> None:
    try:
        parse_record_text(text, "g.txt", name="x_up")
    except RecordError:
        pass


@settings(max_examples=200, deadline=None)
@given(cut=st.integers(min_value=0, max_value=len(VALID)), junk=st.text(max_size=5))
def test_truncated_or_mangled_raises_only_record_error(cut: int, junk: str) -> None:
    try:
        rec = parse_record_text(VALID[:cut] + junk, "t.txt", name="x_up")
    except RecordError:
        return
    assert len(rec) >= 1 and rec.accel.shape == (len(rec), 3)
