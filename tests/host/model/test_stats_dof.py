"""The degrees of freedom of a σ that is itself estimated (host/model/stats.py
``satterthwaite_dof``): a variance made of an exact part and parts read on few dof gives a
t-statistic whose tails are Student's t on the Welch–Satterthwaite ν."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats as sps

from host.model.stats import satterthwaite_dof


def test_no_estimated_share_is_exact() -> None:
    assert satterthwaite_dof(2.0, [], []) == math.inf
    assert satterthwaite_dof(2.0, [0.0, 1.0], [3.0, math.inf]) == math.inf
    # one share that is the whole variance: its own dof
    assert satterthwaite_dof(2.0, [2.0], [5.0]) == pytest.approx(5.0)
    # half the variance on 4 dof: ν = V²/((V/2)²/4) = 16
    assert satterthwaite_dof(2.0, [1.0], [4.0]) == pytest.approx(16.0)


CASES = [(0.0, 1.0, 3, 0.0, 1), (0.5, 1.0, 3, 0.0, 1), (0.2, 1.0, 6, 2.0, 3)]


@pytest.mark.parametrize(("white", "a", "nu_a", "b", "nu_b"), CASES)
def test_the_t_statistic_on_that_nu_covers_as_it_says(
    white: float, a: float, nu_a: int, b: float, nu_b: int
) -> None:
    """x ~ N(0, white + a + b), its variance read as white + â + b̂ with â = a·χ²_νa/νa, b̂
    likewise: x/√V̂ against t(ν̂) with ν̂ from the estimates covers 95 % within 1.5 % (ν̂ from
    the estimates runs high where â came out small: a third exact on ν = 3 covers 93.9 %, the
    normal k = 1.96 91.6 %)."""
    rng = np.random.default_rng(int(10 * white + nu_a + nu_b))
    n = 40000
    x = rng.normal(0.0, math.sqrt(white + a + b), n)
    ah = a * rng.chisquare(nu_a, n) / nu_a
    bh = b * rng.chisquare(nu_b, n) / nu_b
    v = white + ah + bh
    nu = np.array([
        satterthwaite_dof(float(vv), [float(s1), float(s2)], [nu_a, nu_b])
        for vv, s1, s2 in zip(v, ah, bh, strict=True)
    ])  # fmt: skip
    k = sps.t.isf(0.025, nu)
    covered = np.mean(np.abs(x) <= k * np.sqrt(v))
    assert covered == pytest.approx(0.95, abs=0.015)
    # the normal k = 1.96 would not: the test can tell
    assert np.mean(np.abs(x) <= 1.96 * np.sqrt(v)) < 0.935
