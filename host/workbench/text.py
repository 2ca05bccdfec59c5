"""The workbench in words: the diagnosis, a before → after, the ladder, the catalogue, a demo.

Text rendering only (no statistics): the report of :func:`host.workbench.verdict.diagnose`, of
:func:`host.workbench.ladder.add_term` and :func:`host.workbench.ladder.ladder`, the term
catalogue for people, and what the workbench made of a hidden-effect case
(:mod:`host.workbench.scenarios`).
"""

from __future__ import annotations

import math
import textwrap
from collections.abc import Mapping, Sequence

import numpy as np

from host.model.catalogue import BASE
from host.model.fit import Fit, GroupResidual
from host.model.plate import seen_tilts_line
from host.model.spec import ModelTerm, short_spec
from host.model.terms import Term
from host.workbench.candidates import Candidate
from host.workbench.equals import Equals
from host.workbench.ladder import Addition
from host.workbench.scenarios import DemoOutcome, HiddenCase
from host.workbench.verdict import Diagnosis


def _fmt(v: float, unit: str) -> str:
    if not math.isfinite(v):
        return "—"
    a = abs(v)
    s = f"{v:.4g}" if a >= 1e-3 or a == 0 else f"{v:.3e}"
    return f"{s} {unit}".strip()


def _before_after(before: float, after: float) -> str:
    """'20.95 → 1.53', with digits enough (up to four) that a change shows: '20.952 → 20.947'."""
    for digits in range(2, 5):
        if f"{before:.{digits}f}" != f"{after:.{digits}f}":
            break
    return f"{before:.{digits}f} → {after:.{digits}f}"


def _z(z: float) -> str:
    """A residual in σ, or that the model passes exactly through it (no σ to divide by)."""
    return f"{z:+.1f} σ" if math.isfinite(z) else "fitted exactly"


def describe_residual(g: GroupResidual) -> str:
    """'gyro x, record y_up: measured 0.731 °/s, model 0.702, 8.1 σ'."""
    what = "integral" if g.unit == "°" else "mean"
    return (
        f"{g.sensor} {g.axis}, record {g.record}: measured {what} {g.measured:.4f} {g.unit}, "
        f"model {g.model:.4f}, residual {g.residual:+.4f} = {_z(g.z)}"
    )


def readable_spec(model: Sequence[ModelTerm]) -> str:
    """The model for reading: its short spec with a space after each comma, so that a long
    one wraps between terms ('base, temperature_bias:gyro:y'); not for ``--model``."""
    return ", ".join(short_spec(model).split(","))


def format_fit(fit: Fit, compare: bool = True) -> list[str]:
    """The fit's summary (and the compare table)."""
    lines = [
        f"model: {readable_spec(fit.model)}",
        f"fit: RMS z = {fit.rms_z:.2f} over {len(fit.groups)} record/channel values; "
        f"χ² = {fit.chi2:.1f} on {fit.dof} dof (p = {fit.chi2_p:.3g})",
    ]
    if compare:
        lines.append("compare (record, channel: measured, model, residual, z):")
        for g in fit.groups:
            lines.append(
                f"  {g.record:<10} {g.sensor} {g.axis}: {g.measured:>11.4f} {g.model:>11.4f} "
                f"{g.residual:>+9.4f} {g.unit:<4} {g.z:>+6.1f}"
            )
    return lines


def format_candidate(c: Candidate) -> str:
    """One candidate: its test's Δχ² with the χ² it falls from (on the yardstick it was tested
    on, named when that is not the fit's), RMS z before → after on the same yardstick, and
    SIGNIFICANT only when the test passes and RMS z falls."""
    if not c.identifiable:
        return f"{c.label}: NOT identifiable — {c.reason}; would need {c.needs}"
    mark = "SIGNIFICANT" if c.significant else "not significant"
    if c.rises:
        mark += " (its Δχ² passes the test, but RMS z does not fall: its parameters take the "
        mark += "records' degrees of freedom)"
    where = f"; tested with the {c.yardstick}" if c.yardstick else ""
    extra = ""
    if c.confounded_with:
        extra += f"; CONFOUNDED with {', '.join(c.confounded_with)}"
    if c.explained_by:
        extra += f"; explained by {c.explained_by}"
    if c.implausible:
        extra += f"; IMPLAUSIBLE: {c.implausible}"
    return (
        f"{c.label}: {mark}, Δχ² = {c.delta_chi2:.1f} of χ² {c.chi2_before:.1f} "
        f"(p = {c.p_value:.2g}{where}), ΔBIC = {c.delta_bic:+.1f}, "
        f"RMS z {_before_after(c.rms_z_before, c.rms_z_after)}, "
        f"coefficient {_fmt(c.coefficient, '')} ± {_fmt(c.stderr, c.unit)}{extra}"
    )


def format_diagnosis(
    d: Diagnosis,
    compare: bool = True,
    max_candidates: int = 12,
    try_line: str | None = None,
    see_one: Mapping[str, str] | None = None,
) -> str:
    """The human-readable report of :func:`diagnose`; ``try_line`` is the command that adds
    the recommended term, ``see_one`` term -> the lines of the command that adds a member of a
    group of equals (the caller knows the directory and options; else ``DIR``)."""
    lines = ["== 1. compare: measured vs model", *format_fit(d.fit, compare)]
    lines += _where_it_fails(d)
    lines += _what_is_missing(d, max_candidates)
    lines += _unexplained(d)
    lines += _verdict(d)
    lines += _recommended(d)
    for e in d.equals:
        lines.extend(format_equals(e, see_one))
    lines += _what_to_try(d, try_line)
    return "\n".join(lines)


def _where_it_fails(d: Diagnosis) -> list[str]:
    """Section 2: the worst records and channels, and the worst spans inside records."""
    lines = ["== 2. where it fails (|z| > 3, worst first)"]
    if not d.worst and not d.worst_spans:
        lines.append("  nowhere: every record and channel within 3 σ")
    for g in d.worst[:15]:
        lines.append("  " + describe_residual(g))
    for s in d.worst_spans[:5]:
        lines.append(
            f"  {s.sensor} {s.axis}, record {s.record}, {s.t0_s:.1f}–{s.t1_s:.1f} s: departs "
            f"from the record's mean by {s.residual:+.4f} {s.unit} = {s.z:+.1f} σ"
        )
    return lines


def _what_is_missing(d: Diagnosis, max_candidates: int) -> list[str]:
    """Section 3: the significant candidates, then the best of the rest up to
    ``max_candidates`` in all, then the terms not identifiable, one line per term and reason."""
    lines = ["== 3. what is missing (candidates, best first; Holm α = 0.01)"]
    sig = [c for c in d.candidates if c.significant]
    rest = [c for c in d.candidates if not c.significant and c.identifiable]
    for c in sig + rest[: max(0, max_candidates - len(sig))]:
        lines.append("  " + format_candidate(c))
    unident = [c for c in d.candidates if not c.identifiable]
    groups: dict[tuple[str, str], list[str]] = {}
    for c in unident:
        groups.setdefault((c.term, c.reason), []).append(f"{c.sensor}:{c.axes}")
    for (name, reason), chans in groups.items():
        needs = next(c.needs for c in unident if c.term == name)
        lines.append(
            f"  {name} ({', '.join(chans)}): NOT identifiable — {reason}; would need {needs}"
        )
    return lines


def _unexplained(d: Diagnosis) -> list[str]:
    """The structure no catalogue term explains, and the diagnosis's notes."""
    lines = []
    if d.unexplained:
        lines.append("== unexplained structure (no term of the catalogue explains it)")
        for h in d.unexplained[:10]:
            lines.append("  unexplained: " + h.describe())
    return lines + [f"note: {n}" for n in d.notes]


def _verdict(d: Diagnosis) -> list[str]:
    """The verdict, the channels whose residual follows a signal no term explains, and the
    recommended terms that leave nothing to test them."""
    lines = [f"== verdict: {d.verdict}"]
    for h in d.dominant:
        lines.append(
            f"  {h.sensor} {h.axis}: no catalogue term explains it; the residual follows "
            f"{h.signal} (Δχ² = {h.delta_chi2:.1f})"
            + ("; confounded with session time in this plan" if h.time_confounded else "")
        )
    if d.untestable_with:
        lines.extend(textwrap.wrap(
            f"with the recommended terms {', '.join(d.untestable_with)} are UNTESTABLE: no "
            "degrees of freedom left between records (the model passes exactly through each), "
            "so their fall of RMS z is no evidence that the terms are right; records that test "
            "them: other attitudes (tilt_45_*), turns both ways, headings recorded",
            78, initial_indent="  ", subsequent_indent="    "))  # fmt: skip
    return lines


def _recommended(d: Diagnosis) -> list[str]:
    """Each recommended term: its physics, its coefficients in words, and what would tell it
    from the terms it is confounded with."""
    lines = []
    by_label = {c.label: c for c in d.candidates}
    for label in d.recommended:
        c = by_label[label]
        lines.append(f"  {label}: {c.physics}")
        lines.extend("    " + t for t in explain(c, d.g))
        group = [c.label, *c.confounded_with]
        if len(group) > 1:
            lines.append(f"    the data cannot tell apart {' / '.join(group)}; to separate them:")
            for other in group:
                o = by_label.get(other)
                if o is not None:
                    lines.append(f"      {other}: {o.needs}")
    return lines


def _what_to_try(d: Diagnosis, try_line: str | None) -> list[str]:
    """The command that adds the recommended terms (``try_line``, else one naming ``DIR``),
    or why none is recommended."""
    if d.recommended_spec:
        return [try_line or f"  try: python3 -m host model add DIR {d.recommended_spec} "
                f"--model {short_spec(d.fit.model)}"]  # fmt: skip
    if d.equals:
        return ["  recommended alone: none (each group above is one finding)"]
    if d.verdict != "adequate":
        return ["  recommended: nothing from the catalogue"]
    return []


def format_equals(e: Equals, see_one: Mapping[str, str] | None = None) -> list[str]:
    """A group of equals for people (lines of at most 80 characters): its members, that the
    records cannot tell them apart, the records that would, and how to try one (``see_one``:
    term -> the command's lines, as :func:`format_diagnosis` takes them)."""

    def wrap(text: str, first: str, rest: str) -> list[str]:
        return textwrap.wrap(text, 80, initial_indent=first, subsequent_indent=rest)

    out = ["  a group of equals: the records cannot tell these apart (each explains",
           "  the misfit, none adds to another), so none is recommended alone:"]  # fmt: skip
    for m, dc in zip(e.members, e.delta_chi2, strict=True):
        kind = "term" if m in e.terms else "signal (no catalogue term)"
        out += wrap(f"{m} — {kind}, Δχ² = {dc:.1f}", "    ", "        ")
    out.append("  what would tell them apart:")
    for words in e.separate:
        out += wrap(words, "    - ", "      ")
    for t in e.terms:
        if see_one and t in see_one:
            out.append(see_one[t])
        else:
            out += wrap(f"to see one: python3 -m host model add DIR {t}", "  ", "      ")
    return out


def explain(c: Candidate, g: float) -> list[str]:
    """The candidate's coefficients in physical words (for the geometry terms: what tilt puts
    how much gravity on the channel, and which §3 bias estimate it moves)."""
    out = []
    if c.term == "face_error":
        for name, (v, se, _) in c.coefficients.items():
            pair = name.rsplit(".", 1)[-1]
            out.append(
                f"faces {pair} lean {1000 * v:+.2f} ± {1000 * se:.2f} mrad "
                f"({math.degrees(v):+.3f}°) toward {c.axes}: they put {g * v:+.4f} m/s² of "
                f"gravity on accelerometer {c.axes}, so its bias estimate from the {pair} pair "
                "(method.md §3) is off by that much"
            )
    elif c.term == "plate_tilt":
        for name, (v, se, _) in c.coefficients.items():
            side = name.rsplit(".", 1)[-1]
            ruler = " (along the ruler)" if side == "east" else " (across the ruler)"
            out.append(
                f"the plate leans {1000 * v:+.2f} ± {1000 * se:.2f} mrad "
                f"({math.degrees(v):+.3f}°) {side}{ruler}: {g * v:+.4f} m/s² of gravity on "
                "whichever accelerometer points that way, following the heading as the cube turns"
            )
        out.append(
            "  (a fixture error turns with the cube, a plate tilt stays in the room: the still "
            "moments of the turns, at several headings, tell them apart)"
        )
    elif c.term == "lever_arm" and len(c.coefficients) == 3:
        vals = [(float(v), float(e)) for v, e, _ in c.coefficients.values()]
        w2 = math.radians(90.0) ** 2
        perp = max(math.hypot(vals[i][0], vals[j][0]) for i, j in ((1, 2), (0, 2), (0, 1)))
        where = ", ".join(f"{a} {1000 * v:+.1f} ± {1000 * e:.1f} mm"
                          for a, (v, e) in zip("xyz", vals, strict=True))  # fmt: skip
        out.append(
            f"the sensor sits {where} from the centre of the cube (the turn axis): turning at "
            f"90 °/s the centripetal acceleration ω²·r⊥ puts up to {w2 * perp:.3f} m/s² on the "
            "horizontal accelerometers, and each push adds the tangential ω̇×r"
        )
    else:
        for name, (v, se, unit) in c.coefficients.items():
            out.append(f"{name} = {_fmt(v, '')} ± {_fmt(se, unit)}")
    return out


def format_addition(a: Addition) -> str:
    """Before → after of :func:`add_term`."""
    b, f = a.before, a.after
    lines = [
        f"added {', '.join(mt.label for mt in a.added)}",
        f"  RMS z  {b.rms_z:8.2f} → {f.rms_z:.2f}" + _fall(a),
        *_exact_lines(a),
        f"  χ²     {b.chi2:8.1f} → {f.chi2:.1f}  (dof {b.dof} → {f.dof}; p {b.chi2_p:.2g} → "
        f"{f.chi2_p:.2g})",
        f"  BIC    {b.bic:8.1f} → {f.bic:.1f}",
        *(
            [
                f"  held-out RMS z (each record predicted from the others) "
                f"{a.held_out[0].rms_z:.2f} → {a.held_out[1].rms_z:.2f}"
            ]
            if a.held_out is not None
            else []
        ),  # fmt: skip
        *(
            textwrap.wrap(
                f"before on the yardstick the term is tested on: {a.yardstick}",
                78,
                initial_indent="  ",
                subsequent_indent="    ",
            )
            if a.yardstick
            else []
        ),  # fmt: skip
        "  worst residuals before → after:",
    ]
    after_of = {(g.record, g.sensor, g.axis): g for g in f.groups}
    for g in sorted(b.groups, key=lambda g: -abs(g.z) if math.isfinite(g.z) else 0.0)[:5]:
        g2 = after_of[(g.record, g.sensor, g.axis)]
        lines.append(
            f"    {g.sensor} {g.axis}, {g.record}: {g.residual:+.4f} {g.unit} ({_z(g.z)}) → "
            f"{g2.residual:+.4f} ({_z(g2.z)})"
        )
    lines.append("  new coefficients:")
    for p in a.new_parameters:
        lines.append(f"    {p.name} = {_fmt(p.value, '')} ± {_fmt(p.stderr, p.unit)}")
    cov = f.covariance
    if cov is None:
        cov = np.diag([p.stderr**2 for p in f.parameters])
    seen = seen_tilts_line([p.name for p in f.parameters], [p.value for p in f.parameters], cov)
    if seen:
        lines.extend(textwrap.wrap(seen, 78, initial_indent="  ", subsequent_indent="    "))
    return "\n".join(lines)


def _fall(a: Addition) -> str:
    """How much smaller RMS z is — only when no channel is left fitted exactly by it."""
    b, f = a.before, a.after
    if a.exact:
        return "  (not a fall of the error: see below)"
    return f"  ({b.rms_z / f.rms_z:.1f}× smaller)" if f.rms_z > 0 else ""


def _exact_lines(a: Addition) -> list[str]:
    """The channels the addition fits exactly, and RMS z on the channels it leaves testable;
    the records' own views of the plate's tilt tested against the plate's."""
    out: list[str] = []
    if a.exact:
        tb, ta = a.tested_rms_z()
        rest = (f"on the channels still tested, RMS z {tb:.2f} → {ta:.2f}" if math.isfinite(ta)
                else "no channel is left to test it")  # fmt: skip
        out += textwrap.wrap(
            f"{', '.join(a.exact)}: UNTESTABLE with it — no degrees of freedom left between "
            f"records (the model passes exactly through each), so their RMS z says nothing; "
            f"{rest}", 78, initial_indent="  ", subsequent_indent="    ")  # fmt: skip
    if a.seen_tilt is not None:
        out += textwrap.wrap(a.seen_tilt.describe(), 78, initial_indent="  ",
                             subsequent_indent="    ")  # fmt: skip
    return out


def physics_paragraph(t: Term) -> str:
    """The first paragraph of the term's docstring, on one line."""
    return " ".join(t.doc.strip().split("\n\n")[0].split())


def format_terms(cat: Mapping[str, Term]) -> str:
    """The catalogue for people: each term's physics, parameters with units per sensor, and
    what data identifies it (lines of at most 80 characters)."""
    out: list[str] = []
    for t in cat.values():
        out.append(t.name + ("  (base model, method.md §2)" if t.name in BASE else ""))
        out += textwrap.wrap(physics_paragraph(t), 80, initial_indent="  ",
                             subsequent_indent="  ")  # fmt: skip
        for sensor in t.sensors:
            units = ", ".join(f"{p} [{u}]" for p, u in zip(t.params, t.param_units(sensor),
                                                             strict=True))  # fmt: skip
            out += textwrap.wrap(f"{sensor}: {units}", 80, initial_indent="  ",
                                 subsequent_indent="    ")  # fmt: skip
        if t.needs:
            out += textwrap.wrap(f"needs: {t.needs}", 80, initial_indent="  ",
                                 subsequent_indent="    ")  # fmt: skip
    out.append("")
    out.append("Use: --model base,TERM[:SENSOR[:AXES]] (e.g. temperature_bias:gyro:x); your own")
    out.append("terms: --term-file my_terms.py (README, 'Your own term').")
    return "\n".join(out) + "\n"


def format_case(case: HiddenCase) -> str:
    """The heading of a hidden-effect demo: the effect and the term hidden from the fit."""
    lines = [f"######## hidden effect: {case.effect} — {case.description}"]
    if case.term:
        value = (
            "(" + ", ".join(f"{v:.4g}" for v in case.truth_vector) + ")"
            if case.truth_vector
            else f"{case.truth:.4g}"
        )
        lines.append(f"hidden from the fit: {case.term} = {value} {case.unit}")
    return "\n".join(lines)


def format_outcome(o: DemoOutcome, try_line: str | None = None) -> str:
    """What the workbench made of a hidden-effect case: the diagnosis (``try_line``: the
    command adding the recommended term, see :func:`format_diagnosis`), the addition, and
    whether it named the hidden term (and how close its coefficient came to the truth)."""
    case = o.case
    lines = [format_diagnosis(o.diagnosis, compare=False, max_candidates=6, try_line=try_line)]
    if o.addition is not None:
        what = "the hidden term" if case.term else "the top candidate"
        lines.append(f"-- adding {what}")
        lines.append(format_addition(o.addition))
    if case.term:
        lines.append(
            f"== result: named first: {o.found or 'nothing'}"
            + (f" (confounded group {', '.join(o.group)})" if len(o.group) > 1 else "")
            + f" → {'FOUND' if o.named_hidden else 'MISSED'}; coefficient {o.coefficient:.4g} "
            f"vs truth {case.truth:.4g} {case.unit} ({100 * o.coefficient_error:.1f} % off)"
        )
    else:
        lines.append(f"== result: verdict {o.diagnosis.verdict} (expected adequate)")
    return "\n".join(lines)
