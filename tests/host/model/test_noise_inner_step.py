"""A bias step inside one static record is an effect, not noise (issue 39): the record's own
samples show it (:func:`host.model.noise.inner_step`), its blocks are cut there
(:func:`host.model.rows.stepped_edges`), its white noise is read about the two levels and the
session's floor leaves it out — checked on synthetic samples here and on the independent
simulator's sessions in ``tests/independent/test_independent_edge_steps.py``."""

from __future__ import annotations

import numpy as np
from scipy.signal import lfilter

from host.model.noise import NoiseModel, inner_step, integrated_autocorrelation
from host.model.rows import stepped_edges, white_variance

N = 500  # a 10 s static at 50 Hz
SIGMA = 0.01  # m/s² per sample (the independent simulator's accelerometer)


def test_white_noise_shows_no_step_inside_a_record() -> None:
    """Under white noise (and AR(1) noise of τ ≈ 3, a filtered sensor) a step is named at the
    level's rate, 1e-6 per channel: none in 400 records each."""
    rng = np.random.default_rng(11)
    assert not [k for k in range(400) if inner_step(rng.normal(0, SIGMA, N), 30) is not None]
    red = []
    for _ in range(400):
        x = lfilter([1.0], [1.0, -0.5], rng.normal(0, SIGMA, N + 50))  # τ = (1 + ρ)/(1 − ρ) = 3
        red.append(inner_step(x[50:], 30))
    assert red.count(None) == 400


def test_the_plans_least_step_is_found_to_a_few_samples() -> None:
    """A step of twice a sample's σ (the plan's least: 0.02 m/s², 0.05 °/s) at 15–85 % of the
    record is found in every record, at its sample within a few."""
    rng = np.random.default_rng(12)
    for frac in np.linspace(0.15, 0.85, 15):
        at = int(frac * N)
        x = rng.normal(0, SIGMA, N) + 2 * SIGMA * (np.arange(N) >= at) * rng.choice([-1, 1])
        cut = inner_step(x, 30)
        assert cut is not None and abs(cut - at) <= 8, (frac, cut)


def test_a_stepped_record_has_blocks_either_side_and_its_white_noise() -> None:
    """The blocks are cut at the step, at least two either side, none shorter than 8 samples;
    read about them the white variance is the noise's, where about the uncut blocks it takes
    the step (and the serial correlation with it)."""
    rng = np.random.default_rng(13)
    t = np.arange(N) / 50.0
    at = 115
    x = rng.normal(0, SIGMA, N) + 0.05 * (np.arange(N) >= at)
    edges = stepped_edges(t, [at], NoiseModel())
    assert at in [a for a, _ in edges]
    assert sum(e <= at for _, e in edges) >= 2 and sum(a >= at for a, _ in edges) >= 2
    assert min(e - a for a, e in edges) >= 8 and edges[0][0] == 0 and edges[-1][1] == N
    var, devs = white_variance(x, edges)
    assert abs(var / SIGMA**2 - 1.0) < 0.2
    assert integrated_autocorrelation(devs, 30) < 1.5
    uncut, devs_uncut = white_variance(x, [(0, 250), (250, N)])
    assert uncut > 2 * SIGMA**2 and integrated_autocorrelation(devs_uncut, 30) > 5


def test_a_step_near_the_records_end_joins_short_pieces() -> None:
    """A piece too short for a block joins the one before; the blocks still cover the record."""
    t = np.arange(N) / 50.0
    edges = stepped_edges(t, [N - 5], NoiseModel())
    assert edges[0][0] == 0 and edges[-1][1] == N
    assert all(e == a2 for (_, e), (a2, _) in zip(edges[:-1], edges[1:], strict=True))
