"""Groups of equals (host/workbench/equals.py) on sessions of the independent simulator
(tests/independent: white noise, quantisation, one effect; written apart from host/bench), the
floor taken from the session: explanations the plan cannot tell apart are one group, none of
them recommended alone, with the record that would separate them."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from host.model.dataset import Dataset, load_dataset
from host.model.loader import load_term_file
from host.model.spec import parse_model
from host.workbench.equals import family
from host.workbench.text import format_diagnosis
from host.workbench.verdict import diagnose
from tests.independent.simulate import SessionSpec, write_session


def _session(tmp_path: Path, seed: int, effect: str) -> tuple[Dataset, dict[str, Any]]:
    d = tmp_path / f"{effect}-{seed}"
    s = write_session(d, SessionSpec(seed=seed, effect=effect))
    return load_dataset(d), s.truth()["effect"]


@pytest.mark.slow
def test_cross_axis_g2_is_one_group_with_the_face_error_and_nothing_alone(tmp_path: Path) -> None:
    """Accel i += c·(f_j/g)²: on the six faces a face lean of the ±j pair toward i is the same
    numbers. Neither is recommended; the group holds both, says so in words of at most 80
    columns, and names the 45° attitudes that would separate them."""
    ds, e = _session(tmp_path, 1000, "cross_g2")
    d = diagnose(ds, parse_model("base"))
    assert d.verdict != "adequate"
    assert d.recommended == () and d.recommended_spec is None
    g = next(g for g in d.equals if f"face_error:accel:{e['axis']}" in g.terms)
    names = [sg for se, ax, sg in g.signals if (se, ax) == ("accel", e["axis"])]
    assert any(n.startswith(f"(specific force {e['source']})²") for n in names), g.signals
    assert any("45°" in w for w in g.separate)
    text = format_diagnosis(d, compare=False)
    block = text[text.index("a group of equals") - 2 :]
    assert "cannot tell these apart" in block and "recommended alone: none" in block
    assert all(len(line) <= 80 for line in block.splitlines()), block
    obj = d.to_dict()["equals"]
    assert obj and obj[0]["signals"][0]["sensor"] == "accel" and obj[0]["terms"]


@pytest.mark.slow
def test_a_user_term_is_a_member_like_the_catalogues(tmp_path: Path) -> None:
    """A user's term file writing the same cross-axis g² as a term joins the group beside the
    catalogue's face error: the data, not a list of pairs, decide who is equal."""
    ds, e = _session(tmp_path, 1001, "cross_g2")
    j = "xyz".index(e["source"])
    f = tmp_path / "my_terms.py"
    f.write_text(
        "from host.model.terms import term\n\n\n"
        "@term(sensors=('accel',), params={'c': '{u}'}, needs='45° attitudes')\n"
        "def cross_square(sig, sensor, axis):\n"
        "    '''The accelerometer reads the square of a cross-axis specific force.'''\n"
        f"    return (sig.force[:, {j}:{j + 1}] / sig.g) ** 2\n"
    )
    d = diagnose(ds, parse_model("base"), load_term_file(f))
    g = next(g for g in d.equals if f"face_error:accel:{e['axis']}" in g.terms)
    assert f"cross_square:accel:{e['axis']}" in g.terms, g.members
    assert not set(g.terms) & set(d.recommended)


@pytest.mark.slow
def test_a_term_is_not_the_equal_of_its_own_input(tmp_path: Path) -> None:
    """A gyro drift: the scan's 'time since power-on' is time_drift's own column and its
    square a variant of the same input, not another explanation: time_drift is recommended
    alone."""
    ds, e = _session(tmp_path, 1000, "bias_drift_gyro")
    d = diagnose(ds, parse_model("base"))
    label = f"time_drift:gyro:{e['axis']}"
    assert label in d.recommended, (d.recommended, [g.members for g in d.equals])
    assert not any(label in g.terms for g in d.equals)


def test_family_is_the_input_whatever_its_power() -> None:
    assert family("(rate x)²") == family("|rate x|") == family("rate x") == "rate x"
    assert family("temperature²") == "temperature"
    assert family("(time since power-on)²") == "time since power-on"
    assert family("(specific force z)² / |specific force z|") == "specific force z"
    assert family("a step in time after y_dn") == "step"
    assert family("dT/dt (the chip warming or cooling)") != family("temperature")


@pytest.mark.slow
def test_a_plate_tilt_equal_to_face_leans_on_all_channels_together(tmp_path: Path) -> None:
    """Every face leaning, statics without a recorded heading: a plate tilt with a heading
    unknown per static fits the leans of all three channels, as do the three channels' face
    errors together, though no one channel's does. One group holds them all; none alone."""
    ds, _ = _session(tmp_path, 1000, "face_lean")
    d = diagnose(ds, parse_model("base"))
    g = next(g for g in d.equals if "plate_tilt:accel:xyz" in g.terms)
    assert {f"face_error:accel:{a}" for a in "xyz"} <= set(g.terms), g.members
    assert not set(g.terms) & set(d.recommended)
    assert len([h for h in d.equals if "plate_tilt:accel:xyz" in h.members]) == 1
