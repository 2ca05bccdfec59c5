"""What makes the test report a calibration certificate (ISO/IEC 17025 §7.8): its parts.

The result says what was measured; a certificate also says who issued it, for whom, by which
method, when, under which conditions, how every reference is traceable, and who signs it.
:class:`Issue` carries what is not in the result — the laboratory's bench file
(:mod:`host.calib.bench_file`), the customer, where the site came from, the time of issue —
and the functions below give each part as the report's lines (:mod:`host.calib.report` puts
them in its sections, :mod:`host.calib.report_pdf` in its tables). Whatever is not known is
said to be not known: no laboratory without a bench file, no silent default site.

The report number is the bench id, the serial and the UTC time of issue to the millisecond
(``B1-DEMO01-20261126T212605.123Z``): one bench issues one report per serial at a time (the
output directory is locked while it is written), so two reports never share a number.
"""

from __future__ import annotations

import datetime as dt
from dataclasses import dataclass

from host.calib.bench_file import BenchFile, Check
from host.calib.report_lines import wrap
from host.calib.result import CalibrationResult
from host.session.inputs import written_serial

#: where a site value came from (:attr:`Issue.site_from`)
FROM_OPTIONS, FROM_BENCH_FILE, FROM_DEFAULT = "command line", "bench file", "default"
NO_BENCH = "NOBENCH"
METHOD_DOCUMENT = '"The calibration method this project implements" (method.md)'
RELATES_ONLY = "The results relate only to the item calibrated."
TRACEABILITY = "CONDITIONS AND TRACEABILITY OF THE REFERENCES"
NOT_KNOWN_LAB = "not known (no bench file: calibrate --bench-file FILE, docs/bench-file.md)"


@dataclass(frozen=True)
class Issue:
    """A certificate's facts beyond its result: the laboratory's ``bench`` file (None: none
    given), the ``customer`` (None: not given), where the site's latitude and height came from
    (``site_from``: one of :data:`FROM_OPTIONS`, :data:`FROM_BENCH_FILE`, :data:`FROM_DEFAULT`
    each; None: not recorded, e.g. a report made again from a result file), and the time of
    issue (``issued``: ISO UTC; '' the result's computation time)."""

    bench: BenchFile | None = None
    customer: str | None = None
    site_from: tuple[str, str] | None = None
    issued: str = ""


def issue_now() -> str:
    """The time of issue: now, UTC, to the millisecond (ISO)."""
    return dt.datetime.now(dt.UTC).isoformat(timespec="milliseconds")


def issued_at(result: CalibrationResult, issue: Issue) -> dt.datetime:
    """When the report is issued, UTC: ``issue.issued``, else the result's computation."""
    text = issue.issued or result.created
    try:
        t = dt.datetime.fromisoformat(text)
    except ValueError:
        return dt.datetime(1970, 1, 1, tzinfo=dt.UTC)
    return (t if t.tzinfo is not None else t.astimezone()).astimezone(dt.UTC)


def bench_id(result: CalibrationResult, issue: Issue) -> str:
    """The bench: the bench file's id, else the records' bench (one), else ''."""
    if issue.bench is not None:
        return issue.bench.bench_id
    benches = result.provenance.benches if result.provenance is not None else ()
    return benches[0] if len(benches) == 1 else ""


def report_number(result: CalibrationResult, issue: Issue) -> str:
    """Bench id, serial and UTC time of issue to the millisecond: unique per bench and unit
    (module docstring); without a bench id it starts with :data:`NO_BENCH`."""
    t = issued_at(result, issue)
    stamp = t.strftime("%Y%m%dT%H%M%S") + f".{t.microsecond // 1000:03d}Z"
    bench = "".join(c if c.isalnum() else "_" for c in bench_id(result, issue)) or NO_BENCH
    return f"{bench}-{written_serial(result.serial)}-{stamp}"


def page_header(number: str, serial: str, page: int, pages: int) -> str:
    """The line on every page: the report number and 'page i of n'."""
    return f"Report No. {number}, serial No. {written_serial(serial)}, page {page} of {pages}"


def _dates(result: CalibrationResult) -> str:
    """The calibration's dates: the records' first and last start date."""
    pv = result.provenance
    if pv is None or not pv.measured_from:
        return "not known (the records carry no start time)"
    first, last = pv.measured_from[:10], pv.measured_to[:10] or pv.measured_from[:10]
    return first if first == last else f"{first} to {last}"


def laboratory(issue: Issue) -> str:
    """'Example Lab, 1 Example Street, Town' or not known."""
    b = issue.bench
    return NOT_KNOWN_LAB if b is None else f"{b.lab_name}, {b.lab_address}"


def customer(issue: Issue) -> str:
    return issue.customer or "not known (calibrate --customer not given)"


def method_text(result: CalibrationResult) -> str:
    """The method document and the parts of it these records followed."""
    kinds = {res.kind for res in result.residuals}
    parts = []
    if "static" in kinds:
        parts.append("static orientations on the levelled plate (§3)")
    if "turn" in kinds:
        parts.append("hand turns by the integral method (§4)")
    if kinds & {"pose", "move"}:
        parts.append("poses held by hand and the moves between them (docs/calibration.md)")
    if "rate" in kinds:
        parts.append("rate-table records (§8)")
    done = "; ".join(parts) or "no records"
    return f"{METHOD_DOCUMENT}: {done}; {result.method}"


def head_items(result: CalibrationResult, issue: Issue) -> list[tuple[str, str]]:
    """The certificate's facts under its number, (label, text): laboratory, bench, customer,
    the item, the method, the dates of calibration and of issue."""
    sensor = "MPU-6000" if result.provenance is None else result.provenance.sensor
    issued = issued_at(result, issue).strftime("%Y-%m-%d %H:%M:%S UTC")
    return [
        ("Laboratory", laboratory(issue)),
        ("Bench", bench_id(result, issue) or "not known"),
        ("Customer", customer(issue)),
        ("Item", f"IMU {sensor}, serial No. {written_serial(result.serial)}"),
        ("Method", method_text(result)),
        ("Date of calibration", _dates(result)),
        ("Date of issue", issued),
    ]


def head_lines(result: CalibrationResult, issue: Issue) -> list[str]:
    """The number (page 1 of n) and :func:`head_items`, a line each."""
    out = [page_header(report_number(result, issue), result.serial, 1, 1)]
    for label, text in head_items(result, issue):
        out += wrap(f"{label}: {text}", "", "  ")
    return out


def site_text(result: CalibrationResult, issue: Issue) -> str:
    """Where g came from: Helmert's formula at the site, and where the site came from; the
    default site is never used without saying so."""
    lat, h = f"latitude {result.latitude_deg:.3f}°", f"height {result.height_m:.0f} m"
    where = issue.site_from
    if where is None:
        return f"Helmert formula, {lat}, {h}; where the site came from is not recorded"
    if where == (FROM_DEFAULT, FROM_DEFAULT):
        return (f"Helmert formula; site not given: default {lat}, {h} (the source documents' "
                "bench, not this one), so g is not known for this bench")  # fmt: skip
    if where[0] == where[1]:  # both from one place
        said = [f"{lat}, {h} " + ("from the bench file" if where[0] == FROM_BENCH_FILE
                                  else "as given (--latitude, --height)")]  # fmt: skip
    else:
        said = [_site_part(*part) for part in zip(("latitude", "height"), (lat, h), where,
                                                  strict=True)]  # fmt: skip
    text = f"Helmert formula, {', '.join(said)}"
    if FROM_BENCH_FILE in where and issue.bench is not None:
        s = issue.bench.site
        text += f"; site source: {s.source}" + (f", checked {s.checked}" if s.checked else "")
    return text


def _site_part(name: str, value: str, source: str) -> str:
    """'latitude 52.520° (--latitude)', '… (bench file)', 'height not given: default …'."""
    if source == FROM_DEFAULT:
        return f"{name} not given: default {value}"
    return f"{value} ({'--' + name if source == FROM_OPTIONS else 'bench file'})"


def _check(c: Check | None) -> str:
    if c is None:
        return "not known (no bench file)"
    return f"{c.value:g} {c.unit}, last checked {c.checked} with {c.by} (bench file)"


def traceability_items(result: CalibrationResult, issue: Issue) -> list[tuple[str, str]]:
    """The conditions the values hold at and how each reference of the bench is known,
    (label, text): temperature, g, the turn angle, the plate's level, the cube."""
    pv = result.provenance
    temp = (
        f"chip {pv.temp_c[0]:.1f} to {pv.temp_c[1]:.1f} °C" if pv is not None and pv.temp_c
        else "chip temperature not measured"
    )  # fmt: skip
    n = "n" if result.turns is None else str(result.turns)
    sigma = result.noise_model.get("turn_angle_sigma_deg")
    sig = f"; its σ {sigma:g}° per turn is in the fit's weights, so in U" if sigma else ""
    b = issue.bench
    return [
        ("Temperature", f"{temp}; ambient temperature, humidity, pressure not measured"),
        ("g", f"{result.g:.5f} m/s²: {site_text(result, issue)}; not measured with a gravimeter"),
        (
            "Turn angle",
            f"n·360° (n = {n}) by the operator's count of whole turns, the cube "
            f"returned against the ruler; no angle standard{sig}",
        ),  # fmt: skip
        ("Plate level", _check(None if b is None else b.plate)),
        ("Cube squareness", _check(None if b is None else b.cube)),
    ]


def traceability_lines(result: CalibrationResult, issue: Issue) -> list[str]:
    """CONDITIONS AND TRACEABILITY: :func:`traceability_items`, a line each."""
    out = [TRACEABILITY]
    for label, text in traceability_items(result, issue):
        out += wrap(f"{label}{' =' if label == 'g' else ':'} {text}", "  ", "    ")
    return out


def signature_lines(issue: Issue) -> list[str]:
    """The authorised signatory (from the bench file) and the method's three roles, each with
    name, signature and date lines."""
    b = issue.bench
    who = "not known (no bench file)" if b is None else b.signatory + (
        f", {b.signatory_role}" if b.signatory_role else "")  # fmt: skip
    out = wrap(f"Authorised signatory: {who}", "", "  ")
    out += [f"{'':<27}_______________________  /________________/",
            f"{'':<27}{'signature':<25}date", ""]  # fmt: skip
    for role in ("Customer's representative", "Quality control", "Workshop"):
        out.append(f"{role:<27}_______________________  /________________/")
        out.append(f"{'':<27}{'name, signature':<25}date")
    return out
