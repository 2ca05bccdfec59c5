"""The report as a certificate (issue 28, method.md §7–§8): every item the bench knows, read
from the report of a live ``sim://?speed=max`` session and checked against the records'
headers and samples it must come from — and after a ``--redo`` sitting and a ``--from-dir``
recomputation, which keeps the measured-at time."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np
import pytest

from host import __version__
from host.__main__ import main
from host.calib.codec import read_result
from host.session.directory import read_session
from tests.host.cli.cli_run import too_wide

URL = "sim://?speed=max"
#: the board the records name: the dialogue adds the unit's serial to a virtual board's URL
BOARD = f"{URL}&serial=C1"
LIVE = ["--port", URL, "--serial", "C1", "--yes", "--warmup", "0", "--static-seconds", "3",
        "--turns", "1", "--no-archive"]  # fmt: skip


@pytest.fixture(scope="module")
def live(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A live session on the virtual board, then x_ccw measured again in a second sitting."""
    d = tmp_path_factory.mktemp("cert") / "C1"
    who = ["--operator", "A. Tester", "--bench", "bench 2"]
    assert main(["calibrate", *LIVE, "--out", str(d), *who]) in (0, 1)
    assert main(["calibrate", *LIVE, "--out", str(d), "--redo", "x_ccw"]) in (0, 1)
    return d


def _line(text: str, start: str) -> str:
    """The report's line starting with ``start`` (stripped), with its continuation lines."""
    lines = text.splitlines()
    i = next(i for i, ln in enumerate(lines) if ln.strip().startswith(start))
    out = lines[i].strip()
    for ln in lines[i + 1 :]:
        if not ln.startswith("    "):
            break
        out += " " + ln.strip()
    return out


@pytest.mark.slow
def test_every_item_of_the_certificate_from_a_live_session(live: Path) -> None:
    text = (live / "C1_result.txt").read_text(encoding="utf-8")
    res = read_result(live / "C1_result.json")
    recs = read_session(live).records
    meta = recs["x_up"].meta
    # 80 columns; only a single word longer than a line may pass them (a path: a test's
    # temporary directory can be long), alone on its line; a command is broken with \
    assert too_wide(text) == []

    # object: the sensor named from the data, and the simulated mark
    lines = text.splitlines()
    assert lines[0] == f"TEST REPORT, IMU MPU-6000 rev {meta['sensor_revision']}, serial No. C1"
    assert lines[1] == f"*** SIMULATED BOARD {BOARD}: not a measurement of a unit ***"
    unit = _line(text, "Unit:")
    assert f"WHO_AM_I {meta['who_am_i']}" in unit and f"product ID {meta['product_id']}" in unit

    # equipment, from the headers
    board = _line(text, "Board:")
    assert (
        f"firmware {meta['firmware']}" in board and f"protocol {meta['protocol_version']}" in board
    )
    assert f"port {BOARD}" in board
    settings = _line(text, "Sensor settings:")
    for words in (
        f"accelerometer ±{meta['accel_range_g']} g",
        f"gyro ±{meta['gyro_range_dps']} °/s",
        f"{meta['sample_rate_hz']} Hz",
        f"DLPF_CFG {meta['dlpf_cfg']}",
        f"SPI clock {meta['sensor_spi_clock']}",
    ):
        assert words in settings, words
    assert _line(text, "Operator:") == "Operator: A. Tester; bench: bench 2"

    # environment: the chip temperature over every sample
    temps = np.concatenate([r.temp for r in recs.values()])
    env = _line(text, "Environment:")
    assert f"chip temperature {temps.min():.1f} to {temps.max():.1f} °C" in env

    # procedure: plan and timing, sittings, model and algorithm, software
    statics = [r.duration_s for r in recs.values() if r.kind == "static"]
    timing = _line(text, "Timing:")
    assert f"static accumulation time {min(statics):.1f}" in timing and abs(min(statics) - 3) < 0.1
    assert f"turn window {recs['x_ccw'].meta['window_s']} s" in timing
    assert "turns per turn record: 1" in timing
    records = _line(text, "Records:")
    caps = {r.meta["capture"] for r in recs.values()}
    assert caps == {"C1_session.cap", "C1_session_2.cap"}
    assert "measured in 2 sittings" in records
    assert "1: C1_session.cap, 12 records; 2: C1_session_2.cap, x_ccw" in records
    assert _line(text, "Model:") == "Model: base"
    assert _line(text, "Algorithm:") == f"Algorithm: {res.method}"
    assert res.fit is not None and _line(text, "Fit quality:").startswith(res.fit.line())

    # when: measured (the records' start times) and computed (by which software)
    starts = sorted(r.meta["start_time"] for r in recs.values())
    measured = _line(text, "Measured:")
    first = f"Measured: {starts[0][:10]} {starts[0][11:19]}"
    # a fast session can start its first and last record within one second: one time then
    same = starts[0][:19] == starts[-1][:19]
    assert measured.startswith(first if same else f"{first} to {starts[-1][11:19]}")
    assert (" to " in measured.split("(")[0]) != same
    computed = _line(text, "Computed:")
    assert computed == f"Computed: {res.created.replace('T', ' ')} by imu-bench {__version__}"

    # results: expanded uncertainty at 95.45 % (k = 2, Student's t on a σ's dof) and the verdict
    assert "U: the expanded" in text and "k = 2" in text
    from scipy import stats

    for name in ("Gxx", "A0z", "GAyz"):
        row = next(ln for ln in lines if ln.split()[:1] == [name])
        p = res.parameter(name)
        k = 2.0 if math.isinf(p.dof) else stats.t.isf((1 - math.erf(2**0.5)) / 2, p.dof)
        assert f"±{k * p.stderr:.5f}" in row.split(), row
        assert (f"k = {k:.2f}, {p.dof:.0f} dof" in row) == math.isfinite(p.dof), row
    assert _line(text, "Verdict:").startswith(f"Verdict: {'PASS' if res.all_passed else 'FAIL'}")
    i = lines.index("CONCLUSION")
    assert lines[i + 1].strip().startswith("PASS" if res.all_passed else "FAIL")

    # residuals in the order measured: by sitting, then session_s
    table = lines[
        lines.index(next(ln for ln in lines if ln.startswith("Residuals per record"))) + 3 :
    ]
    shown = [ln.split()[0] for ln in table if ln.split() and ln.split()[0] in recs]
    sitting = {c: i for i, c in enumerate(("C1_session.cap", "C1_session_2.cap"))}
    expected = sorted(recs, key=lambda n: (sitting[recs[n].meta["capture"]],
                                           float(recs[n].meta["session_s"])))  # fmt: skip
    assert shown == expected and shown[-1] == "x_ccw"

    # the JSON carries the same, as data
    prov = json.loads((live / "C1_result.json").read_text(encoding="utf-8"))["provenance"]
    assert prov["equipment"]["firmware"] == meta["firmware"]
    assert prov["measured_from"] == starts[0] and prov["measured_to"] == starts[-1]


@pytest.mark.slow
def test_from_dir_keeps_the_measured_at_time(live: Path, tmp_path: Path) -> None:
    before = (live / "C1_result.txt").read_text(encoding="utf-8")
    out = tmp_path / "again"
    out.mkdir()
    assert main(["calibrate", "--from-dir", str(live), "--out", str(out), "--no-archive"]) in (0, 1)
    after = (out / "C1_result.txt").read_text(encoding="utf-8")
    assert _line(after, "Measured:") == _line(before, "Measured:")
    assert _line(after, "Records:") == _line(before, "Records:")
    assert after.splitlines()[1] == before.splitlines()[1]  # still SIMULATED


def test_imported_16_bit_data_is_an_unknown_sensor() -> None:
    from host.calib.calibration import calibrate_from_records
    from host.calib.report import format_report

    real = Path(__file__).resolve().parents[4] / "shared" / "data" / "imucal-example"
    text = format_report(calibrate_from_records(read_session(real)))
    assert text.splitlines()[0] == "TEST REPORT, IMU unknown sensor, serial No. REAL"
    assert "MPU-6000" not in text.splitlines()[0]
    assert "the tolerances below are the MPU-6000's" in _line(text, "Unit:")
    assert re.search(r"Environment: chip temperature not measured", _line(text, "Environment:"))
    assert _line(text, "Measured:") == "Measured: the records carry no start time"
