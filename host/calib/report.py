"""The test report ("protocol", method.md §7) and the result files.

``SERIAL_result.txt``: plain UTF-8, at most 80 columns (fits A4), header with serial and date,
every value on its line with tolerance and a +/− mark, stage-1 bias consistency, residuals per
record, g/latitude/height, three signature lines. ``SERIAL_result.json``: see
:func:`host.calib.codec.result_to_dict`. Further terms of the model (beyond the §2
linear model) get their own section after the §7 table, value ± σ and unit; undetermined
values are marked "not determined" with what would determine them.
"""

from __future__ import annotations

import math
import os
import shlex
from collections.abc import Sequence
from functools import partial
from pathlib import Path

from host.calib.certificate import (
    RELATES_ONLY,
    Issue,
    head_lines,
    page_header,
    report_number,
    signature_lines,
    site_text,
    traceability_lines,
)
from host.calib.codec import FLOOR_SOURCES, result_to_json
from host.calib.commands import command_lines
from host.calib.decision import coverage_note, expanded_uncertainty, statement
from host.calib.provenance import UNKNOWN_SENSOR, Provenance
from host.calib.report_lines import WIDTH, paginate
from host.calib.report_lines import wrap as _wrap
from host.calib.report_tables import (
    bias_consistency,
    noise_lines,
    residual_table,
    value_text,
    verification_lines,
)
from host.calib.result import CalibrationResult
from host.calib.result_text import method_record_lines
from host.calib.values import target_line
from host.calib.verdict import marks, missing_records, outside, undecided
from host.session.atomic import write_texts_atomic
from host.session.directory import SIMULATED_BOARD
from host.session.inputs import written_serial
from host.session.method import (
    GROUPS,
    NOISE_NAMES,
    UNITS,
)


def format_report(
    result: CalibrationResult,
    records_dir: str | os.PathLike[str] | None = None,
    issue: Issue | None = None,
) -> str:
    """The text of ``SERIAL_result.txt`` (lines ≤ 80 characters, pages of at most
    :data:`~host.calib.report_lines.PAGE_LINES` lines, each after the first begun by a form
    feed and the report number with "page i of n"; ends with a newline): the
    :func:`report_sections`, between rules. ``records_dir``: the directory of the records, for
    the next command a poor fit names (:func:`next_command`; None: ``DIR``); ``issue``: the
    certificate's facts beyond the result (:class:`host.calib.certificate.Issue`; None: none
    known, and the report says so)."""
    iss = issue if issue is not None else Issue()
    out: list[str] = []
    starts: set[int] = set()
    for key, lines in report_sections(result, records_dir, iss):
        starts.add(len(out))
        out += [*lines, "-" * WIDTH] if key != "signatures" else ["", *lines]
    number = report_number(result, iss)
    first = next(i for i, ln in enumerate(out) if ln.startswith("Report No. "))
    header = partial(page_header, number, result.serial)
    pages = paginate(out, header, first, frozenset(starts))
    return "\n".join(line.rstrip() for line in pages) + "\n"


def report_sections(
    result: CalibrationResult, records_dir: str | os.PathLike[str] | None, issue: Issue
) -> list[tuple[str, list[str]]]:
    """The report's sections in order, each (key, its lines): the text report sets them
    between rules, the PDF (:mod:`host.calib.report_pdf`) sets those it has tables for as
    tables and the others as paragraphs. A section with nothing to say is left out."""
    r = result
    nxt = next_words(r, records_dir)
    procedure = _procedure(r, nxt)
    if r.earth_rate:
        procedure.append("Earth rate: vertical component included in the reference rates")
    sections = [
        ("head", _head(r, nxt, issue)),
        ("object", _object_and_equipment(r)),
        ("procedure", procedure + _closed_form_check(r)),
        ("traceability", traceability_lines(r, issue)),
        ("results", _results_table(r)),
        ("further", _further_terms(r) if r.further else []),
        ("result", _result_lines(r)),
        ("undetermined", _undetermined(r) if r.undetermined else []),
        ("bias", bias_consistency(r) if r.bias_estimates else []),
        ("residuals", [*noise_lines(r), "-" * WIDTH, *residual_table(r)]),
        ("verification", [] if r.verification is None else verification_lines(r.verification)),
        ("notes", _notes(r)),
        ("conclusion", _conclusion(r, nxt)),
        ("signatures", signature_lines(issue)),
    ]
    return [(k, lines) for k, lines in sections if lines]


def _notes(r: CalibrationResult) -> list[str]:
    """The result's notes, one item each."""
    if not r.notes:
        return []
    out = ["Notes:"]
    for note in r.notes:
        out.extend(_wrap(note, "  -", "    "))
    return out


def _closed_form_check(r: CalibrationResult) -> list[str]:
    """How far the closed form of §3, §4 is from the fit (nothing when there is none)."""
    consts = r.constants()
    cf = [abs(consts[n] - v) for n, v in r.closed_form.items() if n not in NOISE_NAMES]
    cf = [d for d in cf if math.isfinite(d)]
    if not cf:
        return []
    what = "the fit" if not r.further else "the fit (whose further terms move the biases)"
    return _wrap(f"Closed form (§3, §4) differs from {what} by at most {max(cf):.2e}", "", "  ")


#: a row of the results table: name, value, unit, tolerance, mark, U (95 %), note
ResultRow = tuple[str, str, str, str, str, str, str]


def result_rows(r: CalibrationResult) -> list[tuple[str, list[ResultRow]]]:
    """The §7 table as data: each group's title (with its unit) and its rows — every value
    with its unit, tolerance, mark and expanded uncertainty, as the report writes them."""
    decided, consts = marks(r), r.constants()
    std_errors = r.std_errors
    dofs = {p.name: p.dof for p in r.parameters}
    in_model = {p.name for p in r.parameters} | set(r.noise_std)
    groups: list[tuple[str, list[ResultRow]]] = []
    for title, names, unit, tol in GROUPS:
        tol_s = "none" if tol is None else (f"≤{tol:g}" if names[0] in NOISE_NAMES else f"±{tol:g}")
        head = f"{title}" + (f", {unit}" if unit and unit != "rad" else "")
        if not groups or groups[-1][0] != head:
            groups.append((head, []))
        for n in names:
            se, dof = std_errors.get(n, math.nan), dofs.get(n, math.inf)
            note = coverage_note(dof) if math.isfinite(se) else ""
            if not math.isfinite(consts[n]):
                note = "not determined" if n in in_model else "not in the model"
            groups[-1][1].append((n, value_text(consts[n]), UNITS[n], tol_s, decided[n] or " ",
                                  f"±{expanded_uncertainty(se, dof):.5f}" if math.isfinite(se)
                                  else "", note))  # fmt: skip
    return groups


def _results_table(r: CalibrationResult) -> list[str]:
    """The §7 table: every value with its unit, tolerance, mark and expanded uncertainty."""
    out = [
        "RESULTS: value, tolerance, mark (decision rule below), and U: the expanded",
        "uncertainty at 95 % coverage, k = 2 (Student's t where the note gives a dof)",
        *_wrap(statement(r.decision_rule), "", "  "),
        f"  {'value':<7}{'measured':>12}  {'unit':<8}{'tolerance':>11}  mark   U (95 %)",
        "-" * WIDTH,
    ]
    for title, rows in result_rows(r):
        out.append(title)
        for n, v, unit, tol_s, m, se_s, note in rows:
            note = f"  {note}" if note else ""
            out.append(f"  {n:<7}{v:>12}  {unit:<8}{tol_s:>11}   {m}  {se_s:>11}{note}")
    return out


def _further_terms(r: CalibrationResult) -> list[str]:
    """The parameters of the terms beyond the §2 model, value ± U."""
    out = ["Further terms of the model (value ± U, 95 %)"]
    for p in r.further:
        if p.determined:
            u, note = expanded_uncertainty(p.stderr, p.dof), coverage_note(p.dof)
            out.append(f"  {p.name:<34}{value_text(p.value, 6):>14} ± {u:.2g} {p.unit}"
                       + (f" ({note})" if note else ""))  # fmt: skip
        else:
            out.append(f"  {p.name:<34}{'not determined':>14}")
    return out


def _result_lines(r: CalibrationResult) -> list[str]:
    """RESULT: the values outside tolerance or not determined, and those undecided (value ±
    U across a limit), each list wrapped; or all within; and a failed self-test."""
    bad, unsure = outside(r), undecided(r)
    out = []
    for names, what in ((bad, "outside tolerance or not determined"),
                        (unsure, "undecided, value ± U across a limit (not a pass)")):  # fmt: skip
        if names:
            out.append(f"RESULT: {len(names)} value(s) {what}:")
            out.extend(_wrap(" ".join(names), "  ", "  "))
    if not bad and not unsure:
        out.append("RESULT: all values within tolerance")
    if gone := missing_records(r):
        out.extend(_wrap(f"RESULT: INCOMPLETE — records of the method not measured: "
                         f"{' '.join(gone)}", "", "  "))  # fmt: skip
    if r.self_test == "fail":
        out.append("RESULT: FAIL — the sensor failed its MPU-6000 self-test")
    return out


def _undetermined(r: CalibrationResult) -> list[str]:
    """What the records did not determine, by what would determine it, and the combinations
    of those they do determine."""
    out = ["Not determined by these records, and what would determine them:"]
    by_need: dict[str, list[str]] = {}
    for p in r.undetermined:
        by_need.setdefault(p.needs or "more records", []).append(p.name)
    for need, names_ in by_need.items():
        out.extend(_wrap(f"{', '.join(names_)}: {need}", "  -", "    "))
    if r.combinations:
        out.append("  What these records do determine of them:")
        for c in r.combinations:
            out.extend(_wrap(c, "   ", "      "))
    return out


def _head(r: CalibrationResult, nxt: list[str], issue: Issue) -> list[str]:
    """Title (the sensor named from the data), the simulated mark, the certificate's number,
    laboratory, customer, item, method and dates (:func:`host.calib.certificate.head_lines`),
    when measured and when computed, local gravity and where it came from, the verdict and,
    on a poor fit, the next command ``nxt``."""
    pv = r.provenance
    sensor = "MPU-6000" if pv is None else pv.sensor
    out = [f"TEST REPORT, IMU {sensor}, serial No. {written_serial(r.serial)}"]
    out.extend(simulated_banner(r))
    out.extend(head_lines(r, issue))
    if pv is not None and pv.measured_from:
        out.extend(_wrap(f"Measured: {_measured(pv)} (the records' start times)", "", "  "))
    else:
        out.append("Measured: the records carry no start time")
    by = f" by {pv.software}" if pv is not None and pv.software else ""
    out.append(f"Computed: {_time(r.created)}{by}")
    out.extend(_wrap(f"Local gravity g = {r.g:.5f} m/s² ({site_text(r, issue)})", "", "  "))
    out.extend(_wrap(f"Verdict: {r.verdict()} (RESULT below)", "", "  "))
    if nxt:
        out.extend(_command(nxt, "Next: ", "  ", "(what the model lacks)"))
    return out


def _time(iso: str) -> str:
    return iso.replace("T", " ")


def _measured(pv: Provenance) -> str:
    """'2026-11-26 17:48:49 to 17:52:10 UTC+00:00' from the first and last start times."""
    from datetime import datetime

    try:
        t0 = datetime.fromisoformat(pv.measured_from)
        t1 = datetime.fromisoformat(pv.measured_to)
    except ValueError:
        return f"{_time(pv.measured_from)} to {_time(pv.measured_to)}"
    zone = t0.strftime(" UTC%z") if t0.tzinfo is not None else ""
    zone = zone[:-2] + ":" + zone[-2:] if zone else ""
    first = t0.strftime("%Y-%m-%d %H:%M:%S")
    if t1.strftime("%Y-%m-%d %H:%M:%S") == first:
        return first + zone
    last = t1.strftime("%H:%M:%S" if t1.date() == t0.date() else "%Y-%m-%d %H:%M:%S")
    return f"{first} to {last}{zone}"


def _object_and_equipment(r: CalibrationResult) -> list[str]:
    """Object, equipment, environment (method.md §8), from the record headers."""
    pv = r.provenance
    out = ["OBJECT, EQUIPMENT AND ENVIRONMENT (from the record headers)"]
    if pv is None:
        return [*out, "  not in this result file (format v1/v2): recompute with --from-dir"]
    eq = pv.equipment
    names = (("who_am_i", "WHO_AM_I"), ("product_id", "product ID"))
    ids = ", ".join(f"{w} {eq[k]}" for k, w in names if k in eq)
    unit = f"serial No. {written_serial(r.serial)}, {pv.sensor}" + (f" ({ids})" if ids else "")
    if pv.sensor == UNKNOWN_SENSOR:
        unit += "; the tolerances below are the MPU-6000's (method.md §7)"
    out.extend(_wrap(f"Unit: {unit}", "  ", "    "))
    board = []
    if "firmware" in eq:
        board.append(f"firmware {eq['firmware']}")
    if "protocol_version" in eq:
        board.append(f"protocol {eq['protocol_version']}")
    if pv.ports:
        board.append(f"port {', '.join(pv.ports)}")
    if pv.sources:
        more = f" and {len(pv.sources) - 1} more" if len(pv.sources) > 1 else ""
        board.append(f"source {pv.sources[0]}{more}")
    out.extend(_wrap(f"Board: {'; '.join(board) or 'not recorded'}", "  ", "    "))
    st = {"pass": "PASS", "fail": "FAIL (the calibration fails)",
          "not run": "not run (--no-self-test)"}.get(r.self_test, "not run")  # fmt: skip
    out.append(f"  MPU-6000 self-test: {st}")
    settings = [
        form.format(eq[k]) for k, form in (
            ("accel_range_g", "accelerometer ±{} g"), ("gyro_range_dps", "gyro ±{} °/s"),
            ("sample_rate_hz", "{} Hz"), ("smplrt_div", "SMPLRT_DIV {}"),
            ("dlpf_cfg", "DLPF_CFG {}"), ("sensor_spi_clock", "SPI clock {}"),
        ) if k in eq
    ]  # fmt: skip
    out.extend(_wrap(f"Sensor settings: {', '.join(settings) or 'not recorded'}", "  ", "    "))
    who = ", ".join(pv.operators) or ("simulated" if pv.simulated else "not recorded")
    where = ", ".join(pv.benches) or "not recorded"
    out.append(f"  Operator: {who}; bench: {where}")
    temp = (
        f"{pv.temp_c[0]:.1f} to {pv.temp_c[1]:.1f} °C" if pv.temp_c is not None
        else "not measured"
    )  # fmt: skip
    out.extend(_wrap(f"Environment: chip temperature {temp}; humidity, pressure, vibration "
                     "not measured", "  ", "    "))  # fmt: skip
    return out


def _procedure(r: CalibrationResult, nxt: list[str]) -> list[str]:
    """Plan, timing, sittings, model and algorithm (method.md §8 "procedure")."""
    pv = r.provenance
    kinds: dict[str, int] = {}
    for res in r.residuals:
        kinds[res.kind] = kinds.get(res.kind, 0) + 1
    plan = ", ".join(f"{n} {k}" for k, n in sorted(kinds.items()))
    out = ["PROCEDURE"]
    sittings = "" if pv is None else f", measured in {_sittings(pv)}"
    out.extend(_wrap(f"Records: {len(r.residuals)} ({plan}){sittings}", "  ", "    "))
    out.extend(method_record_lines(r))
    if pv is not None and pv.set_aside:
        kept = "; ".join(f"{s.folder}: {_names(s.records)}" for s in pv.set_aside)
        out.extend(_wrap(f"Kept aside, not in this result (measured again, or an earlier "
                         f"sitting's): {kept}", "  ", "    "))  # fmt: skip
    timing = []
    if pv is not None and pv.static_s is not None:
        timing.append(f"static accumulation time {_span(pv.static_s)} s")
    if pv is not None and pv.turn_window_s:
        timing.append(f"turn window {', '.join(f'{w:g}' for w in pv.turn_window_s)} s")
    if pv is not None and pv.turn_s is not None:
        timing.append(f"turn records {_span(pv.turn_s)} s")
    turns = "-" if r.turns is None else str(r.turns)
    timing.append(f"turns per turn record: {turns}")
    out.extend(_wrap(f"Timing: {'; '.join(timing)}", "  ", "    "))
    if pv is not None and pv.stopped:
        out.append("  Stopped when they had enough (--plan adaptive):")
        for name, why in pv.stopped.items():
            out.extend(_wrap(f"{name}: {why}", "    ", "      "))
    if pv is not None and pv.target is not None:
        out.extend(_wrap(target_line(r.parameters, pv.target), "  ", "    "))
    out.extend(_wrap(f"Algorithm: {r.method}", "  ", "    "))
    out.extend(_wrap(f"Model: {r.model}", "  ", "    "))
    if r.fit is not None:
        out.extend(_wrap(r.fit.line(), "  ", "    "))
        story = fit_story(r)
        if story:
            out.extend(_wrap(f"{story} Find it:", "  ", "    "))
            out.extend(_command(nxt, "    ", "    "))
    return out


def _span(x: tuple[float, float]) -> str:
    return f"{x[0]:.1f}" if abs(x[1] - x[0]) < 0.05 else f"{x[0]:.1f} to {x[1]:.1f}"


def _sittings(pv: Provenance) -> str:
    """'1 sitting' or '2 sittings (1: U1_session.cap, 12 records; 2: …, x_ccw)'."""
    n = len(pv.sittings)
    if n <= 1:
        return "1 sitting"
    parts = []
    for i, st in enumerate(pv.sittings, 1):
        what = _names(st.records)
        parts.append(f"{i}: {st.capture or 'no capture'}, {what}")
    return f"{n} sittings (--resume/--redo; {'; '.join(parts)})"


def _names(records: tuple[str, ...]) -> str:
    """'x_ccw, x_cw' for up to three records, else '12 records'."""
    return ", ".join(records) if len(records) <= 3 else f"{len(records)} records"


def _conclusion(r: CalibrationResult, nxt: list[str]) -> list[str]:
    """Verdict, what it rests on, the next command ``nxt`` on a poor fit, and
    repeatability (method.md §8)."""
    out = ["CONCLUSION"]
    out.extend(_wrap(r.verdict(), "  ", "    "))
    if nxt:
        within = "Every value is within tolerance as fitted, but the" if r.all_passed else "The"
        out.extend(_wrap(f"{within} model does not explain the records down to their noise "
                         "(fit quality above): the values hold only if the effect it lacks "
                         "does not bias them.", "  ", "    "))  # fmt: skip
        out.extend(_command(nxt, "  Next: ", "    ", "(what the model lacks)"))
    out.extend(_wrap("Repeatability (method.md §8: three calibrations, coefficient of "
                     f"variation ≤ 1 %): python3 -m host archive repeat {written_serial(r.serial)}",
                     "  ", "    ", keep=("≤ 1 %",)))  # fmt: skip
    out.append(f"  {RELATES_ONLY}")
    return out


def simulated_banner(result: CalibrationResult) -> list[str]:
    """The mark of records from a virtual or emulated board (none for a unit):
    ``*** SIMULATED BOARD <url>: not a measurement of a unit ***`` on one line when it fits in
    80 columns; else the mark on its line and the board's URLs below it, each whole (a URL
    longer than a line is not broken: it is copied)."""
    line = result.simulated_line
    if not line:
        return []
    one = f"*** {line} ***"
    if len(one) <= WIDTH:
        return [one]
    tail = ": not a measurement of a unit"
    by = line.removeprefix(SIMULATED_BOARD).removesuffix(tail).strip()
    return [f"*** {SIMULATED_BOARD}{tail} ***", *_wrap(by, "    ", "    ")]


def result_paths(directory: str | os.PathLike[str], serial: str) -> tuple[Path, Path]:
    """(``DIR/SERIAL_result.txt``, ``DIR/SERIAL_result.json``)."""
    d = Path(directory)
    return d / f"{serial}_result.txt", d / f"{serial}_result.json"


def fit_story(result: CalibrationResult) -> str:
    """'' when the model fits; else what an inadequate fit means for the values (the report
    under its fit line and the screen above the verdict say it; :func:`next_command` is what
    to run next)."""
    q = result.fit
    if q is None or q.verdict != "inadequate":
        return ""
    return (
        f"The model does not fit these records (RMS z {q.rms_z:.2f}: residuals {q.rms_z:.1f}x "
        "their noise): something the model lacks moved them. The standard errors are widened "
        "where the fit is poor, and the verdict on the tolerances is conditional: it holds only "
        "if that effect does not bias the values."
    )


def next_words(
    result: CalibrationResult, records_dir: str | os.PathLike[str] | None = None
) -> list[str]:
    """[] when the model fits; else the words of the command that finds what it lacks:
    ``python3 -m host model diagnose DIR`` on the records' directory ``records_dir`` (None: the
    word ``DIR``) with the result's model and term files, and the ``--noise``/``--floor`` its
    floor came from (the yardstick its fit was judged on)."""
    if not fit_story(result):
        return []
    words = ["python3", "-m", "host", "model", "diagnose"]
    words.append("DIR" if records_dir is None else str(records_dir))
    if result.model != "base":
        words += ["--model", result.model]
    for f in result.term_files:
        words += ["--term-file", f]
    for key in FLOOR_SOURCES:  # the same yardstick: the floor the fit was judged on
        if result.floor_source.get(key):
            words += [f"--{key}", result.floor_source[key]]
    return words


def next_command(
    result: CalibrationResult, records_dir: str | os.PathLike[str] | None = None
) -> str:
    """The :func:`next_words` as one line for a shell (each word quoted when it needs it);
    '' when the model fits."""
    return shlex.join(next_words(result, records_dir))


def _command(words: list[str], lead: str, indent: str, after: str = "") -> list[str]:
    """The command ``words`` after ``lead``, then ``after``: one line when it fits in 80
    columns, else ``after`` on the next line; a command too long for a line broken between
    its words with ``\\`` continuations (:func:`host.calib.commands.command_lines`), so that
    only a single word longer than a line (a path) can pass 80 columns, and it still runs when
    pasted."""
    cmd = shlex.join(words)
    if len(lead) + len(cmd) <= WIDTH:
        head = lead.strip()
        return _wrap(f"{head} {cmd} {after}", lead[: len(lead) - len(lead.lstrip())], indent,
                     (f"{head} {cmd}".strip(), after))  # fmt: skip
    lines = command_lines(words, WIDTH, lead=lead).split("\n")
    return lines + ([indent + after] if after else [])


def path_lines(label: str, paths: Sequence[str | os.PathLike[str]]) -> list[str]:
    """``label`` and the ``paths`` on one line (``A, B``) when it fits in 80 columns; else the
    label alone and each path whole on a line of its own, quoted for a shell when it needs it
    (a path with a space is then still one word to copy)."""
    one = f"{label} {', '.join(str(p) for p in paths)}"
    if len(one) <= WIDTH:
        return [one]
    return [label, *(f"  {shlex.quote(str(p))}" for p in paths)]


def verdict_line(
    result: CalibrationResult,
    report_path: str | os.PathLike[str],
    records_dir: str | os.PathLike[str] | None = None,
) -> str:
    """What a session or ``--from-dir`` ends on (lines ≤ 80 columns but for a word longer
    than a line, such as a path):
    when the model does not fit, the report's :func:`fit_story`; ``Report: PATH``; then the
    :func:`next_command` on the records' directory ``records_dir`` (None: the report's);
    the :func:`simulated_banner` when the records came from a virtual or emulated board;
    and last the verdict, the same line as the report's
    and the result file's (:func:`~host.calib.result_text.verdict_line`)."""
    out = _wrap(fit_story(result), "", "  ")
    out.extend(path_lines("Report:", [report_path]))
    nxt = next_words(result, Path(report_path).parent if records_dir is None else records_dir)
    if nxt:
        out.extend(_command(nxt, "Next: ", "  "))  # broken with \\: it runs when pasted
    out.extend(simulated_banner(result))
    out.extend(_wrap(result.verdict(), "", "  "))  # one line but for a FAIL of many reasons
    return "\n".join(out)


def write_results(
    result: CalibrationResult,
    directory: str | os.PathLike[str],
    records_dir: str | os.PathLike[str] | None = None,
    issue: Issue | None = None,
) -> tuple[Path, Path]:
    """Publish the report and the JSON result in ``directory`` together or not at all
    (:func:`host.session.atomic.write_texts_atomic`: the signed report and the file ``apply()``
    reads never disagree); returns the paths. ``records_dir``: where the records are, for the
    report's next command (None: ``directory``); ``issue``: as in :func:`format_report`.
    UserError names the file that failed."""
    txt, js = result_paths(directory, result.serial)
    where = directory if records_dir is None else records_dir
    write_texts_atomic({txt: format_report(result, where, issue), js: result_to_json(result)})
    return txt, js
