"""The PDF report (issue 28): written by ``calibrate --pdf`` beside the text report, it holds
the same text (read back from the PDF with poppler's pdftotext) and a page of residual plots,
and renders (pdftoppm, as a reader's viewer would) to A4 pages with ink where the text and
the plotted points are."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from host.__main__ import main
from host.bench.plan import write_session
from host.calib.codec import read_result
from host.calib.report import format_report
from host.calib.report_pdf import LINES_PER_PAGE, text_pages
from host.workbench.scenarios import hidden_effect_case

pytest.importorskip("matplotlib")
POPPLER = shutil.which("pdftoppm") and shutil.which("pdftotext")
needs_poppler = pytest.mark.skipif(not POPPLER, reason="poppler-utils (.ci/setup installs it)")


@pytest.fixture(scope="module")
def published(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp("pdf")
    write_session(d, "PDF1", dict(hidden_effect_case("temperature", 4).records))
    assert main(["calibrate", "--from-dir", str(d), "--no-archive", "--pdf"]) in (0, 1)
    return d


def _png(pdf: Path, out: Path) -> list[Path]:
    subprocess.run(["pdftoppm", "-r", "50", "-png", str(pdf), str(out / "page")], check=True)
    return sorted(out.glob("page-*.png"))


@pytest.mark.slow
@needs_poppler
def test_the_pdf_holds_the_report_and_its_residual_plots(published: Path, tmp_path: Path) -> None:
    import matplotlib.image as mpimg

    pdf = published / "PDF1_result.pdf"
    assert pdf.is_file() and pdf.read_bytes()[:5] == b"%PDF-"
    res = read_result(published / "PDF1_result.json")
    report = format_report(res, published)  # the next command names the records
    assert report == (published / "PDF1_result.txt").read_text(encoding="utf-8").replace(
        res.created.replace("T", " "), res.created.replace("T", " ")
    )
    text = subprocess.run(["pdftotext", "-layout", str(pdf), "-"], check=True,
                          capture_output=True, text=True).stdout  # fmt: skip
    # the text pages say what the text report says, line by line (the mark, the values)
    for line in report.splitlines()[:12] + [
        ln for ln in report.splitlines() if ln.split()[:1] in (["Gxx"], ["A0z"], ["RESULT:"])
    ]:
        assert " ".join(line.split()) in " ".join(text.split()), line
    assert "SIMULATED BOARD simulator (source: sim)" in text
    assert "Residuals (measured − model) in the order measured" in text

    pages = _png(pdf, tmp_path)
    cut = text_pages(report.splitlines())
    assert [ln for page in cut for ln in page] == report.splitlines()
    assert all(len(page) <= LINES_PER_PAGE for page in cut)
    assert len(pages) == len(cut) + 1
    for page in pages:
        img = mpimg.imread(page)[..., :3]
        h, w = img.shape[:2]
        assert abs(h / w - 297 / 210) < 0.01  # A4 portrait
        assert (img.mean(axis=2) < 0.5).mean() > 0.003  # ink on every page
    first = mpimg.imread(pages[0])[..., :3]
    top = first[: first.shape[0] // 40]
    red = (top[..., 0] > 0.5) & (top[..., 1] < 0.35) & (top[..., 2] < 0.35)
    assert red.sum() > 20  # the red SIMULATED banner at the top
    plots = mpimg.imread(pages[-1])[..., :3]
    blue = np.abs(plots - np.array([0.12, 0.47, 0.71])).max(axis=2) < 0.12  # matplotlib's C0
    orange = np.abs(plots - np.array([1.0, 0.5, 0.05])).max(axis=2) < 0.12  # C1
    assert blue.sum() > 30 and orange.sum() > 30  # the plotted x and y residuals


def test_no_pdf_unless_asked(tmp_path: Path) -> None:
    write_session(tmp_path, "PDF2", dict(hidden_effect_case("temperature", 4).records))
    assert main(["calibrate", "--from-dir", str(tmp_path), "--no-archive"]) in (0, 1)
    assert not (tmp_path / "PDF2_result.pdf").exists()
    assert (tmp_path / "PDF2_result.txt").is_file()
