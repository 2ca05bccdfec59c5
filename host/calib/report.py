"""The test report ("protocol", method.md §7) and the result files.

``SERIAL_result.txt``: plain UTF-8, at most 80 columns (fits A4), header with serial and date,
every value on its line with tolerance and a +/− mark, stage-1 bias consistency, residuals per
record, g/latitude/height, three signature lines. ``SERIAL_result.json``: see
:meth:`host.calib.result.CalibrationResult.to_dict`. Further terms of the model (beyond the §2
linear model) get their own section after the §7 table, value ± σ and unit; undetermined
values are marked "not determined" with what would determine them.
"""

from __future__ import annotations

import math
import os
from pathlib import Path

from host.calib.result import CalibrationResult
from host.session.atomic import write_texts_atomic
from host.session.method import (
    ACCEL_BIAS_NAMES,
    CONSTANT_NAMES,
    GROUPS,
    GYRO_BIAS_NAMES,
    NOISE_NAMES,
    UNITS,
)

WIDTH = 80
PLUS, MINUS = "+", "−"


def _v(x: float, dec: int = 5) -> str:
    return f"{x:+.{dec}f}" if math.isfinite(x) else "n/d"


def _mark(ok: bool | None) -> str:
    return " " if ok is None else (PLUS if ok else MINUS)


def format_report(result: CalibrationResult) -> str:
    """The text of ``SERIAL_result.txt`` (lines ≤ 80 characters, ends with a newline)."""
    r = result
    passed = r.passed()
    consts = r.constants()
    rule = "-" * WIDTH
    out: list[str] = []
    out.append(f"TEST REPORT, IMU MPU-6000, serial No. {r.serial}")
    if r.simulated:
        out.append(f"*** {r.simulated_line} ***")
    out.append(f"Date and time: {r.created.replace('T', ' ')}")
    out.append(
        f"Local gravity g = {r.g:.5f} m/s² (Helmert formula, latitude {r.latitude_deg:.3f}°, "
        f"height {r.height_m:.0f} m)"
    )
    kinds: dict[str, int] = {}
    for res in r.residuals:
        kinds[res.kind] = kinds.get(res.kind, 0) + 1
    plan = ", ".join(f"{n} {k}" for k, n in sorted(kinds.items()))
    turns = "-" if r.turns is None else str(r.turns)
    out.append(f"Records: {len(r.residuals)} ({plan}); turns per turn record: {turns}")
    out.append(f"Method: {r.method}")
    out.extend(_wrap(f"Verdict: {verdict(r)} (RESULT below)", "", "  "))
    out.append(f"Model: {r.model}")
    if r.fit is not None:
        out.extend(_wrap(r.fit.line(), "", "  "))
        story = fit_story(r)
        if story:
            out.extend(_wrap(story, "", "  "))
    if r.earth_rate:
        out.append("Earth rate: vertical component included in the reference rates")
    cf = [abs(consts[n] - v) for n, v in r.closed_form.items() if n not in NOISE_NAMES]
    cf = [d for d in cf if math.isfinite(d)]
    if cf:
        what = "the fit" if not r.further else "the fit (whose further terms move the biases)"
        out.extend(
            _wrap(f"Closed form (§3, §4) differs from {what} by at most {max(cf):.2e}", "", "  ")
        )
    out.append(rule)
    out.append(f"  {'value':<7}{'measured':>12}  {'unit':<8}{'tolerance':>11}  mark   std error")
    out.append(rule)
    last_title = ""
    std_errors = r.std_errors
    in_model = {p.name for p in r.parameters} | set(r.noise_std)
    for title, names, unit, tol in GROUPS:
        tol_s = "none" if tol is None else (f"≤{tol:g}" if names[0] in NOISE_NAMES else f"±{tol:g}")
        if title != last_title:
            out.append(f"{title}" + (f", {unit}" if unit and unit != "rad" else ""))
        last_title = title
        for n in names:
            se = std_errors.get(n, math.nan)
            se_s = f"±{se:.5f}" if math.isfinite(se) else ""
            note = ""
            if not math.isfinite(consts[n]):
                note = "  not determined" if n in in_model else "  not in the model"
            out.append(
                f"  {n:<7}{_v(consts[n]):>12}  {UNITS[n]:<8}{tol_s:>11}   {_mark(passed[n])}  "
                f"{se_s:>11}{note}"
            )
    out.append(rule)
    if r.further:
        out.append("Further terms of the model (value ± std error)")
        for p in r.further:
            if p.determined:
                out.append(f"  {p.name:<34}{_v(p.value, 6):>14} ± {p.stderr:.2g} {p.unit}")
            else:
                out.append(f"  {p.name:<34}{'not determined':>14}")
        out.append(rule)
    bad = failed_values(r)
    if bad:
        out.append(f"RESULT: {len(bad)} value(s) outside tolerance or not determined:")
        line = "  "
        for n in bad:
            if len(line) + len(n) + 1 > WIDTH:
                out.append(line.rstrip())
                line = "  "
            line += n + " "
        out.append(line.rstrip())
    else:
        out.append("RESULT: all values within tolerance")
    out.append(rule)
    if r.undetermined:
        out.append("Not determined by these records, and what would determine them:")
        by_need: dict[str, list[str]] = {}
        for p in r.undetermined:
            by_need.setdefault(p.needs or "more records", []).append(p.name)
        for need, names_ in by_need.items():
            out.extend(_wrap(f"{', '.join(names_)}: {need}", "  -", "    "))
        if r.combinations:
            out.append("  What these records do determine of them:")
            for c in r.combinations:
                out.extend(_wrap(c, "   ", "      "))
        out.append(rule)

    if r.bias_estimates:
        out.append("Stage 1 bias consistency (§3): estimates from the X, Y, Z pairs")
        out.append(
            f"  {'bias':<6}{'X pair':>11}{'Y pair':>11}{'Z pair':>11}{'mean':>11}{'spread':>11}"
        )
        for n in GYRO_BIAS_NAMES + ACCEL_BIAS_NAMES:
            if n not in r.bias_estimates:
                continue
            e = r.bias_estimates[n]
            spread = max(e) - min(e)
            mean = sum(e) / 3.0
            out.append(
                f"  {n:<6}{_v(e[0]):>11}{_v(e[1]):>11}{_v(e[2]):>11}{_v(mean):>11}"
                f"{spread:>11.5f} {UNITS[n]}"
            )
        out.append("  A spread much larger than the noise means the linear model misses")
        out.append("  something (method.md §3).")
        out.append(rule)

    out.append("Noise (std): largest over the static orientations, per channel (§3)")
    out.append("  gyro  °/s : " + "  ".join(f"{n} {consts[n]:.4f}" for n in NOISE_NAMES[:3]))
    out.append("  accel m/s²: " + "  ".join(f"{n} {consts[n]:.4f}" for n in NOISE_NAMES[3:]))
    out.append(rule)
    out.append("Residuals per record (measured − model): mean / std of samples;")
    out.append("turns: integral residual, degrees")
    out.append(
        f"  {'record':<9}{'N':>6}{'T,s':>6}  {'accel x y z, m/s²':<24}"
        f"{'gyro x y z, °/s (turns °)':<27}"
    )
    for res in r.residuals:
        head = f"  {res.record[:9]:<9}{res.n:>6}{res.duration_s:>6.1f}  "
        if res.kind == "turn" and res.angle_deg is not None:
            acc = f"{'-':<24}"
            gyr = " ".join(f"{x:+8.3f}" for x in res.angle_deg)
            out.append(head + acc + gyr + " °")
            continue
        acc = " ".join(f"{x:+.4f}" if math.isfinite(x) else "    -  " for x in res.accel_mean)
        gyr = " ".join(f"{x:+8.4f}" for x in res.gyro_mean)
        out.append(head + f"{acc:<24}" + gyr)
        if res.kind == "static":
            accs = " ".join(f"{x:7.4f}" for x in res.accel_std)
            gyrs = " ".join(f"{x:8.4f}" for x in res.gyro_std)
            out.append(f"  {'  std':<21}  {accs:<24}{gyrs}")
    if r.verification is not None:
        v = r.verification
        out.append(rule)
        out.extend(_wrap(f"Verification on records not used in the fit: {v.source}", "", "  "))
        out.append("  measured − predicted (limits of method.md §8: 0.01 g, 0.5 °/s; turns °)")
        for x in v.values:
            out.append(
                f"  {x.record[:10]:<10} {x.channel:<8}{x.residual:>+11.4f} {x.unit:<5}"
                f"± {x.sigma:<9.2g} z {x.z:>+7.1f}   limit {x.limit:.3g}  {_mark(x.passed)}"
            )
        out.append(
            f"  RMS z = {v.rms_z:.2f}, χ² = {v.chi2:.1f} on {len(v.values)} values "
            f"(p = {v.p:.3g}): {'all within' if v.passed else 'NOT all within'} the limits"
        )
    if r.notes:
        out.append(rule)
        out.append("Notes:")
        for note in r.notes:
            out.extend(_wrap(note, "  -", "    "))
    out.append(rule)
    out.append("")
    for role in ("Customer's representative", "Quality control", "Workshop"):
        out.append(f"{role:<27}_______________________  /________________/")
        out.append("")
    return "\n".join(line.rstrip() for line in out) + "\n"


def _wrap(text: str, first: str, indent: str) -> list[str]:
    lines: list[str] = []
    line = first
    for word in text.split():
        if line.strip() and len(line) + 1 + len(word) > WIDTH:
            lines.append(line)
            line = indent + word
        else:
            line = f"{line} {word}" if line.strip() else line + word
    if line:
        lines.append(line)
    return lines


def result_paths(directory: str | os.PathLike[str], serial: str) -> tuple[Path, Path]:
    """(``DIR/SERIAL_result.txt``, ``DIR/SERIAL_result.json``)."""
    d = Path(directory)
    return d / f"{serial}_result.txt", d / f"{serial}_result.json"


def failed_values(result: CalibrationResult) -> list[str]:
    """Names of the §7 values outside tolerance, then of the parameters not determined."""
    passed = result.passed()
    bad = [n for n in CONSTANT_NAMES if passed[n] is False]
    return bad + [p.name for p in result.undetermined if p.name not in bad]


def verdict(result: CalibrationResult) -> str:
    """PASS or FAIL and why, in one line (the report's header and the last line on screen)."""
    if result.all_passed:
        return "PASS: every value within tolerance"
    bad = failed_values(result)
    why = f"{len(bad)} value(s) outside tolerance or not determined" if bad else ""
    if result.verification is not None and not result.verification.passed:
        why = (why + "; " if why else "") + "held-out records not predicted within the limits"
    return f"FAIL: {why}"


def fit_story(result: CalibrationResult, directory: str | os.PathLike[str] | None = None) -> str:
    """'' when the model fits; else what an inadequate fit means for the values and the next
    command (``python -m host model diagnose DIR``, ``directory`` the records' when known)."""
    q = result.fit
    if q is None or q.verdict != "inadequate":
        return ""
    where = str(directory) if directory is not None else "DIR"
    return (
        f"The model does not fit these records (RMS z {q.rms_z:.2f}: residuals {q.rms_z:.1f}x "
        "their noise): something the model lacks moved them. The standard errors are widened "
        "where the fit is poor, and PASS/FAIL on the tolerances holds only if that effect does "
        f"not bias the values. Find it: python -m host model diagnose {where}"
    )


def verdict_line(result: CalibrationResult, report_path: str | os.PathLike[str]) -> str:
    """What a session or ``--from-dir`` ends on: the :func:`verdict` and the report's path as
    the last line, preceded by ``*** SIMULATED BOARD <url>: not a measurement of a unit ***``
    when the records came from a virtual or emulated board (on its own line, so the verdict
    still fits an 80-column terminal), and before that, when the model does not fit, the
    report's :func:`fit_story` with the next command."""
    line = f"{verdict(result)}; report {report_path}"
    line = f"*** {result.simulated_line} ***\n{line}" if result.simulated else line
    story = fit_story(result, Path(report_path).parent)
    # the report's story on a poor fit, above the mark and the verdict (the last line)
    return f"{story}\n{line}" if story else line


def write_results(
    result: CalibrationResult, directory: str | os.PathLike[str]
) -> tuple[Path, Path]:
    """Publish the report and the JSON result in ``directory`` together or not at all
    (:func:`host.session.atomic.write_texts_atomic`: the signed report and the file ``apply()``
    reads never disagree); returns the paths. UserError names the file that failed."""
    txt, js = result_paths(directory, result.serial)
    write_texts_atomic({txt: format_report(result), js: result.to_json()})
    return txt, js
