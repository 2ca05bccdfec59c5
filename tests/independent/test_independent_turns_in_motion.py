"""Turn records that start or end in motion (issue 39 item 6), on the independent simulator.

The 50-session figures are ``benchmarks/turns_in_motion.py``'s; these sessions keep what they
show on other seeds: the gyro's scale and cross-axis pulls (fitted − truth)/σ of unit spread
with the turns' angles unknowns of the fit, and the values of an axis whose turns are all in
motion reported as not determined, never sold with the hand's shortfall in them.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from benchmarks.turns_in_motion import (
    CROSS,
    SCALES,
    cuts_of,
    expected_undetermined,
    session_pulls,
)
from tests.independent.simulate import SessionSpec, simulate


def test_a_cut_turn_misses_its_angle_and_leaves_the_rest_alone() -> None:
    """The record starts after the hand turned 8° (or ends 5° before it stops): its true angle
    is 720° less that (and at most one sample's turn, ≤ 2°, more), the integral of what is left; its
    first (last) samples turn fast, and every other record is the uncut session's."""
    cut = (("y_ccw", "starts", 8.0), ("z_cw", "ends", 5.0))
    whole = {r.name: r for r in simulate(SessionSpec(seed=5)).records}
    for r in simulate(SessionSpec(seed=5, turn_cut=cut)).records:
        w = whole[r.name]
        speed = np.linalg.norm(r.true_rate, axis=1)
        if r.name == "y_ccw":
            assert 710.0 < r.turn_deg <= 712.0
            assert np.trapezoid(speed, r.t_ms / 1000.0) == pytest.approx(r.turn_deg, abs=1e-9)
            assert speed[0] > 20.0 and len(r.t_ms) < len(w.t_ms) and r.t_ms[0] == 0.0
            assert float(r.meta["power_on_s"]) > float(w.meta["power_on_s"])
        elif r.name == "z_cw":
            assert -715.0 <= r.turn_deg < -713.0
            assert speed[-1] > 20.0 and len(r.t_ms) < len(w.t_ms)
        else:
            assert r.turn_deg == w.turn_deg and np.array_equal(r.gyro, w.gyro)


def test_one_turn_in_motion_keeps_every_gyro_value_within_its_sigma(tmp_path: Path) -> None:
    """x_cw ends 10° early: Gxx comes from x_ccw (bias·T from the statics), and every gyro
    scale and cross-axis value lies within 4σ of the truth."""
    spec = SessionSpec(seed=9300, turn_cut=(("x_cw", "ends", 10.0),))
    pulls, undetermined = session_pulls(tmp_path / "one", spec)
    assert not undetermined
    assert max(abs(z) for z in pulls.values()) < 4.0, pulls


@pytest.mark.slow
@pytest.mark.timeout(600)
@pytest.mark.parametrize("motion", ["quarters", "continuous"])
def test_pulls_of_unit_spread_over_sessions_with_turns_in_motion(
    tmp_path: Path, motion: str
) -> None:
    """12 sessions, one to three turn records each cut 0.3–15° into (or before the end of) the
    hand's motion: the scale and the cross-axis pulls each have SD in 0.7–1.4, none beyond
    4.5; the values left undetermined are exactly those of the axes whose turns are all in
    motion."""
    scales: list[float] = []
    cross: list[float] = []
    for seed in range(9400, 9412):
        spec = SessionSpec(seed=seed, turn_cut=cuts_of(seed), turn_motion=motion)
        pulls, undetermined = session_pulls(tmp_path / str(seed), spec)
        assert undetermined == expected_undetermined(spec.turn_cut), (seed, spec.turn_cut)
        scales += [pulls[n] for n in SCALES if n in pulls]
        cross += [pulls[n] for n in CROSS if n in pulls]
    for name, z in (("scale", scales), ("cross-axis", cross)):
        sd = float(np.std(z))
        assert 0.7 <= sd <= 1.4 and max(abs(v) for v in z) < 4.5, (name, sd, len(z))
        assert all(math.isfinite(v) for v in z)
