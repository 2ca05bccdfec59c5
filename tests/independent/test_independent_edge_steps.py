"""A bias step inside the first and inside the last record of the plan (issue 39, "Done when":
≥ 9 of 10 at each place): inside ``x_up`` nothing comes before it, and the pair's scale and the
misalignments take the record's level, so only the record's own samples show the step; inside
the closing ``x_up_2`` nothing comes after it; and an accelerometer step among the turns of a
plan without ``x_up_2``, which no static record sees. Ten sessions per case (seeds fixed),
0.02–0.1 m/s² or 0.05–0.5 °/s: never `adequate`, nothing from the catalogue recommended, the
strongest unexplained signal a step on the step's channel in at least 9. Before the record's
samples were read for a step, the step inside ``x_up`` widened that record's σ, the channel's
serial correlation and the session's floor until it fitted: `adequate` in 3 of 5."""

from __future__ import annotations

from pathlib import Path

import pytest

from host.model.dataset import load_dataset
from host.model.spec import parse_model
from host.workbench.scan import STEP
from host.workbench.verdict import diagnose
from tests.independent.simulate import SessionSpec, write_session

SESSIONS = 10


def _named(tmp: Path, effect: str, seed: int, closing: bool = True) -> tuple[bool, str]:
    """Is the step of session ``seed`` named a step on its channel, with no term recommended
    and the verdict not `adequate`? And what the diagnosis said, for the failure's message."""
    d_in = tmp / str(seed)
    spec = SessionSpec(seed=seed, effect=effect, closing=closing)
    e = write_session(d_in, spec).truth()["effect"]
    d = diagnose(load_dataset(d_in), parse_model("base"))
    top = d.dominant[0] if d.dominant else None
    ok = (
        d.verdict != "adequate"
        and not d.recommended
        and top is not None
        and (top.sensor, top.axis) == (e["sensor"], e["axis"])
        and top.signal.startswith(STEP)
    )
    said = top.describe() if top else f"{d.verdict}, {d.recommended}"
    return ok, f"{e['sensor']} {e['axis']} {e['step']:+.3f} in {e['record']}: {said}"


@pytest.mark.slow
@pytest.mark.parametrize("sensor", ["accel", "gyro"])
@pytest.mark.parametrize("place", ["in_first", "in_last"])
def test_a_step_inside_the_first_or_last_record_is_named(
    tmp_path: Path, place: str, sensor: str
) -> None:
    seed0 = {"in_first": 7100, "in_last": 7200}[place] + (50 if sensor == "gyro" else 0)
    effect = f"bias_step_{sensor}_at_{place}"
    results = [_named(tmp_path, effect, seed0 + k) for k in range(SESSIONS)]
    missed = [said for ok, said in results if not ok]
    assert len(missed) <= 1, missed


@pytest.mark.slow
def test_an_accel_step_among_the_turns_with_no_rest_after_them_is_named(tmp_path: Path) -> None:
    """No closing x_up_2: an accelerometer step between the turns about two axes leans every
    turn after it as a seat tilted by Δb/g, which took them for tilted (`adequate` in 2 of 10):
    one step explains every lean and is named, the note saying it could not be told from a
    tilted seat by these records."""
    effect = "bias_step_accel_at_turns"
    results = [_named(tmp_path, effect, 7300 + k, closing=False) for k in range(SESSIONS)]
    missed = [said for ok, said in results if not ok]
    assert len(missed) <= 1, missed


@pytest.mark.slow
def test_a_gyro_step_inside_the_last_turn_with_no_rest_after_it_is_named(tmp_path: Path) -> None:
    """No closing x_up_2: a gyro step inside z_cw, the last record, reaches only that turn's
    integrals, which took it as the hand's turn angle or wobble or a scale asymmetry (named in
    5 of 10, `adequate` in 1): the turn's last rest against its first reads it, on its channel."""
    effect = "bias_step_gyro_at_in_last_turn"
    results = [_named(tmp_path, effect, 7400 + k, closing=False) for k in range(SESSIONS)]
    missed = [said for ok, said in results if not ok]
    assert len(missed) <= 1, missed
