"""Plain-text rendering of the archive's answers (what ``python -m host archive`` prints); the
logic is in :mod:`host.archive.checks`, nothing here decides anything."""

from __future__ import annotations

import math
from collections.abc import Sequence

from host.archive import stats
from host.archive.checks import BenchRow, Chart, DriftRow, LotReport, RepeatRow, TrendPoint
from host.archive.entry import Entry
from host.archive.store import Summary


def _g(v: float, digits: int = 4) -> str:
    return "—" if not math.isfinite(v) else f"{v:.{digits}g}"


def _rate(alpha: float) -> str:
    return f"{100 * alpha:g} %"


def summaries(rows: Sequence[Summary]) -> str:
    """The lines of ``archive list``."""
    if not rows:
        return "the archive has no calibration of this selection\n"
    head = f"{'id':>6}  {'serial':<12} {'bench':<8} {'measured (UTC)':<20} {'verdict':<7} "
    head += f"{'self-test':<9} {'fit':<12} {'result':<10}\n"
    body = "".join(
        f"{r.id:>6}  {r.serial:<12} {r.bench or '-':<8} {r.measured_at[:19]:<20} "
        f"{r.verdict.upper():<7} {r.self_test or '-':<9} {r.fit_verdict or '-':<12} "
        f"{r.result_hash[:10]}\n"
        for r in rows
    )
    return head + body


def entry(e: Entry) -> str:
    """``archive show``: the identity, the hashes and every parameter with its σ."""
    lines = [
        f"serial {e.serial}   bench {e.bench or '-'}   operator {e.operator or '-'}   "
        f"lot {e.lot or '-'}",
        f"measured {e.measured_at}   firmware {e.firmware or '-'}   sensor revision "
        f"{e.sensor_revision or '-'}",
        f"chip temperature {_g(e.temp_min_c, 3)} … {_g(e.temp_max_c, 3)} °C "
        f"(mean {_g(e.temp_mean_c, 3)})",
        f"model {e.model}",
        f"fit: χ² = {_g(e.chi2)} on {e.dof} dof, RMS z = {_g(e.rms_z, 3)}, p = {_g(e.p, 3)}: "
        f"{e.fit_verdict or '-'}",
        f"verdict {e.verdict.upper()}   self-test {e.self_test or 'not recorded'}",
        f"result  sha256 {e.result_hash}",
        f"report  sha256 {e.report_hash}",
        f"records sha256 {e.records_hash} ({len(e.record_hashes)} files)",
        f"covariance: {e.covariance_kind}",
        "",
        f"{'parameter':<28} {'value':>12} {'σ':>10}  unit",
    ]
    lines += [f"{p.name:<28} {_g(p.value, 6):>12} {_g(p.stderr, 3):>10}  {p.unit}"
              for p in e.parameters]  # fmt: skip
    return "\n".join(lines) + "\n"


def trend(serial: str, points: dict[str, list[TrendPoint]]) -> str:
    """``archive trend``: each parameter against time with its σ."""
    out = [f"trend of {serial}: each parameter against time (value ± σ)"]
    for name, ps in points.items():
        out.append(f"\n{name}")
        out += [f"  {p.measured_at[:19]}  {p.bench or '-':<8} {_g(p.value, 6):>12} ± "
                f"{_g(p.stderr, 2)}" for p in ps]  # fmt: skip
    return "\n".join(out) + "\n"


def repeat(rows: Sequence[RepeatRow], alpha: float) -> str:
    """``archive repeat``: per unit and bench, the failing parameters (all of them for one
    unit), and the verdict."""
    units = sorted({(r.serial, r.bench) for r in rows})
    failed = sorted({(r.serial, r.bench) for r in rows if r.failed})
    tested = sum(1 for r in rows if r.dof >= 1)
    out = [
        f"repeatability: between-session scatter against the σ of each fit, χ² per parameter; "
        f"false alarms: {_rate(alpha)} of runs over a lot with nothing wrong "
        f"({tested} parameters tested, p < {alpha / max(tested, 1):.2g} fails)"
    ]
    show = rows if len(units) == 1 else [r for r in rows if (r.serial, r.bench) in failed]
    if show:
        out.append(
            f"{'serial':<12} {'bench':<8} {'parameter':<24} {'n':>2} {'mean':>11} "
            f"{'scatter':>9} {'σ pred':>9} {'χ²':>8} {'p':>8} {'CV':>7}"
        )
    for r in show:
        cv = "—" if not math.isfinite(r.cv) else f"{100 * r.cv:.2f}%"
        mark = "  NOT REPEATABLE" if r.failed else ""
        out.append(
            f"{r.serial:<12} {r.bench:<8} {r.name:<24} {r.n:>2} {_g(r.mean, 5):>11} "
            f"{_g(r.scatter, 3):>9} {_g(r.predicted, 3):>9} {_g(r.chi2, 3):>8} "
            f"{_g(r.p, 2):>8} {cv:>7}{mark}"
        )
    few = sorted({(r.serial, r.bench) for r in rows if r.dof < 1})
    if few:
        out.append(f"untestable (one session only): {len(few)} unit/bench pair(s)")
    if failed:
        out.append(
            "NOT REPEATABLE: " + ", ".join(f"{s} on {b}" for s, b in failed)
            + " — the sessions disagree beyond their σ: look at the mounting and the records"
        )  # fmt: skip
    else:
        out.append(f"repeatable: {len(units) - len(few)} unit/bench pair(s) agree within their σ")
    return "\n".join(out) + "\n"


def drift(rows: Sequence[DriftRow], k: float, alpha: float) -> str:
    """``archive drift``: the units whose parameters moved since their last calibration."""
    moved = [r for r in rows if r.moved]
    units = sorted({r.serial for r in moved})
    out = [
        f"drift since the last calibration: |Δ| > {k:.2f}·σ (false alarms: {_rate(alpha)} of "
        f"runs with nothing moved, over {len(rows)} parameters) or beyond --tol"
    ]
    for r in moved:
        out.append(
            f"{r.serial:<12} {r.name:<24} {r.before_at[:10]} {_g(r.before, 5):>11} -> "
            f"{r.after_at[:10]} {_g(r.after, 5):>11}  Δ = {_g(r.delta, 3)} ({r.z:+.1f} σ)"
        )
    out.append(
        f"recalibrate: {', '.join(units)}" if units else "no unit moved beyond k·σ or tolerance"
    )
    return "\n".join(out) + "\n"


def lot(rep: LotReport, alpha: float) -> str:
    """``archive lot``: per parameter mean, spread, 3σ band against the datasheet, outliers."""
    out = [
        f"lot of {rep.units} unit(s), each unit's latest calibration; outliers by Grubbs' test "
        f"(false alarms: {_rate(alpha)} of lots with no outlier)",
        f"{'parameter':<24} {'n':>4} {'mean':>11} {'spread':>10} {'mean−3σ':>11} {'mean+3σ':>11} "
        f"{'limit':>8}  datasheet",
    ]
    for r in rep.rows:
        s = r.summary
        ok = {None: "-", True: "within", False: "OUTSIDE"}[s.within]
        out.append(
            f"{r.name:<24} {s.n:>4} {_g(s.mean, 4):>11} {_g(s.spread, 3):>10} "
            f"{_g(s.low, 4):>11} {_g(s.high, 4):>11} {_g(s.limit or math.nan, 3):>8}  {ok}"
        )
    outliers = [(r.name, u, v) for r in rep.rows for u, v in r.outliers]
    for name, u, v in outliers:
        out.append(f"outlier: {u} {name} = {_g(v, 5)}")
    for serial, why in rep.failing:
        out.append(f"failing: {serial} ({why})")
    if not outliers and not rep.failing:
        out.append("no outlier, no failing unit")
    return "\n".join(out) + "\n"


def charts(cs: Sequence[Chart]) -> str:
    """``archive control``: per bench and parameter the limits and the points a rule fired on."""
    out = [
        "control charts (individuals, σ from the moving range of the first 20 points); rules: "
        + "; ".join(stats.RULES),
        f"in control a chart signals once per {stats.ARL_WESTERN_ELECTRIC:.0f} points on average "
        f"with all four rules ({stats.ARL_RULE1:.0f} with rule 1 alone)",
    ]
    for c in cs:
        hits = [(i, f) for i, f in enumerate(c.fired) if f]
        out.append(
            f"{c.bench:<8} {c.name:<24} {len(c.values):>4} points  centre {_g(c.centre, 5)}  "
            f"σ {_g(c.sigma, 3)}  {len(hits)} signal(s)"
        )
        for i, f in hits[-5:]:
            rules = ",".join(str(x) for x in f)
            out.append(
                f"    {c.times[i][:19]} {c.serials[i]:<12} {_g(float(c.values[i]), 5)} rule {rules}"
            )
    return "\n".join(out) + "\n"


def benches(rows: Sequence[BenchRow], k: float, alpha: float, reference: str) -> str:
    """``check-bench``: each bench against the others on the reference unit."""
    flagged = sorted({r.bench for r in rows if r.flagged})
    out = [
        f"bench check on the reference unit {reference}: each bench against the others; "
        f"flagged beyond |z| > {k:.2f} (|Eₙ| > {k / 2:.2f} with U = 2u; false alarms: "
        f"{_rate(alpha)} of runs with no bench off)",
        f"{'bench':<8} {'parameter':<24} {'n':>2} {'mean':>11} {'u':>9} {'others':>11} "
        f"{'z':>7} {'Eₙ':>7}",
    ]
    for r in rows:
        if r.flagged or abs(r.en) > 1:
            mark = "  BIASED" if r.flagged else ""
            out.append(
                f"{r.bench:<8} {r.name:<24} {r.sessions:>2} {_g(r.mean, 5):>11} "
                f"{_g(r.u, 2):>9} {_g(r.ref, 5):>11} {r.z:>+7.1f} {r.en:>+7.2f}{mark}"
            )
    out.append(
        f"bench bias: {', '.join(flagged)}" if flagged else "no bench differs from the others"
    )
    return "\n".join(out) + "\n"
