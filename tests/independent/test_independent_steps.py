"""Bias steps and drifts on the independent simulator (issue 24, "Done when": steps and drifts
of 100× the floor are never `adequate` and are named as a step or a drift), the floor from the
session. A step falls early (among the static faces), half-way (the turns) or late (the last
turns and the gap before the closing x_up_2), between two records or inside one, either sign;
a drift is linear in time since power-on."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from host.model.dataset import Dataset, load_dataset
from host.model.spec import parse_model
from host.workbench.scan import STEP, step_cuts
from host.workbench.verdict import Diagnosis, diagnose
from tests.independent.physics import FS_HZ
from tests.independent.simulate import SessionSpec, write_session

#: (effect suffix, seeds): three places in the session, four sessions each
PLACES = (("_early", range(5000, 5004)), ("", range(5004, 5008)), ("_late", range(5008, 5012)))
#: a step is placed by the data around it: between the named place and the true time there
#: may be at most this much of the records' samples, s (one row: a static's 5 s block)
ROW_S = 5.0


def _run(tmp_path: Path, effect: str, seed: int) -> tuple[Dataset, Diagnosis, dict[str, Any]]:
    d = tmp_path / f"{effect}_{seed}"
    spec = SessionSpec(seed=seed, effect=effect)
    truth = write_session(d, spec).truth()["effect"]
    ds = load_dataset(d)
    # the records' clock is since power-on; the simulator's step time since the session began
    truth["at_s"] = float(truth.get("at_session_s", 0.0)) + spec.warmup_s
    return ds, diagnose(ds, parse_model("base")), truth


def _samples_between(ds: Dataset, signal: str, at_s: float) -> float:
    """How much of the records (s of samples) lies between the time ``at_s`` and the nearest
    of the steps a scan finding names (a run of steps the channel cannot tell apart is written
    by its first and last place): 0 when the finding brackets it."""
    cuts = {name: cut for cut, name in step_cuts(ds)}
    at = [cuts[n] for n in signal.split(" / ") if n.startswith(STEP)]
    lo, hi = min(at), max(at)
    if lo <= at_s <= hi:
        return 0.0
    a, b = (at_s, lo) if at_s < lo else (hi, at_s)
    n = sum(int(((s.t_s > a) & (s.t_s < b)).sum()) for s in ds.signals)
    return n / FS_HZ


@pytest.mark.slow
@pytest.mark.timeout(300)
@pytest.mark.parametrize("sensor", ["accel", "gyro"])
def test_a_bias_step_is_named_a_step_wherever_it_falls(tmp_path: Path, sensor: str) -> None:
    """Every session: not `adequate`, nothing recommended on the step's channel (a drift is
    not what is missing), and the strongest unexplained signal is a step on that channel,
    placed where the step fell."""
    for suffix, seeds in PLACES:
        for seed in seeds:
            ds, dg, e = _run(tmp_path, f"bias_step_{sensor}{suffix}", seed)
            where = (suffix, seed, e["axis"], round(e["at_s"], 1))
            assert dg.verdict == "unexplained", (*where, dg.verdict, dg.recommended_spec)
            assert not [r for r in dg.recommended if f":{sensor}:" in r], (*where, dg.recommended)
            top = dg.dominant[0]
            assert (top.sensor, top.axis) == (sensor, e["axis"]), (*where, top.describe())
            assert top.signal.startswith(STEP), (*where, top.describe())
            assert _samples_between(ds, top.signal, e["at_s"]) <= ROW_S, (*where, top.signal)


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
