"""The certificate as a typeset PDF a lab can sign: ``SERIAL_result.pdf`` beside the text report.

Set with reportlab on A4: a title block (the report number, laboratory, bench, customer, item,
method, the dates of calibration and of issue) as a table; the conditions and the traceability
of every reference as a table; the §7 results as a ruled table with units, tolerances, marks
and U (95 % coverage: k = 2, or Student's t on a σ's dof); the residuals per record as a table
and as plots (matplotlib figures embedded as images, the ``plot`` extra); the other sections
of :func:`host.calib.report.report_sections` as paragraphs; the signatures with name and date
lines. Every page has a header (laboratory, report number) and a footer ("page i of n", the
report number, and on a simulated board's result the SIMULATED mark). The words are the text
report's: both come from the same sections. ``calibrate --pdf`` writes it (a few seconds of
drawing, so not unasked).
"""

from __future__ import annotations

import io
import os
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from host.calib.certificate import (
    Issue,
    head_items,
    laboratory,
    report_number,
    traceability_items,
)
from host.calib.decision import statement
from host.calib.report import report_sections, result_rows
from host.calib.report_tables import measured_order, residual_cells
from host.calib.result import CalibrationResult
from host.errors import UserError, write_error
from host.session.inputs import written_serial

FONT, BOLD, MONO = "DejaVuSans", "DejaVuSans-Bold", "DejaVuSansMono"
#: sections set as tables (the others are paragraphs)
TABLED = ("head", "traceability", "results", "residuals", "signatures")
GRID = 0.5  # points: the tables' rules


def pdf_path(txt_path: str | os.PathLike[str]) -> Path:
    """``SERIAL_result.pdf`` beside ``SERIAL_result.txt``."""
    return Path(txt_path).with_suffix(".pdf")


def write_report_pdf(
    result: CalibrationResult,
    path: str | os.PathLike[str],
    records_dir: str | os.PathLike[str] | None = None,
    issue: Issue | None = None,
) -> Path:
    """Write the certificate of ``result`` as a PDF to ``path`` (atomically: a reader never
    sees half a file; ``records_dir`` and ``issue`` as in
    :func:`host.calib.report.format_report`); returns the path. UserError when reportlab or
    matplotlib is missing or the file cannot be written."""
    try:
        from reportlab.lib.pagesizes import A4
        from reportlab.lib.units import mm
        from reportlab.platypus import SimpleDocTemplate
    except ImportError:
        raise UserError(
            "no PDF report: reportlab is not installed (pip install reportlab)"
        ) from None
    iss = issue if issue is not None else Issue()
    _register_fonts()
    out = Path(path)
    tmp = out.with_name(f".{out.name}.tmp")
    number = report_number(result, iss)
    title = f"Calibration certificate {number}, serial No. {written_serial(result.serial)}"
    doc = SimpleDocTemplate(
        str(tmp), pagesize=A4, leftMargin=18 * mm, rightMargin=18 * mm, topMargin=22 * mm,
        bottomMargin=20 * mm, title=title, author=laboratory(iss), subject="IMU calibration",
    )  # fmt: skip
    story = _story(result, iss, records_dir)
    lab = "laboratory not known" if iss.bench is None else iss.bench.lab_name
    maker = _numbered_canvas(lab, number, result.simulated_line)
    try:
        doc.build(story, canvasmaker=maker)
        os.replace(tmp, out)
    except OSError as exc:
        tmp.unlink(missing_ok=True)
        raise write_error(out, exc, "the text report and the JSON are written") from exc
    return out


def _register_fonts() -> None:
    """DejaVu Sans (it has °, ±, −, σ, χ², ≤), from matplotlib's own fonts."""
    from reportlab.pdfbase import pdfmetrics
    from reportlab.pdfbase.ttfonts import TTFont

    if FONT in pdfmetrics.getRegisteredFontNames():
        return
    try:
        import matplotlib
    except ImportError:
        raise UserError(
            "no PDF report: matplotlib is not installed (pip install 'imu-bench[plot]')"
        ) from None
    ttf = Path(matplotlib.get_data_path()) / "fonts" / "ttf"
    for name in (FONT, BOLD, MONO):
        pdfmetrics.registerFont(TTFont(name, str(ttf / f"{name}.ttf")))


def _styles() -> dict[str, Any]:
    from reportlab.lib.colors import HexColor
    from reportlab.lib.styles import ParagraphStyle

    base = ParagraphStyle("body", fontName=FONT, fontSize=8.5, leading=11)
    return {
        "body": base,
        "cell": ParagraphStyle("cell", parent=base, fontSize=8, leading=10),
        "title": ParagraphStyle("title", parent=base, fontName=BOLD, fontSize=15, leading=19),
        "sub": ParagraphStyle("sub", parent=base, fontSize=10, leading=13),
        "h": ParagraphStyle(
            "h", parent=base, fontName=BOLD, fontSize=10, leading=13, spaceBefore=8, spaceAfter=3
        ),  # fmt: skip
        "mono": ParagraphStyle("mono", parent=base, fontName=MONO, fontSize=7, leading=8.6),
        "sim": ParagraphStyle("sim", parent=base, fontName=BOLD, textColor=HexColor("#b22222")),
    }


def _p(text: str, style: Any) -> Any:
    from xml.sax.saxutils import escape

    from reportlab.platypus import Paragraph

    return Paragraph(escape(text), style)


def _story(
    result: CalibrationResult, issue: Issue, records_dir: str | os.PathLike[str] | None
) -> list[Any]:
    """The flowables: each section of the report, as a table where it is one."""
    st = _styles()
    story: list[Any] = []
    setters: dict[str, Callable[[], list[Any]]] = {
        "head": lambda: _title_block(result, issue, st),
        "traceability": lambda: _traceability(result, issue, st),
        "results": lambda: _results(result, st),
        "residuals": lambda: _residuals(result, st),
        "signatures": lambda: _signatures(lines, st),
    }
    for key, lines in report_sections(result, records_dir, issue):
        if key == "head":
            story += setters[key]() + _paragraphs(lines[_head_end(lines) :], st, heading=False)
        elif key in setters:
            story += setters[key]()
        else:
            story += _paragraphs(lines, st)
    return story


def _head_end(lines: list[str]) -> int:
    """Where the text head's own lines (measured, computed, g, verdict) begin: after the
    certificate's items the title block holds."""
    return next(i for i, ln in enumerate(lines) if ln.startswith("Measured:"))


def _table(
    rows: list[list[Any]],
    widths: list[float],
    head: int = 1,
    extra: Sequence[tuple[Any, ...]] = (),
    heights: list[float] | None = None,
) -> Any:
    """A ruled table: a grid of thin rules, the first ``head`` rows shaded."""
    from reportlab.lib.colors import HexColor, black
    from reportlab.platypus import Table, TableStyle

    style = [
        ("GRID", (0, 0), (-1, -1), GRID, black),
        ("FONT", (0, 0), (-1, -1), FONT, 8),
        ("VALIGN", (0, 0), (-1, -1), "TOP"),
        ("TOPPADDING", (0, 0), (-1, -1), 1.5),
        ("BOTTOMPADDING", (0, 0), (-1, -1), 1.5),
        *([("BACKGROUND", (0, 0), (-1, head - 1), HexColor("#e8e8e8")),
           ("FONT", (0, 0), (-1, head - 1), BOLD, 8)] if head else []),
        *extra,
    ]  # fmt: skip
    t = Table(rows, colWidths=widths, rowHeights=heights, repeatRows=head)
    t.setStyle(TableStyle(style))
    return t


def _title_block(result: CalibrationResult, issue: Issue, st: dict[str, Any]) -> list[Any]:
    """Title, the simulated mark, and the certificate's facts as a two-column table."""
    from reportlab.lib.units import mm
    from reportlab.platypus import Spacer

    pv = result.provenance
    sensor = "MPU-6000" if pv is None else pv.sensor
    out = [
        _p("CALIBRATION CERTIFICATE", st["title"]),
        _p(f"Test report, IMU {sensor}, serial No. {written_serial(result.serial)}", st["sub"]),
    ]
    if result.simulated_line:
        out.append(_p(f"*** {result.simulated_line} ***", st["sim"]))
    out.append(Spacer(1, 3 * mm))
    rows = [[_p("Report No.", st["cell"]), _p(report_number(result, issue), st["cell"])]]
    rows += [[_p(k, st["cell"]), _p(v, st["cell"])] for k, v in head_items(result, issue)]
    out += [_table(rows, [38 * mm, 136 * mm], head=0), Spacer(1, 2 * mm)]
    return out


def _traceability(result: CalibrationResult, issue: Issue, st: dict[str, Any]) -> list[Any]:
    from reportlab.lib.units import mm

    rows = [[_p("reference or condition", st["cell"]), _p("value and how it is known", st["cell"])]]
    rows += [[_p(k, st["cell"]), _p(v, st["cell"])] for k, v in traceability_items(result, issue)]
    return [_p("Conditions and traceability of the references", st["h"]),
            _table(rows, [38 * mm, 136 * mm])]  # fmt: skip


def _results(result: CalibrationResult, st: dict[str, Any]) -> list[Any]:
    """The §7 table: a row per value, a spanning row per group."""
    from reportlab.lib.units import mm

    rows: list[list[Any]] = [["value", "measured", "unit", "tolerance", "mark", "U (95 %)",
                              "note"]]  # fmt: skip
    extra: list[tuple[Any, ...]] = [("ALIGN", (1, 1), (1, -1), "RIGHT"),
                                    ("ALIGN", (3, 1), (5, -1), "RIGHT")]  # fmt: skip
    for title, group in result_rows(result):
        extra += [("SPAN", (0, len(rows)), (-1, len(rows))),
                  ("FONT", (0, len(rows)), (-1, len(rows)), BOLD, 8)]  # fmt: skip
        rows.append([title, "", "", "", "", "", ""])
        rows += [list(r) for r in group]
    widths = [w * mm for w in (20, 24, 18, 20, 12, 24, 30)]
    return [
        _p("Results: value, tolerance, mark (decision rule below) and U, the expanded "
           "uncertainty at 95 % coverage, k = 2 (Student's t where the note gives a dof)",
           st["h"]),
        _p(statement(result.decision_rule), st["body"]),
        _table(rows, widths, extra=extra),
    ]  # fmt: skip


def _residuals(result: CalibrationResult, st: dict[str, Any]) -> list[Any]:
    """The residuals per record as a table, then their plots."""
    from reportlab.lib.units import mm
    from reportlab.platypus import Image

    head = ["record", "sit", "at, s", "T, s", "accel x", "y", "z, m/s²", "gyro x", "y",
            "z, °/s (turns °)"]  # fmt: skip
    rows: list[list[Any]] = [head, *residual_cells(result)]
    widths = [w * mm for w in (20, 9, 13, 11, 17, 17, 17, 17, 17, 26)]
    png = io.BytesIO()
    residual_figure(result).savefig(png, format="png", dpi=130)
    png.seek(0)
    return [
        _p("Residuals per record in the order measured (measured − model): mean and std of "
           "the samples; turns: integral residual, degrees", st["h"]),
        _table(rows, widths, extra=[("ALIGN", (1, 1), (-1, -1), "RIGHT")]),
        _p("Residual plots", st["h"]),
        Image(png, width=174 * mm, height=174 * mm * 11.69 / 8.27 * 0.62),
    ]  # fmt: skip


def _signatures(lines: list[str], st: dict[str, Any]) -> list[Any]:
    """The signatory and the method's roles: a row each with name, signature and date."""
    from reportlab.lib.units import mm
    from reportlab.platypus import KeepTogether

    who = lines[0].removeprefix("Authorised signatory: ")
    rows: list[list[Any]] = [["role", "name", "signature", "date"],
                             ["Authorised signatory", _p(who, st["cell"]), "", ""]]  # fmt: skip
    roles = ("Customer's representative", "Quality control", "Workshop")
    rows += [[role, "", "", ""] for role in roles]
    t = _table(rows, [44 * mm, 50 * mm, 50 * mm, 30 * mm],
               heights=[6 * mm] + [11 * mm] * (len(rows) - 1))  # fmt: skip
    return [KeepTogether([_p("Signatures", st["h"]), t])]


def _paragraphs(lines: list[str], st: dict[str, Any], heading: bool = True) -> list[Any]:
    """A section of the text report as paragraphs: its first line its heading (``heading``),
    its wrapped lines joined again (a line indented deeper than the one before continues it;
    a command's ``\\`` too), and lines laid out in columns in a fixed-width font."""
    out: list[Any] = []
    if heading and lines and not lines[0].startswith(" "):
        out.append(_p(lines[0].capitalize() if lines[0].isupper() else lines[0], st["h"]))
        lines = lines[1:]
    para: list[str] = []
    indent = 0

    def flush() -> None:
        if para:
            out.append(_p(" ".join(para), st["body"]))
            para.clear()

    for ln in lines:
        text, lead = ln.strip(), len(ln) - len(ln.lstrip())
        if not text:
            continue
        if para and lead > indent and "  " not in text:
            para.append(text.removesuffix("\\").strip())
            continue
        flush()
        indent = lead
        if "  " in text:
            out.append(_p(ln, st["mono"]))
        else:
            para.append(text.removesuffix("\\").strip())
    flush()
    return out


def _numbered_canvas(lab: str, number: str, simulated: str) -> type:
    """A canvas that draws the header and footer on every page once it knows how many pages
    there are ("page i of n": the pages are kept until the document is saved)."""
    from reportlab.lib.colors import HexColor
    from reportlab.lib.pagesizes import A4
    from reportlab.lib.units import mm
    from reportlab.pdfgen.canvas import Canvas

    class NumberedCanvas(Canvas):
        def __init__(self, *args: Any, **kwargs: Any) -> None:
            super().__init__(*args, **kwargs)
            self._pages: list[dict[str, Any]] = []

        def showPage(self) -> None:  # noqa: N802 (reportlab's name)
            self._pages.append(dict(self.__dict__))
            self._startPage()

        def save(self) -> None:
            n = len(self._pages)
            for i, state in enumerate(self._pages, 1):
                self.__dict__.update(state)
                self._frame(i, n)
                super().showPage()
            super().save()

        def _frame(self, i: int, n: int) -> None:
            w, h = A4
            self.setFont(FONT, 7.5)
            self.drawString(18 * mm, h - 12 * mm, lab[:110])
            self.drawRightString(w - 18 * mm, h - 12 * mm, f"Report No. {number}")
            self.line(18 * mm, h - 14 * mm, w - 18 * mm, h - 14 * mm)
            self.line(18 * mm, 14 * mm, w - 18 * mm, 14 * mm)
            self.drawString(18 * mm, 10 * mm, f"Report No. {number}")
            self.drawRightString(w - 18 * mm, 10 * mm, f"page {i} of {n}")
            if simulated:
                self.setFillColor(HexColor("#b22222"))
                self.drawCentredString(w / 2, 6 * mm, f"*** {simulated} ***"[:120])

    return NumberedCanvas


def residual_figure(result: CalibrationResult) -> Any:
    """Three panels: static accel and gyro residual means (±2σ of white noise, std/√N) and
    the turns' integral residuals, records in the order measured (a matplotlib figure)."""
    import numpy as np
    from matplotlib.figure import Figure

    fig = Figure(figsize=(8.27, 11.69 * 0.62))
    axs = fig.subplots(3, 1)
    ordered = measured_order(result)
    statics = [r for r in ordered if r.kind != "turn"]
    turns = [r for r in ordered if r.kind == "turn" and r.angle_deg is not None]
    panels = (
        (axs[0], statics, "accel", "static records: accelerometer residual mean, m/s²"),
        (axs[1], statics, "gyro", "static records: gyro residual mean, °/s"),
        (axs[2], turns, "turn", "turn records: integral residual, °"),
    )
    for ax, recs, what, label in panels:
        x = np.arange(len(recs), dtype=np.float64)
        for k, (axis, colour) in enumerate(zip("xyz", ("C0", "C1", "C2"), strict=True)):
            y, err = _panel_values(recs, what, k)
            ax.errorbar(x + (k - 1) * 0.15, y, yerr=err, fmt="o", ms=3, color=colour,
                        capsize=2, label=axis)  # fmt: skip
        ax.axhline(0.0, color="0.5", lw=0.8)
        ax.set_title(label, size=9, loc="left")
        ax.set_xticks(x, [r.record for r in recs], rotation=60, size=7)
        ax.tick_params(axis="y", labelsize=7)
        ax.legend(fontsize=7, ncols=3, loc="upper right")
        ax.grid(alpha=0.3)
        if not recs:
            ax.text(0.5, 0.5, "no records of this kind", ha="center", transform=ax.transAxes)
    fig.text(0.07, 0.01, "error bars: ±2σ of a record mean from its white noise (std/√N)",
             size=7, parse_math=False)  # fmt: skip
    fig.subplots_adjust(hspace=0.85, top=0.96, bottom=0.1)
    return fig


def _panel_values(recs: list[Any], what: str, k: int) -> tuple[Any, Any]:
    """Channel ``k``'s residual of each record, and its ±2σ (None for turns)."""
    import numpy as np

    if what == "turn":
        return np.array([r.angle_deg[k] if r.angle_deg else np.nan for r in recs]), None
    mean = [r.accel_mean if what == "accel" else r.gyro_mean for r in recs]
    std = [r.accel_std if what == "accel" else r.gyro_std for r in recs]
    y = np.array([m[k] for m in mean], dtype=np.float64)
    err = 2 * np.array([s[k] / np.sqrt(max(r.n, 1)) for s, r in zip(std, recs, strict=True)])
    return y, err
