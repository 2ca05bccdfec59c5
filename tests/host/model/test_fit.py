"""The model engine (host/model/): terms, specs, noise model, the one least-squares fit."""

from __future__ import annotations

import dataclasses
import textwrap
from pathlib import Path

import numpy as np
import pytest

from host.bench.physics import Environment
from host.bench.plan import Plan, simulate_session
from host.bench.truth import SensorTruth
from host.errors import UserError
from host.model.catalogue import BASE, CATALOGUE
from host.model.dataset import build_dataset, session_from_records
from host.model.fit import fit_model
from host.model.loader import load_term_file
from host.model.noise import NoiseModel, integrated_autocorrelation
from host.model.spec import model_spec, parse_model
from host.model.stats import chi2_isf, chi2_sf


def _session(seed: int = 3, **plan_kw: object) -> tuple[SensorTruth, object]:
    truth = SensorTruth.random(np.random.default_rng(seed)).only("linear", "noise")
    recs = simulate_session(truth, Plan(static_s=10.0, **plan_kw), seed)  # type: ignore[arg-type]
    return truth, build_dataset(session_from_records(recs))


def test_catalogue_terms_have_physics_units_and_columns() -> None:
    required = {
        "bias", "scale", "misalignment", "g_sensitivity", "temperature_bias",
        "temperature_scale", "time_drift", "scale_asymmetry", "scale_nonlinearity",
    }  # fmt: skip
    assert required <= set(CATALOGUE)
    for t in CATALOGUE.values():
        assert t.physics and len(t.physics) > 20, t.name
        assert len(t.units) == len(t.params)
        assert set(t.sensors) <= {"accel", "gyro"}
    assert CATALOGUE["g_sensitivity"].sensors == ("gyro",)


def test_parse_model_specs() -> None:
    base = parse_model("base")
    assert {mt.term.name for mt in base} == set(BASE)
    assert all(mt.axes == (0, 1, 2) for mt in base)
    m = parse_model("bias,temperature_bias:gyro:x,temperature_bias:gyro:z")
    assert model_spec(m) == "bias:accel:xyz,bias:gyro:xyz,temperature_bias:gyro:xz"
    assert parse_model("scale:accel")[0].sensor == "accel"
    for bad in ("", "nope", "bias:magnetometer", "bias:gyro:w", "g_sensitivity:accel", "a:b:c:d"):
        with pytest.raises(UserError):
            parse_model(bad)


def test_base_fit_recovers_the_section2_constants() -> None:
    truth, ds = _session()
    fit = fit_model(ds, parse_model("base"))  # type: ignore[arg-type]
    c = truth.constants()
    for name, tol in (("Axx", 3e-4), ("Azy", 3e-4), ("A0y", 3e-3), ("Gyy", 2e-3),
                      ("G0z", 5e-3), ("GAxz", 5e-3), ("Gzx", 2e-3)):  # fmt: skip
        p = fit.parameter(name)
        assert abs(p.value - c[name]) < tol, (name, p.value, c[name])
        assert 0 < p.stderr < tol
    assert fit.parameter("A0x").unit == "m/s²"
    assert fit.parameter("GAxy").unit == "(°/s)/g"
    assert fit.rms_z < 1.5 and fit.chi2_p > 0.01
    assert not fit.undetermined


def test_bias_only_model_is_a_valid_start_and_worse() -> None:
    _, ds = _session()
    small = fit_model(ds, parse_model("bias"))  # type: ignore[arg-type]
    base = fit_model(ds, parse_model("base"))  # type: ignore[arg-type]
    assert small.n_params == 6 and base.n_params == 33  # 3·4 accel + 3·7 gyro
    assert small.chi2 > 100 * base.chi2


def test_turn_axis_missing_leaves_its_gyro_column_undetermined() -> None:
    _, ds = _session(turn_axes=("x", "y"))
    fit = fit_model(ds, parse_model("base"))  # type: ignore[arg-type]
    assert "Gzz" in fit.undetermined and np.isnan(fit.parameter("Gzz").value)
    assert np.isfinite(fit.parameter("Gxx").value)


def test_chi2_distribution_functions() -> None:
    assert chi2_sf(3.841458820694124, 1) == pytest.approx(0.05, rel=1e-6)
    assert chi2_sf(18.307038053275146, 10) == pytest.approx(0.05, rel=1e-6)
    assert chi2_sf(200.0, 150) == pytest.approx(0.0039, rel=0.05)
    assert chi2_sf(0.0, 3) == 1.0
    assert chi2_isf(0.01, 2) == pytest.approx(9.2103, rel=1e-4)


def test_integrated_autocorrelation_white_and_ar1() -> None:
    rng = np.random.default_rng(0)
    white = rng.standard_normal(20000)
    assert integrated_autocorrelation(white, 30) == pytest.approx(1.0, abs=0.1)
    ar = np.zeros(20000)
    e = rng.standard_normal(20000)
    for i in range(1, len(ar)):
        ar[i] = 0.8 * ar[i - 1] + e[i]
    assert integrated_autocorrelation(ar - ar.mean(), 60) == pytest.approx(9.0, rel=0.15)


def test_serial_correlation_of_white_records_is_not_biased_high() -> None:
    """Seven white records of 500 samples, pooled: τ is 1 in most sessions and ≈ 1 on
    average (summing ρ_k until it first drops to ≤ 0 gave ≈ 1.05 per record, every record
    mean's σ too wide); a correlated sensor's τ still comes back from the pooled runs."""
    rng = np.random.default_rng(1)
    taus = [
        integrated_autocorrelation([rng.standard_normal(500) for _ in range(7)], 30)
        for _ in range(200)
    ]
    assert np.mean(np.array(taus) == 1.0) > 0.9 and np.mean(taus) < 1.01
    runs = []
    for _ in range(7):
        ar = np.zeros(500)
        e = rng.standard_normal(500)
        for i in range(1, 500):
            ar[i] = 0.5 * ar[i - 1] + e[i]
        runs.append(ar - ar.mean())
    assert integrated_autocorrelation(runs, 30) == pytest.approx(3.0, rel=0.15)


@pytest.mark.slow
def test_noise_model_is_honest_under_the_null() -> None:
    """The §2 model on §2 data with white noise AND Gauss-Markov bias instability, the unit's
    wander known (as its noise file gives it, ``--noise``): χ²/dof about 1 or below (never the
    3-10 of a white-noise-only model). A session's own records cannot show a wander between
    them: the floor is no longer taken from the misfit of repeated attitudes."""
    ratios = []
    for seed in range(12):
        truth = SensorTruth.random(np.random.default_rng(seed)).only(
            "linear", "noise", "bias_instability"
        )
        recs = simulate_session(truth, Plan(static_s=30.0), seed)
        known = {
            "accel": float(np.sqrt(np.mean(np.square(truth.accel_bias_instability)))),
            "gyro": float(np.sqrt(np.mean(np.square(truth.gyro_bias_instability)))),
        }
        ds = build_dataset(session_from_records(recs), noise=NoiseModel(floor=known))
        fit = fit_model(ds, parse_model("base"))
        ratios.append(fit.chi2 / fit.dof)
        naive = build_dataset(
            session_from_records(recs),
            noise=NoiseModel(floor={"accel": 0.0, "gyro": 0.0}, turn_angle_sigma_deg=0.01),
        )
        assert fit_model(naive, parse_model("base")).chi2 > fit.chi2
    assert 0.5 < float(np.mean(ratios)) < 1.3


def test_blocks_give_within_record_rows() -> None:
    _, ds = _session()
    static_groups = [g for g in ds.groups if ds.signals[g.record].kind == "static"]
    assert all(len(g.rows) == 2 for g in static_groups)  # 10 s records, 5 s blocks
    turn_groups = [g for g in ds.groups if ds.signals[g.record].kind == "turn"]
    # a turn: one integral per gyro channel; the accelerometer one row per still moment and,
    # on the horizontal channels, one per moving block (the lever arm shows there)
    assert all(len(g.rows) == 1 for g in turn_groups if g.sensor == "gyro")
    for g in turn_groups:
        if g.sensor == "accel":
            agg = ds.aggregator(g.record, "accel", g.axis)
            assert len(g.rows) == agg.shape[0] >= 1
            assert not ds.row_integral[g.rows].any()
            up = abs(float(ds.signals[g.record].up[g.axis])) > 0.5
            others = [ds.aggregator(g.record, "accel", a).shape[0] for a in range(3)]
            # the up channel has only the still moments: fewer rows than the horizontal ones
            assert (len(g.rows) < max(others)) if up else (len(g.rows) == max(others))
            # the rows' mean is whitened exactly (still moments and moving blocks differ)
            w = ds.whiten.dense()[np.ix_(g.rows, g.rows)]
            cov = np.linalg.inv(w.T @ w)
            mean = np.full(len(g.rows), 1.0 / len(g.rows))
            assert mean @ cov @ mean == pytest.approx(g.sigma**2, rel=1e-9)
    # W whitens each group exactly: the record mean has variance σ² (white/B + floor²),
    # a block's departure from it the contrast variance
    for g in static_groups:
        w = ds.whiten.dense()[np.ix_(g.rows, g.rows)]
        cov = np.linalg.inv(w.T @ w)
        mean = np.full(2, 0.5)
        assert mean @ cov @ mean == pytest.approx(g.sigma**2, rel=1e-9)
        h = np.array([1.0, -1.0]) / np.sqrt(2)
        assert h @ cov @ h == pytest.approx(g.contrast_var, rel=1e-9)
        assert g.sigma > ds.floor[g.sensor]


TERM_FILE = textwrap.dedent(
    '''
    from host.model.terms import term

    @term(sensors=("gyro",), params={"c3": "{u}/°C³"}, needs="records at several temperatures")
    def temperature_cubic(sig, sensor, axis):
        """Gyro bias cubic in chip temperature: the strongly curved bias(T) of a resonator."""
        return (sig.temp_c - sig.temp_mean_c)[:, None] ** 3
    '''
)


def test_user_term_file(tmp_path: Path) -> None:
    f = tmp_path / "my_terms.py"
    f.write_text(TERM_FILE)
    cat = load_term_file(f)
    assert "temperature_cubic" in cat and "bias" in cat
    t = cat["temperature_cubic"]
    assert t.param_units("gyro") == ("°/s/°C³",) and "resonator" in t.physics
    truth = SensorTruth.random(np.random.default_rng(1)).only("linear", "noise")
    env = Environment(room_amp_c=3.0, room_period_s=200.0, rise_c=0.0)
    recs = simulate_session(truth, Plan(static_s=10.0, environment=env), 1)
    ds = build_dataset(session_from_records(recs))
    fit = fit_model(ds, parse_model("base,temperature_cubic:gyro:y", cat))
    p = fit.parameter("temperature_cubic.gyro.y")
    assert abs(p.value) < 5 * p.stderr  # nothing there: consistent with zero
    empty = tmp_path / "none.py"
    empty.write_text("x = 1\n")
    broken = tmp_path / "broken.py"
    broken.write_text("def (:\n")
    nodoc = tmp_path / "nodoc.py"
    nodoc.write_text("from host.model.terms import term\n@term()\ndef t(s, a, b):\n    return 0\n")
    for bad in (empty, broken, nodoc, tmp_path / "missing.py"):
        with pytest.raises(UserError):
            load_term_file(bad)


def test_nonlinear_term_is_linearised_and_iterated(tmp_path: Path) -> None:
    """A term written nonlinearly in its parameter (bias = c³·ΔT) converges by Gauss-Newton to
    the same temperature coefficient as the linear term."""
    f = tmp_path / "nl.py"
    f.write_text(
        textwrap.dedent(
            '''
            from host.model.terms import nonlinear_term

            @nonlinear_term(sensors=("gyro",), params={"c": "(°/s/°C)^(1/3)"}, initial=[0.5])
            def cube_temp(sig, sensor, axis, theta):
                """Temperature bias parametrised by its cube root (a nonlinear test term)."""
                return theta[0] ** 3 * sig.d_temp
            '''
        )
    )
    cat = load_term_file(f)
    truth = SensorTruth.random(np.random.default_rng(2)).only("linear", "noise")
    truth = dataclasses.replace(truth, gyro_temp_bias=(0.0, 0.0, 0.027))
    env = Environment(room_amp_c=2.5, room_period_s=240.0, rise_c=0.0)
    recs = simulate_session(truth, Plan(static_s=10.0, environment=env), 2)
    ds = build_dataset(session_from_records(recs))
    nl = fit_model(ds, parse_model("base,cube_temp:gyro:z", cat))
    lin = fit_model(ds, parse_model("base,temperature_bias:gyro:z", cat))
    c = nl.parameter("cube_temp.gyro.z").value
    assert c**3 == pytest.approx(lin.parameter("temperature_bias.gyro.z").value, rel=1e-4)
    assert c**3 == pytest.approx(0.027, rel=0.1)
    assert nl.chi2 == pytest.approx(lin.chi2, rel=1e-4)


def test_empty_session_is_a_user_error() -> None:
    from host.session.directory import Session

    with pytest.raises(UserError):
        build_dataset(Session("X", {}))


@pytest.mark.timeout(60)
def test_noise_free_records_ask_for_a_floor_instead_of_dividing_by_zero(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Constant readings (noise-free simulation, a stuck sensor) left the fit no noise to weigh
    by: ZeroDivisionError traceback. Now one line naming the record and channel, and --floor
    makes the same records fit."""
    from host.__main__ import main
    from host.bench.plan import write_session

    write_session(
        tmp_path, "I1", simulate_session(SensorTruth.ideal(), Plan(static_s=2.0, turns=1), seed=2)
    )
    assert main(["calibrate", "--from-dir", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "reads the same value in every sample" in err[0], err
    assert "--floor accel=" in err[0] and not list(tmp_path.glob("I1_result.*"))
    rc = main(["calibrate", "--from-dir", str(tmp_path), "--floor", "accel=1e-4,gyro=1e-3"])
    assert rc == 0 and (tmp_path / "I1_result.json").exists()
