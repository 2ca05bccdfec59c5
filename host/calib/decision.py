"""The decision rule: how a value, its expanded uncertainty U and its tolerance give its mark.

Pure functions (ILAC-G8:09/2019, §4.2; ISO/IEC 17025 §7.8.6 asks the report to state the rule):

- ``guarded`` — guarded acceptance, the guard band w = U (95 % coverage): ``+`` (pass) only where
  the whole interval value ± U lies within the tolerance, ``−`` (fail) only where it lies
  wholly outside, ``?`` (not decided: ILAC-G8's conditional pass and conditional fail) where it
  reaches across a limit. A ``?`` is not a pass. For a value whose true value sits on a limit
  the chance of a false ``+`` is at most about 2.3 %.
- ``simple`` — simple acceptance (w = 0, "shared risk"): ``+`` where the value lies within the
  tolerance, ``−`` where it does not; U is not used. A value on a limit is accepted with a
  chance of up to 50 % that its true value is outside.

A tolerance is closed: a value (or value ± U) that touches the limit is within it. A value
not determined (NaN) is ``−`` under either rule. A value without a U (the noise levels: the
method gives none) is judged on its value alone under either rule.

U = k·σ covers the true value with :data:`COVERAGE` (95.45 %, ±2σ of a normal distribution):
k = 2 for a σ from the noise model alone; for a σ read on few degrees of freedom (a variance
component of the session carries part of it: the parameter's ``dof``) k is Student's t at
that coverage on those dof (GUM G.3: 3.31 on 3 dof, 2.52 on 6), :func:`coverage_factor`.
"""

from __future__ import annotations

import math

from host.model.stats import NORMAL_DOF

#: coverage factor of the expanded uncertainty of an exact σ: U = K · standard error
K = 2.0
#: the coverage probability of U: that of ±K σ of a normal distribution (95.45 %)
COVERAGE = math.erf(K / math.sqrt(2.0))
GUARDED, SIMPLE = "guarded", "simple"
#: the rules ``calibrate --decision-rule`` chooses from
RULES = (GUARDED, SIMPLE)
#: the rule of a new result: a certificate a laboratory signs takes the low-risk one
DEFAULT_RULE = GUARDED
#: the rule of a result file written before results carried one (they were judged by it)
LEGACY_RULE = SIMPLE
PASS, FAIL, UNDECIDED = "+", "−", "?"


def coverage_factor(dof: float = math.inf) -> float:
    """k of U = k·σ for a σ read on ``dof`` degrees of freedom: Student's t at
    :data:`COVERAGE` (two-sided) on them; :data:`K` for an exact σ (inf, or at least
    :data:`host.model.stats.NORMAL_DOF`). ValueError for a dof that is not positive."""
    if not dof > 0:
        raise ValueError(f"a σ's dof is {dof!r}: expected a positive number")
    if dof >= NORMAL_DOF:
        return K
    from scipy import stats

    return float(stats.t.isf(0.5 * (1.0 - COVERAGE), dof))


def expanded_uncertainty(stderr: float, dof: float = math.inf) -> float:
    """U = k·``stderr`` (same unit) at :data:`COVERAGE`, k by :func:`coverage_factor`."""
    return coverage_factor(dof) * stderr


def coverage_note(dof: float = math.inf) -> str:
    """What a U's row says of its k where it is Student's t ('k = 3.31, 3 dof'); '' for
    :data:`K`."""
    k = coverage_factor(dof)
    return "" if k == K else f"k = {k:.2f}, {dof:.0f} dof"


def check_rule(rule: str) -> str:
    """``rule`` when it is one of :data:`RULES`; ValueError naming them otherwise."""
    if rule not in RULES:
        raise ValueError(f"decision rule {rule!r}: expected one of {', '.join(RULES)}")
    return rule


def mark(
    value: float, tolerance: float, expanded_u: float, rule: str, one_sided: bool = False
) -> str:
    """The mark of ``value`` against ``tolerance`` (±tolerance, or ≤ tolerance when
    ``one_sided``) under ``rule``, with ``expanded_u`` the value's U in the same unit (NaN:
    no U, the value is judged alone): :data:`PASS`, :data:`FAIL` or :data:`UNDECIDED`."""
    check_rule(rule)
    if not math.isfinite(value):
        return FAIL
    size = value if one_sided else abs(value)
    u = expanded_u if rule == GUARDED and math.isfinite(expanded_u) else 0.0
    u = abs(u)
    if size + u <= tolerance:
        return PASS
    if size - u > tolerance:
        return FAIL
    return UNDECIDED


def statement(rule: str) -> str:
    """The rule in words, as the report states it (ISO/IEC 17025 §7.8.6)."""
    if check_rule(rule) == GUARDED:
        return (
            "Decision rule: guarded acceptance (ILAC-G8:09/2019, guard band w = U, 95 %): "
            "+ where the value ± U lies within the tolerance, − where it lies wholly outside, "
            "? where it reaches across a limit (not a pass); values without U (the noise "
            "levels) are judged on their value."
        )
    return (
        "Decision rule: simple acceptance (ILAC-G8:09/2019, w = 0): + where the value lies "
        "within the tolerance, − where it does not; U is not used (a value near a limit may "
        "be accepted with up to 50 % risk that it is outside)."
    )
