"""The verdict policy (issue 43 item 5): a session of the method missing any of its records is
INCOMPLETE, not a pass — named in the verdict, listed and marked in the report, exit status 1;
a plan that names no fixed set of records (poses and moves) is never incomplete."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import pytest

from host.calib.calibration import calibrate_from_records
from host.calib.report import format_report
from host.calib.result import CalibrationResult
from host.calib.values import RecordResidual
from host.calib.verdict import all_passed, method_records, missing_records, reasons
from host.session.directory import read_session
from host.session.records import STATIC_NAMES, TURN_NAMES
from tests.host.cli.cli_run import run
from tests.independent.simulate import SessionSpec, write_session

_NAN3 = (float("nan"),) * 3


def _with_records(r: CalibrationResult, names: list[str], kind: str = "") -> CalibrationResult:
    res = tuple(
        RecordResidual(n, kind or ("turn" if n.endswith("cw") else "static"), 10, 1.0,
                       _NAN3, _NAN3, _NAN3, _NAN3)
        for n in names
    )  # fmt: skip
    return dataclasses.replace(r, residuals=res, records=tuple(names))


@pytest.fixture(scope="module")
def whole(tmp_path_factory: pytest.TempPathFactory) -> CalibrationResult:
    """A session of every record of the method (independent simulator, nothing hidden),
    judged by simple acceptance so that only the records decide here."""
    d = tmp_path_factory.mktemp("whole")
    write_session(d, SessionSpec(seed=7, effect="none"))
    r = calibrate_from_records(read_session(d))
    return dataclasses.replace(r, decision_rule="simple")


def test_the_method_asks_for_its_twelve_records(whole: CalibrationResult) -> None:
    assert method_records(whole) == STATIC_NAMES + TURN_NAMES
    assert missing_records(whole) == [] and whole.all_passed


@pytest.mark.parametrize(
    ("drop", "missing"),
    [
        (["z_dn"], ["z_dn"]),
        (["z_dn", "x_ccw"], ["z_dn", "x_ccw"]),
        (list(TURN_NAMES[::2]), list(TURN_NAMES[::2])),
    ],  # fmt: skip
)
def test_a_record_not_measured_makes_the_result_incomplete(
    whole: CalibrationResult, drop: list[str], missing: list[str]
) -> None:
    names = [n for n in whole.records if n not in drop]
    r = _with_records(whole, names)
    assert missing_records(r) == missing and not all_passed(r)
    assert r.verdict().startswith("INCOMPLETE: " + ", ".join(missing[:6]) + " not measured")
    assert reasons(r)[0] == f"records of the method not measured: {', '.join(missing)}"
    report = format_report(r)
    assert f"NOT MEASURED: {' '.join(missing)}" in report
    assert f"{12 - len(missing)} of 12 measured" in report


def test_a_repeat_measures_its_record_and_rates_measure_the_gyro(
    whole: CalibrationResult,
) -> None:
    names = [n for n in whole.records if n != "x_ccw"] + ["x_ccw_2"]
    assert missing_records(_with_records(whole, names)) == []
    statics = list(STATIC_NAMES) + ["rate_x"]
    r = _with_records(whole, statics)
    r = dataclasses.replace(
        r, residuals=tuple(dataclasses.replace(x, kind="rate") if x.record == "rate_x" else x
                           for x in r.residuals),
    )  # fmt: skip
    assert method_records(r) == STATIC_NAMES and missing_records(r) == []


def test_a_plan_of_poses_names_no_fixed_records(whole: CalibrationResult) -> None:
    r = _with_records(whole, ["pose_01", "pose_02", "move_01_02"], kind="pose")
    assert method_records(r) == () and missing_records(r) == []
    assert "Method's records" not in format_report(r)


def test_from_dir_without_z_dn_and_x_ccw_says_incomplete(tmp_path: Path) -> None:
    """The issue's own case: the two records deleted, `calibrate --from-dir` names them in
    its last line, the report lists them not measured, and the exit status is a failed
    verdict's; export refuses it."""
    d = tmp_path / "part"
    write_session(d, SessionSpec(seed=7, effect="none"))
    for name in ("z_dn", "x_ccw"):
        (d / f"IND01_{name}.txt").unlink()
    rc, out, err = run(["calibrate", "--from-dir", str(d), "--no-archive"])
    assert rc == 1
    last = err.rstrip("\n").splitlines()[-1]
    assert last.startswith("INCOMPLETE: z_dn, x_ccw not measured"), err
    assert "NOT MEASURED: z_dn x_ccw" in out and "10 of 12 measured" in out
    doc = json.loads((d / "IND01_result.json").read_text(encoding="utf-8"))
    assert doc["all_passed"] is False and doc["verdict"].startswith("INCOMPLETE")
    rc, text, err = run(["export", str(d), "--to", "px4"])
    assert rc == 1 and text == "" and "not measured: z_dn, x_ccw" in err
