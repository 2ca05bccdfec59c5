"""The report as a calibration certificate (issue 43, ISO/IEC 17025 §7.8): every item read
from the report of a live ``sim://`` session with a bench file, in the text and in the PDF's
text (poppler's pdftotext), with the report number and "page i of n" on every page; a rendered
page holds ruled tables; two reports never share a number; and what is not known is said to
be not known — the default site above all."""

from __future__ import annotations

import dataclasses
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from host.__main__ import main
from host.calib.bench_file import load_bench_file
from host.calib.calibration import CalibrationOptions, calibrate_from_records
from host.calib.certificate import (
    FROM_BENCH_FILE,
    FROM_DEFAULT,
    FROM_OPTIONS,
    RELATES_ONLY,
    Issue,
    report_number,
)
from host.calib.codec import read_result
from host.calib.decision import coverage_factor
from host.calib.report import format_report
from host.calib.report_lines import FORM_FEED, PAGE_LINES
from host.calib.result import CalibrationResult
from host.session.directory import Session, read_session
from tests.host.cli.cli_run import run, too_wide

try:
    from calib_truth import make_records
except ImportError:  # tests/ imported as a package
    from tests.host.calib_truth import make_records

EXAMPLE = Path(__file__).resolve().parents[3] / "docs" / "examples" / "bench.toml"
POPPLER = shutil.which("pdftoppm") and shutil.which("pdftotext")
needs_poppler = pytest.mark.skipif(not POPPLER, reason="poppler-utils (.ci/setup installs it)")
LIVE = ["--port", "sim://?speed=max", "--serial", "C2", "--yes", "--warmup", "0",
        "--static-seconds", "3", "--turns", "1", "--no-archive"]  # fmt: skip
CUSTOMER = "ACME Drones Ltd, 5 Rotor Lane"


@pytest.fixture(scope="module")
def result() -> CalibrationResult:
    options = CalibrationOptions(created="2026-11-30T10:00:00+01:00")
    return calibrate_from_records(Session("CERT1", make_records(seed=5)), options)


def _pages(text: str) -> list[list[str]]:
    """The report's pages: split at the form feeds."""
    return [page.strip("\n").split("\n") for page in text.split(FORM_FEED)]


def _number_and_pages(pages: list[list[str]], number: str) -> None:
    """Every page has the number and 'page i of n', on its own header line."""
    n = len(pages)
    for i, page in enumerate(pages, 1):
        header = f"Report No. {number}, serial No. "
        heads = [ln for ln in page if ln.startswith(header) and ln.endswith(f"page {i} of {n}")]
        assert len(heads) == 1, (i, page[:3])
        assert len(page) <= PAGE_LINES


def test_what_is_not_known_is_said_to_be_not_known(result: CalibrationResult) -> None:
    text = format_report(result, issue=Issue(site_from=(FROM_DEFAULT, FROM_DEFAULT)))
    flat = " ".join(text.split())
    assert "Laboratory: not known (no bench file" in flat
    assert "Customer: not known (calibrate --customer not given)" in flat
    assert "Plate level: not known (no bench file)" in flat
    assert "Cube squareness: not known (no bench file)" in flat
    assert "Authorised signatory: not known (no bench file)" in flat
    # the default site is never used silently: the head's g line and the traceability say so
    said = "site not given: default latitude 55.750°, height 150 m"
    assert flat.count(said) == 2 and "g is not known for this bench" in flat
    assert RELATES_ONLY in text and too_wide(text) == []
    number = report_number(result, Issue())
    assert number == "NOBENCH-CERT1-20261130T090000.000Z"  # the computation's time, in UTC
    pages = _pages(text)
    assert len(pages) >= 2
    _number_and_pages(pages, number)


def test_a_site_given_in_part_says_which_part_is_the_default(result: CalibrationResult) -> None:
    r = dataclasses.replace(result, latitude_deg=48.5)
    text = " ".join(format_report(r, issue=Issue(site_from=(FROM_OPTIONS, FROM_DEFAULT))).split())
    assert "latitude 48.500° (--latitude), height not given: default height 150 m" in text
    bench = load_bench_file(EXAMPLE)
    text = " ".join(format_report(r, issue=Issue(bench=bench, site_from=(FROM_OPTIONS,
                                  FROM_BENCH_FILE))).split())  # fmt: skip
    assert "latitude 48.500° (--latitude), height 150 m (bench file)" in text
    assert f"site source: {bench.site.source}" in text and "default" not in text


def test_two_reports_of_one_unit_never_share_a_number(result: CalibrationResult) -> None:
    bench = load_bench_file(EXAMPLE)
    first = Issue(bench=bench, issued="2026-11-30T09:00:00.001+00:00")
    later = dataclasses.replace(first, issued="2026-11-30T09:00:00.002+00:00")
    a, b = report_number(result, first), report_number(result, later)
    assert a == "B1-CERT1-20261130T090000.001Z" and a != b
    other = dataclasses.replace(result, serial="CERT2")
    assert report_number(other, first) != a  # another unit at the same time on the bench
    assert f"Report No. {a}," in format_report(result, issue=first)


@pytest.fixture(scope="module")
def live(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A live session on the virtual board with the example bench file and a customer, and
    its PDF."""
    d = tmp_path_factory.mktemp("cert") / "C2"
    argv = ["calibrate", *LIVE, "--out", str(d), "--bench-file", str(EXAMPLE),
            "--customer", CUSTOMER, "--pdf"]  # fmt: skip
    assert main(argv) in (0, 1)
    return d


def _items(res: CalibrationResult, records: Path, sep: str) -> list[str]:
    """Every §7.8 item the report of ``res`` (of the records in ``records``) must hold, as
    phrases; ``sep``: what follows a label (': ' in the text, ' ' in a table's cells)."""
    bench = load_bench_file(EXAMPLE)
    recs = read_session(records).records
    temps = np.concatenate([r.temp for r in recs.values()])
    starts = sorted(r.meta["start_time"] for r in recs.values())
    gxx = res.parameter("Gxx")
    return [
        bench.lab_name, bench.lab_address,  # the laboratory
        "Bench", bench.bench_id,
        CUSTOMER,  # the customer and the unit
        f"IMU {res.provenance.sensor if res.provenance else ''}, serial No. C2",
        "The calibration method this project implements", "method.md",  # the method
        f"Date of calibration{sep}{starts[0][:10]}",
        "Date of issue",
        f"{gxx.value:+.5f}", f"±{coverage_factor(gxx.dof) * gxx.stderr:.5f}", "U (95 %)",
        "±0.03",  # results, U
        f"chip {temps.min():.1f} to {temps.max():.1f} °C",  # conditions
        f"{res.g:.5f} m/s²", "from the bench file", bench.site.source,  # g and its source
        "n·360° (n = 1) by the operator's count of whole turns",  # the turn angle
        f"{bench.plate.value:g} mrad, last checked {bench.plate.checked}",  # the plate
        f"{bench.cube.value:g} mrad, last checked {bench.cube.checked}",  # the cube
        RELATES_ONLY,
        f"{bench.signatory}, {bench.signatory_role}",  # the authorised signatory
        "signature", "date",
    ]  # fmt: skip


@pytest.mark.slow
@needs_poppler
def test_every_item_of_a_certificate_in_the_text_and_the_pdf(live: Path, tmp_path: Path) -> None:
    res = read_result(live / "C2_result.json")
    text = (live / "C2_result.txt").read_text(encoding="utf-8")
    number = re.search(r"^Report No\. (\S+),", text, re.M)
    assert number is not None and number.group(1).startswith("B1-C2-")
    number_s = number.group(1)
    flat = " ".join(text.split())
    for item in _items(res, live, ": "):
        assert " ".join(item.split()) in flat, item
    _number_and_pages(_pages(text), number_s)
    assert too_wide(text) == []

    pdf = live / "C2_result.pdf"
    out = subprocess.run(["pdftotext", str(pdf), "-"], check=True, capture_output=True,
                         text=True).stdout  # fmt: skip
    pages = out.rstrip("\f").split("\f")
    pdf_flat = " ".join(out.split())
    assert "CALIBRATION CERTIFICATE" in pdf_flat
    for item in _items(res, live, " "):
        assert " ".join(item.split()) in pdf_flat, item
    assert len(pages) >= 2
    for i, page in enumerate(pages, 1):  # the number and page i of n on every page
        assert f"page {i} of {len(pages)}" in page and f"Report No. {number_s}" in page, i
    assert "SIMULATED BOARD" in pages[-1]  # the mark in the footer of every page, the last too

    # two reports of the same records never share a number
    again = tmp_path / "again"
    again.mkdir()
    rc, _, err = run(["calibrate", "--from-dir", str(live), "--out", str(again), "--no-archive",
                      "--bench-file", str(EXAMPLE)])  # fmt: skip
    assert rc in (0, 1), err
    second = re.search(r"^Report No\. (\S+),", (again / "C2_result.txt").read_text("utf-8"), re.M)
    assert second is not None and second.group(1) != number_s
    assert second.group(1).startswith("B1-C2-")


@pytest.mark.slow
@needs_poppler
def test_a_rendered_page_holds_ruled_tables(live: Path, tmp_path: Path) -> None:
    import matplotlib.image as mpimg

    pdf = live / "C2_result.pdf"
    subprocess.run(["pdftoppm", "-r", "100", "-f", "1", "-l", "3", "-png", str(pdf),
                    str(tmp_path / "p")], check=True)  # fmt: skip
    best: tuple[int, int] = (0, 0)
    for png in sorted(tmp_path.glob("p-*.png")):
        img = mpimg.imread(png)[..., :3].mean(axis=2)
        h, w = img.shape
        assert abs(h / w - 297 / 210) < 0.01  # A4 portrait
        dark = img < 0.6
        # a table's columns are vertical rules: dark runs over many rows at one x, which no
        # glyph of text makes (a line of 8-point text is about 11 pixels tall here)
        columns = _clusters([x for x in range(w) if _longest_run(dark[:, x]) >= 40])
        # and its rows are horizontal rules over a third of the page's width at least
        rows = _clusters([y for y in range(h) if _longest_run(dark[y, :]) >= w // 3])
        best = max(best, (len(columns), len(rows)))
    # the results table: value, measured, unit, tolerance, mark, U, note between 8 rules
    assert best[0] >= 8 and best[1] >= 12, best
    # the text of a cell sits between two rules: the result table's row is cells
    text = subprocess.run(["pdftotext", "-layout", str(pdf), "-"],
                          check=True, capture_output=True, text=True).stdout  # fmt: skip
    row = next(ln for ln in text.splitlines() if ln.split()[:1] == ["Gxx"])
    assert len(row.split()) >= 4  # name, value, tolerance, mark, U: cells, not one string


def _longest_run(mask: np.ndarray) -> int:
    """The longest run of True in ``mask``."""
    edges = np.diff(np.concatenate(([0], mask.astype(np.int8), [0])))
    starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    return int((ends - starts).max()) if len(starts) else 0


def _clusters(xs: list[int]) -> list[int]:
    """The starts of runs of adjacent positions."""
    return [x for i, x in enumerate(xs) if i == 0 or x - xs[i - 1] > 2]


def test_a_bench_file_of_another_bench_or_broken_is_refused(tmp_path: Path) -> None:
    d = tmp_path / "U"
    rc, _, err = run(["calibrate", *LIVE, "--out", str(d), "--bench-file", str(EXAMPLE),
                      "--bench", "B7"])  # fmt: skip
    assert rc == 2 and "--bench B7: the bench file" in err and "of bench B1" in err
    assert len(err.strip().splitlines()) == 1 and not d.exists()
    bad = tmp_path / "bad.toml"
    bad.write_text(EXAMPLE.read_text(encoding="utf-8").replace("level_mrad = 0.2", "level_mrad ="))
    rc, _, err = run(["calibrate", *LIVE, "--out", str(d), "--bench-file", str(bad)])
    assert rc == 2 and "not TOML" in err and len(err.strip().splitlines()) == 1
    rc, _, err = run(["calibrate", *LIVE, "--out", str(d), "--customer", "A\x1b[2J"])
    assert rc == 2 and "--customer" in err and "control character" in err
