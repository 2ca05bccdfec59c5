"""The QC lead's page (host/archive/page.py) rendered in a real headless Chromium — it renders,
the charts are there, the script ran, nothing is logged to the console, nothing is fetched from
the network; at a desktop's 1280 px and a phone's 390 px every chart has both axes titled, its
unit on y, nothing is clipped or too small to read and nothing is wider than the screen. The
attention list has one line per unit and the lot table says what its marks mean."""

from __future__ import annotations

import html
import json
import re
import shutil
import subprocess
import tempfile
from pathlib import Path

import numpy as np
import pytest

from host.archive.charts import param_unit
from host.archive.page import page_data, render
from host.archive.store import Archive
from tests.host.archive.lot_sim import simulate_lot

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")


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


#: measures the page as laid out: the viewport, the document's width, and per chart where its
#: axis titles and every text are drawn (their boxes on the screen, in CSS pixels); it posts
#: them to the page holding it (headless Chromium's window is never narrower than 500 px, so a
#: phone's screen is a frame of its width)
PROBE = """<script>
const box = (e) => { const r = e.getBoundingClientRect();
  return {l: r.left, r: r.right, t: r.top, b: r.bottom, h: r.height, text: e.textContent}; };
const charts = [...document.querySelectorAll("svg.chart")].map((svg) => ({
  frame: box(svg),
  x: [...svg.querySelectorAll("text.xt")].map(box),
  y: [...svg.querySelectorAll("text.yt")].map(box),
  texts: [...svg.querySelectorAll("text")].map(box),
}));
parent.postMessage(JSON.stringify({
  width: window.innerWidth, scroll: document.documentElement.scrollWidth, charts: charts,
  font: Math.min(...[...document.querySelectorAll("p, li, td")].map(
    (e) => parseFloat(getComputedStyle(e).fontSize))),
}), "*");
</script>"""
#: a screen of ``{width}`` CSS pixels holding the page, keeping what the probe posts
SCREEN = """<!DOCTYPE html><html><body style="margin:0">
<iframe src="probed.html" style="width:{width}px;height:3000px;border:0"></iframe>
<script>addEventListener("message", (e) => {{ document.body.dataset.probe = e.data; }});</script>
</body></html>"""


@pytest.fixture(scope="module")
def lot_page(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The page of a simulated lot of 24 units on 4 benches (a drifting unit, a biased bench, a
    failed self-test), with the probe above added at its end."""
    d = tmp_path_factory.mktemp("page")
    lot = simulate_lot(np.random.default_rng(21), units=24)
    with Archive(str(d / "a.sqlite")) as a:
        a.add_many(lot.entries)
        text = render(page_data(a, reference="REF", names=["A0x", "G0z"]))
    page = d / "probed.html"
    page.write_text(text.replace("</body>", PROBE + "</body>"), encoding="utf-8")
    return page


def _inside(b: dict, frame: dict) -> bool:
    return (b["l"] >= frame["l"] - 0.5 and b["r"] <= frame["r"] + 0.5
            and b["t"] >= frame["t"] - 0.5 and b["b"] <= frame["b"] + 0.5)  # fmt: skip


@pytest.mark.slow
@pytest.mark.skipif(CHROMIUM is None, reason="chromium is not installed (.ci/setup installs it)")
@pytest.mark.timeout(300)
@pytest.mark.parametrize("width", [1280, 390])
def test_every_chart_titles_both_axes_with_units_at_desktop_and_phone_width(
    lot_page: Path, width: int
) -> None:
    screen = lot_page.with_name(f"screen{width}.html")
    screen.write_text(SCREEN.format(width=width), encoding="utf-8")
    run = _chromium(screen, "--window-size=1400,3000", "--virtual-time-budget=5000", "--dump-dom")
    assert run.returncode == 0, run.stderr[-2000:]
    found = re.search(r'data-probe="([^"]*)"', run.stdout)
    assert found is not None, run.stdout[-2000:]
    probe = json.loads(html.unescape(found.group(1)))
    assert probe["width"] == width  # laid out at that width (else the test tests nothing)
    assert probe["scroll"] <= probe["width"]  # nothing wider than the screen
    assert probe["font"] >= 14  # the page's text
    assert len(probe["charts"]) == 4 * 2 + 1
    for chart in probe["charts"]:
        frame = chart["frame"]
        assert frame["r"] <= width  # the chart fits the screen
        (x,), (y,) = chart["x"], chart["y"]
        assert x["text"] in ("calibrated (UTC)", "calibration (in time order)")
        name = y["text"].split(" ")[0]
        assert y["text"] == f"{name} ({param_unit(name)})" and param_unit(name) != "?"
        for t in chart["texts"]:  # every label drawn inside its chart, none too small to read
            assert _inside(t, frame), (t, frame)
            assert t["h"] >= 9.5, t  # a line of 10 CSS px: a font of 9 px or more


def test_the_attention_list_has_one_line_per_unit_with_its_worst_finding(tmp_path: Path) -> None:
    lot = simulate_lot(np.random.default_rng(21), units=24)
    with Archive(str(tmp_path / "a.sqlite")) as a:
        a.add_many(lot.entries)
        d = page_data(a, reference="REF", names=["A0x"])
    items = re.findall(r"<li><b>([^<]*)</b>: (.*?)</li>", render(d))
    units = [u for u, _ in items if not u.startswith("bench ")]
    assert len(units) == len(set(units))  # one line per unit
    findings = {u: why for u, why in items}
    # U0007 drifted in A0x (and more): its worst, the drift, first; a failed self-test alone
    assert findings["U0007"].startswith("A0x moved") and " UTC to 20" in findings["U0007"]
    assert findings["U0011"] == "self-test failed"
    moved = [r for r in d.drift if r.moved and r.serial == "U0007"]
    more = len(moved) - 1 + sum(1 for r in d.repeat if r.failed and r.serial == "U0007")
    if more:
        assert f">and {more} more</span>" in findings["U0007"]


def test_the_lot_table_gives_units_and_says_what_each_mark_means(tmp_path: Path) -> None:
    lot = simulate_lot(np.random.default_rng(21), units=24)
    with Archive(str(tmp_path / "a.sqlite")) as a:
        a.add_many(lot.entries)
        d = page_data(a, names=["A0x"])
    table = render(d).split('<table id="lot">')[1].split("</table>")[0]
    rows = re.findall(r"<tr><td>(\w+)</td><td>([^<]*)</td>(.*?)</tr>", table)
    assert len(rows) == len(d.lot.rows) == 12
    assert {n: u for n, u, _ in rows} == {n: param_unit(n) for n, _, _ in rows}
    assert {"A0x": "m/s²", "G0z": "°/s", "Gxx": "1"}.items() <= {n: u for n, u, _ in rows}.items()
    for _, _, cells in rows:  # this lot is well inside every limit
        mark, means = re.findall(r"<td[^>]*>([^<]*)</td>", cells)[-2:]
        assert (mark, means) == ("within", "mean ± 3·spread inside the datasheet limit")


def test_a_wide_lot_and_an_outlier_are_said_to_be_no_failure() -> None:
    """A lot whose mean ± 3·spread reaches past the limit, with an outlier: the marks say what
    they mean — unusual, not a FAIL — in the text of ``archive lot`` too."""
    from host.archive import stats
    from host.archive.checks import LotReport, LotRow, lot_mark
    from host.cli.archive_text import lot as lot_text

    wide = LotRow("G0z", stats.lot_summary(np.array([-9.0, 8.0, 0.5, 7.0]), 20.0),
                  (("U9", 8.0),))  # fmt: skip
    calm = LotRow("A0x", stats.lot_summary(np.array([0.01, 0.02, 0.0, 0.01]), 0.5), ())
    assert wide.summary.within is False and calm.summary.within is True
    mark, means = lot_mark(wide)
    assert mark == "OUTSIDE" and "past the datasheet limit" in means and "no unit's FAIL" in means
    assert "outlier U9: unusual for this lot, not a failure" in means
    text = lot_text(LotReport([wide, calm], 4, ()), 0.01, width=80)
    assert "unit" in text.splitlines()[2] and " °/s " in text and " m/s² " in text
    assert "OUTSIDE: mean ± 3·spread of this lot past the datasheet limit" in text
    assert "within: mean ± 3·spread inside the datasheet limit" in text
    assert "outlier: U9 G0z = 8 °/s: unusual for this lot, not a failure" in text
    assert max(len(ln) for ln in text.splitlines()) <= 80
