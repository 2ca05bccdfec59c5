"""The test report as a PDF a lab can file: ``SERIAL_result.pdf`` beside ``SERIAL_result.txt``.

The pages are the text report itself (:func:`host.calib.report.format_report`, set in a
monospaced font on A4, so the PDF and the text never say different things), then one page of
residual plots in the order the records were measured (method.md §8, residual analysis):
the static records' accelerometer and gyro residual means with their ±2σ of white noise
(std/√N), and the turns' integral residuals. Drawn with matplotlib's PDF backend (the
``plot`` extra); without matplotlib no PDF is written and :func:`write_report_pdf` says why.
``calibrate --pdf`` writes it (a few seconds of drawing, so not unasked).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from host.calib.report import format_report, measured_order
from host.calib.result import CalibrationResult
from host.errors import UserError, write_error
from host.session.inputs import written_serial

#: A4 portrait, inches; text lines per page at the font size below
A4 = (8.27, 11.69)
LINES_PER_PAGE = 88
FONT_PT = 7.0


def text_pages(lines: list[str], per_page: int = LINES_PER_PAGE) -> list[list[str]]:
    """The report's lines cut into pages of at most ``per_page``, each cut after a rule
    (a line of '-') where one falls in the page's second half, so sections stay whole."""
    pages: list[list[str]] = []
    rest = list(lines)
    while len(rest) > per_page:
        cut = per_page
        rules = [i + 1 for i, ln in enumerate(rest[:per_page]) if ln.startswith("-----")]
        if rules and rules[-1] >= per_page // 2:
            cut = rules[-1]
        pages.append(rest[:cut])
        rest = rest[cut:]
    return [*pages, rest] if rest else pages


def pdf_path(txt_path: str | os.PathLike[str]) -> Path:
    """``SERIAL_result.pdf`` beside ``SERIAL_result.txt``."""
    return Path(txt_path).with_suffix(".pdf")


def write_report_pdf(
    result: CalibrationResult,
    path: str | os.PathLike[str],
    records_dir: str | os.PathLike[str] | None = None,
) -> Path:
    """Write the report of ``result`` as a PDF to ``path`` (atomically: a reader never sees
    half a file; ``records_dir`` as in :func:`host.calib.report.format_report`); returns the
    path. UserError when matplotlib is missing or the file cannot be written."""
    try:
        from matplotlib.backends.backend_pdf import PdfPages
    except ImportError:
        raise UserError(
            "no PDF report: matplotlib is not installed (pip install 'imu-bench[plot]')"
        ) from None
    out = Path(path)
    tmp = out.with_name(f".{out.name}.tmp")
    lines = format_report(result, records_dir).splitlines()
    title = f"Test report, serial No. {written_serial(result.serial)}"
    if result.simulated:
        title = f"{title} ({result.simulated_line})"
    meta = {"Title": title, "Author": "imu-bench", "Subject": "IMU calibration (method.md §7)"}
    try:
        with PdfPages(tmp, metadata=meta) as pdf:
            for page in text_pages(lines):
                pdf.savefig(_text_page(page, result))
            pdf.savefig(_residual_page(result))
        os.replace(tmp, out)
    except OSError as exc:
        tmp.unlink(missing_ok=True)
        raise write_error(out, exc, "the text report and the JSON are written") from exc
    return out


def _text_page(lines: list[str], result: CalibrationResult) -> object:
    from matplotlib.figure import Figure

    fig = Figure(figsize=A4)
    fig.text(0.07, 0.965, "\n".join(lines), family="DejaVu Sans Mono", size=FONT_PT,
             va="top", ha="left", parse_math=False, linespacing=1.25)  # fmt: skip
    if result.simulated:  # on every page, as on the screen: not a unit
        fig.text(0.5, 0.985, f"*** {result.simulated_line} ***", ha="center", va="top",
                 size=8, color="firebrick", parse_math=False)  # fmt: skip
    return fig


def _residual_page(result: CalibrationResult) -> object:
    """Three panels: static accel and gyro residual means (±2σ of white noise) and the turns'
    integral residuals, records in the order measured."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=A4)
    axs = fig.subplots(3, 1)
    fig.suptitle(
        "Residuals (measured − model) in the order measured, serial No. "
        + written_serial(result.serial),
        size=10,
    )
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
            if what == "turn":
                y = np.array([r.angle_deg[k] if r.angle_deg else np.nan for r in recs])
                err = None
            else:
                mean = [r.accel_mean if what == "accel" else r.gyro_mean for r in recs]
                std = [r.accel_std if what == "accel" else r.gyro_std for r in recs]
                y = np.array([m[k] for m in mean], dtype=np.float64)
                err = 2 * np.array(
                    [s[k] / np.sqrt(max(r.n, 1)) for s, r in zip(std, recs, strict=True)]
                )
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
    fig.subplots_adjust(hspace=0.75, top=0.93, bottom=0.08)
    return fig
