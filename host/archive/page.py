"""The page a QC lead opens: ``archive report --html FILE``, one self-contained HTML file (no
server, no network, no script from elsewhere) with the units that need attention, the lot
table, control charts per bench and parameter and the trends of the units flagged — charts as
inline SVG. :func:`render` builds the text from the answers of :mod:`host.archive.checks`;
:func:`svg_chart` is a pure function of the points."""

from __future__ import annotations

import html
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from host.archive import checks, stats
from host.archive.checks import BenchRow, Chart, DriftRow, LotReport, RepeatRow, TrendPoint
from host.archive.schema import now_utc
from host.archive.store import Archive
from host.session.inputs import written_serial

W, H, PAD = 520, 180, 34


def _e(s: object) -> str:
    return html.escape(str(s))


def _u(serial: str) -> str:
    """A unit's serial as the page shows it: by the serial rule (one line), then for HTML."""
    return _e(written_serial(serial))


def _g(v: float, digits: int = 4) -> str:
    return "—" if not math.isfinite(v) else f"{v:.{digits}g}"


def svg_chart(
    title: str,
    y: Sequence[float],
    *,
    err: Sequence[float] | None = None,
    centre: float = math.nan,
    sigma: float = math.nan,
    marked: Sequence[bool] | None = None,
    labels: Sequence[str] | None = None,
) -> str:
    """An inline SVG of the points ``y`` in order (error bars ``err``, 1 σ), with the centre
    line and ±1/2/3 σ limits when ``centre``/``sigma`` are finite; ``marked`` points (a rule
    fired) drawn red; ``labels`` the points' tooltips."""
    v = np.asarray(y, dtype=np.float64)
    e = np.zeros_like(v) if err is None else np.nan_to_num(np.asarray(err, dtype=np.float64))
    lo = np.nanmin(v - e) if v.size else 0.0
    hi = np.nanmax(v + e) if v.size else 1.0
    if math.isfinite(centre) and math.isfinite(sigma):
        lo, hi = min(lo, centre - 3.3 * sigma), max(hi, centre + 3.3 * sigma)
    if not hi > lo:
        lo, hi = lo - 1.0, hi + 1.0
    n = max(v.size, 2)

    def px(i: int) -> float:
        return PAD + (W - 2 * PAD) * i / (n - 1)

    def py(val: float) -> float:
        return H - PAD + (H - 2 * PAD) * (lo - val) / (hi - lo)

    parts = [
        f'<svg class="chart" xmlns="http://www.w3.org/2000/svg" width="{W}" height="{H}" '
        f'viewBox="0 0 {W} {H}" role="img" aria-label="{_e(title)}">',
        f'<text x="{PAD}" y="14" class="t">{_e(title)}</text>',
        f'<rect x="{PAD}" y="{PAD}" width="{W - 2 * PAD}" height="{H - 2 * PAD}" class="frame"/>',
    ]
    if math.isfinite(centre) and math.isfinite(sigma):
        for k, cls in ((0, "cl"), (1, "s1"), (-1, "s1"), (2, "s2"), (-2, "s2"), (3, "s3"),
                       (-3, "s3")):  # fmt: skip
            yy = py(centre + k * sigma)
            parts.append(f'<line x1="{PAD}" x2="{W - PAD}" y1="{yy:.1f}" y2="{yy:.1f}" '
                         f'class="{cls}"/>')  # fmt: skip
    parts.append(f'<text x="2" y="{PAD + 4}" class="a">{_e(_g(hi, 3))}</text>')
    parts.append(f'<text x="2" y="{H - PAD + 4}" class="a">{_e(_g(lo, 3))}</text>')
    pts = [(px(i), py(float(val))) for i, val in enumerate(v) if math.isfinite(val)]
    if len(pts) > 1:
        path = " ".join(f"{x:.1f},{yy:.1f}" for x, yy in pts)
        parts.append(f'<polyline points="{path}" class="line"/>')
    for i, val in enumerate(v):
        if not math.isfinite(val):
            continue
        x, yy = px(i), py(float(val))
        if e[i] > 0:
            parts.append(f'<line x1="{x:.1f}" x2="{x:.1f}" y1="{py(val - e[i]):.1f}" '
                         f'y2="{py(val + e[i]):.1f}" class="err"/>')  # fmt: skip
        cls = "pt bad" if marked is not None and marked[i] else "pt"
        tip = f"<title>{_e(labels[i])}</title>" if labels is not None else ""
        parts.append(f'<circle cx="{x:.1f}" cy="{yy:.1f}" r="3" class="{cls}">{tip}</circle>')
    parts.append("</svg>")
    return "".join(parts)


@dataclass(frozen=True)
class PageData:
    """What the page shows (each from :mod:`host.archive.checks`)."""

    title: str
    archive: str
    generated: str
    alpha: float
    lot: LotReport
    repeat: list[RepeatRow]
    drift: list[DriftRow]
    drift_k: float
    benches: list[BenchRow]
    bench_k: float
    reference: str
    charts: list[Chart]
    trends: dict[str, dict[str, list[TrendPoint]]]
    #: simulated calibrations the lot, drift and control charts left out
    simulated: int = 0


STYLE = """
body{font:14px/1.4 system-ui,sans-serif;margin:24px;color:#222;max-width:1150px}
h1{font-size:22px}h2{font-size:18px;margin-top:28px;border-bottom:1px solid #ccc}
table{border-collapse:collapse;margin:8px 0}td,th{padding:2px 8px;border-bottom:1px solid #eee;
text-align:right}td:first-child,th:first-child{text-align:left}.bad{color:#b00;font-weight:600}
.charts{display:flex;flex-wrap:wrap;gap:10px}.chart{background:#fff;border:1px solid #ddd}
.chart .t{font-size:12px;font-weight:600}.chart .a{font-size:10px;fill:#666}
.chart .frame{fill:none;stroke:#ccc}.chart .line{fill:none;stroke:#36c;stroke-width:1}
.chart .pt{fill:#36c}.chart .pt.bad{fill:#d00;r:4}.chart .err{stroke:#36c}
.chart .cl{stroke:#090}.chart .s1{stroke:#ddd;stroke-dasharray:2 3}
.chart .s2{stroke:#fc6;stroke-dasharray:4 3}.chart .s3{stroke:#d33}
.ok{color:#070}
"""


def _attention(d: PageData) -> str:
    items: list[str] = []
    for serial, why in d.lot.failing:
        items.append(f"<li><b>{_u(serial)}</b>: {_e(why)}</li>")
    for serial, rms_z in d.lot.conditional:
        items.append(f"<li><b>{_u(serial)}</b>: conditional PASS, the model does not fit its "
                     f"records (RMS z {_e(_g(rms_z, 3))})</li>")  # fmt: skip
    for row in d.lot.rows:
        for serial, v in row.outliers:
            items.append(f"<li><b>{_u(serial)}</b>: {_e(row.name)} = {_e(_g(v, 5))} is an "
                         "outlier of the lot</li>")  # fmt: skip
    for dr in d.drift:
        if dr.moved:
            since = dr.before_at[:10]
            items.append(f"<li><b>{_u(dr.serial)}</b>: {_e(dr.name)} moved {_e(_g(dr.delta, 3))}"
                         f" ({dr.z:+.1f} σ) since {_e(since)}: recalibrate</li>")  # fmt: skip
    for serial, bench in sorted({(r.serial, r.bench) for r in d.repeat if r.failed}):
        names = ", ".join(r.name for r in d.repeat if r.failed and r.serial == serial)
        items.append(f"<li><b>{_u(serial)}</b> on {_e(bench)}: not repeatable ({_e(names)})</li>")
    for br in d.benches:
        if br.flagged:
            items.append(f"<li><b>bench {_e(br.bench)}</b>: {_e(br.name)} biased by "
                         f"{_e(_g(br.mean - br.ref, 3))} (Eₙ = {br.en:+.2f}) on {_u(d.reference)}"
                         "</li>")  # fmt: skip
    if not items:
        return '<p class="ok" id="attention">Nothing needs attention.</p>'
    return f'<ul id="attention">{"".join(items)}</ul>'


def _lot_table(rep: LotReport) -> str:
    head = ("<tr><th>parameter</th><th>n</th><th>mean</th><th>spread</th><th>mean−3σ</th>"
            "<th>mean+3σ</th><th>datasheet ±</th><th></th></tr>")  # fmt: skip
    rows = []
    for r in rep.rows:
        s = r.summary
        ok = {None: "", True: '<span class="ok">within</span>',
              False: '<span class="bad">OUTSIDE</span>'}[s.within]  # fmt: skip
        rows.append(
            f"<tr><td>{_e(r.name)}</td><td>{s.n}</td><td>{_g(s.mean)}</td><td>{_g(s.spread, 3)}"
            f"</td><td>{_g(s.low)}</td><td>{_g(s.high)}</td><td>{_g(s.limit or math.nan, 3)}"
            f"</td><td>{ok}</td></tr>"
        )
    return f'<table id="lot">{head}{"".join(rows)}</table>'


def _left_out(n: int) -> str:
    """The line that says how many simulated calibrations the statistics left out."""
    if not n:
        return ""
    return (f'<p id="simulated">Left out of the lot, drift and control charts: {n} simulated '
            "calibration(s) (sim://, emu://: not a unit).</p>")  # fmt: skip


def render(d: PageData) -> str:
    """The whole page."""
    charts = [
        svg_chart(
            f"{c.bench} · {c.name}", c.values.tolist(), centre=c.centre, sigma=c.sigma,
            marked=[bool(f) for f in c.fired],
            labels=[f"{t[:19]} {written_serial(s)}"
                    for t, s in zip(c.times, c.serials, strict=True)],
        )
        for c in d.charts
    ]  # fmt: skip
    trends = [
        svg_chart(
            f"{written_serial(serial)} · {name}", [p.value for p in pts],
            err=[p.stderr for p in pts],
            labels=[f"{p.measured_at[:19]} {p.bench} {_g(p.value, 6)} ± {_g(p.stderr, 2)}"
                    for p in pts],
        )
        for serial, by in d.trends.items()
        for name, pts in by.items()
    ]  # fmt: skip
    signals = sum(1 for c in d.charts for f in c.fired if f)
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>{_e(d.title)}</title><style>{STYLE}</style></head>
<body>
<h1>{_e(d.title)}</h1>
<p>Archive {_e(d.archive)} · generated {_e(d.generated)} · {d.lot.units} unit(s) · false alarms
{100 * d.alpha:g} % per check over a lot with nothing wrong.</p>
{_left_out(d.simulated)}
<h2>Units that need attention</h2>
{_attention(d)}
<h2>The lot</h2>
<p>Each unit's latest calibration; mean ± 3·spread against the datasheet limit.</p>
{_lot_table(d.lot)}
<h2>Control charts</h2>
<p>Individuals charts per bench{
        (" of the reference unit " + _u(d.reference)) if d.reference else ""
    }; σ from the moving range of the first 20 points; red: a
Western Electric rule fired ({signals} point(s)). In control a chart signals once per
{stats.ARL_WESTERN_ELECTRIC:.0f} points on average.</p>
<div class="charts" id="control">{"".join(charts)}</div>
<h2>Trends of the units flagged</h2>
<div class="charts" id="trends">{"".join(trends) or "<p>No unit flagged.</p>"}</div>
<script>
document.body.dataset.charts = String(document.querySelectorAll("svg.chart").length);
</script>
</body></html>
"""


def page_data(
    archive: Archive,
    *,
    reference: str | None = None,
    lot: str | None = None,
    names: Sequence[str] | None = None,
    alpha: float = stats.DEFAULT_ALPHA,
    title: str = "IMU calibration archive",
) -> PageData:
    """Ask the archive every question the page shows. Control charts: of the reference unit
    on each bench when given, else of every session on each bench; ``names`` limits them (by
    default the first six parameters of the lot)."""
    rep = checks.lot_report(archive, lot, alpha=alpha)
    chart_names = list(names) if names else [r.name for r in rep.rows][:6]
    repeat = checks.repeat(archive, alpha=alpha, lot=lot)
    drift, k = checks.drift(archive, alpha=alpha, lot=lot)
    benches: list[BenchRow] = []
    bench_k = math.nan
    if reference:
        benches, bench_k = checks.check_bench(archive, reference, alpha=alpha)
    flagged: dict[str, set[str]] = {}
    for r in drift:
        if r.moved:
            flagged.setdefault(r.serial, set()).add(r.name)
    for rr in repeat:
        if rr.failed:
            flagged.setdefault(rr.serial, set()).add(rr.name)
    for row in rep.rows:
        for serial, _ in row.outliers:
            flagged.setdefault(serial, set()).add(row.name)
    trends = {s: checks.trend(archive, s, sorted(ns)) for s, ns in sorted(flagged.items())}
    return PageData(
        title=title, archive=archive.display_url, generated=now_utc()[:19] + " UTC",
        alpha=alpha, lot=rep, repeat=repeat, drift=drift, drift_k=k, benches=benches,
        bench_k=bench_k, reference=reference or "",
        charts=checks.control_charts(archive, serial=reference, names=chart_names),
        trends=trends, simulated=archive.simulated_count(lot=lot),
    )  # fmt: skip
