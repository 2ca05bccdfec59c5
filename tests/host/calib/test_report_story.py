"""The first run tells one story: when the model does not fit, the report and the last lines on
screen say what that means for the values and give the next command (issue 24, item 5)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

from host.calib.calibration import calibrate_from_records
from host.calib.report import fit_story, format_report, verdict_line
from host.session.directory import read_session
from tests.independent.simulate import SessionSpec, write_session


def test_a_poor_fit_is_said_with_its_meaning_and_the_next_command(tmp_path: Path) -> None:
    """A gyro bias step between records (independent simulator): the fit is inadequate; the
    report says so beside its fit line and names `model diagnose` on the records' directory;
    the screen ends on the same story, then the verdict as the last line. A control (nothing
    hidden) gets no such story."""
    step = tmp_path / "step"
    write_session(step, SessionSpec(seed=7, effect="bias_step_gyro"))
    res = calibrate_from_records(read_session(step))
    assert res.fit is not None and res.fit.verdict == "inadequate"
    story = fit_story(res, step)
    assert f"python -m host model diagnose {step}" in story
    assert "standard errors are widened" in story and "PASS/FAIL" in story
    report = format_report(res)
    assert "The model does not fit these records" in report
    assert "python -m host model diagnose" in " ".join(report.split())
    lines = verdict_line(res, step / "IND01_result.txt").splitlines()
    assert lines[0] == story and lines[-1].startswith(("PASS: ", "FAIL: "))

    ctrl = tmp_path / "ctrl"
    write_session(ctrl, SessionSpec(seed=7, effect="none"))
    res0 = calibrate_from_records(read_session(ctrl))
    assert res0.fit is not None and res0.fit.verdict != "inadequate"
    assert fit_story(res0) == "" and "does not fit" not in format_report(res0)
    assert "model diagnose" not in verdict_line(res0, ctrl / "IND01_result.txt")
    # the story follows the fit's verdict, nothing else
    bad = dataclasses.replace(res0, fit=dataclasses.replace(res0.fit, verdict="inadequate"))
    assert fit_story(bad).endswith("python -m host model diagnose DIR")
