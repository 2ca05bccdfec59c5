"""Records that stop when they have enough (host/workbench/stopping.py), on samples this test
draws itself (white and serially correlated noise, quantised): the σ a record gives its own
mean is the scatter of such means, and a record stops where that σ reaches the target."""

from __future__ import annotations

import math

import numpy as np
import pytest

from host.workbench.stopping import (
    TURN_PAIRS_MAX,
    StaticRule,
    mean_sigma,
    stop_index,
    turns_stop,
)


def _ar1(rng: np.random.Generator, n: int, rho: float, sd: float) -> np.ndarray:
    """An AR(1) sequence of stationary standard deviation ``sd`` (ρ = 0: white)."""
    e = rng.normal(0.0, sd * math.sqrt(1.0 - rho**2), n)
    x = np.empty(n)
    x[0] = rng.normal(0.0, sd)
    for i in range(1, n):
        x[i] = rho * x[i - 1] + e[i]
    return x


@pytest.mark.parametrize("rho", [0.0, 0.5])
def test_the_sigma_of_a_mean_is_the_scatter_of_such_means(rho: float) -> None:
    rng = np.random.default_rng(7)
    pulls, sigmas = [], []
    for _ in range(300):
        x = _ar1(rng, 1000, rho, 0.02)
        q = 0.001  # quantised as the sensor's counts are
        x = np.round(x / q) * q
        s = float(mean_sigma(x[:, None])[0])
        pulls.append(float(x.mean()) / s)
        sigmas.append(s)
    # the true σ of the mean of an AR(1) sequence: sd·√((1+ρ)/(1−ρ)/n) for n ≫ 1/(1−ρ)
    true = 0.02 * math.sqrt((1 + rho) / (1 - rho) / 1000)
    assert 0.85 < float(np.std(pulls)) < 1.15
    assert 0.85 < float(np.median(sigmas)) / true < 1.15


def test_white_noise_alone_would_claim_a_correlated_record_more_precise_than_it_is() -> None:
    # the check above passes for ρ=0.5 only because τ is counted: without it σ is √3 low
    rng = np.random.default_rng(3)
    x = _ar1(rng, 5000, 0.5, 1.0)
    naive = float(np.std(x, ddof=1)) / math.sqrt(len(x))
    assert float(mean_sigma(x[:, None])[0]) / naive > 1.5


def test_a_record_stops_where_its_own_sigma_reaches_the_target() -> None:
    rng = np.random.default_rng(11)
    rate, sd = 50.0, 0.05  # Hz; °/s a sample
    t = np.arange(0.0, 200.0, 1.0 / rate)
    gyro = rng.normal(0.0, sd, (len(t), 3))
    accel = 9.8 * np.array([0.0, 0.0, 1.0]) + rng.normal(0.0, 0.001, (len(t), 3))
    # σ of the mean sd/√N reaches 0.001 °/s at N = 2500 samples: 50 s
    rule = StaticRule(accel_sigma=1.0, gyro_sigma=0.001, min_s=10.0, max_s=200.0)
    n, why = stop_index(rule, t, accel, gyro)
    assert 42.0 <= n / rate <= 60.0, n / rate
    assert why.startswith("σ of the mean met its target")
    # a loose target: never before the method's minimum
    n, why = stop_index(StaticRule(1.0, 1.0, 10.0, 200.0), t, accel, gyro)
    assert n / rate == pytest.approx(10.0, abs=0.05)
    # a target out of reach: the maximum, and it says the target was not met
    n, why = stop_index(StaticRule(1.0, 1e-6, 10.0, 30.0), t, accel, gyro)
    assert n / rate == pytest.approx(30.0, abs=0.05)
    assert "maximum, target not met" in why
    # the accelerometer counts as well as the gyro
    n, _ = stop_index(StaticRule(1e-5, 1.0, 10.0, 200.0), t, accel, gyro)
    assert n / rate > 150.0


def test_the_rule_for_a_target_scales_with_it() -> None:
    a = StaticRule.for_target(0.1, 9.8)
    b = StaticRule.for_target(0.05, 9.8)
    assert b.gyro_sigma == pytest.approx(a.gyro_sigma / 2)
    assert b.accel_sigma == pytest.approx(a.accel_sigma / 2)
    # gyro g-sensitivity 0.1 (°/s)/g from a face pair: σ_mean/√2 ≤ target·0.1
    assert a.gyro_sigma / math.sqrt(2) == pytest.approx(0.1 * 0.1)


def test_turn_pairs_go_on_until_the_scale_meets_the_target_or_the_maximum() -> None:
    assert turns_stop(0.04, 0.05, 1) is not None
    assert turns_stop(0.06, 0.05, 1) is None
    assert turns_stop(0.06, 0.05, TURN_PAIRS_MAX - 1) is None
    why = turns_stop(0.06, 0.05, TURN_PAIRS_MAX)
    assert why is not None and "maximum" in why
    assert turns_stop(math.inf, 0.05, 1) is None


def test_the_second_face_stops_when_the_pair_has_enough_with_the_turns_to_come() -> None:
    """Target σ/tolerance 0.01: a face alone needs its gyro mean at 0.01·√2·0.1 °/s. With the
    opposite face at 0.001 °/s the pair's g-sensitivity σ² = (σ_up² + 0.001²)/4 ≤ (0.001)²
    asks σ_up² ≤ 3e-6; white noise of 0.05 °/s at 50 Hz gives σ_up² = 5e-5/T, and 4 s of turns
    to come on the face shrink it to 5e-5/(T + 4): the face alone stops at 25 s, the pair at
    16.7 s, with the turns at 12.7 s (hand-derived; looked at once a second)."""
    rng = np.random.default_rng(12)
    rate, sd = 50.0, 0.05
    t = np.arange(0.0, 60.0, 1.0 / rate)
    gyro = rng.normal(0.0, sd, (len(t), 3))
    accel = rng.normal(9.8, 1e-4, (len(t), 3))
    rule = StaticRule(accel_sigma=1.0, gyro_sigma=0.01 * math.sqrt(2.0) * 0.1, max_s=60.0)
    opposite = np.full(3, 0.001)
    alone, _ = stop_index(rule, t, accel, gyro)
    pair, _ = stop_index(rule, t, accel, gyro, opposite=opposite)
    turns, why = stop_index(rule, t, accel, gyro, opposite=opposite, extra_rest_s=4.0)
    assert 23.0 <= alone / rate <= 27.0
    assert 15.0 <= pair / rate <= 19.0
    assert 11.0 <= turns / rate <= 15.0
    assert "opposite face and 4 s of turns" in why
    # an opposite face alone past the pair's target (0.0021² > 2·0.001414²): to the maximum
    n, why = stop_index(rule, t, accel, gyro, opposite=np.full(3, 0.0021))
    assert n == len(t) and "target not met" in why
