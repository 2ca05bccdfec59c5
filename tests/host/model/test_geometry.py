"""Placement is data (issue 25): the plate's tilt, with each record's heading read from its
header, on sessions written by the independent simulator (``tests/independent``) with the cube
placed at random headings — data the bench's physics did not write."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from host.model.dataset import load_dataset
from host.model.fit import fit_model
from host.model.geometry import placement, plate_axes
from host.model.spec import parse_model
from tests.independent.simulate import SessionSpec, write_session


def test_plate_axes_turn_with_the_heading() -> None:
    """At heading ψ the reference axis points ψ counter-clockwise from the fence: its
    components along (east, north) are (cos ψ, sin ψ), for every face."""
    for up in (*np.eye(3), *(-np.eye(3))):
        ref = placement(up)[0]
        psi = np.radians([0.0, 30.0, 90.0, 180.0, 270.0])
        east, north = plate_axes(up, psi)
        np.testing.assert_allclose(east @ ref, np.cos(psi), atol=1e-12)
        np.testing.assert_allclose(north @ ref, np.sin(psi), atol=1e-12)
        np.testing.assert_allclose(east @ up, 0.0, atol=1e-12)


@pytest.mark.parametrize("seed", [11, 12])
def test_tilt_recovered_with_recorded_random_headings(tmp_path: Path, seed: int) -> None:
    d = tmp_path / "s"
    write_session(
        d, SessionSpec(seed=seed, effect="plate_tilt", headings="random", record_heading=True)
    )
    truth = json.loads((d / "truth.json").read_text())["effect"]
    ds = load_dataset(d)
    headings = {s.placement_deg for s in ds.signals}
    assert None not in headings and len(headings) > 1  # placed at several, recorded, headings
    fit = fit_model(ds, parse_model("base,plate_tilt:accel"))
    p = {q.name: q for q in fit.parameters}
    got = np.array([p["plate_tilt.east"].value, p["plate_tilt.north"].value])
    want = np.array([truth["up_east_rad"], truth["up_north_rad"]])
    # within 10 % of the tilt's size, as a vector (azimuth included)
    assert np.linalg.norm(got - want) < 0.1 * np.linalg.norm(want), (got, want)
    # and the model then explains the records: χ²/dof near 1 (RMS z ≤ 1.5)
    chi2 = float(fit.white_residual @ fit.white_residual)
    assert math.sqrt(chi2 / fit.dof) < 1.5


@pytest.mark.parametrize("heading", [0.0, 90.0])
def test_a_noted_45_attitude_on_a_tilted_plate_reads_the_tilt_at_its_heading(
    heading: float,
) -> None:
    """The 45° attitudes a planner may ask for with the heading noted: the independent
    simulator places each at that heading on a tilted plate, and the horizontal force it
    writes is g·(t_e·e + t_n·n) at the model's plate axes for that heading (the same
    reference axis on both sides: the first body axis not parallel to up)."""
    from host.bench.plan import tilted_45
    from host.model.geometry import reference_axis
    from tests.independent.simulate import Extra, simulate

    extra = tuple(Extra(n, "static", up, heading_deg=heading) for n, up in tilted_45())
    s = simulate(SessionSpec(seed=4, effect="plate_tilt", extra=extra))
    t_e, t_n = s.effect.params["up_east_rad"], s.effect.params["up_north_rad"]
    for (name, up), r in zip(tilted_45(), s.records[-len(extra) :], strict=True):
        assert r.name == name
        u = np.asarray(up)
        f = r.true_force.mean(axis=0)
        east, north = plate_axes(u, np.radians([heading]))
        np.testing.assert_allclose(f - (f @ u) * u, s.g * (t_e * east[0] + t_n * north[0]),
                                   atol=s.g * 2e-4, err_msg=name)  # fmt: skip
        ref = "xyz".index(reference_axis(u)[1])
        assert abs(u[ref]) < 0.9  # the operator's arrow is not the one pointing up
