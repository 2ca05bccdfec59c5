"""The plate's tilt from the turns' motion (issue 40), on the independent simulator: turns of one
continuous motion resting only at their ends (no rest inside a turn draws a circle), every
record at a random multiple of 90°, no heading recorded.

The 50-session figures are ``benchmarks/tilt_motion.py``'s; these few sessions keep what they
show: the tilt read from every sample of the turns, its size within 10 % and 3σ, RMS z ≤ 1.5
with it; the lever arm within 3σ with and without a tilt; the diagnosis never selling a lever
arm for a tilt or a tilt for a lever arm.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from benchmarks.tilt_motion import tilt_size
from benchmarks.yardstick_pulls import truth_of
from host.model.catalogue import CATALOGUE
from host.model.components import fit_with_components
from host.model.dataset import Dataset, load_dataset
from host.model.fit import Fit
from host.model.plate import session_plate
from host.model.spec import parse_model
from host.workbench.verdict import diagnose
from tests.independent.simulate import SessionSpec, write_session


def _session(tmp_path: Path, seed: int, effect: str) -> tuple[Dataset, dict]:
    d = tmp_path / f"{effect}_{seed}"
    spec = SessionSpec(seed=seed, effect=effect, headings="random", turn_motion="continuous")
    truth = write_session(d, spec).truth()
    return load_dataset(d), truth


def _pulls(fit: Fit, truth: dict, prefix: str) -> dict[str, float]:
    out = {}
    for p in fit.parameters:
        t = truth_of(p.name, truth) if p.name.startswith(prefix) else None
        if t is not None:
            out[p.name] = (p.value - t) / p.stderr
    return out


@pytest.mark.slow
@pytest.mark.parametrize("seed", [4100, 4101])
def test_the_tilt_is_read_from_the_motion_of_turns_without_inner_rests(
    tmp_path: Path, seed: int
) -> None:
    """No turn rests inside itself, yet the tilt is found from every sample: each turn's
    circle is read from its motion, the fit's size within 10 % and 3σ of the truth, its two
    angles and every static's own view of it within 4σ, RMS z ≤ 1.5 with the term."""
    ds, truth = _session(tmp_path, seed, "plate_tilt")
    plate = session_plate(ds.signals)
    assert plate is not None and len(plate.circles) == 6
    assert all(c.source == "motion" and c.n_rests == 2 for c in plate.circles)
    note = next(n for n in ds.notes if n.startswith("plate tilt"))
    assert "read from the motion of 6 turns" in note and "the hand" in note
    # no hand is simulated: the hand's component is far below the tilt's g·θ
    assert plate.circles[0].scatter[1] < 0.05 * 9.8 * plate.size
    fit = fit_with_components(ds, parse_model("base,plate_tilt:accel")).fit
    size, sd = tilt_size(fit)
    true = float(truth["effect"]["tilt_rad"])
    assert abs(size - true) <= min(0.1 * true, 3.0 * sd), (size, true, sd)
    pulls = _pulls(fit, truth, "plate_tilt")
    assert len(pulls) == 2 + 2 * 7  # the two angles, two per static (7 with x_up_2)
    assert max(abs(z) for z in pulls.values()) < 4.0, pulls
    assert fit.rms_z <= 1.5


@pytest.mark.slow
@pytest.mark.parametrize("effect", ["lever_arm_mm", "plate_tilt_lever_arm"])
def test_the_lever_arm_is_recovered_with_and_without_a_tilt(tmp_path: Path, effect: str) -> None:
    """A sensor 10–50 mm off the cube's centre: each component within 3σ, on a level plate
    (where the motion shows no tilt: the plate stays level for the fit) and on a tilted one
    (the tilt and the lever arm fitted together)."""
    ds, truth = _session(tmp_path, 4110, effect)
    tilted = effect != "lever_arm_mm"
    plate = session_plate(ds.signals)
    assert plate is not None and (plate.p_level < 1e-3) == tilted
    spec = "base,plate_tilt:accel,lever_arm:accel" if tilted else "base,lever_arm:accel"
    fit = fit_with_components(ds, parse_model(spec)).fit
    pulls = _pulls(fit, truth, "lever_arm")
    assert len(pulls) == 3 and max(abs(z) for z in pulls.values()) < 3.0, pulls
    assert fit.rms_z <= 1.5


@pytest.mark.slow
def test_a_tilt_is_never_sold_as_a_lever_arm_nor_a_lever_arm_as_a_tilt(tmp_path: Path) -> None:
    """The diagnosis of a tilt alone recommends the tilt and neither a lever arm nor a face
    error; of a lever arm alone the lever arm, never the tilt."""
    cat = dict(CATALOGUE)
    ds, _ = _session(tmp_path, 4120, "plate_tilt")
    rec = diagnose(ds, parse_model("base"), cat).recommended_spec or ""
    assert "plate_tilt" in rec and "lever_arm" not in rec and "face_error" not in rec, rec
    ds, _ = _session(tmp_path, 4120, "lever_arm_mm")
    rec = diagnose(ds, parse_model("base"), cat).recommended_spec or ""
    assert "lever_arm" in rec and "plate_tilt" not in rec, rec


def test_the_motion_shows_no_tilt_on_a_level_plate(tmp_path: Path) -> None:
    """A control session of continuous turns: the tilts the turns' motion shows are their
    noise (the level plate's probability of circles that large is not small), so the
    diagnosis says nothing of a plate."""
    ds, _ = _session(tmp_path, 4130, "none")
    plate = session_plate(ds.signals)
    assert plate is not None and plate.p_level > 1e-3
    assert max(c.size for c in plate.circles) < 5 * max(c.size_sd for c in plate.circles)
    assert not any(n.startswith("plate tilt") for n in ds.notes)
