"""The verdict policy of a calibration result: which values pass, whether the result does.

Pure functions of a result's values (any object with the fields of :class:`Judged`; the result
of :mod:`host.calib.result` is one): the method.md §7 mark of every toleranced value under the
result's decision rule (:mod:`host.calib.decision`: ``+``, ``−`` or ``?``, which is not a
pass), the values that fail, whether the whole result passes (every value ``+`` and
determined, every record of the method measured (else INCOMPLETE), the held-out records
predicted within the §8 accuracy, no failed self-test) and
whether a PASS is *conditional* (it rests on a model that does not fit the records). Their
words are :mod:`host.calib.result_text`.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from typing import Protocol

from host.calib.decision import FAIL, PASS, UNDECIDED, expanded_uncertainty, mark
from host.calib.values import (
    FitQuality,
    ParameterResult,
    RecordResidual,
    Verification,
    constants_of,
    tolerance_of,
    undetermined_of,
)
from host.session.method import NOISE_NAMES
from host.session.records import (
    MOVE_NAME_RE,
    POSE_NAME_RE,
    RECORD_NAME_RE,
    STATIC_NAMES,
    TURN_NAMES,
)


class Judged(Protocol):
    """What the policy reads of a result."""

    @property
    def parameters(self) -> tuple[ParameterResult, ...]: ...

    @property
    def noise_std(self) -> Mapping[str, float]: ...

    @property
    def fit(self) -> FitQuality | None: ...

    @property
    def verification(self) -> Verification | None: ...

    @property
    def self_test(self) -> str: ...

    @property
    def decision_rule(self) -> str: ...

    @property
    def records(self) -> tuple[str, ...]: ...

    @property
    def residuals(self) -> tuple[RecordResidual, ...]: ...


def method_records(r: Judged) -> tuple[str, ...]:
    """The records the result's method asks for: a session of faces and turns (any record
    named ``x_up`` … ``z_cw``) follows method.md §3, §4 — the six faces, and a turn each way
    about each axis unless rate-table records measure the gyro instead; () for a session of
    another plan (poses and moves, or records of other names), which names no fixed set."""
    kinds = {x.record: x.kind for x in r.residuals} or dict.fromkeys(r.records, "")
    if not any(RECORD_NAME_RE.match(n) for n in kinds) or any(
        POSE_NAME_RE.match(n) or MOVE_NAME_RE.match(n) for n in kinds
    ):
        return ()
    rates = any(k == "rate" for k in kinds.values())
    return STATIC_NAMES if rates else STATIC_NAMES + TURN_NAMES


def missing_records(r: Judged) -> list[str]:
    """The method's records (:func:`method_records`) the session did not measure, in the
    method's order; a repeat (``x_ccw_2``) measures its record too. Any makes the result
    INCOMPLETE, not a pass."""
    measured = set()
    for name in {x.record for x in r.residuals} or set(r.records):
        if m := RECORD_NAME_RE.match(name):
            measured.add(f"{m.group('axis')}_{m.group('dir')}")
    return [n for n in method_records(r) if n not in measured]


def value_mark(
    name: str, value: float, stderr: float, rule: str, dof: float = math.inf
) -> str | None:
    """The mark of the §7 value ``name`` (``value``, its 1-σ ``stderr`` read on ``dof``
    degrees of freedom; NaN: none) under ``rule`` (:func:`host.calib.decision.mark`, U = k ·
    stderr, :func:`host.calib.decision.expanded_uncertainty`); None: no tolerance."""
    tol = tolerance_of(name)
    if tol is None:
        return None
    u = expanded_uncertainty(stderr, dof)
    return mark(value, tol, u, rule, one_sided=name in NOISE_NAMES)


def marks(r: Judged) -> dict[str, str | None]:
    """§7 name -> its mark under the result's decision rule: ``+``, ``−`` (outside, or not
    determined), ``?`` (U reaches across a limit: not a pass), None no tolerance (or not in
    the model)."""
    stderr = {p.name: p.stderr for p in r.parameters}
    dof = {p.name: p.dof for p in r.parameters}
    in_model = set(stderr) | set(r.noise_std)
    consts = constants_of(r.parameters, r.noise_std)
    return {
        n: value_mark(n, v, stderr.get(n, math.nan), r.decision_rule, dof.get(n, math.inf))
        if n in in_model
        else None
        for n, v in consts.items()
    }


def passed(r: Judged) -> dict[str, bool | None]:
    """§7 name -> True where the mark is ``+``, False ``−`` or ``?``, None no tolerance (or
    not in the model)."""
    return {n: None if m is None else m == PASS for n, m in marks(r).items()}


def judged_parameters(r: Judged) -> tuple[ParameterResult, ...]:
    """The result's parameters, each §7 one's ``passed`` flag as the decision rule gives it
    (the flag a result file and the archive keep)."""
    flags = passed(r)
    return tuple(
        dataclasses.replace(p, passed=flags[p.name]) if p.name in flags else p for p in r.parameters
    )


def undecided(r: Judged) -> list[str]:
    """Names of the §7 values marked ``?``: their value ± U reaches across a limit."""
    return [n for n, m in marks(r).items() if m == UNDECIDED]


def outside(r: Judged) -> list[str]:
    """Names of the §7 values marked ``−`` (outside tolerance, or not determined), then of
    the other parameters not determined."""
    bad = [n for n, m in marks(r).items() if m == FAIL]
    return bad + [p.name for p in undetermined_of(r.parameters) if p.name not in bad]


def failed_values(r: Judged) -> list[str]:
    """Names of every value that is not a pass: outside tolerance or not determined
    (:func:`outside`), then undecided (:func:`undecided`)."""
    return outside(r) + undecided(r)


def reasons(r: Judged) -> list[str]:
    """Why the result is not a pass, in words ('outside tolerance: Gxx, A0z'); [] when it
    passed (:func:`all_passed`)."""
    consts = constants_of(r.parameters, r.noise_std)
    bad = [n for n in outside(r) if n in consts and math.isfinite(consts[n])]
    out = [f"records of the method not measured: {', '.join(gone)}"] if (
        gone := missing_records(r)) else []  # fmt: skip
    if bad:
        out.append(f"outside tolerance: {', '.join(bad)}")
    if unsure := undecided(r):
        out.append(f"undecided under {r.decision_rule} acceptance: {', '.join(unsure)}")
    if nan := undetermined_of(r.parameters):
        out.append(f"not determined: {', '.join(p.name for p in nan)}")
    if r.verification is not None and not r.verification.passed:
        out.append("held-out records not predicted within the limits")
    if r.self_test == "fail":
        out.append("the sensor failed its self-test")
    if not out and not all_passed(r):  # a cause named nowhere above is still no pass
        out.append("the verdict is not a pass")
    return out


def all_passed(r: Judged) -> bool:
    """Every toleranced value marked ``+``, every parameter determined, every record of the
    method measured, the held-out records (if verified) predicted within the §8 accuracy, and
    no failed self-test of the sensor."""
    ok = all(p is not False for p in passed(r).values()) and not undetermined_of(r.parameters)
    ok = ok and not missing_records(r)
    ok = ok and r.self_test != "fail"
    return ok and (r.verification is None or r.verification.passed)


def misfit(r: Judged) -> bool:
    """The fit's verdict is ``inadequate``: the model does not explain the records."""
    return r.fit is not None and r.fit.verdict == "inadequate"


def conditional(r: Judged) -> bool:
    """A PASS that rests on a model that does not fit these records: every value is within
    tolerance as fitted, but it holds only if the effect the model lacks does not bias the
    values. It does not change :func:`all_passed` (nor the exit status 0)."""
    return all_passed(r) and misfit(r)
