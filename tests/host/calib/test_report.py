"""The test report (§7), the result files and ``python3 -m host calibrate --from-dir``."""

from __future__ import annotations

import json
import re
import shutil
from pathlib import Path

import numpy as np
import pytest

from host import __version__
from host.__main__ import main
from host.calib.calibration import CalibrationOptions, calibrate_from_records
from host.calib.codec import result_from_json, result_to_json
from host.calib.report import format_report, write_results
from host.calib.result import CalibrationResult
from host.session.directory import Session, record_path, write_record
from host.session.method import CONSTANT_NAMES
from host.session.records import Record

try:
    from calib_truth import TRUTH, make_records
except ImportError:  # tests/ imported as a package
    from tests.host.calib_truth import TRUTH, make_records

# shared/ sits beside the checkout (as in CI)
REAL = Path(__file__).resolve().parents[4] / "shared" / "data" / "imucal-example"


@pytest.fixture(scope="module")
def result() -> CalibrationResult:
    truth = dict(TRUTH, A0z=-0.95)  # one value outside its tolerance (±0.8)
    return calibrate_from_records(
        Session("SIM7", make_records(seed=13, truth=truth)),
        CalibrationOptions(created="2024-05-06T10:11:12+03:00"),
    )


def _write_session(d: Path, serial: str = "SIM7", seed: int = 13) -> None:
    for name, rec in make_records(seed=seed).items():
        write_record(record_path(d, serial, name), rec)


def test_report_layout(result: CalibrationResult) -> None:
    text = format_report(result)
    lines = text.splitlines()
    # records that do not name their sensor (no who_am_i in the header): not called an MPU-6000
    assert lines[0] == "TEST REPORT, IMU unknown sensor, serial No. SIM7"
    assert lines[1] == "Report No. NOBENCH-SIM7-20240506T071112.000Z, serial No. SIM7, page 1 of 3"
    i = lines.index("Measured: the records carry no start time")  # under the certificate's lines
    assert lines[i + 1] == f"Computed: 2024-05-06 10:11:12+03:00 by imu-bench {__version__}"
    assert max(len(ln) for ln in lines) <= 80
    assert text.encode("utf-8").decode("utf-8") == text and "\t" not in text
    assert "latitude 55.750°, height 150 m" in text and f"g = {result.g:.5f} m/s²" in text
    result_line = "RESULT: 1 value(s) outside tolerance or not determined:"
    table = lines[: lines.index(result_line)]
    for name in CONSTANT_NAMES:
        rows = [ln for ln in table if ln.split()[:1] == [name]]
        assert len(rows) == 1, name
    row = {ln.split()[0]: ln for ln in table if ln.split()[:1] and ln.split()[0] in CONSTANT_NAMES}
    a0z = result.constants()["A0z"]
    assert row["A0z"].split()[1] == f"{a0z:+.5f}" and a0z < -0.8
    assert "±0.8" in row["A0z"] and " − " in row["A0z"]
    assert "±0.5" in row["A0x"] and " + " in row["A0x"]
    assert "±0.03" in row["Gxx"] and " + " in row["Gxx"]
    assert "≤0.05" in row["Gstdx"] and "none" in row["Astdx"]
    assert (
        "RESULT: 1 value(s) outside tolerance" in text
        and lines[lines.index(result_line) + 1].strip() == "A0z"
    )
    assert "Stage 1 bias consistency" in text
    for role in ("Customer's representative", "Quality control", "Workshop"):
        assert sum(ln.startswith(role) and "____" in ln for ln in lines) == 1
    for rec in ("x_up", "z_dn", "x_ccw", "z_cw"):
        assert any(ln.split()[:1] == [rec] for ln in lines), rec


def test_report_not_measured() -> None:
    res = calibrate_from_records(
        Session("S", make_records(("x_up", "x_dn", "y_up", "y_dn", "z_up", "z_dn")))
    )
    text = format_report(res)
    gxx = next(ln for ln in text.splitlines() if ln.split()[:1] == ["Gxx"])
    assert "n/d" in gxx and "not determined" in gxx and " − " in gxx
    # and the report says what would determine it
    assert "  - Gxx, Gyz, Gzy: add any one of: x_ccw, x_cw" in text.splitlines()
    assert "  - Gzz, Gxy, Gyx: add any one of: z_ccw, z_cw" in text.splitlines()
    assert max(len(ln) for ln in text.splitlines()) <= 80


def test_write_results(tmp_path: Path, result: CalibrationResult) -> None:
    txt, js = write_results(result, tmp_path)
    assert txt.name == "SIM7_result.txt" and js.name == "SIM7_result.json"
    assert txt.read_text(encoding="utf-8") == format_report(result)
    back = result_from_json(js.read_text(encoding="utf-8"))
    assert back.constants()["A0z"] == result.constants()["A0z"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["SIM7_result.json", "SIM7_result.txt"]


@pytest.mark.slow
def test_cli_from_dir(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    _write_session(tmp_path)
    rc = main(["calibrate", "--from-dir", str(tmp_path)])
    out = capsys.readouterr().out
    assert rc == 0
    assert out.startswith("TEST REPORT, IMU unknown sensor, serial No. SIM7")
    assert (tmp_path / "SIM7_result.txt").read_text(encoding="utf-8").splitlines()[0] == (
        out.splitlines()[0]
    )
    d = json.loads((tmp_path / "SIM7_result.json").read_text(encoding="utf-8"))
    assert abs(d["constants"]["Gyy"] - TRUTH["Gyy"]) < 1e-3
    # recomputing with the result files present works (they are not records)
    rc = main(
        [
            "calibrate",
            "--from-dir",
            str(tmp_path),
            "--json",
            "--latitude",
            "0",
            "--height",
            "0",
            "--turns",
            "2",
        ]
    )
    d = json.loads(capsys.readouterr().out)
    assert rc == 0 and d["latitude_deg"] == 0.0 and d["g"] == pytest.approx(9.7803)
    assert set(CONSTANT_NAMES) <= set(d["constants"]) and d["turns"] == 2


def test_cli_real_data(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    for p in REAL.glob("REAL_*.txt"):
        shutil.copy(p, tmp_path / p.name)
    rc = main(["calibrate", "--from-dir", str(tmp_path), "--json"])
    d = json.loads(capsys.readouterr().out)
    assert rc == 1  # A0x, A0y outside ±0.5 m/s² (a different sensor): a failed unit
    assert d["pass"]["A0x"] is False and d["serial"] == "REAL" and d["turns"] == 1


@pytest.mark.parametrize(
    ("setup", "args", "message"),
    [
        ("truncate", [], r"^error: .*SIM7_x_dn.txt:\d+: no line of underscores"),
        ("none", ["--yes"], r"^error: --yes needs --serial"),  # the live dialogue, no port
        ("missing", [], r"^error: .*nope: no such directory"),
        ("ok", ["--turns", "1"], r"^error: SIM7_x_ccw.txt: the cube turned \+7\d\d°"),
        ("ok", ["--serial", "XX"], r"^error: .*no records of serial 'XX'"),
        ("ok", ["--latitude", "100"], r"^error: latitude 100.0 is not within"),
        ("wrongface", [], r"^error: SIM7_y_up.txt: gravity is on -Y, expected \+Y: the cube"),
    ],
)
@pytest.mark.slow
def test_cli_errors_one_line(
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    setup: str,
    args: list[str],
    message: str,
) -> None:
    _write_session(tmp_path)
    if setup == "truncate":
        p = tmp_path / "SIM7_x_dn.txt"
        p.write_text(p.read_text(encoding="utf-8")[:3000], encoding="utf-8")
    if setup == "wrongface":
        text = (tmp_path / "SIM7_y_dn.txt").read_text(encoding="utf-8")
        text = "".join(ln for ln in text.splitlines(True) if not ln.startswith("#"))
        (tmp_path / "SIM7_y_up.txt").write_text(text, encoding="utf-8")  # no header
    argv = ["calibrate"]
    if setup != "none":
        argv += ["--from-dir", str(tmp_path / "nope" if setup == "missing" else tmp_path)]
    rc = main(argv + args)
    err = capsys.readouterr().err
    assert rc == 2
    assert err.count("error:") == 1 and "Traceback" not in err
    lines = err.strip().splitlines()
    if len(lines) > 1:  # a record to measure again: the sentence, then the command that does
        from tests.host.cli.cli_run import command_after, too_wide

        assert too_wide(err) == [] and command_after(err, "with:")[-2] == "--redo", err
    assert re.search(message, " ".join(err.split())), err


def test_only_records_from_a_real_port_make_an_unmarked_report(tmp_path: Path) -> None:
    # The same records, once from /dev/ttyACM0 and once from emu://: only the second report and
    # JSON carry the SIMULATED BOARD mark, and it names the URL.
    from host.bench.plan import Plan, simulate_session
    from host.bench.truth import SensorTruth

    recs = simulate_session(SensorTruth.random(np.random.default_rng(3)), Plan(turns=1), seed=3)
    for port, marked in (("/dev/ttyACM0", False), ("emu://?seed=3&noise_seed=3", True)):
        records = {
            n: Record(r.name, r.t_ms, r.accel, r.gyro, r.temp, {**r.meta, "port": port})
            for n, r in recs.items()
        }
        result = calibrate_from_records(Session("M1", records))
        report = format_report(result).splitlines()
        assert report[1].startswith("*** SIMULATED BOARD emu://?seed=3&noise_seed=3") is marked
        notes = json.loads(result_to_json(result))["notes"]
        assert (
            any(n.startswith("SIMULATED BOARD emu://?seed=3&noise_seed=3") for n in notes) is marked
        )


def test_a_long_board_url_is_shown_whole_within_80_columns(result: CalibrationResult) -> None:
    """A virtual board's URL with its options runs past the mark's line: the mark keeps its
    line and the URL follows whole on its own (one that is longer than a line stays whole:
    it is copied, not read), in the report and in the lines a session ends on."""
    import dataclasses

    from host.calib.provenance import Provenance
    from host.calib.report import verdict_line

    short = "sim://?speed=max"
    long_ = "emu://?seed=3&noise_seed=3&speed=max&operator=auto&operator_fault=drop_turn&stimulus=warm.csv"
    longer = "sim://?" + "&".join(f"option{i}=value{i}" for i in range(9))
    for by in ((short,), (long_,), (longer,), (short, long_)):
        sim = dataclasses.replace(result, provenance=Provenance(simulated=True, simulated_by=by))
        report = format_report(sim).splitlines()
        ending = verdict_line(sim, "out/SIM7_result.txt").splitlines()
        for lines in (report, ending):
            text = "\n".join(lines)
            assert all(len(ln) <= 80 or ln.strip() in by for ln in lines), by
            assert text.count("*** SIMULATED BOARD") == 1
            for url in by:  # each URL whole on one line
                assert any(url in ln.split() or f"{url}," in ln.split() for ln in lines) or (
                    f"SIMULATED BOARD {url}:" in text
                ), url
        assert report[1].startswith("*** SIMULATED BOARD")
        assert ending[-1] == sim.verdict()
        one_line = len(f"*** {sim.simulated_line} ***") <= 80
        assert (report[1] == f"*** {sim.simulated_line} ***") is one_line


def test_from_dir_ends_on_the_verdict_and_the_report(tmp_path: Path, capsys) -> None:
    # The real imucal session: one-way turns only, so it is INCOMPLETE (the method's ccw turns
    # not measured) and fails besides (values out of tolerance); the last lines on the terminal
    # say so and where the report is, also with --json on stdout.
    for extra in ([], ["--json"]):
        out = tmp_path / f"o{len(extra)}"
        out.mkdir()
        rc = main(["calibrate", "--from-dir", str(REAL), "--out", str(out), *extra])
        err = capsys.readouterr().err.rstrip("\n").splitlines()
        k = next(k for k, ln in enumerate(err) if ln.startswith("INCOMPLETE: "))
        verdict = " ".join(ln.strip() for ln in err[k:])
        assert rc == 1 and verdict.startswith("INCOMPLETE: x_ccw, y_ccw, z_ccw not measured; ")
        assert "outside tolerance" in verdict and all(len(ln) <= 80 for ln in err[k:])
        # the model does not fit imucal's session either: a reason of the verdict, and the next
        # command names the records' directory (not --out); real data: no SIMULATED mark
        assert verdict.endswith("; the model does not fit")
        # (a path too long for the line follows its label on a line of its own)
        i = next(i for i, ln in enumerate(err) if ln.startswith("Report:"))
        assert " ".join(ln.strip() for ln in err[i:k]) == (
            f"Report: {out / 'REAL_result.txt'} Next: python3 -m host model diagnose {REAL}"
        )
        lines = (out / "REAL_result.txt").read_text().splitlines()
        head = lines[: lines.index("-" * 80)]  # the head: the lines before the first rule
        assert f"Verdict: {verdict} (RESULT below)" in " ".join(ln.strip() for ln in head)
