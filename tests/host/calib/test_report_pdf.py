"""The typeset PDF (issue 43) of a ``--from-dir`` recomputation without a bench file: it says
what is not known as the text report does, embeds the residual plots, marks a simulated
board's result on every page, and is written only when asked; without reportlab it is one
line saying what to install."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from host.__main__ import main
from host.bench.plan import write_session
from host.calib.codec import read_result
from host.calib.report_pdf import write_report_pdf
from host.errors import UserError
from host.workbench.scenarios import hidden_effect_case

pytest.importorskip("matplotlib")
pytest.importorskip("reportlab")
POPPLER = shutil.which("pdftoppm") and shutil.which("pdftotext")
needs_poppler = pytest.mark.skipif(not POPPLER, reason="poppler-utils (.ci/setup installs it)")


@pytest.fixture(scope="module")
def published(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp("pdf")
    write_session(d, "PDF1", dict(hidden_effect_case("temperature", 4).records))
    assert main(["calibrate", "--from-dir", str(d), "--no-archive", "--pdf"]) in (0, 1)
    return d


@pytest.mark.slow
@needs_poppler
def test_the_pdf_says_what_the_text_says_and_plots_the_residuals(
    published: Path, tmp_path: Path
) -> None:
    import matplotlib.image as mpimg

    pdf = published / "PDF1_result.pdf"
    assert pdf.is_file() and pdf.read_bytes()[:5] == b"%PDF-"
    report = (published / "PDF1_result.txt").read_text(encoding="utf-8")
    text = subprocess.run(["pdftotext", str(pdf), "-"], check=True, capture_output=True,
                          text=True).stdout  # fmt: skip
    flat = " ".join(text.split())
    for line in report.splitlines():  # the head's own lines and the verdict, word for word
        if line.startswith(("Measured:", "Computed:", "Verdict:", "RESULT:")):
            assert " ".join(line.split()) in flat, line
    for said in ("not known (no bench file)", "not known (calibrate --customer not given)",
                 "site not given: default latitude 55.750°", "Residual plots"):  # fmt: skip
        assert said in flat, said
    pages = text.rstrip("\f").split("\f")
    assert all("SIMULATED BOARD simulator (source: sim)" in page for page in pages)

    subprocess.run(["pdftoppm", "-r", "100", "-png", str(pdf), str(tmp_path / "p")], check=True)
    images = [mpimg.imread(p)[..., :3] for p in sorted(tmp_path.glob("p-*.png"))]
    assert len(images) == len(pages)
    red = [((im[..., 0] > 0.5) & (im[..., 0] - im[..., 1] > 0.3)).sum() for im in images]
    assert min(red) > 20  # the red SIMULATED mark on every page
    blue = [(np.abs(im - np.array([0.12, 0.47, 0.71])).max(axis=2) < 0.12).sum() for im in images]
    orange = [(np.abs(im - np.array([1.0, 0.5, 0.05])).max(axis=2) < 0.12).sum() for im in images]
    assert max(blue) > 30 and max(orange) > 30  # matplotlib's C0, C1: the x and y residuals


def test_no_pdf_unless_asked(tmp_path: Path) -> None:
    write_session(tmp_path, "PDF2", dict(hidden_effect_case("temperature", 4).records))
    assert main(["calibrate", "--from-dir", str(tmp_path), "--no-archive"]) in (0, 1)
    assert not (tmp_path / "PDF2_result.pdf").exists()
    assert (tmp_path / "PDF2_result.txt").is_file()


@pytest.mark.slow
def test_without_reportlab_one_line_says_what_to_install(
    published: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    res = read_result(published / "PDF1_result.json")
    for name in [m for m in sys.modules if m == "reportlab" or m.startswith("reportlab.")]:
        monkeypatch.delitem(sys.modules, name)
    monkeypatch.setitem(sys.modules, "reportlab", None)
    with pytest.raises(UserError, match=r"reportlab is not installed \(pip install reportlab\)"):
        write_report_pdf(res, tmp_path / "x.pdf")
    assert not (tmp_path / "x.pdf").exists()
