"""A rate's derivative (``host.model.turning.derivative``) against calculus: the five-point
quartic is exact for a quartic, at any spacing of the times."""

from __future__ import annotations

import numpy as np
import pytest

from host.model.turning import derivative


@pytest.mark.parametrize("seed", range(8))
def test_a_quartic_is_differentiated_exactly_at_uneven_times(seed: int) -> None:
    rng = np.random.default_rng(seed)
    n = int(rng.integers(5, 400))
    t = np.cumsum(rng.uniform(0.002, 0.03, n)) + rng.uniform(0.0, 5.0)
    t0 = float(t.mean())
    coef = rng.normal(0.0, 1.0, (5, 3)) * [[1.0], [10.0], [50.0], [100.0], [300.0]]
    x = t - t0
    y = sum(coef[p] * x[:, None] ** p for p in range(5))
    want = sum(p * coef[p] * x[:, None] ** (p - 1) for p in range(1, 5))
    got = derivative(t, y)
    scale = np.max(np.abs(want), axis=0)
    assert np.all(np.abs(got[2:-2] - want[2:-2]) <= 1e-7 * scale)


def test_few_samples_fall_back_to_differences() -> None:
    t = np.array([0.0, 0.01, 0.03, 0.04])
    y = np.column_stack([3.0 * t + 1.0, -2.0 * t])
    assert np.allclose(derivative(t, y), [[3.0, -2.0]] * 4)
