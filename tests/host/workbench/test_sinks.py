"""An implausible variance component is a finding, not a sink; the gyro at a turn's rests
(issue 39, item 2), on the independent simulator's sessions."""

from __future__ import annotations

from pathlib import Path

import pytest

from host.model.components import fit_with_components, without_components
from host.model.dataset import load_dataset
from host.model.spec import parse_model
from host.workbench.sinks import implausible, rest_changes, rest_hits, what_absorbed
from tests.independent.simulate import SessionSpec, write_session


def _session(tmp_path: Path, effect: str, seed: int, **kw: object) -> tuple[Path, dict]:
    d = tmp_path / f"{effect}_{seed}"
    s = write_session(d, SessionSpec(seed=seed, effect=effect, **kw))  # type: ignore[arg-type]
    return d, s.truth()["effect"]


def test_the_gyro_at_a_turns_rests_reads_a_bias_change_since_its_face(tmp_path: Path) -> None:
    """A gyro step between the y and z turns of a plan without the closing x_up: the z turns'
    rests read it against z_up, on the step's channel, its size within 4σ; nothing else is
    significant."""
    d, e = _session(tmp_path, "bias_step_gyro_at_turns", 1000, closing=False)
    hits = rest_hits(load_dataset(d), 0.01)
    assert [h.axis for h in hits] == [e["axis"]]
    (p,) = hits[0].steps
    assert abs(p.size - e["step"]) <= 4 * p.size_sd, (p.size, e["step"], p.size_sd)


def test_the_turns_rests_read_no_change_on_a_control(tmp_path: Path) -> None:
    """On a control the changes at the rests scatter as their σ says (|z| < 4.5 over ~18)."""
    d, _ = _session(tmp_path, "none", 1001)
    changes = rest_changes(load_dataset(d))
    assert len(changes) >= 18  # three channels of each of the six turns
    assert max(abs(c.z) for c in changes) < 4.5
    assert not rest_hits(load_dataset(d), 0.01)


def test_a_component_at_zero_keeps_the_rows_white_noise(tmp_path: Path) -> None:
    """without_components puts the turn wobble's rows back at their white variance: the
    cross-axis turn integrals' σ falls to the integrated white noise (≈ 0.01°, far under the
    wobble they had), the up channels' untouched."""
    d, _ = _session(tmp_path, "bias_step_gyro_at_turns", 1000, closing=False)
    joint = fit_with_components(load_dataset(d), parse_model("base"))
    ds = joint.dataset
    wobble = next(c for c in ds.components if c.name == "turn wobble")
    assert wobble.value > 0.5 and implausible(ds)
    free = without_components(ds, ["turn wobble"])
    for old, new in zip(ds.groups, free.groups, strict=True):
        sig = ds.signals[old.record]
        cross = sig.kind == "turn" and old.sensor == "gyro" and abs(sig.up[old.axis]) < 0.5
        if cross:
            assert new.sigma < 0.05 < old.sigma
        else:
            assert new.sigma == old.sigma


@pytest.mark.slow
def test_what_the_wobble_absorbed_is_the_step(tmp_path: Path) -> None:
    """The wobble that swallowed a step between the turns: on the yardstick without it the
    scan finds the step on its channel, and with that step in the model the wobble is
    plausible again."""
    d, e = _session(tmp_path, "bias_step_gyro_at_turns", 1000, closing=False)
    model = parse_model("base")
    ds = fit_with_components(load_dataset(d), model).dataset
    found = what_absorbed(ds, model, 0.01)
    assert found is not None and found.hit is not None
    assert (found.hit.sensor, found.hit.axis) == ("gyro", e["axis"])
    assert found.hit.signal.startswith("a step in time")
    assert not any(c.plausible for c in found.after)
