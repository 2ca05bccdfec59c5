"""The diagnosis (host/workbench/verdict.py) on simulated sessions with ONE hidden effect, a control
with none, confounded and unidentifiable cases, and the real imucal data."""

from __future__ import annotations

import functools
import json
import math
from pathlib import Path

import numpy as np
import pytest

from host.model.dataset import build_dataset, load_dataset, session_from_records
from host.model.plate import session_plate
from host.model.spec import parse_model
from host.model.stats import chi2_isf
from host.workbench.candidates import holm
from host.workbench.ladder import add_term, ladder
from host.workbench.scenarios import case_dataset, hidden_effect_case, run_case
from host.workbench.text import format_diagnosis
from host.workbench.verdict import VERDICTS, diagnose

REAL = Path(__file__).resolve().parents[4] / "shared" / "data" / "imucal-example"


def _check_found(
    effect: str, seed: int, *, tilted: bool = False, alone: bool = True, other_ok: bool = False
) -> None:
    """The hidden term is named first and recommended; adding it takes RMS z down at least
    3× to the noise. The floor is the unit's known bias wander (what ``--noise`` gives from a
    noise file). ``other_ok``: the other sensor may keep a signal of its own (the verdict is
    then `unexplained`); the hidden term's sensor only a step or a drift in time: the unit's
    Gauss-Markov wander (τ 300 s) is shared by neighbouring records on both sensors, and the
    control of the same seed shows the same step (the 45° plan's seed 0: "a step in time after
    tilt_45_2" on accel z, Δχ² 19.6, with or without the hidden term)."""
    case = hidden_effect_case(effect, seed, tilted=tilted)
    out = run_case(case, case.known_noise())
    d = out.diagnosis
    sensor = case.term.split(":")[1]
    if other_ok and d.verdict == "unexplained":
        in_time = ("a step in time", "time since power-on", "(time since power-on)²")
        mine = [h for h in d.dominant if h.sensor == sensor]
        assert all(h.signal.startswith(in_time) for h in mine), d.dominant
    else:
        assert d.verdict == "missing_effect"
    first = d.candidates[0]
    assert first.significant and first.identifiable
    group = (first.label, *first.confounded_with)
    assert case.term in group, (case.term, group)
    if alone:
        assert first.label == case.term and not first.confounded_with
    assert d.recommended_spec is not None
    # confounded terms fit the records equally well: which of them is recommended is a tie
    assert set(d.recommended_spec.split(",")) & set(group if not alone else (case.term,))
    a = out.addition
    assert a is not None
    assert a.after.rms_z <= 1.5, a.after.rms_z
    assert a.before.rms_z >= 3.0 * a.after.rms_z, (a.before.rms_z, a.after.rms_z)
    assert a.before.chi2 - a.after.chi2 > chi2_isf(1e-4, 1), (a.before.chi2, a.after.chi2)
    assert out.coefficient == pytest.approx(case.truth, rel=0.2)


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.slow
def test_hidden_temperature_bias_is_named_first(seed: int) -> None:
    """Gyro bias ∝ chip temperature, the room cycling ±2.5 °C (temperature up AND down)."""
    _check_found("temperature", seed)


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.slow
def test_hidden_gyro_time_drift_at_constant_temperature(seed: int) -> None:
    _check_found("drift", seed)


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.slow
def test_hidden_accel_scale_asymmetry_six_attitudes_is_a_group_of_equals(seed: int) -> None:
    """With only the six ±1 g faces asymmetry and quadratic nonlinearity move the record means
    identically: they are one group of equals, neither recommended alone, with the record that
    would separate them; adding either takes the misfit away."""
    case = hidden_effect_case("asymmetry", seed)
    out = run_case(case, case.known_noise())
    d = out.diagnosis
    assert d.verdict == "missing_effect"
    group = next(g for g in d.equals if case.term in g.terms)
    other = case.term.replace("scale_asymmetry", "scale_nonlinearity")
    assert other in group.terms
    # on the six faces a face error of the two other pairs moves the bias estimates alike too;
    # a signal of the scan that is the term's own input (|f|, f²) is the term, not another
    assert set(group.terms) <= {case.term, other, "face_error:" + case.term.split(":", 1)[1]}
    assert not group.signals, group.signals
    assert case.term not in d.recommended and other not in d.recommended
    assert any("45°" in w for w in group.separate)
    text = format_diagnosis(d, compare=False)
    assert "cannot tell these apart" in text
    a = out.addition
    assert a is not None and a.after.rms_z <= 1.5 and a.before.rms_z >= 3.0 * a.after.rms_z


@pytest.mark.slow
@pytest.mark.parametrize("seed", range(2))
def test_hidden_accel_scale_asymmetry_separated_by_45_degree_attitudes(seed: int) -> None:
    # the 45° plan's long session: the gyro's Gauss-Markov wander (τ 300 s) is shared by
    # neighbouring records, so with the turns weighed by their measured scatter a gyro
    # residual may follow temperature; the accelerometer must be fully explained
    _check_found("asymmetry", seed, tilted=True, alone=True, other_ok=True)


@pytest.mark.slow
@pytest.mark.parametrize("seed", range(3))
def test_monotonic_warmup_confounds_temperature_and_time(seed: int) -> None:
    case = hidden_effect_case("warmup", seed)
    d = run_case(case).diagnosis
    first = d.candidates[0]
    assert first.significant
    group = {first.label, *first.confounded_with}
    axis = case.term.rsplit(":", 1)[1]
    assert {f"temperature_bias:gyro:{axis}", f"time_drift:gyro:{axis}"} <= group


@pytest.mark.slow
def test_constant_temperature_makes_temperature_terms_unidentifiable() -> None:
    d = run_case(hidden_effect_case("drift", 0)).diagnosis
    temp = [c for c in d.candidates if c.term.startswith("temperature")]
    assert temp and all(not c.identifiable for c in temp)
    assert all("°C" in c.reason and "temperature" in c.needs for c in temp)
    assert all(not c.significant and math.isnan(c.delta_chi2) for c in temp)


@functools.cache
def _control(seed: int) -> tuple[str, str | None, tuple, float]:
    """The control of ``seed`` (§2 data, nothing hidden, the unit's wander known) diagnosed
    with the §2 model: verdict, recommended spec, dominant findings and RMS z. Diagnosed once
    per run: the 100-seed control and the RMS z test read the same sessions."""
    case = hidden_effect_case("none", seed)
    d = diagnose(case_dataset(case, case.known_noise()), parse_model("base"))
    return d.verdict, d.recommended_spec, tuple(d.dominant), d.fit.rms_z


# 100 full diagnoses: about 30 s of CPU (3 of the 100 are not adequate, seeds 37, 51, 65)
@pytest.mark.slow
@pytest.mark.timeout(300)
def test_control_is_adequate_in_at_least_95_of_100_seeds() -> None:
    """False discoveries: §2 data (white noise + Gauss-Markov bias instability) diagnosed
    with the §2 model, ~60 candidates and ~100 signal tests each. The unit's wander is known
    (``--noise``): a session's own records cannot show a wander between them, and without a
    noise file it is rightly misfit (a drift looks the same)."""
    verdicts = [_control(s)[0] for s in range(100)]
    assert verdicts.count("adequate") >= 95, verdicts


def test_holm() -> None:
    assert holm([0.001, 0.04, 0.03], alpha=0.05) == [True, False, False]
    assert holm([0.001, 0.012, 0.02], alpha=0.05) == [True, True, True]
    assert holm([], alpha=0.05) == []


@pytest.mark.slow
def test_json_shape_and_add_and_ladder() -> None:
    ds = case_dataset(hidden_effect_case("temperature", 1))
    d = diagnose(ds, parse_model("base"))
    obj = json.loads(json.dumps(d.to_dict()))
    assert set(obj) >= {"model", "fit", "worst", "candidates", "verdict", "unexplained"}
    assert set(obj["fit"]) >= {"rms_z", "chi2_p", "dof"}
    c0 = obj["candidates"][0]
    for k in ("term", "sensor", "axes", "significant", "identifiable", "delta_bic",
              "rms_z_after", "coefficient", "stderr", "unit", "confounded_with"):  # fmt: skip
        assert k in c0
    assert obj["verdict"] in VERDICTS
    assert obj["worst"] and abs(obj["worst"][0]["z"]) > 3
    a = add_term(ds, parse_model("base"), c0["label"])
    assert a.after.chi2 < a.before.chi2 and a.new_parameters
    steps = ladder(ds)
    added = [s.added for s in steps]
    assert steps[0].model == "bias:accel:xyz,bias:gyro:xyz"
    assert any(s.startswith("scale:gyro") for s in added)
    assert any(s.startswith("temperature_bias:gyro") for s in added)
    assert steps[-1].rms_z < steps[0].rms_z / 10


@pytest.mark.skipif(not REAL.is_dir(), reason="shared real data not present")
def test_real_imucal_data() -> None:
    """Real consumer IMU, one-way turns, constant fake temperature: temperature terms are NOT
    identifiable; the accelerometer bias-estimate disagreement (README) is real structure."""
    ds = load_dataset(REAL)
    d = diagnose(ds, parse_model("base"))
    assert d.verdict != "adequate"
    temp = [c for c in d.candidates if c.term.startswith("temperature")]
    assert temp and not any(c.identifiable for c in temp)
    assert "25.0" in temp[0].reason
    # the misfit sits in the accelerometer, as the three bias estimates say
    worst = d.worst
    assert worst and worst[0].sensor == "accel" and abs(worst[0].z) > 10
    sig = d.significant
    assert sig and all(c.sensor == "accel" for c in sig)
    assert any(n.startswith("records carry no power-on time") for n in d.notes)


# --------------------------------------------------------------------------- issue 12


def _with_gyro_g2(records: dict, coef_dps: float) -> dict:
    """The records with an effect outside the catalogue added: gyro x reads coef·(f_z/g)²
    (a gyro g²-sensitivity), on every sample (statics and turns)."""
    from host.session.records import Record

    out = {}
    for name, r in records.items():
        gyro = r.gyro.copy()
        gyro[:, 0] += coef_dps * float(r.up[2]) ** 2
        out[name] = Record(r.name, r.t_ms, r.accel, gyro, r.temp, r.meta)
    return out


@pytest.mark.skipif(not REAL.is_dir(), reason="shared real data not present")
def test_real_imucal_plate_tilt_is_what_the_rests_show_and_no_face_error_is_claimed() -> None:
    """imucal's real session (issue 25): the accelerometer at the rests inside each turn lies on
    a circle of ≈ 5 mrad about the turn axis — a tilted plate, which a face error cannot draw.
    The records carry no placement heading, so on the statics that tilt reads like a face lean:
    the diagnosis refuses the face error with that reason instead of claiming one (it used to
    claim 'faces ±z lean +3.9 mrad toward x' from the ruler convention), and the plate's tilt,
    added, comes out at the size the rests show."""
    ds = load_dataset(REAL)
    base = parse_model("base")
    d = diagnose(ds, base)
    text = format_diagnosis(d, compare=False)
    assert "faces ±z lean" not in text and "faces ±x lean" not in text
    assert "face_error (accel:x, accel:y, accel:z): NOT identifiable" in text
    assert "placement_heading_deg" in text
    assert d.recommended_spec is None or "face_error" not in d.recommended_spec
    a = add_term(ds, base, "plate_tilt:accel:xyz")
    tilt = {p.name: p for p in a.after.parameters if p.term_name == "plate_tilt"}
    e, n = tilt["plate_tilt.east"], tilt["plate_tilt.north"]
    size = math.hypot(e.value, n.value)
    rests = session_plate(ds.signals)  # what the notes report: the circles of the rests
    assert rests is not None and rests.size_sd <= 1e-3
    assert 4.0e-3 <= rests.size <= 6.5e-3
    # the fit agrees with the rests (its σ is widened by the statics' misfit, not asserted)
    assert 4.0e-3 <= size <= 6.5e-3 and abs(size - rests.size) < 3 * rests.size_sd
    assert any(n.startswith(f"plate tilt {1e3 * rests.size:.2f}") for n in ds.notes)


@pytest.mark.parametrize("seed", range(3))
@pytest.mark.parametrize("known_noise", [False, True])
@pytest.mark.slow
def test_effect_outside_the_catalogue_is_unexplained_and_named(
    seed: int, known_noise: bool
) -> None:
    """A gyro g²-sensitivity (not in the catalogue): verdict unexplained, the signal named on
    the right channel, nothing recommended — with the floor measured from the session and
    with the unit's known noise (``--noise``)."""
    case = hidden_effect_case("none", seed)
    noise = case.known_noise() if known_noise else None
    recs = _with_gyro_g2(dict(case.records), 0.03)
    ds = build_dataset(session_from_records(recs), noise=noise)
    d = diagnose(ds, parse_model("base"))
    assert d.verdict == "unexplained"
    assert d.recommended_spec is None and d.to_dict()["recommended"] is None
    # on the six faces (f_z/g)² and |f_z|/g are the same numbers: one finding, both named
    named = [(h.sensor, h.axis, h.signal.split(" / ")[0]) for h in d.dominant]
    assert ("gyro", "x", "(specific force z)²") in named, named
    # the plan measures the Z faces last: the scan says the signal goes with session time
    hit = next(h for h in d.dominant if h.signal.startswith("(specific force z)²"))
    # (with the unit's wander known the turn integrals weigh more: the turn angle estimated
    # jointly with base has 1-2 dof left there and is not resolved in seeds 1 and 2 (0.07-0.11°
    # from the closures before the fit); the plan's f_z² follows time at r ≈ 0.38 then (0.55
    # with the angle measured before the fit): still a correlation, below the "confounded" mark)
    assert hit.time_r > (0.3 if known_noise else 0.5)
    assert hit.time_confounded == ("session time" in hit.describe())
    if not known_noise:
        assert hit.time_confounded
    text = format_diagnosis(d, compare=False)
    assert "try: python" not in text
    assert "recommended: nothing" in text or "recommended alone: none" in text


@pytest.mark.slow
def test_nothing_hidden_is_adequate_with_rms_z_near_one() -> None:
    """§2 data with white noise and bias wander, the wander known as a noise file gives it
    (the floor no longer comes from the misfit of repeated attitudes): adequate, and RMS z of
    the right model close to 1 (median over seeds in 0.7 … 1.3)."""
    rms = []
    for seed in range(10):  # the first ten controls of the 100-seed test: diagnosed once
        verdict, recommended_spec, dominant, rms_z = _control(seed)
        assert verdict == "adequate", (seed, verdict, dominant)
        assert recommended_spec is None
        rms.append(rms_z)
    assert 0.7 <= float(np.median(rms)) <= 1.3, rms


@pytest.mark.slow
def test_implausible_coefficient_is_not_recommended_and_named_an_alias() -> None:
    """Without the scale term, a gyro temperature-scale takes its place on a session whose
    temperature varies: beyond the datasheet's range, called an alias, never recommended."""
    ds = case_dataset(hidden_effect_case("temperature", 0))
    d = diagnose(ds, parse_model("bias,misalignment,g_sensitivity"))
    bad = [c for c in d.candidates if c.implausible]
    assert bad
    assert any(
        c.term == "temperature_scale" and "alias of the omitted base term(s) scale:gyro"
        in c.implausible for c in bad
    )  # fmt: skip
    assert not {c.label for c in bad} & set(d.recommended)
    assert "IMPLAUSIBLE" in format_diagnosis(d, compare=False)


def _stepped_session(tilt_en: tuple[float, float], seed: int) -> dict:
    """Six static faces (20 s) and a CCW turn about each axis made as four quarter turns with
    1.5 s rests (the way imucal's session was made), on a plate tilted by ``tilt_en`` (east,
    north, rad; every record placed at heading 0 and saying so in its header). Biases differ
    per axis; white noise."""
    from host.model.geometry import pose_from_up
    from host.session.records import HEADING_KEY, Record

    rng = np.random.default_rng(seed)
    g = 9.80665
    bias_a = np.array([0.05, -0.08, 0.11])
    bias_g = np.array([0.4, -0.7, 0.25])
    out: dict[str, Record] = {}

    def gravity(up: np.ndarray, psi: np.ndarray) -> np.ndarray:
        r = pose_from_up(up)
        e0, n0 = r[0], r[1]
        c, s = np.cos(psi)[:, None], np.sin(psi)[:, None]
        e, n = e0 * c - n0 * s, n0 * c + e0 * s
        return g * (up[None, :] + tilt_en[0] * e + tilt_en[1] * n)

    for k, ax in enumerate("xyz"):
        for sign, tag in ((1, "up"), (-1, "dn")):
            up = np.zeros(3)
            up[k] = sign
            n = 1000
            t = np.arange(n) * 20.0
            acc = gravity(up, np.zeros(n)) + bias_a + rng.normal(0, 0.01, (n, 3))
            gyr = bias_g + rng.normal(0, 0.03, (n, 3))
            out[f"{ax}_{tag}"] = Record(f"{ax}_{tag}", t, acc, gyr, np.full(n, 25.0),
                                        {HEADING_KEY: "0"})  # fmt: skip
        up = np.zeros(3)
        up[k] = 1.0
        # rest 1.5 s, quarter turn in 1 s (raised-cosine rate), four times, rest 1.5 s
        dt = 0.02
        seg_rest, seg_turn = int(1.5 / dt), int(1.0 / dt)
        rates = [np.zeros(seg_rest)]
        for _ in range(4):
            u = (np.arange(seg_turn) + 0.5) / seg_turn
            rates += [90.0 * (1 - np.cos(2 * np.pi * u)), np.zeros(seg_rest)]
        rate = np.concatenate(rates)  # °/s, integral 360°
        n = len(rate)
        psi = np.radians(np.concatenate([[0.0], np.cumsum((rate[1:] + rate[:-1]) / 2 * dt)]))
        acc = gravity(up, psi) + bias_a + rng.normal(0, 0.01, (n, 3))
        gyr = rate[:, None] * up[None, :] + bias_g + rng.normal(0, 0.03, (n, 3))
        out[f"{ax}_ccw"] = Record(f"{ax}_ccw", np.arange(n) * dt * 1000, acc, gyr,
                                  np.full(n, 25.0),
                                  {"turns": "1", HEADING_KEY: "0"})  # fmt: skip
    return out


@pytest.mark.parametrize("seed", range(2))
@pytest.mark.slow
def test_plate_tilt_is_one_pair_of_angles_read_from_the_still_moments_of_turns(seed: int) -> None:
    """A tilted plate, stepped turns: the horizontal accelerometers follow the heading at the
    still moments, which only a plate tilt explains (a face error or bias turns with the
    cube). The verdict names plate_tilt (ONE shared pair of angles) and the fit reads it."""
    tilt = (0.003, -0.002)
    ds = build_dataset(session_from_records(_stepped_session(tilt, seed)), turns=1)
    d = diagnose(ds, parse_model("base"))
    assert d.verdict == "missing_effect" and d.recommended_spec is not None
    assert d.recommended_spec.split(",") == ["plate_tilt:accel:xyz"], d.recommended_spec
    first = d.candidates[0]
    assert first.term == "plate_tilt" and first.n_params == 2  # shared, not per channel
    a = add_term(ds, parse_model("base"), d.recommended_spec)
    east, north = (a.after.parameter(f"plate_tilt.{s}") for s in ("east", "north"))
    assert east.value == pytest.approx(tilt[0], abs=4 * east.stderr + 1e-4)
    assert north.value == pytest.approx(tilt[1], abs=4 * north.stderr + 1e-4)
    assert a.after.chi2_p > 0.001
    assert a.before.rms_z > 3 * a.after.rms_z


@pytest.mark.slow
def test_diagnose_prints_the_components_its_fit_used(tmp_path: Path) -> None:
    """A model with a gyro scale asymmetry takes the turns' closures: the turn angle is then
    not measured (its rows carry white noise only), as the joint fit says. Diagnose read a
    turn angle measured before the fit (1.2°, the asymmetry's own closure), printed it and
    weighed the turns with it, so the asymmetry's stated σ came out 70× its scatter (0.0023
    for a value 0.004 recovered to 0.00003)."""
    from tests.independent.simulate import SessionSpec, write_session

    write_session(tmp_path, SessionSpec(seed=4000, effect="scale_asymmetry"))
    d = diagnose(load_dataset(tmp_path), parse_model("base,scale_asymmetry:gyro"))
    angle = [n for n in d.notes if n.startswith("a named variance component: turn angle")]
    assert len(angle) == 1 and "not measured" in angle[0], angle
    p = d.fit.parameter("scale_asymmetry.gyro.x")
    assert p.stderr < 1e-4 and abs(p.value - 0.004) < 4.0 * p.stderr, (p.value, p.stderr)
