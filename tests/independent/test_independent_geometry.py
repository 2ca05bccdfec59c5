"""A face's lean is one angle whether the cube rests or turns on it (issue 25, item 4): on
independent sessions whose every face leans 1–5 mrad (the statics and the turns on that face
alike), ``face_error:accel`` reads the lean once — the accelerometer at rest and the gyro
while turning — and the gyro's cross-axis constants are no longer the lean.

The truth the fit should return, from the simulator's own matrices (method.md §2 signs: row i
of the output, column k of the input; x row (1+Sxx, Sxz, −Sxy), y row (−Syz, 1+Syy, Syx), z
row (Szy, −Szx, 1+Szz)): a face pair ±k leaning θ̄ (mean) and δ (half the difference), the
lean toward the accelerometer's axis i is [C_A·θ̄]_i / C_A,ii; the difference δ tilts the
sensor in the cube and moves both sensors' misalignments, by [C_A·δ]_i and [C_G·δ]_i; the
gyro turns only on +k, so it reads [C_G·θ₊]_i of which the shared angle takes C_G,ii·θ̄'.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from host.model.components import fit_with_components
from host.model.dataset import load_dataset
from host.model.fit import Fit
from host.model.spec import parse_model
from tests.independent.simulate import SessionSpec, SimSession, write_session

#: §2 name -> (output axis i, input axis k, sign of the entry C[i, k])
LAYOUT = {"xz": (0, 1, 1), "xy": (0, 2, -1), "yz": (1, 0, -1), "yx": (1, 2, 1),
          "zy": (2, 0, 1), "zx": (2, 1, -1)}  # fmt: skip


def _pulls(s: SimSession, fit: Fit) -> dict[str, list[float]]:
    """(fitted − truth)/σ of every face lean and every accelerometer and gyro misalignment."""
    ca, cg = s.base.accel_matrix, s.base.gyro_matrix
    lean = {k: np.asarray(v, dtype=float) for k, v in s.effect.params["lean_rad"].items()}
    p = {q.name: q for q in fit.parameters}
    out: dict[str, list[float]] = {"face": [], "A": [], "G": []}
    for name, (i, k, sign) in LAYOUT.items():
        ax = "xyz"[k]
        mean, half = (lean["+" + ax] + lean["-" + ax]) / 2, (lean["+" + ax] - lean["-" + ax]) / 2
        seen = float((ca @ mean)[i] / ca[i, i])
        face = p.get(f"face_error.accel.{'xyz'[i]}.±{ax}")
        if face is not None:
            out["face"].append((face.value - seen) / face.stderr)
        want_a = sign * (ca[i, k] + (ca @ half)[i])
        want_g = sign * (cg[i, k] + (cg @ lean["+" + ax])[i] - cg[i, i] * seen)
        out["A"].append((p["A" + name].value - want_a) / p["A" + name].stderr)
        out["G"].append((p["G" + name].value - want_g) / p["G" + name].stderr)
    return out


def _fit(d: Path, spec: str) -> Fit:
    return fit_with_components(load_dataset(d), parse_model(spec)).fit


def test_a_face_lean_is_read_once_by_the_accelerometer_at_rest_and_the_gyro_turning(
    tmp_path: Path,
) -> None:
    """One session: with the base model alone the gyro takes the lean of the face it turned on
    for cross-axis sensitivity (tens to hundreds of σ); with face_error the one angle explains
    the accelerometer's statics and turn rests and the gyro's turns: every lean, every
    accelerometer and gyro misalignment within 4σ of the truth."""
    s = write_session(tmp_path, SessionSpec(seed=0, effect="face_lean"))
    base = _pulls(s, _fit(tmp_path, "base"))
    assert max(abs(z) for z in base["G"]) > 20.0, base["G"]
    shared = _pulls(s, _fit(tmp_path, "base,face_error:accel"))
    assert len(shared["face"]) == 6
    for what, z in shared.items():
        assert max(abs(v) for v in z) < 4.0, (what, np.round(z, 2))


SESSIONS = 30


@pytest.mark.slow
def test_face_lean_pulls_have_unit_spread_over_independent_sessions(tmp_path: Path) -> None:
    """(fitted − truth)/σ over 30 sessions (180 values each): the leans, the accelerometer's
    and the gyro's misalignments with standard deviation 0.7–1.4 and mean within 3/√180 of 0.
    Measured: 1.20, 1.03, 1.17; the gyro's share of the product (gyro − accelerometer
    misalignment) × the lean toward the third axis is left out of the linear model (≈ 3e-5 at
    10 mrad × 3 mrad)."""
    pulls: dict[str, list[float]] = {"face": [], "A": [], "G": []}
    for seed in range(SESSIONS):
        d = tmp_path / f"s{seed}"
        s = write_session(d, SessionSpec(seed=seed, effect="face_lean"))
        for what, z in _pulls(s, _fit(d, "base,face_error:accel")).items():
            pulls[what].extend(z)
    for what, v in pulls.items():
        z = np.array(v)
        assert len(z) == 6 * SESSIONS, what
        assert 0.7 <= float(np.std(z, ddof=1)) <= 1.4, (what, float(np.std(z, ddof=1)))
        assert abs(float(np.mean(z))) < 3.0 / np.sqrt(len(z)), (what, float(np.mean(z)))


@pytest.mark.slow
@pytest.mark.parametrize("recorded", [True, False], ids=["headings", "no_headings"])
def test_plate_tilt_size_and_azimuth_are_honest(tmp_path: Path, recorded: bool) -> None:
    """A plate tilted 0.1°–1° toward any azimuth, every record at a random multiple of 90°,
    the headings recorded or not (then the turns' headings are read from their rests' circles
    and each carries its correction as an unknown; the frame is the first turn's reference
    axis). Over 30 sessions with base + plate_tilt: RMS z ≤ 1.5 and |tilt| within 10 % in
    every session, (fitted − truth)/σ of the tilt's size and azimuth (× size) with sd 0.7–1.4
    and mean within 3/√30 of 0.

    Measured (seeds 0–29): recorded, size/azimuth sd 1.21/0.99, RMS z median 0.98, at most
    1.15 (the size's sd was 2.1 and RMS z up to 1.67 before the tilt's columns went through
    the accelerometer's matrix, the statics' with the tilt taken out); not recorded
    1.13/1.18 (1.10/0.98 on seeds 30–69; the azimuth's was 3.9 with the circles' headings
    taken as exact, and 1.41 with the accelerometer's scales alone, its misalignment turning
    the circle: the matrix now takes its columns from the turns' circle centres)."""
    size: list[float] = []
    azimuth: list[float] = []
    for seed in range(SESSIONS):
        d = tmp_path / f"s{seed}"
        spec = SessionSpec(seed=seed, effect="plate_tilt", headings="random",
                           record_heading=recorded)  # fmt: skip
        s = write_session(d, spec)
        ds = load_dataset(d)
        fit = fit_with_components(ds, parse_model("base,plate_tilt:accel")).fit
        up = np.array([s.effect.params["up_east_rad"], s.effect.params["up_north_rad"]])
        if not recorded:  # the frame: the first turn's reference axis
            first = next(x.name for x in ds.signals if x.kind == "turn")
            a = np.radians(next(r.heading_deg for r in s.records if r.name == first))
            up = np.array([[np.cos(a), np.sin(a)], [-np.sin(a), np.cos(a)]]) @ up
        names = [p.name for p in fit.parameters]
        k = [names.index("plate_tilt.east"), names.index("plate_tilt.north")]
        got = np.array([fit.parameters[i].value for i in k])
        cov = fit.covariance[np.ix_(k, k)]
        assert fit.rms_z <= 1.5, (seed, fit.rms_z)
        assert abs(np.linalg.norm(got) / np.linalg.norm(up) - 1.0) <= 0.1, (seed, got, up)
        u = got / np.linalg.norm(got)
        w = np.array([-u[1], u[0]])
        size.append((np.linalg.norm(got) - np.linalg.norm(up)) / np.sqrt(u @ cov @ u))
        turn = np.angle(complex(*got) / complex(*up))
        azimuth.append(turn * np.linalg.norm(got) / np.sqrt(w @ cov @ w))
    for what, v in (("size", size), ("azimuth", azimuth)):
        z = np.array(v)
        assert abs(float(np.mean(z))) < 3.0 / np.sqrt(SESSIONS), (what, z.round(2))
        assert 0.7 <= float(np.std(z, ddof=1)) <= 1.4, (what, z.round(2))
