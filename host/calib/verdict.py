"""The verdict policy of a calibration result: which values pass, whether the result does.

Pure functions of a result's values (any object with the fields of :class:`Judged`; the result
of :mod:`host.calib.result` is one): the method.md §7 pass flag of every toleranced value, the
values that fail, whether the whole result passes (every value within tolerance and
determined, the held-out records predicted within the §8 accuracy, no failed self-test) and
whether a PASS is *conditional* (it rests on a model that does not fit the records). Their
words are :mod:`host.calib.result_text`.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Protocol

from host.calib.values import (
    FitQuality,
    ParameterResult,
    Verification,
    constants_of,
    undetermined_of,
    within,
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


def passed(r: Judged) -> dict[str, bool | None]:
    """§7 name -> True within tolerance, False outside or not determined, None no tolerance
    (or not in the model)."""
    in_model = {p.name for p in r.parameters} | set(r.noise_std)
    consts = constants_of(r.parameters, r.noise_std)
    return {n: within(n, v) if n in in_model else None for n, v in consts.items()}


def failed_values(r: Judged) -> list[str]:
    """Names of the §7 values outside tolerance, then of the parameters not determined."""
    bad = [n for n, ok in passed(r).items() if ok is False]
    return bad + [p.name for p in undetermined_of(r.parameters) if p.name not in bad]


def all_passed(r: Judged) -> bool:
    """Every toleranced value within tolerance, every parameter determined, the held-out
    records (if verified) predicted within the §8 accuracy, and no failed self-test of the
    sensor."""
    ok = all(p is not False for p in passed(r).values()) and not undetermined_of(r.parameters)
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
