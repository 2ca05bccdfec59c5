"""The report's tables of numbers: noise, residuals per record in the order measured, the
stage-1 bias consistency and the held-out verification (:mod:`host.calib.report` sets them in
the text report, :mod:`host.calib.report_pdf` in the PDF), and how the report writes a value
and its mark."""

from __future__ import annotations

import math

from host.calib.report_lines import wrap
from host.calib.result import CalibrationResult
from host.calib.values import RecordResidual, Verification
from host.session.method import ACCEL_BIAS_NAMES, GYRO_BIAS_NAMES, NOISE_NAMES, UNITS

PLUS, MINUS = "+", "−"


def value_text(x: float, dec: int = 5) -> str:
    return f"{x:+.{dec}f}" if math.isfinite(x) else "n/d"


def mark(ok: bool | None) -> str:
    return " " if ok is None else (PLUS if ok else MINUS)


def measured_order(r: CalibrationResult) -> list[RecordResidual]:
    """The residuals of ``r`` in the order their records were measured (sitting, then
    ``session_s``); records of unknown time last, by name."""
    order = r.provenance.measured_order if r.provenance is not None else ()
    rank = {name: i for i, name in enumerate(order)}
    return sorted(r.residuals, key=lambda x: (rank.get(x.record, len(rank)), x.record))


def sitting_of(r: CalibrationResult) -> dict[str, int]:
    """record -> the number of the sitting it was measured in (1, 2, … as the report's
    PROCEDURE counts them: ``--resume`` and ``--redo`` each start one); empty when the result
    does not say (format v1/v2)."""
    if r.provenance is None:
        return {}
    return {n: i for i, st in enumerate(r.provenance.sittings, 1) for n in st.records}


def bias_consistency(r: CalibrationResult) -> list[str]:
    """§3's three bias estimates per bias, from the X, Y, Z face pairs, and their spread."""
    out = [
        "Stage 1 bias consistency (§3): estimates from the X, Y, Z pairs",
        f"  {'bias':<6}{'X pair':>11}{'Y pair':>11}{'Z pair':>11}{'mean':>11}{'spread':>11}",
    ]
    for n in GYRO_BIAS_NAMES + ACCEL_BIAS_NAMES:
        if n not in r.bias_estimates:
            continue
        e = r.bias_estimates[n]
        spread = max(e) - min(e)
        mean = sum(e) / 3.0
        cells = "".join(f"{value_text(x):>11}" for x in (*e, mean))
        out.append(f"  {n:<6}{cells}{spread:>11.5f} {UNITS[n]}")
    out.append("  A spread much larger than the noise means the linear model misses")
    out.append("  something (method.md §3).")
    return out


def noise_lines(r: CalibrationResult) -> list[str]:
    consts = r.constants()
    return [
        "Noise (std): largest over the static orientations, per channel (§3)",
        "  gyro  °/s : " + "  ".join(f"{n} {consts[n]:.4f}" for n in NOISE_NAMES[:3]),
        "  accel m/s²: " + "  ".join(f"{n} {consts[n]:.4f}" for n in NOISE_NAMES[3:]),
    ]


def residual_table(r: CalibrationResult) -> list[str]:
    """Every record's residuals in the order measured, with its sitting and start."""
    out = [
        "Residuals per record in the order measured (measured − model): mean / std of",
        "samples; turns: integral residual, degrees; sit: the sitting it was measured in",
        "(PROCEDURE above); at: its start, s into that sitting",
        f"  {'record':<9}{'sit':>4}{'at,s':>6}{'T,s':>5}  {'accel x y z, m/s²':<24}"
        f"{'gyro x y z, °/s (turns °)':<26}",
    ]
    at = r.provenance.session_s if r.provenance is not None else {}
    sitting = sitting_of(r)
    for res in measured_order(r):
        t = at.get(res.record)
        t_s = f"{t:6.0f}" if t is not None else f"{'-':>6}"
        sit = str(sitting.get(res.record, "-"))
        head = f"  {res.record[:9]:<9}{sit:>4}{t_s}{res.duration_s:>5.1f}  "
        out.extend(residual_rows(head, res))
    return out


def residual_rows(head: str, res: RecordResidual) -> list[str]:
    """One record's rows of the residual table: a turn's integral residuals, a static's or
    rate's means (and a static's samples' std)."""
    if res.kind == "turn" and res.angle_deg is not None:
        return [head + f"{'-':<24}" + " ".join(f"{x:+8.3f}" for x in res.angle_deg) + " °"]
    acc = " ".join(f"{x:+.4f}" if math.isfinite(x) else "    -  " for x in res.accel_mean)
    gyr = " ".join(f"{x:+8.4f}" for x in res.gyro_mean)
    out = [head + f"{acc:<24}" + gyr]
    if res.kind == "static":
        accs = " ".join(f"{x:7.4f}" for x in res.accel_std)
        gyrs = " ".join(f"{x:8.4f}" for x in res.gyro_std)
        out.append(f"  {'  std':<24}  {accs:<24}{gyrs}")
    return out


def verification_lines(v: Verification) -> list[str]:
    """The held-out records measured against the result (method.md §8 limits)."""
    out = wrap(f"Verification on records not used in the fit: {v.source}", "", "  ")
    out.append("  measured − predicted (limits of method.md §8: 0.01 g, 0.5 °/s; turns °)")
    for x in v.values:
        out.append(
            f"  {x.record[:10]:<10} {x.channel:<8}{x.residual:>+11.4f} {x.unit:<5}"
            f"± {x.sigma:<9.2g} z {x.z:>+7.1f}   limit {x.limit:.3g}  {mark(x.passed)}"
        )
    out.append(
        f"  RMS z = {v.rms_z:.2f}, χ² = {v.chi2:.1f} on {len(v.values)} values "
        f"(p = {v.p:.3g}): {'all within' if v.passed else 'NOT all within'} the limits"
    )
    return out


def residual_cells(r: CalibrationResult) -> list[list[str]]:
    """The residual table as cells, a row per record in the order measured (record, sitting,
    start s, length s, accel x y z m/s², gyro x y z °/s; a turn's integral residuals, degrees,
    in the gyro cells), and a static record's samples' std in a row below it."""
    at = r.provenance.session_s if r.provenance is not None else {}
    sitting = sitting_of(r)
    out: list[list[str]] = []
    for res in measured_order(r):
        t = at.get(res.record)
        head = [res.record, str(sitting.get(res.record, "-")),
                "-" if t is None else f"{t:.0f}", f"{res.duration_s:.1f}"]  # fmt: skip
        if res.kind == "turn" and res.angle_deg is not None:
            out.append([*head, "-", "-", "-", *(f"{x:+.3f}°" for x in res.angle_deg)])
            continue
        acc = [f"{x:+.4f}" if math.isfinite(x) else "-" for x in res.accel_mean]
        out.append([*head, *acc, *(f"{x:+.4f}" for x in res.gyro_mean)])
        if res.kind == "static":
            std = [*(f"{x:.4f}" for x in res.accel_std), *(f"{x:.4f}" for x in res.gyro_std)]
            out.append(["  std", "", "", "", *std])
    return out
