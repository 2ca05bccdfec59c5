"""Bias steps and drifts on the independent simulator (issue 24, "Done when": steps and drifts
of 100× the floor are never `adequate` and are named as a step or a drift), the floor from the
session. A step falls early (among the static faces), half-way (the turns) or late (the last
turns and the gap before the closing x_up_2), between two records or inside one, either sign;
a drift is linear in time since power-on. A step is placed to the sample with a 95 % ±, and two
steps on one channel are named both when both are significant."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from host.model.dataset import Dataset, load_dataset
from host.model.signals import AXES
from host.model.spec import parse_model
from host.model.stats import chi2_sf
from host.workbench.scan import STEP, step_cuts, time_column
from host.workbench.steps import Placed, channel_cuts, two_against_one
from host.workbench.verdict import Diagnosis, diagnose
from tests.independent.physics import FS_HZ
from tests.independent.simulate import SessionSpec, write_session

#: (effect suffix, seeds): three places in the session, four sessions each
PLACES = (("_early", range(5000, 5004)), ("", range(5004, 5008)), ("_late", range(5008, 5012)))


def _run(tmp_path: Path, effect: str, seed: int) -> tuple[Dataset, Diagnosis, dict[str, Any]]:
    d = tmp_path / f"{effect}_{seed}"
    spec = SessionSpec(seed=seed, effect=effect)
    truth = write_session(d, spec).truth()["effect"]
    ds = load_dataset(d)
    # the records' clock is since power-on; the simulator's step time since the session began
    truth["at_s"] = float(truth.get("at_session_s", 0.0)) + spec.warmup_s
    if "at_session_s_2" in truth:
        truth["at_2_s"] = float(truth["at_session_s_2"]) + spec.warmup_s
    return ds, diagnose(ds, parse_model("base")), truth


def _held(p: Placed, at_s: float) -> bool:
    """The true time inside the step's stated ± (95 %), one sample period either side: the
    records' clock starts at a record's first sample, which the simulator takes up to one
    sample period after the record's start."""
    return p.lo_s - 1.0 / FS_HZ <= at_s <= p.hi_s + 1.0 / FS_HZ


@pytest.mark.slow
@pytest.mark.timeout(300)
@pytest.mark.parametrize("sensor", ["accel", "gyro"])
def test_a_bias_step_is_named_a_step_wherever_it_falls(tmp_path: Path, sensor: str) -> None:
    """Every session: not `adequate`, nothing recommended on the step's channel (a drift is
    not what is missing), no unexplained signal on the other sensor, and the strongest
    unexplained signal is one step on that channel,
    its size within 4σ of the truth; its 95 % ± holds the true time in all but a few of the 12
    (3 misses would be 1 in 50 at the stated rate)."""
    missed = []
    for suffix, seeds in PLACES:
        for seed in seeds:
            ds, dg, e = _run(tmp_path, f"bias_step_{sensor}{suffix}", seed)
            where = (suffix, seed, e["axis"], round(e["at_s"], 1))
            assert dg.verdict == "unexplained", (*where, dg.verdict, dg.recommended_spec)
            assert not [r for r in dg.recommended if f":{sensor}:" in r], (*where, dg.recommended)
            top = dg.dominant[0]
            assert (top.sensor, top.axis) == (sensor, e["axis"]), (*where, top.describe())
            assert top.signal.startswith(STEP), (*where, top.describe())
            assert len(top.steps) == 1, (*where, top.signal)
            # nothing on the other sensor: an accelerometer step once also showed as a false gyro
            # "(rate y)²" (the step tilted the later turns' gravity, read as tilted turn axes)
            others = [h.signal for h in dg.dominant if h.sensor != sensor]
            assert not others, (*where, others)
            (p,) = top.steps
            assert abs(p.size - e["step"]) <= 4.0 * p.size_sd, (*where, p)
            if not _held(p, e["at_s"]):
                missed.append((*where, top.signal))
    assert len(missed) <= 2, missed


@pytest.mark.slow
@pytest.mark.timeout(600)
def test_the_stated_plus_minus_holds_the_step_at_its_rate(tmp_path: Path) -> None:
    """Calibration over 30 sessions (five per sensor and place, seeds 5300–5304): the step's
    95 % ± holds the true time in 26–30 of them (outside that range 1 time in 20 at the
    stated rate), no session names a second step, and a step inside a static's 5 s block is
    placed within 0.5 s of the truth (the row boundary alone would leave up to 2.5 s), its ±
    inside one block's length. (That ± is wider than the error: the session's floor takes the
    step's share of that static's two blocks as wander, host.model.noise.wander_floor.)"""
    held, seconds, in_block = 0, [], []
    for sensor in ("accel", "gyro"):
        for suffix in ("_early", "", "_late"):
            for seed in range(5300, 5305):
                ds, dg, e = _run(tmp_path, f"bias_step_{sensor}{suffix}", seed)
                top = dg.dominant[0]
                assert top.signal.startswith(STEP) and top.axis == e["axis"], top.describe()
                held += _held(top.steps[0], e["at_s"])
                if len(top.steps) > 1:
                    seconds.append((sensor, suffix, seed, top.signal))
                static = [s for s in ds.signals
                          if s.kind == "static" and s.t_s[0] < e["at_s"] < s.t_s[-1]]  # fmt: skip
                if static:
                    p = top.steps[0]
                    in_block.append((abs(p.at_s - e["at_s"]), p.sd_s))
    assert 26 <= held <= 30, held
    assert seconds == [], seconds
    assert in_block and all(err < 0.5 and pm < 5.0 for err, pm in in_block), in_block


def _two_tell(ds: Dataset, dg: Diagnosis, e: dict[str, Any]) -> bool:
    """The two true steps (at their true times) explain significantly more than the best one
    step anywhere, alone or with a drift (Bonferroni over the scan's cuts at 5 %): the records
    can tell that there are two (a drift is a staircase two steps of one sign resemble). Where
    they cannot, one step elsewhere, or with a drift, does as well: a gyro step during the
    turns about its own axis is seen by the later statics alone, and the g-sensitivity takes
    the faces' share."""
    cuts = channel_cuts(ds, dg.fit.basis, e["sensor"], AXES.index(e["axis"]))
    assert cuts is not None
    drift = time_column(ds, dg.fit, e["sensor"], e["axis"])
    gain = two_against_one(cuts, dg.fit.white_residual, e["at_s"], e["at_2_s"], drift)
    return chi2_sf(gain, 1) * len(step_cuts(ds)) < 0.05


@pytest.mark.slow
@pytest.mark.timeout(600)
@pytest.mark.parametrize("sensor", ["accel", "gyro"])
def test_two_steps_on_a_channel_are_named_both(tmp_path: Path, sensor: str) -> None:
    """Two steps on one channel (each 100× a mean's noise, either sign), 8 sessions: whenever
    the records tell two steps from one (:func:`_two_tell`), the strongest signal on the
    channel names two steps, each size within 4σ of its truth and each ± holding its time (one
    miss allowed)."""
    both, missed = 0, []
    for seed in range(5200, 5208):
        ds, dg, e = _run(tmp_path, f"bias_two_steps_{sensor}", seed)
        if not _two_tell(ds, dg, e):
            continue
        both += 1
        top = next(h for h in dg.dominant if (h.sensor, h.axis) == (sensor, e["axis"]))
        assert len(top.steps) == 2, (seed, top.signal)
        for p, at, size in zip(top.steps, (e["at_s"], e["at_2_s"]),
                               (e["step"], e["step_2"]), strict=True):  # fmt: skip
            assert abs(p.size - size) <= 4.0 * p.size_sd, (seed, p, size)
            if not _held(p, at):
                missed.append((seed, at, top.signal))
    assert both >= 3, both  # not vacuous: gyro 4 of these 8, accel more
    assert len(missed) <= 1, missed


@pytest.mark.slow
@pytest.mark.parametrize("sensor", ["accel", "gyro"])
def test_a_bias_drift_is_named_a_drift(tmp_path: Path, sensor: str) -> None:
    """A drift of 100× the floor over the session: `missing_effect`, with time_drift on its
    channel recommended (a catalogue term: the drift is named by it, not by a step)."""
    for seed in range(5100, 5103):
        _, dg, e = _run(tmp_path, f"bias_drift_{sensor}", seed)
        assert dg.verdict == "missing_effect", (seed, dg.verdict, [h.signal for h in dg.dominant])
        assert f"time_drift:{sensor}:{e['axis']}" in dg.recommended, (seed, dg.recommended)
        assert not [h for h in dg.dominant if h.signal.startswith(STEP)], dg.dominant
