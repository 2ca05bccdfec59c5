"""The scans (host.workbench.scan) on sessions from the independent simulator (tests/independent:
white noise, quantisation and one effect, written apart from host/bench), floor from the
session: a bias step between records is never `adequate` and is named a step in time."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from host.model.dataset import load_dataset
from host.model.design import aggregate
from host.model.spec import parse_model
from host.workbench.scan import (
    STEP,
    ScanHit,
    _joined,
    _steps_aggregated,
    step_cuts,
)
from host.workbench.steps import step_times
from host.workbench.verdict import diagnose
from tests.independent.simulate import SessionSpec, write_session


@pytest.mark.slow
def test_a_gyro_bias_step_is_named_a_step_on_its_channel(tmp_path: Path) -> None:
    """0.12 °/s half-way through (≈ 100× a record mean's noise), 3 sessions: the verdict is not
    `adequate`, nothing is recommended alone, and the strongest unexplained signal is one step
    in time on the right channel, its stated ± holding the true time and its size the truth."""
    for seed in (3000, 3001, 3002):
        d = tmp_path / str(seed)
        spec = SessionSpec(seed=seed, effect="bias_step_gyro")
        write_session(d, spec)
        truth = json.loads((d / "truth.json").read_text())["effect"]
        ds = load_dataset(d)
        dg = diagnose(ds, parse_model("base"))
        assert dg.verdict == "unexplained", (seed, dg.verdict, dg.recommended_spec)
        top = dg.dominant[0]
        assert (top.sensor, top.axis) == ("gyro", truth["axis"]), top
        assert top.signal.startswith(STEP), top
        # the records' time is since power-on (the session starts after the warm-up): one
        # step, placed where it fell (inside its 95 % ±, one sample of clock offset allowed),
        # its size within 4σ, and the name reads back to a time inside that ±
        at = truth["at_session_s"] + spec.warmup_s
        (p,) = top.steps
        assert p.lo_s - 0.02 <= at <= p.hi_s + 0.02, (top.signal, at)
        assert abs(p.size - truth["step"]) <= 4.0 * p.size_sd, (p, truth["step"])
        ((when, size),) = step_times(ds.signals, top.signal) or [(None, None)]
        assert when is not None and p.lo_s - 0.01 <= when <= p.hi_s + 0.01, top.signal


def test_warming_is_read_from_the_bend_of_the_session_s_temperature() -> None:
    """The chip's dT/dt at each sample: a room swing (±0.4 °C, 7 min) seen through 10 s
    records 35 s apart with 0.02 °C of noise. The derivative follows the truth within each
    record (within a tenth of the swing's rate; its change over a record, which one slope per
    record set to 0, within 40 %), and a record without neighbours in time gets its own slope."""
    from types import SimpleNamespace

    from host.model.signals import RecordSignals
    from host.workbench.scan import warming_rates

    rng = np.random.default_rng(2)
    w = 2.0 * np.pi / 420.0

    def record(name: str, t0: float) -> RecordSignals:
        t = t0 + np.arange(500) * 0.02
        temp = 30.0 + 0.4 * np.sin(w * t) + rng.normal(0.0, 0.02, len(t))
        z = np.zeros((len(t), 3))
        return RecordSignals(
            name=name, kind="static", t_s=t, temp_c=temp, force=z, rate=z, accel=z, gyro=z,
            g=9.8, up=np.array([0.0, 0.0, 1.0]),
        )  # fmt: skip

    recs = [record(f"r{i}", 35.0 * i) for i in range(12)]
    got = warming_rates(SimpleNamespace(signals=tuple(recs), time_known=True))
    bends = 0
    for r in recs[2:-2]:
        truth = 0.4 * w * np.cos(w * r.t_s)
        assert np.max(np.abs(got[r.name] - truth)) < 0.1 * 0.4 * w, r.name
        change, want = got[r.name][-1] - got[r.name][0], truth[-1] - truth[0]
        if abs(want) > 0.5 * 0.4 * w * w * 10.0:  # a record where the rate bends
            bends += 1
            assert abs(change - want) < 0.4 * abs(want), (r.name, change, want)
    assert bends >= 3
    alone = warming_rates(SimpleNamespace(signals=(recs[3],), time_known=True))["r3"]
    assert (
        np.ptp(alone) == 0.0
        and abs(alone[0] - 0.4 * w * np.cos(w * recs[3].t_s.mean())) < 0.1 * 0.4 * w
    )


def test_a_step_is_tried_in_every_gap_and_between_the_rows_of_a_record(tmp_path: Path) -> None:
    """One step per gap between records, named by the record before it and placed in the gap;
    inside a record one between each of its rows (a static's two 5 s blocks: its middle; a
    turn's still moments and moving blocks: many), each inside the record's span."""
    d = tmp_path / "s"
    write_session(d, SessionSpec(seed=7))
    ds = load_dataset(d)
    cuts = step_cuts(ds)
    assert [t for t, _ in cuts] == sorted(t for t, _ in cuts)
    assert len({n for _, n in cuts}) == len(cuts)
    order = sorted(ds.signals, key=lambda s: float(s.t_s[0]))
    for before, after in zip(order[:-1], order[1:], strict=True):
        at = {n: t for t, n in cuts}[f"{STEP} after {before.name}"]
        assert before.t_s[-1] < at < after.t_s[0]
    for s in ds.signals:
        inside = [t for t, n in cuts if n.startswith(f"{STEP} during {s.name},")]
        assert all(s.t_s[0] < t < s.t_s[-1] for t in inside)
        if s.kind == "static":
            assert inside == [pytest.approx(float(s.t_s[0]) + 5.0, abs=0.03)], (s.name, inside)
        else:
            assert len(inside) >= 8, (s.name, len(inside))


def test_a_step_goes_with_time_without_being_confounded_with_it() -> None:
    """A step or a drift correlated with time since power-on is time itself (told apart from
    each other by the groups of equals); another signal as correlated is confounded."""
    step = ScanHit("accel", "z", f"{STEP} during x_cw, 7.9 s in", 1.0, 1e4, 0.0, True, 0.88)
    drift = ScanHit("accel", "z", "time since power-on", 0.9, 1e4, 0.0, True, 1.0)
    warm = ScanHit("accel", "z", "temperature", 0.6, 7e3, 0.0, True, 0.83)
    assert not step.time_confounded and not drift.time_confounded
    assert warm.time_confounded and "CONFOUNDED with session time" in warm.describe()
    assert "CONFOUNDED" not in step.describe()


def test_a_run_of_equal_steps_is_written_by_its_first_and_last_place() -> None:
    steps = [f"{STEP} after {n}" for n in ("z_up", "z_dn", "x_ccw", "x_cw")]
    assert _joined(steps) == f"{steps[0]} / … / {steps[-1]}"
    assert _joined(steps[:2]) == " / ".join(steps[:2])
    assert _joined(["(specific force z)²", "|specific force z|"]) == (
        "(specific force z)² / |specific force z|"
    )


@settings(max_examples=60, deadline=None)
@given(
    st.integers(1, 6),
    st.integers(1, 40),
    st.integers(1, 8),
    st.integers(0, 2**32 - 1),
    st.sampled_from(["block", "trapezoid", "sparse"]),
)
def test_a_record_s_signals_and_steps_aggregate_at_once_as_one_at_a_time(
    rows: int, samples: int, cuts: int, seed: int, weights: str
) -> None:
    """The scan's columns of one record in one product (every signal; a step at every cut
    from the running sum of the rows' weights) are what aggregating each signal, and each
    step as 0 before and 1 after, gives one at a time (round-off zeroed alike)."""
    rng = np.random.default_rng(seed)
    t = np.sort(rng.uniform(0.0, 10.0, samples))
    if weights == "block":  # a static's block means: equal weights on a run of samples
        agg = np.zeros((rows, samples))
        for b, part in enumerate(np.array_split(np.arange(samples), rows)):
            agg[b, part] = 1.0 / max(len(part), 1)
    else:  # a turn's integrals (uneven weights), or rows weighing few samples
        agg = rng.uniform(0.0, 0.1, (rows, samples))
        if weights == "sparse":
            agg[rng.random((rows, samples)) < 0.7] = 0.0
    at = np.concatenate([rng.uniform(-1.0, 11.0, cuts), rng.choice(t, min(cuts, samples))])
    one_by_one = aggregate(agg, (t[:, None] > at[None, :]).astype(float))
    batched = _steps_aggregated(agg, t, at)
    assert np.array_equal(one_by_one == 0.0, batched == 0.0)
    assert np.allclose(batched, one_by_one, rtol=1e-12, atol=1e-12)
    signals = rng.normal(0.0, 1.0, (samples, cuts)) * rng.choice([1e-12, 1.0, 1e3], cuts)
    signals[:, 0] = 0.0  # a signal that does not vary in this record
    each = np.column_stack([aggregate(agg, signals[:, k]) for k in range(cuts)])
    together = aggregate(agg, signals, np.abs(signals).max(axis=0))  # each column's own scale
    assert np.allclose(together, each, rtol=1e-12, atol=1e-12 * np.max(np.abs(signals)))
