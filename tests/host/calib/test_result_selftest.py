"""The self-test's outcome in the result (host/calib/result.py, report.py): read from the
records' ``self_test`` header, kept in the result file, and a failed self-test fails the
calibration whatever the values say."""

from __future__ import annotations

import json

import pytest

from host.calib.calibration import CalibrationOptions, calibrate_from_records
from host.calib.codec import result_from_json, result_to_json
from host.calib.report import format_report
from host.calib.result import CalibrationResult
from host.session.directory import Session

try:
    from calib_truth import make_records
except ImportError:  # tests/ imported as a package
    from tests.host.calib_truth import make_records


def _result(self_test: str | None) -> CalibrationResult:
    records = make_records(seed=13)  # every value within tolerance
    if self_test is not None:
        for rec in records.values():
            rec.meta["self_test"] = self_test
    return calibrate_from_records(
        Session("ST1", records), CalibrationOptions(created="2024-05-06T10:11:12+03:00")
    )


@pytest.mark.parametrize(
    ("self_test", "passed", "line"),
    [(None, True, "not run"), ("pass", True, "PASS"), ("fail", False, "FAIL")],
)
@pytest.mark.slow
def test_the_self_test_is_in_the_result_and_a_failure_fails_it(
    self_test: str | None, passed: bool, line: str
) -> None:
    r = _result(self_test)
    assert r.self_test == (self_test or "")
    assert r.all_passed is passed
    text = format_report(r)
    assert f"MPU-6000 self-test: {line}" in text
    if not passed:
        assert r.verdict() == "FAIL: the sensor failed its self-test"
        assert "RESULT: FAIL — the sensor failed its MPU-6000 self-test" in text
        assert "RESULT: all values within tolerance" in text  # the values themselves pass
    back = result_from_json(result_to_json(r))
    assert back.self_test == r.self_test and back.all_passed is passed


def test_an_older_result_file_has_no_self_test() -> None:
    d = json.loads(result_to_json(_result("fail")))
    del d["self_test"]
    assert result_from_json(json.dumps(d)).self_test == ""
