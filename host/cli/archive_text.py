"""The text of ``python3 -m host archive``'s answers, within the terminal's width (80 columns
into a pipe or a file): prose wrapped at words (continuations indented by two), tables
through :func:`host.cli.screen.table` (too wide, their least needed columns are left out and
named). The answers are :mod:`host.archive.checks`'; nothing here decides anything."""

from __future__ import annotations

import math
import textwrap
from collections.abc import Sequence

from host.archive import stats
from host.archive.charts import param_unit
from host.archive.checks import (
    LOT_MARKS,
    BenchRow,
    Chart,
    DriftRow,
    IdenticalRepeat,
    LotReport,
    RepeatRow,
    TrendPoint,
    lot_mark,
)
from host.archive.entry import Entry, conditional_pass
from host.archive.schema import minute_utc
from host.archive.store import Summary
from host.cli.screen import Column, table, terminal_width


def _g(v: float, digits: int = 4) -> str:
    return "—" if not math.isfinite(v) else f"{v:.{digits}g}"


def _rate(alpha: float) -> str:
    return f"{100 * alpha:g} %"


def prose(text: str, width: int) -> list[str]:
    """``text`` wrapped at words within ``width``, continuations indented by two (a word
    longer than a line, such as a path, stays whole)."""
    return textwrap.wrap(text, width, subsequent_indent="  ", break_long_words=False,
                         break_on_hyphens=False) or [""]  # fmt: skip


#: the verdict of a conditional PASS in the archive's tables, and what the star means
CONDITIONAL = "PASS*"
FOOTNOTE = (
    "* conditional PASS: every value within tolerance as fitted, on a model that does not fit "
    "the records (not a clean pass; python3 -m host model diagnose DIR on its records)"
)


def verdict_of(verdict: str, fit_verdict: str) -> str:
    """PASS, FAIL, or :data:`CONDITIONAL` for a PASS on a model that does not fit."""
    return CONDITIONAL if conditional_pass(verdict, fit_verdict) else verdict.upper()


def _text(lines: Sequence[str]) -> str:
    return "\n".join(lines) + "\n"


def summaries(rows: Sequence[Summary], width: int | None = None) -> str:
    """The lines of ``archive list``: one calibration a row, oldest first."""
    if not rows:
        return "the archive has no calibration of this selection\n"
    cols = [
        Column("id", [str(r.id) for r in rows]),
        Column("serial", [r.serial for r in rows], "<"),
        Column("bench", [r.bench or "-" for r in rows], "<", rank=3),
        Column("measured (UTC)", [r.measured_at[:16].replace("T", " ") for r in rows], "<"),
        Column("verdict", [verdict_of(r.verdict, r.fit_verdict) for r in rows], "<"),
        Column("self-test", [r.self_test or "-" for r in rows], "<", rank=2),
        Column("fit", [r.fit_verdict or "-" for r in rows], "<", rank=1),
        Column("result", [r.result_hash[:8] for r in rows], "<", rank=4),
    ]
    w = width or terminal_width()
    star = any(conditional_pass(r.verdict, r.fit_verdict) for r in rows)
    return _text(table(cols, w) + (prose(FOOTNOTE, w) if star else []))


def entry(e: Entry, width: int | None = None) -> str:
    """``archive show``: the identity, the hashes and every parameter with its σ."""
    w = width or terminal_width()
    lines = [
        *prose(f"serial {e.serial}   bench {e.bench or '-'}   operator {e.operator or '-'}   "
                f"lot {e.lot or '-'}", w),
        *prose(f"measured {e.measured_at}   firmware {e.firmware or '-'}   sensor revision "
                f"{e.sensor_revision or '-'}", w),
        f"chip temperature {_g(e.temp_min_c, 3)} … {_g(e.temp_max_c, 3)} °C "
        f"(mean {_g(e.temp_mean_c, 3)})",
        *prose(f"model {e.model}", w),
        *prose(f"fit: χ² = {_g(e.chi2)} on {e.dof} dof, RMS z = {_g(e.rms_z, 3)}, "
                f"p = {_g(e.p, 3)}: {e.fit_verdict or '-'}", w),
        *prose(f"verdict {_verdict_words(e)}   self-test {e.self_test or 'not recorded'}", w),
        f"{len(e.record_hashes)} record files; covariance: {e.covariance_kind}",
        f"result  sha256 {e.result_hash}",
        f"report  sha256 {e.report_hash}",
        f"records sha256 {e.records_hash}",
        "",
    ]  # fmt: skip
    ps = e.parameters
    lines += table(
        [
            Column("parameter", [p.name for p in ps], "<"),
            Column("value", [_g(p.value, 6) for p in ps]),
            Column("σ", [_g(p.stderr, 3) for p in ps]),
            Column("unit", [p.unit for p in ps], "<", rank=1),
        ],
        w,
    )
    return _text(lines)


def _verdict_words(e: Entry) -> str:
    if conditional_pass(e.verdict, e.fit_verdict):
        return f"{CONDITIONAL} (conditional: the model does not fit, RMS z {_g(e.rms_z, 3)})"
    return e.verdict.upper()


def trend(serial: str, points: dict[str, list[TrendPoint]], width: int | None = None) -> str:
    """``archive trend``: each parameter against time with its σ."""
    w = width or terminal_width()
    out = [f"trend of {serial}: each parameter against time (value ± σ)"]
    for name, ps in points.items():
        out.append(f"\n{name}")
        rows = table(
            [
                Column("measured (UTC)", [p.measured_at[:19].replace("T", " ") for p in ps], "<"),
                Column("bench", [p.bench or "-" for p in ps], "<", rank=1),
                Column("value", [_g(p.value, 6) for p in ps]),
                Column("± σ", [f"± {_g(p.stderr, 2)}" for p in ps], "<"),
            ],
            w - 2,
        )
        out += ["  " + r for r in rows[1:]]  # the columns say themselves: no header
    return _text(out)


def repeat(
    rows: Sequence[RepeatRow],
    alpha: float,
    width: int | None = None,
    identical: Sequence[IdenticalRepeat] = (),
) -> str:
    """``archive repeat``: per unit and bench, the failing parameters (all of them for one
    unit), the sessions that are an earlier one over again (``identical``), and the verdict."""
    w = width or terminal_width()
    units = sorted({(r.serial, r.bench) for r in rows})
    failed = sorted({(r.serial, r.bench) for r in rows if r.failed})
    tested = sum(1 for r in rows if r.dof >= 1)
    out = prose(
        f"repeatability: between-session scatter against the σ of each fit, χ² per parameter "
        f"(its p from Welch's F on ν where a σ is read on few dof); "
        f"false alarms: {_rate(alpha)} of runs over a lot with nothing wrong "
        f"({tested} parameters tested, p < {alpha / max(tested, 1):.2g} fails)",
        w,
    )
    show = rows if len(units) == 1 else [r for r in rows if (r.serial, r.bench) in failed]
    for serial, bench in sorted({(r.serial, r.bench) for r in show}):
        rs = [r for r in show if (r.serial, r.bench) == (serial, bench)]
        out.append(f"{serial} on {bench}")
        cols = [
            Column("parameter", [r.name for r in rs], "<"),
            Column("n", [str(r.n) for r in rs]),
            Column("mean", [_g(r.mean, 5) for r in rs], rank=2),
            Column("scatter", [_g(r.scatter, 3) for r in rs]),
            Column("σ pred", [_g(r.predicted, 3) for r in rs]),
            Column("χ²", [_g(r.chi2, 3) for r in rs], rank=1),
            Column("ν", ["—" if not math.isfinite(r.nu) else f"{r.nu:.0f}" for r in rs], rank=3),
            Column("p", [_g(r.p, 2) for r in rs]),
            Column(
                "CV", ["—" if not math.isfinite(r.cv) else f"{100 * r.cv:.2f}%" for r in rs], rank=3
            ),  # fmt: skip
            Column("", ["fails" if r.failed else "" for r in rs], "<"),
        ]
        out += ["  " + ln for ln in table(cols, w - 2)]
    few = sorted({(r.serial, r.bench) for r in rows if r.dof < 1})
    if few:
        out.append(f"untestable (one session only): {len(few)} unit/bench pair(s)")
    out += _identical(identical, w)
    if failed:
        out += prose(
            "NOT REPEATABLE: " + ", ".join(f"{s} on {b}" for s, b in failed)
            + " — the sessions disagree beyond their σ: look at the mounting and the records",
            w,
        )  # fmt: skip
    elif identical:
        out.append(f"repeatability not shown: {len(identical)} session(s) repeat an earlier one")
    else:
        out.append(f"repeatable: {len(units) - len(few)} unit/bench pair(s) agree within their σ")
    return _text(out)


def _identical(found: Sequence[IdenticalRepeat], w: int) -> list[str]:
    """One line per session that is an earlier one over again, bit for bit."""
    out: list[str] = []
    for r in found:
        out += prose(
            f"IDENTICAL: {r.serial} #{r.later} has {r.what} of #{r.earlier} bit for bit — "
            "not a repeat (a copy, or the same simulated noise: sim:// noise_seed); "
            "its agreement proves nothing",
            w,
        )
    return out


def drift(rows: Sequence[DriftRow], k: float, alpha: float, width: int | None = None) -> str:
    """``archive drift``: the units whose parameters moved since their last calibration."""
    w = width or terminal_width()
    moved = [r for r in rows if r.moved]
    units = sorted({r.serial for r in moved})
    out = prose(
        f"drift since the last calibration: |Δ| > {k:.2f}·σ (false alarms: {_rate(alpha)} of "
        f"runs with nothing moved, over {len(rows)} parameters) or beyond --tol",
        w,
    )
    for when in sorted({(r.serial, r.before_at, r.after_at) for r in moved}):
        rs = [r for r in moved if (r.serial, r.before_at, r.after_at) == when]
        serial, before, after = when
        out.append(f"{serial}: {minute_utc(before)} -> {minute_utc(after)}")
        cols = [
            Column("parameter", [r.name for r in rs], "<"),
            Column("before", [_g(r.before, 5) for r in rs]),
            Column("after", [_g(r.after, 5) for r in rs]),
            Column("Δ", [_g(r.delta, 3) for r in rs]),
            Column("Δ/σ", [f"{r.z:+.1f}" for r in rs]),
        ]
        out += ["  " + ln for ln in table(cols, w - 2)]
    out += prose(
        f"recalibrate: {', '.join(units)}" if units else "no unit moved beyond k·σ or tolerance",
        w,
    )
    return _text(out)


def _mark_meanings(rep: LotReport, w: int) -> list[str]:
    """What each mark of the lot table's datasheet column means, once per mark shown."""
    shown = {r.summary.within for r in rep.rows}
    return [
        ln
        for within in (False, True, None)
        if within in shown
        for ln in prose(f"{LOT_MARKS[within][0]}: {LOT_MARKS[within][1]}", w)
    ]


def lot(rep: LotReport, alpha: float, width: int | None = None) -> str:
    """``archive lot``: per parameter mean, spread, 3σ band against the datasheet, outliers."""
    w = width or terminal_width()
    out = prose(
        f"lot of {rep.units} unit(s), each unit's latest calibration; outliers by Grubbs' test "
        f"(false alarms: {_rate(alpha)} of lots with no outlier)",
        w,
    )
    ss = [r.summary for r in rep.rows]
    marks = [lot_mark(r) for r in rep.rows]
    out += table(
        [
            Column("parameter", [r.name for r in rep.rows], "<"),
            Column("unit", [param_unit(r.name) for r in rep.rows], "<"),
            Column("n", [str(s.n) for s in ss]),
            Column("mean", [_g(s.mean, 4) for s in ss]),
            Column("spread", [_g(s.spread, 3) for s in ss]),
            Column("mean−3σ", [_g(s.low, 4) for s in ss], rank=1),
            Column("mean+3σ", [_g(s.high, 4) for s in ss], rank=1),
            Column("limit", [_g(s.limit or math.nan, 3) for s in ss]),
            Column("datasheet", [m for m, _ in marks], "<"),
        ],
        w,
    )
    out += _mark_meanings(rep, w)
    outliers = [(r.name, u, v) for r in rep.rows for u, v in r.outliers]
    for name, u, v in outliers:
        out += prose(f"outlier: {u} {name} = {_g(v, 5)} {param_unit(name)}: unusual for this "
                     "lot, not a failure (its own verdict is below)", w)  # fmt: skip
    for serial, why in rep.failing:
        out += prose(f"failing: {serial} ({why})", w)
    for serial, rms_z in rep.conditional:
        out += prose(f"conditional: {serial} ({CONDITIONAL}: the model does not fit its "
                     f"records, RMS z {_g(rms_z, 3)})", w)  # fmt: skip
    clean = rep.units - len(rep.failing) - len(rep.conditional)
    counts = ((clean, "PASS"), (len(rep.conditional), CONDITIONAL), (len(rep.failing), "FAIL"))
    said = ", ".join(f"{n} {v}" for n, v in counts if n)
    out += prose(f"latest verdicts: {said}", w) if said else []
    if rep.conditional:
        out += prose(FOOTNOTE, w)
    if not outliers and not rep.failing and not rep.conditional:
        out.append("no outlier, no failing unit, no conditional pass")
    return _text(out)


def charts(cs: Sequence[Chart], width: int | None = None) -> str:
    """``archive control``: per bench and parameter the limits and the points a rule fired on."""
    w = width or terminal_width()
    out = prose(
        "control charts (individuals, σ from the moving range of the first 20 points); rules: "
        + "; ".join(stats.RULES),
        w,
    )
    out += prose(
        f"in control a chart signals once per {stats.ARL_WESTERN_ELECTRIC:.0f} points on "
        f"average with all four rules ({stats.ARL_RULE1:.0f} with rule 1 alone)",
        w,
    )
    if not cs:
        return _text(out)
    fired = [[(i, f) for i, f in enumerate(c.fired) if f] for c in cs]
    bench_w = max(len(c.bench) for c in cs)
    name_w = max(len(c.name) for c in cs)
    for c, hits in zip(cs, fired, strict=True):
        out += prose(
            f"{c.bench:<{bench_w}}  {c.name:<{name_w}}  {len(c.values):>4} points  centre "
            f"{_g(c.centre, 5)}  σ {_g(c.sigma, 3)}  {len(hits)} signal(s)",
            w,
        )
        for i, f in hits[-5:]:
            rules = ",".join(str(x) for x in f)
            out += prose(
                f"    {c.times[i][:19].replace('T', ' ')}  {c.serials[i]}  "
                f"{_g(float(c.values[i]), 5)}  rule {rules}",
                w,
            )
    return _text(out)


def benches(
    rows: Sequence[BenchRow], k: float, alpha: float, reference: str, width: int | None = None
) -> str:
    """``check-bench``: each bench against the others on the reference unit."""
    w = width or terminal_width()
    flagged = sorted({r.bench for r in rows if r.flagged})
    out = prose(
        f"bench check on the reference unit {reference}: each bench against the others; "
        f"flagged beyond |z| > {k:.2f} (|Eₙ| > {k / 2:.2f} with U = 2u; false alarms: "
        f"{_rate(alpha)} of runs with no bench off)",
        w,
    )
    shown = [r for r in rows if r.flagged or abs(r.en) > 1]
    if shown:
        out += table(
            [
                Column("bench", [r.bench for r in shown], "<"),
                Column("parameter", [r.name for r in shown], "<"),
                Column("n", [str(r.sessions) for r in shown], rank=2),
                Column("mean", [_g(r.mean, 5) for r in shown]),
                Column("u", [_g(r.u, 2) for r in shown], rank=1),
                Column("others", [_g(r.ref, 5) for r in shown]),
                Column("z", [f"{r.z:+.1f}" for r in shown]),
                Column("Eₙ", [f"{r.en:+.2f}" for r in shown]),
                Column("", ["BIASED" if r.flagged else "" for r in shown], "<"),
            ],
            w,
        )
    out += prose(
        f"bench bias: {', '.join(flagged)}" if flagged else "no bench differs from the others",
        w,
    )
    return _text(out)
