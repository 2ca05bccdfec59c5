"""The whitening kept as its blocks (host/model/whitening.py): every product with it agrees with
the dense matrix, and the fit through it equals a dense generalised least squares built here
from the groups' covariances alone."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from host.bench.plan import Plan, simulate_session
from host.bench.truth import SensorTruth
from host.model.dataset import Dataset, build_dataset, session_from_records
from host.model.design import design
from host.model.fit import fit_model
from host.model.spec import parse_model
from host.model.whitening import Whitener, group_means, groups_by_size, helmert_contrasts
from host.session.directory import read_session

REAL = Path(__file__).resolve().parents[4] / "shared" / "data" / "imucal-example"


def _random_whitener(rng: np.random.Generator) -> tuple[Whitener, np.ndarray]:
    """Blocks of sizes 1..5 on shuffled rows (not contiguous), and W assembled here."""
    sizes = [1, 1, 2, 3, 3, 5, 1, 4, 2, 2]
    n = sum(sizes)
    perm = rng.permutation(n)
    blocks, dense, start = [], np.zeros((n, n)), 0
    for b in sizes:
        rows = perm[start : start + b]
        start += b
        w = rng.normal(size=(b, b)) + 3.0 * np.eye(b)
        blocks.append((rows, w))
        for i, r in enumerate(rows):
            for j, c in enumerate(rows):
                dense[r, c] = w[i, j]
    return Whitener(n, tuple(blocks)), dense


def test_block_products_agree_with_the_dense_matrix() -> None:
    rng = np.random.default_rng(7)
    wh, w = _random_whitener(rng)
    n = w.shape[0]
    for a in (rng.normal(size=n), rng.normal(size=(n, 4)), rng.normal(size=(n, 1))):
        np.testing.assert_allclose(wh.apply(a), w @ a, rtol=0, atol=1e-12)
        np.testing.assert_allclose(wh.solve_t(a), np.linalg.solve(w.T, a), rtol=0, atol=1e-12)
        np.testing.assert_allclose(wh.inv_apply(a), np.linalg.solve(w, a), rtol=0, atol=1e-12)
        assert wh.apply(a).shape == a.shape
    np.testing.assert_array_equal(wh.dense(), w)
    # one block replaced: the copy changes there only, the original not at all
    rows, old = wh.blocks[3]
    new = 2.0 * old + np.eye(len(rows))
    changed = wh.with_block(rows, new)
    expect = w.copy()
    expect[np.ix_(rows, rows)] = new
    np.testing.assert_array_equal(changed.dense(), expect)
    np.testing.assert_array_equal(wh.dense(), w)
    a = rng.normal(size=n)
    np.testing.assert_allclose(changed.apply(a), expect @ a, rtol=0, atol=1e-12)
    with pytest.raises(ValueError, match="not one block"):
        wh.with_block(rows[:-1], new[:-1, :-1])
    with pytest.raises(ValueError, match="rows"):
        wh.apply(np.zeros(n + 1))


def _group_covariance(ds: Dataset) -> np.ndarray:
    """Cov (n, n) of the rows from each group's σ of its mean and its contrast variance: the
    b rows of a group have Cov = v_c·(I − J/b) + σ²·J (J all ones), groups independent."""
    cov = np.zeros((ds.n_rows, ds.n_rows))
    for g in ds.groups:
        b = len(g.rows)
        j = np.ones((b, b))
        c = g.sigma**2 * j if b == 1 else g.contrast_var * (np.eye(b) - j / b) + g.sigma**2 * j
        cov[np.ix_(g.rows, g.rows)] = c
    return cov


def _datasets() -> list[Dataset]:
    truth = SensorTruth.random(np.random.default_rng(5))
    recs = simulate_session(truth, Plan(static_s=10.0), 5)
    out = [build_dataset(session_from_records(recs), moving=False)]
    if REAL.is_dir():
        out.append(build_dataset(read_session(REAL), moving=False))
    return out


@pytest.mark.parametrize("k", [0, 1])
def test_fit_equals_dense_least_squares_from_the_group_covariances(k: int) -> None:
    datasets = _datasets()
    if k >= len(datasets):
        pytest.skip("the real imucal data is not here")
    ds = datasets[k]
    model = parse_model("base")
    fit = fit_model(ds, model)
    assert not fit.undetermined
    # generalised least squares with the dense covariance, nothing of the whitener used
    cov = _group_covariance(ds)
    x, offset, _ = design(ds, model)
    y = ds.y - ds.nominal - offset
    ci = np.linalg.inv(cov)
    info = x.T @ ci @ x
    theta = np.linalg.solve(info, x.T @ ci @ y)
    se = np.sqrt(np.diag(np.linalg.inv(info)))
    got = np.array([p.value for p in fit.parameters])
    got_se = np.array([p.stderr for p in fit.parameters])
    unscaled = np.array(
        [p.stderr / {(c.sensor, c.axis): c.se_scale for c in fit.channels}[(p.sensor, p.axis)]
         for p in fit.parameters]
    )  # fmt: skip
    np.testing.assert_allclose((got - theta) / se, 0.0, atol=1e-8)
    np.testing.assert_allclose(unscaled, se, rtol=1e-8)
    assert np.all(got_se >= unscaled)
    r = y - x @ theta
    assert fit.chi2 == pytest.approx(float(r @ ci @ r), rel=1e-9)
    # each record/channel z: its mean residual over its σ less what the fit absorbed
    absorbed = x @ np.linalg.solve(info, x.T)
    for g, gr in zip(ds.groups, fit.groups, strict=True):
        a = np.zeros(ds.n_rows)
        a[g.rows] = 1.0 / len(g.rows)
        var = float(a @ cov @ a - a @ absorbed @ a)
        assert gr.residual == pytest.approx(float(a @ r), abs=1e-9 * g.sigma)
        if var > (1e-3 * g.sigma) ** 2:
            assert gr.z == pytest.approx(float(a @ r) / np.sqrt(var), abs=1e-7)


@pytest.mark.parametrize("b", [2, 3, 7, 40])
def test_helmert_contrasts_are_orthonormal_and_blind_to_the_mean(b: int) -> None:
    """The contrasts a static record's block means are whitened with: orthonormal rows, each
    orthogonal to the ones vector (a common level moves none of them), row k − 1 comparing the
    first k blocks with block k."""
    h = helmert_contrasts(b)
    assert h.shape == (b - 1, b)
    assert np.allclose(h @ h.T, np.eye(b - 1), atol=1e-12)
    assert np.allclose(h @ np.ones(b), 0.0, atol=1e-12)
    for k in range(1, b):
        row = h[k - 1]
        assert np.all(row[:k] > 0) and row[k] < 0 and np.all(row[k + 1 :] == 0)
        assert np.allclose(row[:k], row[0]) and row[k] == pytest.approx(-k * row[0])


@settings(max_examples=40, deadline=None)
@given(st.lists(st.integers(1, 40), min_size=1, max_size=30), st.integers(0, 2**32 - 1))
def test_group_means_are_each_group_s_mean(sizes: list[int], seed: int) -> None:
    """The groups' means taken a size at a time are each group's own ``np.mean`` to the bit
    (the residual tables and the candidates' RMS z after adding one are read from them), rows
    in any order."""
    rng = np.random.default_rng(seed)
    rows = np.split(rng.permutation(sum(sizes)), np.cumsum(sizes)[:-1])

    class _Group:
        def __init__(self, r: np.ndarray) -> None:
            self.rows = r

    values = rng.normal(0.0, 1.0, sum(sizes)) * rng.choice([1e-6, 1.0, 1e6], sum(sizes))
    got = group_means(values, groups_by_size([_Group(r) for r in rows]))  # type: ignore[arg-type]
    assert got.tolist() == [float(np.mean(values[r])) for r in rows]
