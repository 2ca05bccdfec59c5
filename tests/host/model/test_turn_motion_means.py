"""The means a turn's rows are read from (``host.model.turn_motion.range_means``): each range's
mean as numpy's own mean of that slice, in one pass."""

from __future__ import annotations

import numpy as np
import pytest

from host.model.turn_motion import range_means


@pytest.mark.parametrize("seed", range(10))
def test_each_range_is_the_mean_of_its_slice(seed: int) -> None:
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 3000))
    x = rng.normal(rng.normal(0, 10, 4), rng.uniform(0.001, 2.0, 4), (n, 4))
    starts = rng.integers(0, n, 40)
    stops = np.minimum(n, starts + rng.integers(1, 300, 40))
    ranges = np.column_stack([starts, stops])
    got = range_means(x, ranges)
    want = np.array([x[a:e].mean(axis=0) for a, e in ranges])
    assert got.shape == (40, 4)
    assert np.allclose(got, want, rtol=0.0, atol=1e-11 * (1.0 + np.abs(x).max()))


def test_a_range_of_zeros_has_a_mean_of_exactly_zero() -> None:
    x = np.zeros((50, 3))
    x[10:20, 0] = np.linspace(0.3, 1.7, 10)
    x[30:35, 2] = -2.5
    ranges = np.array([[0, 10], [10, 20], [20, 30], [30, 35], [40, 50]])
    got = range_means(x, ranges, centred=False)
    assert np.all(got[[0, 2, 4]] == 0.0)
    assert got[1, 0] == pytest.approx(1.0) and got[3, 2] == pytest.approx(-2.5)
    assert np.all(got[:, 1] == 0.0)
