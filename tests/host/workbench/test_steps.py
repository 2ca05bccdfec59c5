"""A step in time placed to the sample (host.workbench.steps): the cuts are the steps the scan
would aggregate, the profile's shortcut is the refit, and a step's name reads back to the time
and size it states. Sessions from the independent simulator (tests/independent)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from host.model.components import fit_with_components
from host.model.dataset import Dataset, load_dataset
from host.model.fit import Fit
from host.model.spec import parse_model
from host.workbench.scan import _columns
from host.workbench.steps import (
    STEP,
    Placed,
    _Profiles,
    channel_cuts,
    short_step_name,
    step_name,
    step_times,
)
from tests.independent.simulate import SessionSpec, write_session

_CACHE: dict[str, tuple[Dataset, Fit]] = {}


def _session(tmp_path_factory: pytest.TempPathFactory, effect: str) -> tuple[Dataset, Fit]:
    if effect not in _CACHE:
        d = tmp_path_factory.mktemp(effect)
        write_session(d, SessionSpec(seed=11, effect=effect))
        joint = fit_with_components(load_dataset(d), parse_model("base"))
        _CACHE[effect] = (joint.dataset, joint.fit)
    return _CACHE[effect]


@pytest.mark.parametrize(("sensor", "axis"), [("accel", 0), ("gyro", 2)])
@pytest.mark.slow
def test_every_cut_is_the_step_the_scan_aggregates(
    tmp_path_factory: pytest.TempPathFactory, sensor: str, axis: int
) -> None:
    """A cut between two samples (inside a static's block, a turn's still moment, a moving
    block, a gap) is the column a step at that time gives the channel's rows (0 before, 1
    after, aggregated like a term), whitened, with the fit's columns removed."""
    ds, fit = _session(tmp_path_factory, "none")
    cuts = channel_cuts(ds, fit.basis, sensor, axis)
    assert cuts is not None
    assert np.all(np.diff(cuts.lo) >= 0) and np.all(cuts.lo < cuts.hi)
    rng = np.random.default_rng(3)
    for k in rng.choice(cuts.white.shape[1], size=12, replace=False):
        at = 0.5 * (cuts.lo[k] + cuts.hi[k])
        x = _columns(ds, sensor, axis, [], [at])
        assert x is not None
        w = ds.whiten.apply(x)[:, 0]
        want = w - fit.basis @ (fit.basis.T @ w)
        assert np.allclose(cuts.white[:, k], want, atol=1e-9 * np.max(np.abs(want))), at


def test_the_profile_given_a_step_is_the_refit_with_both(
    tmp_path_factory: pytest.TempPathFactory,
) -> None:
    """What a cut adds to a step already placed is the Δχ² of the two together less that of
    the first alone (least squares on both columns)."""
    ds, fit = _session(tmp_path_factory, "bias_step_accel")
    cuts = channel_cuts(ds, fit.basis, "accel", 1)
    assert cuts is not None
    pro = _Profiles(cuts, fit.white_residual)
    alone = pro.alone()
    rng = np.random.default_rng(5)
    for i in rng.choice(len(alone), size=4, replace=False):
        given_i = pro.given(int(i))
        for k in rng.choice(len(alone), size=6, replace=False):
            if abs(float(cuts.lo[k]) - float(cuts.lo[i])) < 1.0:
                continue
            x = cuts.white[:, [int(i), int(k)]]
            beta, *_ = np.linalg.lstsq(x, fit.white_residual, rcond=None)
            both = float((x @ beta) @ (x @ beta))
            assert given_i[k] == pytest.approx(both - alone[i], rel=1e-6, abs=1e-6)


@pytest.mark.slow
def test_the_cuts_kept_in_parts_are_their_columns(
    tmp_path_factory: pytest.TempPathFactory,
) -> None:
    """Products with the cuts, their squared norms, a few columns and the cuts with a drift's
    direction removed, all read from the parts, are those of the (n_rows, K) matrix of their
    columns (the parts are never that matrix)."""
    ds, fit = _session(tmp_path_factory, "bias_step_gyro")
    for sensor, axis in (("gyro", 0), ("accel", 2)):
        cuts = channel_cuts(ds, fit.basis, sensor, axis)
        assert cuts is not None
        white = cuts.white
        scale = float(np.max(np.abs(white)))
        r = fit.white_residual
        assert np.allclose(cuts.dot(r), r @ white, rtol=0, atol=1e-10 * scale * np.abs(r).sum())
        nn = np.einsum("ij,ij->j", white, white)
        assert np.allclose(cuts.norms2(), nn, rtol=1e-9, atol=1e-12 * float(np.max(nn)))
        ks = [0, len(cuts.lo) // 3, len(cuts.lo) - 1]
        assert np.allclose(cuts.columns(ks), white[:, ks], rtol=0, atol=1e-12 * scale)
        drift = np.random.default_rng(1).normal(size=len(r))
        drift -= fit.basis @ (fit.basis.T @ drift)
        u = drift / np.linalg.norm(drift)
        less = white - np.outer(u, u @ white)
        got = cuts.without(u)
        assert np.allclose(got.white, less, rtol=0, atol=1e-12 * scale)
        nn_less = np.einsum("ij,ij->j", less, less)
        assert np.allclose(got.norms2(), nn_less, rtol=1e-9, atol=1e-12 * float(np.max(nn)))


@settings(max_examples=60, deadline=None)
@given(
    at=st.floats(0.0, 1.0),
    left=st.floats(0.0, 30.0),
    right=st.floats(0.0, 30.0),
    size=st.floats(-1.0, 1.0).filter(lambda x: abs(x) > 1e-3),
)
def test_a_step_s_name_reads_back_to_the_time_and_size_it_states(
    tmp_path_factory: pytest.TempPathFactory, at: float, left: float, right: float, size: float
) -> None:
    """Inside one record ('during x_cw, 7.52 s in (± 0.15 s, 95 %)') or across a gap
    ('between 9.92 s into z_dn and the start of x_ccw'): the time read back lies in the stated
    interval (to the 0.01 s written; an end in a gap between records is written as the gap's
    end, where any time moves the rows alike) and the size is the one written (3 digits)."""
    ds, _ = _session(tmp_path_factory, "none")
    t0 = min(float(s.t_s[0]) for s in ds.signals)
    t1 = max(float(s.t_s[-1]) for s in ds.signals)
    t = t0 + at * (t1 - t0)
    p = Placed(t, max(t0, t - left), min(t1, t + right), size, 0.01, 100.0, 100.0)
    name = step_name(ds.signals, p, "m/s²")
    assert name.startswith(STEP)
    back = step_times(ds.signals, name)
    assert back is not None and len(back) == 1, name
    when, got = back[0]
    ends = sorted(float(x) for s in ds.signals for x in (s.t_s[0], s.t_s[-1]))
    lo = max(e for e in ends if e <= p.lo_s)
    hi = min(e for e in ends if e >= p.hi_s)
    inside = any(s.t_s[0] <= p.lo_s <= s.t_s[-1] for s in ds.signals)
    lo = p.lo_s if inside else lo
    inside = any(s.t_s[0] <= p.hi_s <= s.t_s[-1] for s in ds.signals)
    hi = p.hi_s if inside else hi
    assert lo - 0.006 <= when <= hi + 0.006, (name, p)
    assert got == pytest.approx(size, rel=5e-3), name
    # two steps in one finding: both read back, in order
    two = step_times(ds.signals, f"{name}, and {name}")
    assert two is not None and [w for w, _ in two] == [when, when]


@settings(max_examples=80, deadline=None)
@given(text=st.text(max_size=60))
def test_any_other_text_is_no_step_and_never_an_error(
    tmp_path_factory: pytest.TempPathFactory, text: str
) -> None:
    """A name that is no step is None; a step's name the scan never wrote is None or times,
    never an exception."""
    ds, _ = _session(tmp_path_factory, "none")
    if not text.startswith(STEP):
        assert step_times(ds.signals, text) is None
    back = step_times(ds.signals, f"{STEP} {text}")
    assert back is None or all(np.isfinite(t) for t, _ in back)


@settings(max_examples=60, deadline=None)
@given(
    at=st.floats(0.0, 1.0),
    at2=st.floats(0.0, 1.0),
    left=st.floats(0.0, 30.0),
    right=st.floats(0.0, 30.0),
    size=st.floats(-1.0, 1.0).filter(lambda x: abs(x) > 1e-3),
)
def test_a_step_s_short_name_is_the_same_steps(
    tmp_path_factory: pytest.TempPathFactory,
    at: float,
    at2: float,
    left: float,
    right: float,
    size: float,
) -> None:
    """The short name a command gives a step (``plan --separate``, which an 80-column line must
    hold) reads back to steps that put every sample of every record on the same side as the
    full name's, with the same sizes' ratio; it is never longer."""
    ds, _ = _session(tmp_path_factory, "none")
    t0 = min(float(s.t_s[0]) for s in ds.signals)
    t1 = max(float(s.t_s[-1]) for s in ds.signals)
    names = []
    for a in (at, at2):
        t = t0 + a * (t1 - t0)
        p = Placed(t, max(t0, t - left), min(t1, t + right), size, 0.01, 100.0, 100.0)
        names.append(step_name(ds.signals, p, "°/s"))
    for name in (names[0], f"{names[0]}, and {names[1]}"):
        full, short = step_times(ds.signals, name), short_step_name(ds.signals, name)
        assert len(short) <= len(name)
        back = step_times(ds.signals, short)
        assert full is not None
        if short == name:  # a step before the first sample: left as it was
            continue
        assert back is not None and len(back) == len(full), short
        for s in ds.signals:
            for (tf, _), (tb, _) in zip(full, back, strict=True):
                assert np.array_equal(s.t_s > tf, s.t_s > tb), (name, short, s.name)
        if len(full) == 2:
            assert back[0][1] / back[1][1] == pytest.approx(full[0][1] / full[1][1], rel=1e-2)
