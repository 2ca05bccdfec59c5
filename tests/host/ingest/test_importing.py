"""``python3 -m host import``: column files, timing quality, automatic segmentation (issue 15)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from host.__main__ import main
from host.bench.physics import Bench, Environment, static_motion
from host.bench.sim import Simulator, turn_motion
from host.bench.truth import SensorTruth
from host.calib.calibration import calibrate_from_records
from host.errors import UserError
from host.ingest.importing import (
    STANDARD_G,
    ForeignFileError,
    Stream,
    parse_axes,
    parse_column_text,
    parse_columns,
    parse_units,
)
from host.ingest.segmentation import segment_stream
from host.ingest.stillness import find_still
from host.session.directory import Session, read_record, read_session
from host.session.records import STATIC_NAMES, TURN_NAMES, Record
from host.session.spacing import timing_quality, trapezoid, uniform_rate_error_deg
from host.wire.capture import CaptureWriter
from host.wire.frames import encode_imu_samples

COLS = parse_columns("t,ax,ay,az,gx,gy,gz,temp")


# ---- column files -------------------------------------------------------------------------
@settings(max_examples=60, suppress_health_check=[HealthCheck.too_slow], deadline=None)
@given(
    n=st.integers(2, 40),
    delim=st.sampled_from([",", "\t", ";", " ", "  "]),
    header=st.booleans(),
    order=st.permutations(["t", "ax", "ay", "az", "gx", "gy", "gz", "temp", "skip"]),
    seed=st.integers(0, 2**32 - 1),
)
def test_column_file_round_trip(
    n: int, delim: str, header: bool, order: list[str], seed: int
) -> None:
    """Any column order, separator and header: each value lands on its quantity and axis."""
    rng = np.random.default_rng(seed)
    t = np.cumsum(rng.uniform(0.001, 0.05, n))
    vals = {
        "t": t,
        "ax": rng.normal(1, 5, n),
        "ay": rng.normal(2, 5, n),
        "az": rng.normal(3, 5, n),
        "gx": rng.normal(-10, 50, n),
        "gy": rng.normal(20, 50, n),
        "gz": rng.normal(-30, 50, n),
        "temp": rng.normal(30, 3, n),
        "skip": rng.normal(0, 1, n),
    }
    lines = [delim.join(order)] if header else []
    for i in range(n):
        lines.append(delim.join(repr(float(vals[c][i])) for c in order))
    s = parse_column_text("\n".join(lines) + "\n", "f.csv", tuple(order))
    assert np.allclose(s.t_s, t)
    assert np.allclose(s.accel, np.column_stack([vals["ax"], vals["ay"], vals["az"]]))
    assert np.allclose(s.gyro, np.column_stack([vals["gx"], vals["gy"], vals["gz"]]))
    assert np.allclose(s.temp, vals["temp"])
    assert ("header" in s.meta) == header


def test_units_and_axes_convert_and_map_every_axis_differently() -> None:
    text = "t_ms ax ay az gx gy gz\n0 0.1 0.2 1.0 0.01 0.02 0.03\n10 0.1 0.2 1.0 0.01 0.02 0.03\n"
    cols = parse_columns("t,ax,ay,az,gx,gy,gz")
    s = parse_column_text(
        text, "f.txt", cols, parse_units("t=ms,accel=g,gyro=rad/s"), parse_axes("y,-z,x")
    )
    assert s.t_s[1] == pytest.approx(0.010)
    # ours = (file y, −file z, file x)
    assert s.accel[0] == pytest.approx(np.array([0.2, -1.0, 0.1]) * STANDARD_G)
    assert s.gyro[0] == pytest.approx(np.degrees([0.02, -0.03, 0.01]))
    assert s.meta["axes"] == "y,-z,x"
    assert "not recorded" in s.meta["temperature"]


def test_counts_units_and_nominal_rate() -> None:
    cols = parse_columns("ax,ay,az,gx,gy,gz")
    s = parse_column_text(
        "16384,0,-8192,131,262,-65.5\n0,16384,0,0,0,0\n",
        "c.csv",
        cols,
        parse_units("accel=counts:16384,gyro=counts:131"),
        rate_hz=50.0,
    )
    assert s.accel[0] == pytest.approx([STANDARD_G, 0.0, -STANDARD_G / 2])
    assert s.gyro[0] == pytest.approx([1.0, 2.0, -0.5])
    assert s.t_s.tolist() == [0.0, 0.02]


@pytest.mark.parametrize(
    ("text", "columns", "expect"),
    [
        ("1,2,3,4,5,6,7,8\n" * 11 + "1,2,3,4,5,6,x7,8\n", COLS, "f.csv:12: column 7 (gz)"),
        ("1,2,3,4,5,6,7,8\n1,2,3,4,5,6,7\n", COLS, "f.csv:2: 7 columns"),
        ("2,2,3,4,5,6,7,8\n1,2,3,4,5,6,7,8\n", COLS, "time goes backwards"),
        ("1,2,3,4,5,6,nan,8\n", COLS, "not a finite number"),
        ("a,b\n", COLS, "the header has 2 columns"),
        ("# only a comment\n", COLS, "no rows of numbers"),
    ],
)
def test_bad_column_files_name_line_and_column_never_remeasure(
    text: str, columns: tuple[str, ...], expect: str
) -> None:
    with pytest.raises(ForeignFileError) as exc:
        parse_column_text(text, "f.csv", columns)
    msg = str(exc.value)
    assert expect in msg
    assert "re-measure" not in msg and "\n" not in msg


@pytest.mark.parametrize(
    ("func", "arg", "expect"),
    [
        (parse_columns, "t,ax,ay,az,gx,gy", "no column for gz"),
        (parse_columns, "t,ax,ay,az,gx,gy,gz,ax", "ax named twice"),
        (parse_columns, "t,ax,ay,az,gx,gy,gz,pressure", "unknown column name"),
        (parse_units, "t=min", "t=s, t=ms or t=us"),
        (parse_units, "accel=counts:0", "counts per g"),
        (parse_units, "speed=1", "unknown quantity"),
        (parse_axes, "x,x,z", "exactly once"),
        (parse_axes, "x,y", "three axes"),
    ],
)
def test_bad_options_explain_themselves(func: object, arg: str, expect: str) -> None:
    with pytest.raises(ForeignFileError, match=expect):
        func(arg)  # type: ignore[operator]


def test_cli_refuses_a_file_without_columns_with_one_line(tmp_path: Path, capsys) -> None:
    f = tmp_path / "log.csv"
    f.write_text("1,2,3,4,5,6,7\n")
    assert main(["import", str(f), "--serial", "S1", "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "--columns" in err and err.count("\n") == 1 and "Traceback" not in err


# ---- timing quality -----------------------------------------------------------------------
def _bursty_times(rng: np.random.Generator, duration_s: float) -> np.ndarray:
    """Host time stamps of a USB logger: 2.1 ms spacing with stalls of 50-252 ms."""
    t = [0.0]
    while t[-1] < duration_s:
        if rng.random() < 0.012:
            t.append(t[-1] + rng.uniform(0.05, 0.252))
        else:
            t.append(t[-1] + rng.normal(0.0021, 0.0002))
    return np.array(t)


def test_timing_quality_numbers_and_limits() -> None:
    uniform = timing_quality(np.arange(500) * 0.02)
    assert uniform.median_ms == pytest.approx(20.0)
    assert uniform.gap_share == 0.0 and not uniform.warning
    t = np.arange(100) * 0.002
    t[50:] += 0.3  # one 302 ms gap in 0.498 s
    q = timing_quality(t)
    assert q.worst_gap_ms == pytest.approx(302.0)
    assert q.gap_share == pytest.approx(0.302 / t[-1], rel=1e-6)
    assert q.warning


def _turn_rate(t: np.ndarray, t0: float, dur: float, angle: float) -> np.ndarray:
    ph = np.clip((t - t0) / dur, 0.0, 1.0)
    return np.where((ph > 0) & (ph < 1), angle / dur * (1 - np.cos(2 * np.pi * ph)), 0.0)


def test_bursty_column_file_warns_and_integrates_over_true_times(tmp_path: Path, capsys) -> None:
    """Still 4 s, a 720° turn about +z in 5 s, still 4 s, sampled at bursty host times."""
    rng = np.random.default_rng(11)
    t = _bursty_times(rng, 13.0)
    rate = _turn_rate(t, 4.0, 5.0, 720.0)
    bias = np.array([0.7, -1.3, 0.4])
    gyro = bias + np.column_stack([0 * t, 0 * t, rate]) + rng.normal(0, 0.03, (t.size, 3))
    accel = np.array([0.05, -0.08, 9.81]) + rng.normal(0, 0.01, (t.size, 3))
    rows = [f"{1e3 * a:.3f},{b[0]:.5f},{b[1]:.5f},{b[2]:.5f},{c[0]:.4f},{c[1]:.4f},{c[2]:.4f}"
            for a, b, c in zip(t, accel, gyro, strict=True)]  # fmt: skip
    f = tmp_path / "log.csv"
    f.write_text("time_ms,ax,ay,az,gx,gy,gz\n" + "\n".join(rows) + "\n")
    out = tmp_path / "rec"
    argv = ["import", str(f), "--columns", "t,ax,ay,az,gx,gy,gz", "--units", "t=ms"]
    assert main([*argv, "--serial", "B1", "--out", str(out)]) == 0
    cap = capsys.readouterr()
    assert "warning: z_ccw: irregular sample times" in cap.err
    assert "re-measure" not in cap.out + cap.err
    rec = read_record(out / "B1_z_ccw.txt")
    assert rec.meta["timing_warning"] == "yes"
    assert float(rec.meta["timing_worst_gap_ms"]) > 50.0
    ts = rec.t_ms / 1000.0
    true_angle = trapezoid(ts, rec.gyro - bias)[2]
    assert true_angle == pytest.approx(720.0, abs=2.0)
    # the same samples taken as evenly spaced would be visibly wrong (what the warning says)
    assert uniform_rate_error_deg(ts, rec.gyro) > 3.0


# ---- segmentation of a continuous simulated session ---------------------------------------
STATIC_S = 30.0
REST_S = 5.0
TURN_WINDOW_S = 12.0


def _continuous_session(seed: int) -> tuple[object, list[tuple[str, float, float]]]:
    """One continuous stream of a whole session (no beeps), and where the dialogue's records
    would have been: (name, start, end) in true seconds."""
    truth = SensorTruth.random(np.random.default_rng(seed))
    sim = Simulator(truth, Bench(), Environment(), seed=seed + 1)
    rng = np.random.default_rng(seed + 2)
    windows = []
    t = 0.0
    for name in STATIC_NAMES:
        sim.set_motion(static_motion(name), t)
        windows.append((name, t + 0.5, t + STATIC_S - 0.5))
        t += STATIC_S
    for ax in "xyz":
        sim.set_motion(static_motion(f"{ax}_up"), t)
        t += REST_S
        for d, sfx in ((1, "ccw"), (-1, "cw")):
            sim.set_motion(turn_motion(rng, f"{ax}_up", t, TURN_WINDOW_S, 2, d, 1.0), t)
            windows.append((f"{ax}_{sfx}", t, t + TURN_WINDOW_S))
            t += TURN_WINDOW_S + REST_S
    return sim.run_until(t), windows


def _write_cap(path: Path, block: object) -> None:
    b = block  # SampleBlock
    with CaptureWriter(path) as w:
        for i in range(0, len(b), 25):  # type: ignore[arg-type]
            sl = slice(i, i + 25)
            data = encode_imu_samples(i & 0xFFFF, b.t_us[sl], b.counts[sl], b.flags[sl])  # type: ignore[attr-defined]
            w.write(int(b.t_s[sl][-1] * 1e9) + 3_000_000, data)  # type: ignore[attr-defined]


def _dialogue_records(block: object, windows: list[tuple[str, float, float]]) -> dict:
    b = block
    out = {}
    for name, t0, t1 in windows:
        sel = (b.t_s >= t0) & (b.t_s < t1)  # type: ignore[attr-defined]
        meta = {"turns": "2"} if name in TURN_NAMES else {}
        t_us = b.t_us[sel]  # type: ignore[attr-defined]
        out[name] = Record(
            name,
            (t_us - t_us[0]) / 1000.0,
            b.accel[sel],
            b.gyro[sel],
            b.temp[sel],
            meta,  # type: ignore[attr-defined]
        )
    return out


#: agreement of the segmented and the dialogue's records (same samples, other cut points: the
#: dialogue's turns hold 1 s of the rests around them, the cut's start and end at the motion, so
#: the accelerometer rows inside the turns differ; on this unit, with effects the base model
#: lacks, that moves the accelerometer's constants by up to 3e-4, as far from the truth)
AGREE = {"A": 5e-4, "A0": 2e-3, "G": 5e-4, "G0": 5e-3, "GA": 5e-3}


def _group(name: str) -> str:
    if name.startswith("GA"):
        return "GA"
    if name[:2] in ("A0", "G0"):
        return name[:2]
    return name[0]


@pytest.mark.timeout(60)  # a 5-minute session simulated, decoded, segmented, fitted twice
@pytest.mark.slow
def test_continuous_capture_is_cut_into_the_12_records_with_the_dialogue_constants(
    tmp_path: Path, capsys
) -> None:
    block, windows = _continuous_session(3)
    cap = tmp_path / "session.cap"
    _write_cap(cap, block)
    out = tmp_path / "rec"
    assert main(["import", str(cap), "--serial", "C1", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "6 of 6 static records, 6 of 6 turn records" in printed
    assert "median ms" in printed and "x_ccw " in printed  # the timing table
    assert "at rest when every gyro channel is within" in printed  # the stated thresholds
    session = read_session(out)
    assert set(session.records) == set(STATIC_NAMES + TURN_NAMES)
    for name in TURN_NAMES:
        rec = session.records[name]
        assert rec.meta["turns"] == "2"
        assert rec.meta["direction"] == name.split("_")[1]
        assert "segmentation" in rec.meta and rec.meta["source"] == "session.cap"
    seg = calibrate_from_records(session)
    ref = calibrate_from_records(Session("C1", _dialogue_records(block, windows)))
    for k, v in seg.constants().items():
        if "std" in k:
            continue
        assert abs(v - ref.constants()[k]) < AGREE[_group(k)], k
    assert (out / "C1_segments.tsv").exists()


@pytest.mark.slow
def test_labels_file_corrects_the_cut(tmp_path: Path, capsys) -> None:
    """Relabel a rest period as a second x_up and leave z_cw out: the records follow."""
    block, _ = _continuous_session(5)
    cap = tmp_path / "s.cap"
    _write_cap(cap, block)
    out = tmp_path / "a"
    assert main(["import", str(cap), "--serial", "L1", "--out", str(out)]) == 0
    labels = out / "L1_segments.tsv"
    rows = labels.read_text().splitlines()
    edited = []
    done_rest = False
    for r in rows:
        f = r.split("\t")
        if not r.startswith("#") and f[3] == "-" and "+x" in f[5] and not done_rest:
            f[3], done_rest = "x_up_2", True
        elif not r.startswith("#") and f[3] == "z_cw":
            f[3] = "-"
        edited.append("\t".join(f))
    labels.write_text("\n".join(edited) + "\n")
    out2 = tmp_path / "b"
    assert main(["import", str(cap), "--serial", "L1", "--out", str(out2), "--labels",
                 str(labels)]) == 0  # fmt: skip
    names = {p.name for p in out2.glob("L1_*.txt")}
    assert "L1_x_up_2.txt" in names and "L1_z_cw.txt" not in names
    assert read_record(out2 / "L1_x_up_2.txt").meta["up"] == "+x"
    assert not (out2 / "L1_segments.tsv").exists()  # the user's labels file stays the source
    capsys.readouterr()
    # the same cut over the first directory: the old z_cw there is named, not used silently
    argv = ["import", str(cap), "--serial", "L1", "--out", str(out), "--labels", str(labels)]
    assert main([*argv, "--force"]) == 0
    assert "also holds L1_z_cw.txt" in capsys.readouterr().err


@pytest.mark.slow
def test_a_binary_labels_file_is_one_line(tmp_path: Path, capsys) -> None:
    block, _ = _continuous_session(5)
    cap = tmp_path / "s.cap"
    _write_cap(cap, block)
    labels = tmp_path / "labels.tsv"
    labels.write_bytes(bytes(range(256)) * 4)
    out = tmp_path / "o"
    argv = ["import", str(cap), "--serial", "B1", "--out", str(out), "--labels", str(labels)]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "not UTF-8" in err and "labels.tsv" in err, err
    assert not out.exists() or not list(out.glob("B1_*.txt"))  # nothing imported


def test_existing_records_are_not_overwritten(tmp_path: Path, capsys) -> None:
    block, _ = _continuous_session(5)
    cap = tmp_path / "s.cap"
    _write_cap(cap, block)
    out = tmp_path / "o"
    assert main(["import", str(cap), "--serial", "E1", "--out", str(out)]) == 0
    before = (out / "E1_x_up.txt").read_bytes()
    labels = str(out / "E1_segments.tsv")
    assert main(["import", str(cap), "--serial", "E1", "--out", str(out), "--labels", labels]) == 2
    assert "already exists" in capsys.readouterr().err
    assert (out / "E1_x_up.txt").read_bytes() == before


def test_stillness_thresholds_follow_the_data_noise() -> None:
    """Ten times the noise -> ten times the thresholds; a still stream stays still."""
    rng = np.random.default_rng(2)
    n = 3000
    t = np.arange(n) * 0.01
    for scale in (1.0, 10.0):
        acc = np.array([0.1, -0.2, 9.8]) + rng.normal(0, 0.01 * scale, (n, 3))
        gyr = np.array([1.0, -2.0, 0.5]) + rng.normal(0, 0.03 * scale, (n, 3))
        still, thr = find_still(t, acc, gyr)
        assert still.mean() > 0.97
        assert thr.gyro_std == pytest.approx(4 * 0.03 * scale * np.ones(3), rel=0.25)
        assert thr.bias_dps == pytest.approx([1.0, -2.0, 0.5], abs=0.02 * scale)


def test_accel_in_g_without_units_is_named(tmp_path: Path) -> None:
    rng = np.random.default_rng(4)
    n = 1000
    s = Stream(
        np.arange(n) * 0.01,
        np.array([0.0, 0.0, 1.0]) + rng.normal(0, 0.001, (n, 3)),
        rng.normal(0, 0.03, (n, 3)),
        np.full(n, 25.0),
        {"source": "g.csv"},
    )
    with pytest.raises(Exception, match="looks like g: add --units accel=g"):
        segment_stream(s)
    assert math.isfinite(STANDARD_G)


# ---- imucal's session ---------------------------------------------------------------------
REAL = Path(__file__).resolve().parents[4] / "shared" / "data" / "imucal-example"
IMUCAL_ORDER = {"x_p": "x_up", "x_a": "x_dn", "y_p": "y_up", "y_a": "y_dn", "z_p": "z_up",
                "z_a": "z_dn", "x_rot": "x_cw", "y_rot": "y_cw", "z_rot": "z_cw"}  # fmt: skip


def _write_imucal_session(real: Session, d: Path) -> tuple[Path, Path]:
    """imucal's session CSV (n_samples, gyr_*, acc_*) and section list, from the records."""
    rows = ["n_samples,gyr_x,gyr_y,gyr_z,acc_x,acc_y,acc_z"]
    sections = {}
    n = 0
    for sec, name in IMUCAL_ORDER.items():
        rec = real.records[name]
        sections[sec] = {"start": n, "end": n + len(rec)}
        for g, a in zip(rec.gyro, rec.accel, strict=True):
            rows.append(
                f"{n},{g[0]:.17g},{g[1]:.17g},{g[2]:.17g},{a[0]:.17g},{a[1]:.17g},{a[2]:.17g}"
            )
            n += 1
    csv, js = d / "example_ferraris_session.csv", d / "example_ferraris_session_list.json"
    csv.write_text("\n".join(rows) + "\n")
    import json

    js.write_text(json.dumps(sections))
    return csv, js


def test_imucal_session_calibrates_to_the_shared_records_constants(tmp_path: Path, capsys) -> None:
    real = read_session(REAL)
    csv, js = _write_imucal_session(real, tmp_path)
    out = tmp_path / "rec"
    argv = ["import", str(csv), "--sections", str(js), "--rate", "102.4"]
    assert main([*argv, "--serial", "IMU1", "--out", str(out)]) == 0
    capsys.readouterr()
    imported = read_session(out)
    assert set(imported.records) == set(real.records)
    assert imported.records["y_cw"].meta["direction"] == "cw"
    a = calibrate_from_records(imported).constants()
    b = calibrate_from_records(real).constants()
    for k, v in b.items():
        if math.isnan(v):
            assert math.isnan(a[k]), k
        else:
            assert a[k] == pytest.approx(v, rel=1e-6, abs=1e-9), k


def test_imucal_section_list_beside_the_session_is_found(tmp_path: Path, capsys) -> None:
    csv, _ = _write_imucal_session(read_session(REAL), tmp_path)
    argv = ["import", str(csv), "--rate", "102.4", "--serial", "I2", "--out", str(tmp_path / "o")]
    assert main(argv) == 0
    assert "example_ferraris_session_list.json" in capsys.readouterr().out
    assert len(read_session(tmp_path / "o").records) == 9


def test_imucal_session_needs_its_rate(tmp_path: Path, capsys) -> None:
    csv, js = _write_imucal_session(read_session(REAL), tmp_path)
    argv = ["import", str(csv), "--sections", str(js), "--serial", "I", "--out", str(tmp_path)]
    assert main(argv) == 2
    assert "--rate HZ" in capsys.readouterr().err


# ---- turns in steps, the calibration's integral, messages for imported data ---------------
def test_a_turn_made_in_four_steps_with_pauses_is_one_turn() -> None:
    """imucal's example turns were made as four 90° steps: still, 4 × (90°, pause), still."""
    rng = np.random.default_rng(8)
    t = np.arange(0, 20.0, 0.01)
    rate = sum(_turn_rate(t, 3.0 + 3.5 * k, 1.0, -90.0) for k in range(4))  # 2.5 s pauses
    gyro = np.array([0.4, 0.9, -0.6]) + rng.normal(0, 0.04, (t.size, 3))
    gyro[:, 1] += rate  # about +y, clockwise seen from above
    accel = np.array([0.1, 9.8, -0.2]) + rng.normal(0, 0.01, (t.size, 3))
    segs, _, _ = segment_stream(Stream(t, accel, gyro, np.full(t.size, 25.0), {"source": "s"}))
    turns = [s for s in segs if s.turns]
    assert [(s.label, s.turns, s.direction) for s in turns] == [("y_cw", 1, -1)]
    assert "in 4 steps" in turns[0].quality
    # from the rest before the first step (at 3.0 s) to the rest after the last (at 14.5 s)
    assert abs(turns[0].t0_s - 3.0) < 0.05 and abs(turns[0].t1_s - 14.5) < 0.05


def test_the_calibration_integrates_turns_over_the_true_sample_times() -> None:
    from host.session.method import record_stats

    rng = np.random.default_rng(12)
    t = _bursty_times(rng, 9.0)
    rate = _turn_rate(t, 2.0, 5.0, 360.0)
    gyro = np.column_stack([rate, 0 * t, 0 * t])
    rec = Record("x_ccw", t * 1000.0, np.tile([9.8, 0, 0], (t.size, 1)), gyro, 0 * t + 25)
    stats = record_stats(rec)
    assert stats.gyro_integral[0] == pytest.approx(360.0, abs=1.0)
    assert abs(trapezoid(np.linspace(t[0], t[-1], t.size), gyro)[0] - 360.0) > 3.0


def test_bad_imported_records_are_not_sent_back_to_the_bench(tmp_path: Path) -> None:
    """A segment labelled with the wrong face: the message points at the cut, not the bench."""
    rng = np.random.default_rng(1)
    recs = {}
    for name in STATIC_NAMES:
        up = np.zeros(3)
        up["xyz".index(name[0])] = 1.0 if name.endswith("up") else -1.0
        if name == "y_up":
            up = np.array([0.0, 0.0, 1.0])  # the user's stream had z up here
        n = 200
        recs[name] = Record(name, np.arange(n) * 20.0, 9.81 * up + rng.normal(0, 0.01, (n, 3)),
                            rng.normal(0, 0.02, (n, 3)), np.full(n, 25.0),
                            {"importer": "columns", "source": "log.csv"})  # fmt: skip
    with pytest.raises(UserError) as exc:
        calibrate_from_records(Session("U1", recs))
    assert "re-measure" not in str(exc.value)
    assert "y_up segment" in str(exc.value) and "--labels" in str(exc.value)


def test_wrong_time_and_gyro_units_are_named(tmp_path: Path, capsys) -> None:
    rng = np.random.default_rng(9)
    t = np.arange(0, 14.0, 0.01)
    rate = _turn_rate(t, 4.0, 5.0, 360.0)
    gyro = rng.normal(0, 0.03, (t.size, 3))
    gyro[:, 0] += rate
    accel = np.array([9.8, 0.1, -0.2]) + rng.normal(0, 0.01, (t.size, 3))
    rows = [f"{a:.3f},{b[0]:.4f},{b[1]:.4f},{b[2]:.4f},{c[0]:.6f},{c[1]:.6f},{c[2]:.6f}"
            for a, b, c in zip(t * 1000, accel, np.radians(gyro), strict=True)]  # fmt: skip
    f = tmp_path / "rad.csv"
    f.write_text("\n".join(rows) + "\n")
    base = ["import", str(f), "--columns", "t,ax,ay,az,gx,gy,gz", "--serial", "R1"]
    assert main([*base, "--out", str(tmp_path / "a")]) == 2  # t in ms read as s
    assert "add --units t=ms" in capsys.readouterr().err
    assert main([*base, "--units", "t=ms", "--out", str(tmp_path / "b")]) == 0
    assert "is the gyro in rad/s? add --units gyro=rad/s" in capsys.readouterr().err
    assert main([*base, "--units", "t=ms,gyro=rad/s", "--out", str(tmp_path / "c")]) == 0
    assert (tmp_path / "c" / "R1_x_ccw.txt").exists()


def test_text_in_a_skipped_column_is_not_a_header() -> None:
    text = "date t ax ay az gx gy gz\n2026-11-23 0.00 1 2 3 4 5 6\n2026-11-23 0.02 1 2 3 4 5 7\n"
    cols = parse_columns("skip,t,ax,ay,az,gx,gy,gz")
    s = parse_column_text(text, "d.txt", cols)
    assert s.t_s.tolist() == [0.0, 0.02] and s.gyro[1].tolist() == [4.0, 5.0, 7.0]
    s = parse_column_text(text.split("\n", 1)[1], "d.txt", cols)
    assert len(s) == 2 and "header" not in s.meta


def test_record_and_labels_together_are_one_line(tmp_path: Path, capsys) -> None:
    """Was: --labels silently unused beside --record (the whole file became the record)."""
    argv = ["import", str(tmp_path / "s.csv"), "--serial", "R1", "--out", str(tmp_path / "o"),
            "--record", "x_up", "--labels", str(tmp_path / "l.tsv")]  # fmt: skip
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--record and --labels: give one" in err
    assert not (tmp_path / "o").exists()
