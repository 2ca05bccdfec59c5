"""Every command that reads records checks their timing (issue 26 item 2): the same timing table
as ``import`` when a record has gaps, turns integrated over the true times, and a turn record
cut in the middle of its motion (far from whole turns) refused with its name and its moving end."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from host.__main__ import main
from host.session.directory import read_record, record_path, write_record
from host.session.records import Record
from host.session.spacing import timing_quality, timing_report
from tests.host.sim_sessions import write_sim_session


def _cut(rec: Record, keep: np.ndarray) -> Record:
    t = rec.t_ms[keep]
    return Record(rec.name, t - t[0], rec.accel[keep], rec.gyro[keep], rec.temp[keep], rec.meta)


@pytest.fixture(scope="module")
def gappy(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A simulated session whose x_up record lost 0.3 s of samples twice (a USB stall)."""
    d = write_sim_session(tmp_path_factory.mktemp("gappy"), "T1", 41)
    rec = read_record(record_path(d, "T1", "x_up"))
    t = rec.t_ms
    keep = ~(((t > 1000) & (t < 1300)) | ((t > 3000) & (t < 3300)))
    write_record(record_path(d, "T1", "x_up"), _cut(rec, keep))
    return d


@pytest.mark.parametrize(
    "argv",
    [["calibrate", "--from-dir", "{d}", "--out", "{o}"], ["model", "diagnose", "{d}", "--brief"],
     ["thermal", "{d}", "--out", "{o}"],
     pytest.param(["noise", "{d}/T1_x_up.txt"], marks=pytest.mark.slow)],
    ids=["calibrate", "model", "thermal", "noise"],
)  # fmt: skip
def test_every_command_prints_the_timing_table_when_a_record_has_gaps(
    gappy: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], argv: list[str]
) -> None:
    main([a.format(d=gappy, o=tmp_path) for a in argv])
    err = capsys.readouterr().err
    assert "record    samples median ms worst gap ms  in gaps" in err
    line = next(ln for ln in err.splitlines() if ln.split(" ")[0].endswith("x_up"))
    assert "irregular" in line  # noise names the file (T1_x_up), the others the record
    assert "x_up: irregular sample times" in err and "worst gap 3" in err


def test_no_table_when_the_timing_is_regular(tmp_path: Path) -> None:
    from host.session.directory import read_session

    d = write_sim_session(tmp_path, "T2", 42)
    assert timing_report(read_session(d).records) == ""


@pytest.mark.parametrize("end", ["starts", "ends"])
def test_a_turn_record_cut_mid_turn_is_refused_with_its_name(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], end: str
) -> None:
    d = write_sim_session(tmp_path, "T3", 43)
    path = record_path(d, "T3", "y_cw")
    rec = read_record(path)
    rate = np.abs(rec.gyro[:, 1])
    moving = np.flatnonzero(rate > 0.5 * rate.max())
    mid = int(moving[len(moving) // 2])  # the middle of the turn, turning fast
    keep = np.arange(len(rec)) >= mid if end == "starts" else np.arange(len(rec)) <= mid
    write_record(path, _cut(rec, keep))
    for argv in (["calibrate", "--from-dir", str(d)], ["model", "diagnose", str(d)],
                 ["plan", str(d)]):  # fmt: skip
        assert main(argv) == 2
        err = " ".join(capsys.readouterr().err.split())  # one line, however wrapped
        assert "T3_y_cw.txt" in err and "the turn was not complete" in err, err
        assert f"the record {end} in motion" in err, err


def test_calibrate_integrates_turns_over_the_true_times(tmp_path: Path) -> None:
    """x_ccw keeps only every third sample in its first half (a logger that slowed down): the
    calibration's turn integral follows the true times, so Gxx hardly moves, while evenly
    spaced samples over the same span would move the integral by degrees."""
    from host.calib.calibration import calibrate_from_records
    from host.session.directory import read_session
    from host.session.spacing import uniform_rate_error_deg

    d = write_sim_session(tmp_path, "T4", 44)
    before = calibrate_from_records(read_session(d)).constants()["Gxx"]
    path = record_path(d, "T4", "x_ccw")
    rec = read_record(path)
    idx = np.arange(len(rec))
    keep = (idx >= len(rec) // 2) | (idx % 3 == 0)
    write_record(path, _cut(rec, keep))
    cut = read_record(path)
    assert timing_quality(cut.t_ms / 1000.0).n == int(keep.sum())
    assert uniform_rate_error_deg(cut.t_ms / 1000.0, cut.gyro) > 20.0
    after = calibrate_from_records(read_session(d)).constants()["Gxx"]
    assert abs(after - before) < 2e-4, (before, after)
