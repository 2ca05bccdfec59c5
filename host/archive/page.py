"""The page a QC lead opens: ``archive report --html FILE``, one self-contained HTML file (no
server, no network, no script from elsewhere) with the units that need attention, the lot
table, control charts per bench and parameter and the trends of the units flagged — charts as
inline SVG (:mod:`host.archive.charts`). :func:`render` builds the text from the answers of
:mod:`host.archive.checks`."""

from __future__ import annotations

import dataclasses
import html
import math
from collections.abc import Sequence
from dataclasses import dataclass

from host.archive import checks, stats
from host.archive.charts import param_unit, svg_chart
from host.archive.checks import (
    BenchRow,
    Chart,
    DriftRow,
    IdenticalRepeat,
    LotReport,
    RepeatRow,
    TrendPoint,
    lot_mark,
)
from host.archive.schema import minute_utc, now_utc
from host.archive.store import Archive
from host.session.inputs import written_serial


def _e(s: object) -> str:
    return html.escape(str(s))


def _u(serial: str) -> str:
    """A unit's serial as the page shows it: by the serial rule (one line), then for HTML."""
    return _e(written_serial(serial))


def _g(v: float, digits: int = 4) -> str:
    return "—" if not math.isfinite(v) else f"{v:.{digits}g}"


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
    #: sessions that are an earlier one over again (no repeat)
    identical: list[IdenticalRepeat] = dataclasses.field(default_factory=list)


STYLE = """
body{font:15px/1.45 system-ui,sans-serif;margin:24px;color:#222;max-width:1150px}
@media (max-width:600px){body{margin:10px}}
h1{font-size:22px}h2{font-size:18px;margin-top:28px;border-bottom:1px solid #ccc}
.wide{overflow-x:auto;max-width:100%}
table{border-collapse:collapse;margin:8px 0}td,th{padding:2px 8px;border-bottom:1px solid #eee;
text-align:right;vertical-align:top}td:first-child,th:first-child{text-align:left}
td.means,th.means{text-align:left;min-width:16em}.bad{color:#b00;font-weight:600}
.more{color:#555;text-decoration:underline dotted}
.charts{display:flex;flex-wrap:wrap;gap:10px}
.chart{background:#fff;border:1px solid #ddd;max-width:100%;height:auto}
.chart .t{font-size:15px;font-weight:600}.chart .a{font-size:13px;fill:#444}
.chart .ty{text-anchor:end}.chart .tx{text-anchor:middle}.chart .legend{text-anchor:end}
.chart .xt,.chart .yt{font-size:14px;fill:#222;text-anchor:middle}
.chart .frame{fill:none;stroke:#ccc}.chart .tick{stroke:#888}
.chart .line{fill:none;stroke:#36c;stroke-width:1}
.chart .pt{fill:#36c}.chart .pt.bad{fill:#d00;r:4}.chart .err{stroke:#36c}
.chart .band{fill:#36c;fill-opacity:.15;stroke:none}
.chart .cl{stroke:#090}.chart .s1{stroke:#ddd;stroke-dasharray:2 3}
.chart .s2{stroke:#fc6;stroke-dasharray:4 3}.chart .s3{stroke:#d33}
.ok{color:#070}
"""


def _unit_findings(d: PageData) -> dict[str, list[tuple[int, float, str]]]:
    """Each unit's findings as (rank, size, text): the worst is the least rank (failing,
    conditional, identical repeat, moved, not repeatable, outlier), then the greatest size."""
    out: dict[str, list[tuple[int, float, str]]] = {}

    def add(serial: str, rank: int, size: float, text: str) -> None:
        out.setdefault(serial, []).append((rank, size, text))

    for serial, why in d.lot.failing:
        add(serial, 0, 0.0, why)
    for serial, rms_z in d.lot.conditional:
        add(serial, 1, rms_z, "conditional PASS, the model does not fit its records (RMS z "
            f"{_g(rms_z, 3)})")  # fmt: skip
    for ir in d.identical:
        add(ir.serial, 2, 0.0, f"session #{ir.later} is #{ir.earlier} over again ({ir.what}, "
            "bit for bit): not a repeat")  # fmt: skip
    for dr in d.drift:
        if dr.moved:
            add(dr.serial, 3, abs(dr.z), f"{dr.name} moved {_g(dr.delta, 3)} "
                f"{param_unit(dr.name)} ({dr.z:+.1f} σ) from {minute_utc(dr.before_at)} to "
                f"{minute_utc(dr.after_at)}: recalibrate")  # fmt: skip
    for r in d.repeat:
        if r.failed:
            add(r.serial, 4, -r.p, f"{r.name} not repeatable on {r.bench} (p {r.p:.2g})")
    for row in d.lot.rows:
        for serial, v in row.outliers:
            add(serial, 5, 0.0, f"{row.name} = {_g(v, 5)} {param_unit(row.name)} is an outlier"
                " of the lot: unusual, not a failure")  # fmt: skip
    return out


def _attention(d: PageData) -> str:
    """One line per unit: its worst finding and how many more (listed in its tooltip); one
    line per biased bench."""
    items: list[str] = []
    for serial, found in sorted(_unit_findings(d).items()):
        found.sort(key=lambda f: (f[0], -f[1]))
        worst, rest = found[0][2], [f[2] for f in found[1:]]
        more = (f' <span class="more" title="{_e("; ".join(rest))}">and {len(rest)} more</span>'
                if rest else "")  # fmt: skip
        items.append(f"<li><b>{_u(serial)}</b>: {_e(worst)}{more}</li>")
    for br in d.benches:
        if br.flagged:
            items.append(f"<li><b>bench {_e(br.bench)}</b>: {_e(br.name)} biased by "
                         f"{_e(_g(br.mean - br.ref, 3))} {_e(param_unit(br.name))} (Eₙ = "
                         f"{br.en:+.2f}) on {_u(d.reference)}</li>")  # fmt: skip
    if not items:
        return '<p class="ok" id="attention">Nothing needs attention.</p>'
    return f'<ul id="attention">{"".join(items)}</ul>'


def _lot_table(rep: LotReport) -> str:
    """The lot table: each parameter with its unit, the mark and what the mark means."""
    head = ("<tr><th>parameter</th><th>unit</th><th>n</th><th>mean</th><th>spread</th>"
            "<th>mean − 3·spread</th><th>mean + 3·spread</th><th>datasheet ±</th><th>mark</th>"
            '<th class="means">what the mark means</th></tr>')  # fmt: skip
    rows = []
    for r in rep.rows:
        s = r.summary
        mark, means = lot_mark(r)
        cls = {None: "", True: "ok", False: "bad"}[s.within]
        rows.append(
            f"<tr><td>{_e(r.name)}</td><td>{_e(param_unit(r.name))}</td><td>{s.n}</td>"
            f"<td>{_g(s.mean)}</td><td>{_g(s.spread, 3)}</td><td>{_g(s.low)}</td>"
            f"<td>{_g(s.high)}</td><td>{_g(s.limit or math.nan, 3)}</td>"
            f'<td class="{cls}">{_e(mark)}</td><td class="means">{_e(means)}</td></tr>'
        )
    return f'<div class="wide"><table id="lot">{head}{"".join(rows)}</table></div>'


def _left_out(n: int) -> str:
    """The line that says how many simulated calibrations the statistics left out."""
    if not n:
        return ""
    return (f'<p id="simulated">Left out of the lot, drift and control charts: {n} simulated '
            "calibration(s) (sim://, emu://: not a unit).</p>")  # fmt: skip


def _control_svgs(d: PageData) -> list[str]:
    """The control charts: each bench's points in time, centre line and ±1/2/3 σ."""
    return [
        svg_chart(
            f"{c.bench} · {c.name}", c.name, c.values.tolist(), c.times, centre=c.centre,
            sigma=c.sigma, marked=[bool(f) for f in c.fired],
            labels=[f"{t[:19]} {written_serial(s)}"
                    for t, s in zip(c.times, c.serials, strict=True)],
        )
        for c in d.charts
    ]  # fmt: skip


def _trend_svgs(d: PageData) -> list[str]:
    """The trends of the units flagged: each calibration's value in time with its ± U."""
    return [
        svg_chart(
            f"{written_serial(serial)} · {name}", name, [p.value for p in pts],
            [p.measured_at for p in pts], u=[p.expanded for p in pts],
            labels=[f"{p.measured_at[:19]} {p.bench} {_g(p.value, 6)} ± {_g(p.expanded, 2)} "
                    f"(U, 95 %) {param_unit(name)}" for p in pts],
        )
        for serial, by in d.trends.items()
        for name, pts in by.items()
    ]  # fmt: skip


def render(d: PageData) -> str:
    """The whole page."""
    signals = sum(1 for c in d.charts for f in c.fired if f)
    trends = "".join(_trend_svgs(d)) or "<p>No unit flagged.</p>"
    ref = (" of the reference unit " + _u(d.reference)) if d.reference else ""
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
<p>One line per unit: its worst finding, and how many more (their tooltip lists them).</p>
{_attention(d)}
<h2>The lot</h2>
<p>Each unit's latest calibration; mean ± 3·spread against the datasheet limit. A mark is about
the lot, not a unit: a unit fails by its own report (listed above).</p>
{_lot_table(d.lot)}
<h2>Control charts</h2>
<p>Individuals charts per bench{ref}, in time (UTC); centre line (CL) and ±1/2/3 σ (UCL, LCL:
±3 σ), σ from the moving range of the first 20 points; red: a Western Electric rule fired
({signals} point(s)). In control a chart signals once per
{stats.ARL_WESTERN_ELECTRIC:.0f} points on average.</p>
<div class="charts" id="control">{"".join(_control_svgs(d))}</div>
<h2>Trends of the units flagged</h2>
<p>Each calibration's value in time; the band and bars: ± U, the expanded uncertainty at 95 %
coverage as the certificate gives it (twice the fit's σ, or Student's t on its dof).</p>
<div class="charts" id="trends">{trends}</div>
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
        identical=checks.identical_repeats(archive, lot=lot),
    )  # fmt: skip
