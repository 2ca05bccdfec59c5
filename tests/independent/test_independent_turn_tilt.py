"""One turn made with the cube seated 3°–4° off its face (issue 25, "a tilted turn axis is
named"), written by the independent simulator and read through the commands a user runs:
``calibrate`` must not print the cross-axis rate the tilt puts on the other gyros (θ·ω, about
0.06 of the rate: three times the datasheet's ±2 %) as the sensor's misalignment, and both
``calibrate`` and ``model diagnose`` must name the tilted turn with its size."""

from __future__ import annotations

import contextlib
import io
import json
import re
from pathlib import Path

import numpy as np
import pytest

from host.__main__ import main
from host.model.components import fit_with_components
from host.model.dataset import load_dataset
from host.model.spec import parse_model
from tests.independent.simulate import SessionSpec, write_session

#: the datasheet's cross-axis sensitivity (method.md §7), as a fraction of the rate
CROSS_AXIS = 0.02
#: a gyro cross-axis row: name, value, tolerance, mark, U (95 %), and its k where it is
#: Student's t on the σ's dof (the note 'k = 2.52, 6 dof'; '' for k = 2)
ROW = re.compile(
    r"^  (G[xyz][xyz]) +([+-][0-9.]+)  rad +±([0-9.]+) +([+−]) +±([0-9.]+)(?:  k = ([0-9.]+), "
    r"[0-9]+ dof)?$",
    re.M,
)
NAMED = re.compile(r"(\w+): turned about an axis ([0-9.]+) mrad \(([0-9.]+)°\) off ([+-][xyz])")


def _run(argv: list[str]) -> tuple[int, str]:
    out = io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(io.StringIO()):
        rc = main(argv)
    return rc, out.getvalue()


@pytest.mark.parametrize(
    "seed", [0, pytest.param(1, marks=pytest.mark.slow), pytest.param(2, marks=pytest.mark.slow)]
)
def test_one_tilted_turn_is_named_and_its_cross_axis_never_printed_as_the_sensors(
    tmp_path: Path, seed: int
) -> None:
    d = tmp_path / "s"
    write_session(d, SessionSpec(seed=seed, effect="one_turn_axis_tilt"))
    truth = json.loads((d / "truth.json").read_text())
    record, lean = truth["effect"]["record"], np.array(truth["effect"]["lean_rad"])
    size = float(np.linalg.norm(lean))
    # the fake cross-axis the tilt puts on the other gyros is far beyond the datasheet's
    assert size > 2.5 * CROSS_AXIS
    rc, text = _run(["calibrate", "--from-dir", str(d), "--no-archive"])
    assert rc in (0, 1), text
    report = (d / "IND01_result.txt").read_text(encoding="utf-8")
    rows = ROW.findall(report)
    assert len(rows) == 6, report
    for name, value, _tol, mark, _u, _k in rows:
        # no cross-axis value outside the datasheet's ±2 % is printed as the sensor's error;
        # each is the simulated unit's own, within a small part of the tilt it was freed of
        assert abs(float(value)) <= CROSS_AXIS and mark == "+", (name, value, mark)
        assert abs(float(value) - truth["constants"][name]) < 0.02 * size, name
    _rc, diagnosis = _run(["model", "diagnose", str(d)])
    for said in (text, diagnosis):
        named = {m[0]: m for m in NAMED.findall(said.replace("\n    ", " "))}
        # the tilted turn, and only it, is named, with its size in mrad and degrees
        assert list(named) == [record], said
        _, mrad, deg, axis = named[record]
        assert abs(float(mrad) - 1e3 * size) < 0.05 * 1e3 * size
        assert abs(float(deg) - np.degrees(size)) < 0.05 * np.degrees(size)
        assert axis == "+" + truth["effect"]["axis"]


@pytest.mark.slow
def test_a_tilted_turn_on_a_tilted_plate_prints_no_cross_axis_value_beyond_its_sigma(
    tmp_path: Path,
) -> None:
    """One turn seated 3°–4° off its face on a plate tilted 1°, headings unrecorded: the plate's
    tilt bounds where the turn's axis is (about 17.5 mrad), and the printed U carries it."""
    pulls = []
    for seed in range(2, 22):
        d = tmp_path / f"p{seed}"
        write_session(d, SessionSpec(seed=seed, effect="one_turn_axis_tilt_tilted_plate",
                                     headings="random"))  # fmt: skip
        truth = json.loads((d / "truth.json").read_text())
        rc, text = _run(["calibrate", "--from-dir", str(d), "--no-archive"])
        assert rc in (0, 1), text
        assert truth["effect"]["record"] in text
        rows = ROW.findall((d / "IND01_result.txt").read_text(encoding="utf-8"))
        assert len(rows) == 6
        pulls += [(float(v) - truth["constants"][n]) / (float(u) / float(k or 2))
                  for n, v, _t, _m, u, k in rows]  # fmt: skip
    z = np.array(pulls)
    # the printed U (k·σ) holds the unit's own value within 4 σ in every session, and is
    # not widened past use (the pulls' RMS near 1)
    assert np.max(np.abs(z)) < 4.0, np.round(z, 1)
    assert 0.7 < float(np.sqrt(np.mean(z**2))) < 1.5, np.round(z, 1)


#: §2 misalignment names (tests/independent/truth.py's keys)
MIS = ("xz", "xy", "yz", "yx", "zy", "zx")
TILTED_SESSIONS = 30


@pytest.mark.slow
def test_both_turns_tilted_leave_the_accelerometers_sigma_honest(tmp_path: Path) -> None:
    """Both turns about one axis seated 2°–5° off their face: their lean is read from their
    own accelerometer rows against that face's static, so those rows' level is the lean, not
    a second reading of the sensor (host.model.whitening.FREE_LEVEL_RAD). Over 30 sessions,
    ``base`` fitted jointly with its components, (fitted − truth)/σ of the accelerometer's
    biases, scales and misalignments and the gyro's with sd 0.7–1.4 and mean within 3/√n of 0.
    Measured (seeds 0–29): the accelerometer's bias, scale, misalignment sd 1.06, 1.08, 1.05;
    the gyro's 0.93, 0.99, 0.96 (1.03, 1.10 with the turn axis's lean taken for tangents:
    the tilted axis's scale and its cross-axis values biased by up to 1.4σ at 5°). Before,
    the tilted turns' rows counted the static's noise twice: the accelerometer's sd 1.29,
    1.10, 1.57 on these seeds (1.27, 1.03, 1.73 over 50 sessions of
    ``benchmarks/yardstick.py --cases turn_axis_tilt``)."""
    groups = {
        "A0": [f"A0{a}" for a in "xyz"], "Ascale": [f"A{a}{a}" for a in "xyz"],
        "Amis": [f"A{k}" for k in MIS], "G0": [f"G0{a}" for a in "xyz"],
        "Gscale": [f"G{a}{a}" for a in "xyz"], "Gmis": [f"G{k}" for k in MIS],
    }  # fmt: skip
    pulls: dict[str, list[float]] = {k: [] for k in groups}
    for seed in range(TILTED_SESSIONS):
        d = tmp_path / f"t{seed}"
        s = write_session(d, SessionSpec(seed=seed, effect="turn_axis_tilt"))
        c = s.base.constants()
        fit = fit_with_components(load_dataset(d), parse_model("base")).fit
        p = {q.name: q for q in fit.parameters}
        for k, names in groups.items():
            pulls[k].extend((p[n].value - c[n]) / p[n].stderr for n in names)
    for k, v in pulls.items():
        z = np.array(v)
        sd = float(np.std(z, ddof=1))
        assert 0.7 <= sd <= 1.4, (k, round(sd, 2), z.round(1))
        assert abs(float(np.mean(z))) < 3.0 / np.sqrt(len(z)), (k, z.round(1))
