"""The words of a calibration result: its verdict line and its one-line summary.

The verdict line is what the report's header and conclusion, the last line on screen and the
result file's ``verdict`` say alike (the policy behind it: :mod:`host.calib.verdict`); the
summary is the result's ``repr``.
"""

from __future__ import annotations

from typing import Protocol

from host.calib.verdict import Judged, all_passed, failed_values, misfit


class Summarized(Judged, Protocol):
    """What the summary reads of a result, beyond what the verdict does."""

    @property
    def serial(self) -> str: ...

    @property
    def model(self) -> str: ...

    @property
    def simulated(self) -> bool: ...


def verdict_line(r: Judged) -> str:
    """PASS or FAIL and why, in one line. ``PASS (conditional: the model does not fit, RMS z
    8.35)`` when the PASS is conditional; a FAIL on a model that does not fit says so as its
    last reason; ``— self-test not run`` ends the line when the self-test was skipped."""
    fit = r.fit
    skipped = " — self-test not run" if r.self_test == "not run" else ""
    if all_passed(r) and fit is not None and misfit(r):
        return f"PASS (conditional: the model does not fit, RMS z {fit.rms_z:.2f}){skipped}"
    if all_passed(r):
        return "PASS: every value within tolerance" + skipped
    bad = failed_values(r)
    why = [f"{len(bad)} value(s) outside tolerance or not determined"] if bad else []
    if r.verification is not None and not r.verification.passed:
        why.append("held-out records not predicted within the limits")
    if r.self_test == "fail":
        why.append("the sensor failed its self-test")
    if misfit(r):
        why.append("the model does not fit")
    return f"FAIL: {'; '.join(why)}{skipped}"


def summary(r: Summarized) -> str:
    """One line: serial, model, size, verdict, and SIMULATED for simulated records."""
    verdict = "PASS" if all_passed(r) else "FAIL"
    fit = f", fit {r.fit.verdict}" if r.fit is not None else ""
    sim = ", SIMULATED" if r.simulated else ""
    return (
        f"<CalibrationResult {r.serial}: model {r.model}, "
        f"{len(r.parameters)} parameters, {verdict}{fit}{sim}>"
    )
