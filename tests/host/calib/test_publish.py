"""Compute and write (host/calib/publish.py): the one step from records to the published result,
shared by the live calibration and ``calibrate --from-dir``."""

from __future__ import annotations

import dataclasses
import io
import json
from pathlib import Path

import pytest

from host.calib.codec import read_result
from host.calib.publish import ComputeSettings, compute_and_write, parse_floor, show_result
from host.errors import UserError
from host.session.directory import read_session
from tests.host.sim_sessions import write_sim_session


@pytest.fixture(scope="module")
def records_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_sim_session(tmp_path_factory.mktemp("publish") / "Q7", "Q7", seed=9)


def test_the_floor_option_reads_each_sensor_apart() -> None:
    assert dict(parse_floor("accel=0.002,gyro=0.03").floor) == {"accel": 0.002, "gyro": 0.03}
    assert dict(parse_floor("gyro=0.5").floor) == {"gyro": 0.5}
    assert dict(parse_floor(None).floor) == {}
    for bad in ("accel=-1", "mag=1", "gyro=nan", "accel"):
        with pytest.raises(UserError, match="--floor: expected accel=VALUE,gyro=VALUE"):
            parse_floor(bad)


def test_both_files_are_written_with_the_settings(records_dir: Path, tmp_path: Path) -> None:
    session = read_session(records_dir, None)
    pub = compute_and_write(session, tmp_path, ComputeSettings(latitude_deg=-41.5, height_m=820.0))
    assert (pub.report_path, pub.json_path) == (
        tmp_path / "Q7_result.txt",
        tmp_path / "Q7_result.json",
    )
    doc = json.loads(pub.json_path.read_text())
    assert (doc["latitude_deg"], doc["height_m"]) == (-41.5, 820.0)
    assert "serial No. Q7" in pub.report_path.read_text()
    out = io.StringIO()
    show_result(pub, as_json=True, out=out)
    assert json.loads(out.getvalue()) == doc
    out = io.StringIO()
    show_result(pub, as_json=False, out=out)
    assert out.getvalue() == pub.report_path.read_text()


def test_bad_settings_write_nothing(records_dir: Path, tmp_path: Path) -> None:
    session = read_session(records_dir, None)
    with pytest.raises(UserError, match="--turns must be at least 1"):
        compute_and_write(session, tmp_path, ComputeSettings(turns=0))
    with pytest.raises(UserError, match="no such directory"):
        compute_and_write(session, tmp_path / "absent", ComputeSettings())
    assert list(tmp_path.iterdir()) == []


def test_from_dir_keeps_an_earlier_result_of_other_records(tmp_path: Path) -> None:
    """A result is computed again in place from the same records; one of other records is
    moved to earlier/ with its report, bytes unchanged, never replaced."""
    from host.calib.publish import set_aside_other_result
    from tests.host.issue31_sweep import _calibrated

    d = _calibrated(tmp_path)
    again = read_result(d / "Q1_result.json")
    assert set_aside_other_result(d, again, print) is None  # the same records
    before = (d / "Q1_result.json").read_bytes()
    other = dataclasses.replace(again, records=again.records[:-1])
    aside = set_aside_other_result(d, other, print)
    assert aside is not None and aside.parent.name == "earlier"
    assert (aside / "Q1_result.json").read_bytes() == before
    assert (aside / "Q1_result.txt").is_file() and not (d / "Q1_result.json").exists()
