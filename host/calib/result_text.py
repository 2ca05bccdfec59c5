"""The words of a calibration result: its verdict line and its one-line summary.

The verdict line is what the report's header and conclusion, the last line on screen and the
result file's ``verdict`` say alike (the policy behind it: :mod:`host.calib.verdict`); the
summary is the result's ``repr``; the list of the method's records, those not measured
marked, is the report's.
"""

from __future__ import annotations

import textwrap
from typing import Protocol

from host.calib.verdict import (
    Judged,
    all_passed,
    method_records,
    misfit,
    missing_records,
    outside,
    undecided,
)


class Summarized(Judged, Protocol):
    """What the summary reads of a result, beyond what the verdict does."""

    @property
    def serial(self) -> str: ...

    @property
    def model(self) -> str: ...

    @property
    def simulated(self) -> bool: ...


#: the verdict is the screen's last line: at most this many characters (an 80-column terminal)
VERDICT_WIDTH = 80


def verdict_line(r: Judged) -> str:
    """PASS, FAIL or INCOMPLETE and why, in one line. INCOMPLETE (not a pass) names the
    method's records not measured, then any other reason. ``PASS (conditional: the model
    does not fit, RMS z 8.35)`` when the PASS is conditional; a FAIL on a model that does
    not fit says so as its last reason; values whose ± U reaches across a limit (``?``
    under guarded acceptance, :mod:`host.calib.decision`) are named as undecided; ``—
    self-test not run`` ends the line when the self-test was skipped. The undecided values
    are named up to three, fewer (then only counted) where the line would pass
    :data:`VERDICT_WIDTH` characters."""
    fit = r.fit
    skipped = " — self-test not run" if r.self_test == "not run" else ""
    if all_passed(r) and fit is not None and misfit(r):
        return f"PASS (conditional: the model does not fit, RMS z {fit.rms_z:.2f}){skipped}"
    if all_passed(r):
        return "PASS: every value within tolerance" + skipped
    line = ""
    for most in (3, 2, 1, 0):
        line = _failed_line(r, most) + skipped
        if len(line) <= VERDICT_WIDTH:
            break
    return line


def _failed_line(r: Judged, most: int) -> str:
    """FAIL or INCOMPLETE and its reasons, naming up to ``most`` undecided values (0: only
    their count)."""
    bad, unsure = outside(r), undecided(r)
    why = [f"{len(bad)} value(s) outside tolerance or not determined"] if bad else []
    if unsure:
        names = _names(unsure, most) if most else f"{len(unsure)} values"
        why.append(f"{names} undecided (± U across a limit)")
    if r.verification is not None and not r.verification.passed:
        why.append("held-out records not predicted within the limits")
    if r.self_test == "fail":
        why.append("the sensor failed its self-test")
    if misfit(r):
        why.append("the model does not fit")
    if gone := missing_records(r):
        head = f"INCOMPLETE: {_names(gone, 6)} not measured"
        return "; ".join([head, *why])
    return f"FAIL: {'; '.join(why)}"


def _names(names: list[str], most: int = 3) -> str:
    """Up to ``most`` names, then how many more."""
    more = f" and {len(names) - most} more" if len(names) > most else ""
    return ", ".join(names[:most]) + more


def method_record_lines(r: Judged, width: int = 80) -> list[str]:
    """The report's list of the records the method asks for, those not measured marked NOT
    MEASURED, in lines ≤ ``width``; [] for a plan that names no fixed set (poses and
    moves)."""
    need, gone = method_records(r), missing_records(r)
    if not need:
        return []
    head = f"Method's records (method.md §3, §4): {len(need) - len(gone)} of {len(need)} measured"
    parts = [(head + ("" if gone else ": " + " ".join(need)), "  ", "    ")]
    if gone:
        parts.append(("measured: " + " ".join(n for n in need if n not in gone), "    ", "      "))
        parts.append(("NOT MEASURED: " + " ".join(gone), "    ", "      "))
    return [
        line
        for text, first, rest in parts
        for line in textwrap.wrap(text, width, initial_indent=first, subsequent_indent=rest)
    ]


def summary(r: Summarized) -> str:
    """One line: serial, model, size, verdict, and SIMULATED for simulated records."""
    verdict = "PASS" if all_passed(r) else "FAIL"
    fit = f", fit {r.fit.verdict}" if r.fit is not None else ""
    sim = ", SIMULATED" if r.simulated else ""
    return (
        f"<CalibrationResult {r.serial}: model {r.model}, "
        f"{len(r.parameters)} parameters, {verdict}{fit}{sim}>"
    )
