"""The archive's statistics (host/archive/stats.py) against their stated false-alarm rates:
many simulated null lots (nothing wrong), the fraction of runs that flag anything is the
stated family-wise rate; and a planted problem of a realistic size is found."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats as sps

from host.archive import stats

ALPHA = 0.05  # a rate large enough to count in a few hundred lots
LOTS = 1000


def _rate_ok(flags: np.ndarray, alpha: float) -> None:
    """The flagged fraction is the stated rate: within 4 binomial σ, and Bonferroni may only
    be conservative by its (small) second-order term."""
    n = flags.size
    k = int(flags.sum())
    sd = np.sqrt(n * alpha * (1 - alpha))
    assert alpha * n * (1 - alpha) - 4 * sd <= k <= alpha * n + 4 * sd, (k, n)


def test_repeat_flags_the_stated_fraction_of_null_lots() -> None:
    rng = np.random.default_rng(1)
    units, params, sessions = 100, 6, 3
    sigma = rng.uniform(0.5, 2.0, (LOTS, units, params, sessions))  # each session its own σ
    x = 3.0 + rng.normal(0.0, sigma)
    r = stats.repeatability(x, sigma)
    m = units * params
    flags = (r.p < ALPHA / m).any(axis=(1, 2))
    _rate_ok(flags, ALPHA)
    # χ² of the null is χ²(2): its p-values are uniform
    assert sps.kstest(r.p.ravel()[:20000], "uniform").pvalue > 1e-3


def test_repeat_statistics_on_a_small_case() -> None:
    x = np.array([1.0, 2.0, 4.0])
    s = np.array([1.0, 1.0, 2.0])
    r = stats.repeatability(x, s)
    w = 1 / s**2
    mean = (w * x).sum() / w.sum()
    assert r.mean == pytest.approx(mean)
    assert r.chi2 == pytest.approx(((x - mean) ** 2 * w).sum())
    assert r.dof == 2 and r.p == pytest.approx(sps.chi2.sf(r.chi2, 2))
    assert r.scatter == pytest.approx(np.std(x, ddof=1))
    assert r.predicted == pytest.approx(np.sqrt(np.mean(s**2)))
    # near zero the CV is not given; far from zero it is scatter/|mean|
    near = stats.repeatability(np.array([0.001, -0.002, 0.0]), np.full(3, 0.001))
    assert np.isnan(near.cv)
    far = stats.repeatability(np.array([1.0, 1.01, 0.99]), np.full(3, 0.01))
    assert far.cv == pytest.approx(0.01)
    one = stats.repeatability(np.array([1.0, np.nan, np.nan]), np.array([0.1, np.nan, np.nan]))
    assert one.n == 1 and np.isnan(one.p)


@pytest.mark.parametrize("nu", [3, 6, 20])
def test_repeat_p_is_uniform_when_each_sigma_is_read_on_few_dof(nu: int) -> None:
    """Each session's σ estimated on ν dof (s² = σ²·χ²_ν/ν, as a variance component makes
    it): the χ² tail then rejects a true repeat several times too often (at ν = 3 about 8 %
    of triples at p < 1 %); Welch's F keeps the rate at 1 % and the p uniform."""
    rng = np.random.default_rng(nu)
    n = 20000
    sigma = rng.uniform(0.5, 2.0, (n, 3))
    x = 3.0 + rng.normal(0.0, sigma)
    s = sigma * np.sqrt(rng.chisquare(nu, (n, 3)) / nu)
    plain = stats.repeatability(x, s)
    welch = stats.repeatability(x, s, np.full((n, 3), float(nu)))
    assert np.all(np.isfinite(welch.nu)) and np.all(welch.nu > 0)
    assert np.mean(welch.p < 0.01) == pytest.approx(0.01, abs=0.0035)
    assert np.mean(plain.p < 0.01) > 0.015  # the χ² tail over-rejects: the test would see it
    assert sps.kstest(welch.p, "uniform").pvalue > 1e-3


def test_repeat_with_exact_sigmas_is_the_chi2_test_and_a_step_still_fails() -> None:
    x = np.array([1.0, 2.0, 4.0])
    s = np.array([1.0, 1.0, 2.0])
    exact = stats.repeatability(x, s, np.full(3, np.inf))
    assert exact.p == pytest.approx(sps.chi2.sf(exact.chi2, 2)) and np.isinf(exact.nu)
    few = stats.repeatability(x, s, np.array([4.0, 4.0, np.inf]))
    assert few.p > exact.p  # σ known less well: the same scatter is less surprising
    # Welch's statistic by hand: λ = Σ (1 − w/W)²/ν over the sessions with a finite ν
    w = 1 / s**2
    lam = ((1 - w[:2] / w.sum()) ** 2 / 4.0).sum()
    f = exact.chi2 / 2 / (1 + 2 * lam / 8)
    assert few.nu == pytest.approx(8 / (3 * lam))
    assert few.p == pytest.approx(sps.f.sf(f, 2, 8 / (3 * lam)))
    step = stats.repeatability(np.array([0.0, 0.0, 30.0]), np.ones(3), np.full(3, 6.0))
    assert step.p < 1e-3


def test_drift_flags_the_stated_fraction_and_finds_a_move() -> None:
    rng = np.random.default_rng(2)
    units, params = 200, 6
    s1 = rng.uniform(0.5, 2.0, (LOTS, units, params))
    s2 = rng.uniform(0.5, 2.0, (LOTS, units, params))
    a = rng.normal(0.0, s1)
    b = rng.normal(0.0, s2)
    k = stats.family_z(ALPHA, units * params)
    z = stats.drift_z(a, s1, b, s2)
    _rate_ok(stats.drifted(z, b - a, k).any(axis=(1, 2)), ALPHA)
    b[:, 3, 2] += 10 * np.hypot(s1[:, 3, 2], s2[:, 3, 2])  # one unit moved 10 σ
    moved = stats.drifted(stats.drift_z(a, s1, b, s2), b - a, k)
    assert moved[:, 3, 2].mean() > 0.99
    # a tolerance flags a move below k·σ
    assert stats.drifted(np.array([1.0]), np.array([0.3]), 5.0, 0.2)[0]


def test_grubbs_flags_the_stated_fraction_of_null_lots() -> None:
    rng = np.random.default_rng(3)
    n = 200
    x = rng.normal(0.0, 1.0, (4000, n))
    g = stats.grubbs_statistic(x)
    _rate_ok(g > stats.grubbs_critical(n, ALPHA), ALPHA)


def test_grubbs_finds_planted_outliers_and_only_them() -> None:
    rng = np.random.default_rng(4)
    x = rng.normal(0.0, 1.0, 200)
    x[17] = 7.0
    x[90] = -6.5
    assert sorted(stats.grubbs_outliers(x, 0.01)) == [17, 90]
    assert stats.grubbs_outliers(rng.normal(size=200), 0.001) == []


def test_lot_summary_against_the_datasheet() -> None:
    x = np.array([0.1, 0.2, 0.3, np.nan])
    s = stats.lot_summary(x, limit=0.5)
    assert (s.n, s.mean) == (3, pytest.approx(0.2))
    assert s.spread == pytest.approx(0.1)
    assert (s.low, s.high) == (pytest.approx(-0.1), pytest.approx(0.5))
    assert s.within is True
    assert stats.lot_summary(x, limit=0.45).within is False
    assert stats.lot_summary(x).within is None


def test_the_run_rules_in_control_signal_after_the_stated_run_length() -> None:
    rng = np.random.default_rng(5)
    x = rng.normal(0.0, 1.0, (1200, 1000))
    fired = stats.run_rules(x, 0.0, 1.0)
    any_rule = fired.any(axis=-1)
    assert any_rule.any(axis=-1).all()
    first = np.argmax(any_rule, axis=-1) + 1.0
    # Champ & Woodall: ARL 91.75 with all four rules; SE of the mean here ≈ 2.6
    assert first.mean() == pytest.approx(stats.ARL_WESTERN_ELECTRIC, abs=11)
    # rule 1 alone: a point beyond 3σ with p = 0.0027 (ARL 370)
    p1 = 1 / stats.ARL_RULE1
    assert fired[..., 0].mean() == pytest.approx(p1, rel=0.1)
    assert p1 == pytest.approx(2 * sps.norm.sf(3))


def test_each_run_rule_fires_on_its_pattern() -> None:
    def rules(seq: list[float]) -> set[int]:
        f = stats.run_rules(np.array(seq), 0.0, 1.0)
        return {int(r) + 1 for r in np.flatnonzero(f[-1])}

    assert rules([0, 0, 3.5]) == {1}
    assert rules([0, 2.5, -1, 2.2]) == {2}
    assert rules([0, 1.5, 1.2, 0.3, 1.1, 1.4]) == {3}
    assert rules([0.2, 0.5, 0.1, 0.3, 0.4, 0.2, 0.6, 0.3]) == {4}
    assert rules([0.2, -0.5, 0.1, 0.3, 0.4, 0.2, 0.6, 0.3]) == set()
    assert rules([0, -2.5, -2.2]) == {2}


def test_individuals_limits_from_the_moving_range() -> None:
    rng = np.random.default_rng(6)
    x = rng.normal(5.0, 2.0, 20000)
    c, s = stats.individuals_limits(x, baseline=20000)
    assert c == pytest.approx(5.0, abs=0.05) and s == pytest.approx(2.0, rel=0.02)


def test_bench_comparison_flags_the_stated_fraction_and_finds_a_biased_bench() -> None:
    rng = np.random.default_rng(7)
    benches, params, sessions = 4, 6, 3
    sig = rng.uniform(0.5, 2.0, (LOTS, params, benches, sessions))
    x = rng.normal(0.0, sig)
    mean, u = stats.bench_means(x, sig)
    k = stats.family_z(ALPHA, benches * params)
    null = stats.compare_benches(mean, u, k)
    # Birge scaling only widens u: the rate may be conservative, never above the stated
    frac = null.flagged.any(axis=(1, 2)).mean()
    assert 0.3 * ALPHA <= frac <= ALPHA + 4 * np.sqrt(ALPHA / LOTS)
    x[:, 2, 1, :] += 8 * sig[:, 2, 1, :].mean()  # bench 1 reads parameter 2 eight σ high
    mean, u = stats.bench_means(x, sig)
    hit = stats.compare_benches(mean, u, k)
    assert hit.flagged[:, 2, 1].mean() > 0.95
    # the biased bench is left out of the others' reference: they are not dragged along
    others = np.delete(hit.flagged, 1, axis=2)
    assert others.any(axis=(1, 2)).mean() <= ALPHA + 4 * np.sqrt(ALPHA / LOTS)


def test_en_with_the_usual_expanded_uncertainty() -> None:
    c = stats.compare_benches(np.array([1.0, 0.0, 0.0]), np.array([0.1, 0.1, 0.1]), 1e9)
    # bench 0 against the weighted mean of the other two: u_ref = 0.1/√2
    z = 1.0 / np.sqrt(0.01 + 0.005)
    assert c.z[0] == pytest.approx(z) and c.en[0] == pytest.approx(z / 2)
