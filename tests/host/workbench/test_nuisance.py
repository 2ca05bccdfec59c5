"""Degrees of freedom stated per channel, and the records' own unknowns tested against the
shared parameter they stand for (issue 39, item 3). On sessions of the independent simulator
(tests/independent) and imucal's real session."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from host.model.dataset import load_dataset
from host.model.fit import fit_model
from host.model.spec import parse_model
from host.workbench.ladder import add_term
from host.workbench.nuisance import seen_tilt_test
from host.workbench.text import format_addition
from tests.independent.simulate import SessionSpec, write_session

REAL = Path(__file__).resolve().parents[4] / "shared" / "data" / "imucal-example"


def _tilted(tmp_path: Path, seed: int) -> Path:
    """A plate tilted 0.1°–1°, every record at a random multiple of 90°, no heading recorded."""
    d = tmp_path / f"tilt{seed}"
    write_session(d, SessionSpec(seed=seed, effect="plate_tilt", headings="random"))
    return d


@pytest.mark.slow
def test_the_records_views_of_one_tilt_agree_with_it(tmp_path: Path) -> None:
    """Every record sat on the plate as the turns did: each static's own view of the tilt has
    the plate's size, within its σ (pooled z sd near 1, no session flagged)."""
    zs, ps = [], []
    for seed in range(8):
        t = seen_tilt_test(fit_model(load_dataset(_tilted(tmp_path, seed)),
                                     parse_model("base,plate_tilt:accel")))  # fmt: skip
        assert t is not None and t.dof == 7, seed  # six faces and the closing x_up
        zs += [v.z for v in t.views]
        ps.append(t.p_value)
    assert 0.7 <= float(np.std(zs)) <= 1.4, np.std(zs)
    assert min(ps) > 1e-3, ps


@pytest.mark.slow
def test_an_addition_that_fits_channels_exactly_is_no_fall(tmp_path: Path) -> None:
    """With no heading recorded each static carries its own view of the tilt: the
    accelerometer's record values are then fitted exactly. The headline was 'RMS z 37.86 →
    0.95 (39.7× smaller)'; now those channels are named UNTESTABLE and RMS z is given on the
    channels still tested."""
    a = add_term(load_dataset(_tilted(tmp_path, 3)), parse_model("base"), "plate_tilt:accel")
    assert a.exact == ("accel x", "accel y", "accel z")
    text = format_addition(a)
    assert "× smaller" not in text and "UNTESTABLE" in text and "not a fall" in text
    before, after = a.tested_rms_z()
    assert f"RMS z {before:.2f} → {after:.2f}" in " ".join(text.split())
    assert 0.5 < after < 1.5
    # a term that leaves every channel testable keeps its fall
    b = add_term(load_dataset(_tilted(tmp_path, 3)), parse_model("base"), "lever_arm:accel")
    assert not b.exact and "UNTESTABLE" not in format_addition(b)


@pytest.mark.skipif(not REAL.is_dir(), reason="shared real data not present")
def test_imucal_statics_do_not_all_sit_on_its_plate() -> None:
    """imucal: the statics' own tilts 2.1–6.6 mrad against the plate's 4.9; x_dn far off."""
    a = add_term(load_dataset(REAL), parse_model("base"), "plate_tilt:accel")
    t = a.seen_tilt
    assert t is not None and t.dof == 6 and t.p_value < 1e-6
    worst = max(t.views, key=lambda v: abs(v.z))
    assert worst.record == "x_dn" and worst.z < -4
    assert 4.0e-3 < t.plate < 6.0e-3
    text = " ".join(format_addition(a).split())
    assert "do not all sit on the plate" in text and "UNTESTABLE" in text


@pytest.mark.slow
@pytest.mark.skipif(not REAL.is_dir(), reason="shared real data not present")
def test_imucal_verdict_says_the_accelerometer_is_untestable_with_the_tilt() -> None:
    from host.workbench.text import format_diagnosis
    from host.workbench.verdict import diagnose

    d = diagnose(load_dataset(REAL), parse_model("base"))
    assert "plate_tilt:accel:xyz" in d.recommended
    assert d.untestable_with == ("accel x", "accel y", "accel z")
    text = " ".join(format_diagnosis(d).split())
    assert "accel x, accel y, accel z are UNTESTABLE" in text
    assert any("own views of the tilt" in n for n in d.notes)
