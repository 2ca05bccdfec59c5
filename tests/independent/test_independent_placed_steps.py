"""Bias steps placed in every pause of the plan and inside records (issue 39, "Done when"): a
gyro step of 0.05–0.5 °/s or an accelerometer step of 0.02–0.1 m/s² between the two faces of a
pair, between pairs, between the faces and the turns, between the two turns about an axis,
between the turns about two axes, before the closing x_up again, inside a static and inside a
turn; the turns' places also in a plan without the closing record, where a step after the
statics reaches the turns alone. Never `adequate`, nothing from the catalogue recommended, the
strongest unexplained signal a step on the step's channel. One session per place here (the
yardstick runs ten of each sensor: ``benchmarks/yardstick.py --cases step_gyro_at_pair,…``)."""

from __future__ import annotations

from pathlib import Path

import pytest

from host.model.dataset import load_dataset
from host.model.spec import parse_model
from host.workbench.scan import STEP
from host.workbench.verdict import diagnose
from tests.independent.simulate import SessionSpec, write_session

#: (place, closing record measured, sensor): every place once, the sensors in turn; the turns'
#: places again without the closing record (where a gyro step went `adequate`)
PLACES = [
    ("pair", True, "gyro"), ("pairs", True, "gyro"), ("to_turns", True, "accel"),
    ("turn_pair", True, "accel"), ("turns", True, "accel"), ("closing", True, "gyro"),
    ("in_static", True, "accel"), ("in_turn", True, "gyro"), ("turn_pair", False, "gyro"),
    ("turns", False, "gyro"),
]  # fmt: skip


#: the places in the order their seeds were first given (the places inside the first and the
#: last record came later: ``test_independent_edge_steps.py``)
SEEDED = ("closing", "in_static", "in_turn", "pair", "pairs", "to_turns", "turn_pair", "turns")


@pytest.mark.slow
@pytest.mark.parametrize(("place", "closing", "sensor"), PLACES)
def test_a_step_in_a_pause_of_the_plan_is_named_a_step(
    tmp_path: Path, place: str, closing: bool, sensor: str
) -> None:
    seed = 7000 + SEEDED.index(place)
    spec = SessionSpec(seed=seed, effect=f"bias_step_{sensor}_at_{place}", closing=closing)
    e = write_session(tmp_path, spec).truth()["effect"]
    d = diagnose(load_dataset(tmp_path), parse_model("base"))
    assert d.verdict != "adequate", (e, d.notes)
    assert not d.recommended, (e, d.recommended, d.notes)
    assert d.dominant, (e, d.verdict, d.notes)
    top = d.dominant[0]
    assert (top.sensor, top.axis) == (sensor, e["axis"]) and top.signal.startswith(STEP), (
        e,
        top.describe(),
    )
