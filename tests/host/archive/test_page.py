"""The QC lead's page (host/archive/page.py): the SVG charts as pure functions, and the whole
page rendered in a real headless Chromium — it renders, the charts are there, the script ran,
nothing is logged to the console, nothing is fetched from the network."""

from __future__ import annotations

import re
import shutil
import subprocess
import tempfile
from pathlib import Path

import numpy as np
import pytest

from host.archive.page import page_data, render, svg_chart
from host.archive.store import Archive
from tests.host.archive.lot_sim import simulate_lot

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")


def test_a_chart_has_a_point_per_value_and_marks_the_signals() -> None:
    svg = svg_chart("B1 · <A0x>", [1.0, 2.0, float("nan"), 1.5], centre=1.5, sigma=0.2,
                    marked=[False, True, False, False], labels=["a", "b", "c", "d"])  # fmt: skip
    assert svg.count("<circle") == 3  # the NaN is left out
    assert svg.count('class="pt bad"') == 1
    assert "&lt;A0x&gt;" in svg and "<A0x>" not in svg
    assert svg.count("<line") == 7  # centre and ±1, 2, 3 σ
    # higher values are drawn higher (smaller y)
    ys = [float(y) for y in re.findall(r'<circle cx="[\d.]+" cy="([\d.]+)"', svg)]
    assert ys[1] < ys[2] < ys[0]


def _chromium(page: Path, *extra: str) -> subprocess.CompletedProcess[str]:
    assert CHROMIUM is not None
    with tempfile.TemporaryDirectory() as profile:
        return subprocess.run(
            [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu",
             "--disable-background-networking", "--no-first-run", f"--user-data-dir={profile}",
             "--enable-logging=stderr", "--v=0", *extra, page.as_uri()],
            capture_output=True, text=True, timeout=120,
        )  # fmt: skip


def _console(stderr: str) -> list[str]:
    return [line for line in stderr.splitlines() if ":CONSOLE" in line]


@pytest.mark.slow
@pytest.mark.skipif(CHROMIUM is None, reason="chromium is not installed (.ci/setup installs it)")
@pytest.mark.timeout(300)
def test_the_page_renders_in_a_real_browser_with_its_charts(tmp_path: Path) -> None:
    lot = simulate_lot(np.random.default_rng(21), units=24)
    with Archive(str(tmp_path / "a.sqlite")) as a:
        a.add_many(lot.entries)
        d = page_data(a, reference="REF", names=["A0x", "G0z"])
    text = render(d)
    # self-contained: no reference to anything outside the file but the SVG namespace
    outside = re.findall(r"(?:src|href)=|https?://(?!www\.w3\.org/2000/svg)", text)
    assert outside == []
    page = tmp_path / "report.html"
    page.write_text(text, encoding="utf-8")
    run = _chromium(page, "--dump-dom")
    assert run.returncode == 0, run.stderr[-2000:]
    dom = run.stdout
    n_svg = dom.count('<svg class="chart"')
    assert n_svg == 4 * 2 + 1  # REF on 4 benches × 2 parameters, and U0007's A0x trend
    assert f'data-charts="{n_svg}"' in dom  # the page's script ran and counted them
    assert "U0011</b>: self-test failed" in dom and "bench B3</b>: G0z" in dom
    assert _console(run.stderr) == []
    shot = tmp_path / "report.png"
    run = _chromium(page, "--window-size=1200,2000", f"--screenshot={shot}")
    assert run.returncode == 0 and shot.stat().st_size > 20_000  # a page, not a blank


@pytest.mark.slow
@pytest.mark.skipif(CHROMIUM is None, reason="chromium is not installed (.ci/setup installs it)")
def test_the_console_check_sees_an_error(tmp_path: Path) -> None:
    """The check above can fail: a page that logs an error is caught by it."""
    page = tmp_path / "bad.html"
    page.write_text("<!DOCTYPE html><html><body><script>console.error('boom'); undefined_fn();"
                    "</script></body></html>")  # fmt: skip
    run = _chromium(page, "--dump-dom")
    found = _console(run.stderr)
    assert any("boom" in line for line in found) and len(found) == 2
