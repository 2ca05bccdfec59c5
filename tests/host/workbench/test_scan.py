"""The scans (host.workbench.scan) on sessions from the independent simulator (tests/independent:
white noise, quantisation and one effect, written apart from host/bench), floor from the
session: a bias step between records is never `adequate` and is named a step in time."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from host.model.dataset import load_dataset
from host.model.spec import parse_model
from host.workbench.scan import STEP, step_cuts
from host.workbench.verdict import diagnose
from tests.independent.simulate import SessionSpec, write_session


@pytest.mark.slow
def test_a_gyro_bias_step_is_named_a_step_on_its_channel(tmp_path: Path) -> None:
    """0.12 °/s half-way through (≈ 100× a record mean's noise), 3 sessions: the verdict is not
    `adequate`, nothing is recommended alone, and the strongest unexplained signal is a step in
    time on the right channel, placed in the gap or the record where the step fell."""
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
        # the records' time is since power-on (the session starts after the warm-up): the
        # step is placed in the gap or the record where it fell, within the gap's slack
        at = truth["at_session_s"] + spec.warmup_s
        cut = {name: t for t, name in step_cuts(ds)}[top.signal.split(" / ")[0]]
        assert abs(cut - at) <= 30.0, (top.signal, at)


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
