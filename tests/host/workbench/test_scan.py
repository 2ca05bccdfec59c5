"""The scans (host.workbench.scan) on sessions from the independent simulator (tests/independent:
white noise, quantisation and one effect, written apart from host/bench), floor from the
session: a bias step between records is never `adequate` and is named a step in time."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from host.model.dataset import load_dataset
from host.model.spec import parse_model
from host.workbench.verdict import diagnose
from tests.independent.simulate import SessionSpec, write_session


@pytest.mark.slow
def test_a_gyro_bias_step_is_named_a_step_on_its_channel(tmp_path: Path) -> None:
    """0.12 °/s half-way through (≈ 100× a record mean's noise), 3 sessions: the verdict is not
    `adequate`, nothing is recommended alone, and the strongest unexplained signal is a step in
    time on the right channel, placed between the records either side of the true step."""
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
        assert top.signal.startswith("a step in time after "), top
        name = top.signal.removeprefix("a step in time after ")
        before = next(s for s in ds.signals if s.name == name)
        after = min((s for s in ds.signals if s.t_s[0] > before.t_s[-1]),
                    key=lambda s: float(s.t_s[0]))  # fmt: skip
        # the records' time is since power-on (the session starts after the warm-up): the
        # step falls between the two records, within the gap's slack
        at = truth["at_session_s"] + spec.warmup_s
        assert float(before.t_s[0]) <= at + 30.0 and float(after.t_s[-1]) >= at - 30.0, (
            name, after.name, at)  # fmt: skip
