"""The independent simulator against the physics it claims: it is evidence only if it is right.

Checks from first principles and from method.md's closed forms (§3, §4), never against the
project's own simulator or model.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from tests.independent import physics as ph
from tests.independent.effects import EFFECTS
from tests.independent.simulate import SessionSpec, SimRecord, SimSession, simulate


def _quiet(spec: SessionSpec) -> SessionSpec:
    """``spec`` without noise and quantisation: the true signals alone."""
    return replace(spec, accel_density=0.0, gyro_density=0.0, temp_noise_c=0.0, quantise=False)


def _by_name(s: SimSession) -> dict[str, SimRecord]:
    return {r.name: r for r in s.records}


def _rests(rate_up: np.ndarray) -> np.ndarray:
    return np.abs(rate_up) < 1e-9


@pytest.mark.parametrize("effect", ["none", "plate_tilt", "face_lean", "turn_axis_tilt"])
def test_force_is_g_at_rest(effect: str) -> None:
    s = simulate(_quiet(SessionSpec(seed=5, effect=effect, headings="random")))
    for r in s.records:
        still = _rests(np.linalg.norm(r.true_rate, axis=1))
        assert still.sum() > 20
        np.testing.assert_allclose(np.linalg.norm(r.true_force[still], axis=1), s.g, rtol=1e-12)


def test_local_g_is_helmert() -> None:
    # 55.75°, 150 m: the default site (method.md §3's formula evaluated by hand)
    assert ph.local_g() == pytest.approx(9.81521, abs=2e-5)
    assert ph.local_g(0.0, 0.0) == pytest.approx(9.78030)


def test_static_face_puts_g_on_its_axis_with_the_right_sign() -> None:
    s = simulate(_quiet(SessionSpec(seed=2)))
    for r in s.records:
        if r.meta["kind"] != "static":
            continue
        k = "xyz".index(r.name[0])
        sign = -1.0 if "_dn" in r.name else 1.0
        expect = np.zeros(3)
        expect[k] = sign * s.g
        np.testing.assert_allclose(r.true_force, np.tile(expect, (len(r.t_ms), 1)), atol=1e-9)


@pytest.mark.parametrize("turns", [1, 2])
def test_turn_integrals_are_360_n(turns: int) -> None:
    s = simulate(_quiet(SessionSpec(seed=7, turns=turns)))
    for r in s.records:
        if r.meta["kind"] != "turn":
            continue
        k = "xyz".index(r.name[0])
        t = r.t_ms / 1000.0
        integral = np.trapezoid(r.true_rate[:, k], t)
        sign = 1 if r.name.endswith("ccw") else -1
        # exact in continuous time; the 50 Hz trapezoid is off by < 0.005° (a turn's white-noise
        # integral is ≈ 0.01°)
        assert integral == pytest.approx(sign * 360.0 * turns, abs=5e-3)
        # the other axes see nothing of a turn on a perfect bench
        others = [i for i in range(3) if i != k]
        assert np.max(np.abs(r.true_rate[:, others])) < 1e-9
        # a hand: it rests before, between the quarter turns and after, never beyond ±250 °/s
        rest = _rests(r.true_rate[:, k])
        assert rest[:5].all() and rest[-5:].all()
        starts = np.flatnonzero(np.diff(rest.astype(int)) == -1)
        assert len(starts) == 4 * turns
        assert np.max(np.abs(r.gyro)) < 250.0
        # back where it started: gravity in body axes the same at the first and last sample
        np.testing.assert_allclose(r.true_force[0], r.true_force[-1], atol=1e-9)


@pytest.mark.parametrize("turns", [1, 2])
def test_a_continuous_turn_is_one_motion_of_360_n_resting_only_at_its_ends(turns: int) -> None:
    """The method's bench: each turn record turns 360°·n in one motion (its trapezoid
    integral within 0.005°, the profile's own angle exact), the rate never below 1 °/s
    between the motion's first and last 0.3 s (no rest inside it), within ±250 °/s, and the
    rate and angular acceleration the derivatives of the angle and the rate."""
    s = simulate(_quiet(SessionSpec(seed=3, turns=turns, turn_motion="continuous")))
    for r in s.records:
        if r.meta["kind"] != "turn":
            continue
        w = r.true_rate @ ph.axis_vector("+" + r.name[0])
        t = r.t_ms / 1000.0
        assert abs(abs(np.trapezoid(w, t)) - 360.0 * turns) < 0.005
        assert abs(abs(r.turn_deg) - 360.0 * turns) < 1e-9
        moving = np.flatnonzero(np.abs(w) > 1e-9)
        inner = (t > t[moving[0]] + 0.3) & (t < t[moving[-1]] - 0.3)
        assert np.all(np.abs(w[inner]) > 1.0) and np.max(np.abs(w)) < 250.0
        assert t[moving[0]] > 0.6 and t[-1] - t[moving[-1]] > 0.35  # rests at both ends
    prof = ph.continuous_turn(np.random.default_rng(7), turns, 12.0, -1)
    tt = np.linspace(0.0, 12.0, 240001)
    np.testing.assert_allclose(np.gradient(prof.angle_deg(tt), tt), prof.rate_dps(tt), atol=1e-3)
    np.testing.assert_allclose(np.gradient(prof.rate_dps(tt), tt), prof.accel_dps2(tt), atol=0.05)


def test_noise_std_matches_the_stated_density() -> None:
    spec = SessionSpec(seed=11, static_s=200.0, accel_density=0.003, gyro_density=0.006)
    r = _by_name(simulate(spec))["z_up"]
    a_sd = np.std(r.accel, axis=0, ddof=1)
    g_sd = np.std(r.gyro, axis=0, ddof=1)
    # white noise at 50 Hz: density·√25, plus the quantisation's LSB²/12
    a_exp = math.hypot(0.003 * 5.0, ph.ACCEL_LSB / math.sqrt(12))
    g_exp = math.hypot(0.006 * 5.0, ph.GYRO_LSB / math.sqrt(12))
    np.testing.assert_allclose(a_sd, a_exp, rtol=0.04)  # 10 000 samples: std's error ≈ 0.7 %
    np.testing.assert_allclose(g_sd, g_exp, rtol=0.04)
    # white: neighbouring samples uncorrelated
    x = r.gyro[:, 0] - r.gyro[:, 0].mean()
    assert abs(np.dot(x[1:], x[:-1]) / np.dot(x, x)) < 0.05


def test_quantised_to_the_mpu6000_lsb() -> None:
    s = simulate(SessionSpec(seed=3))
    for r in s.records[:3] + s.records[6:8]:
        for values, lsb in ((r.accel, ph.ACCEL_LSB), (r.gyro, ph.GYRO_LSB)):
            counts = values / lsb
            np.testing.assert_allclose(counts, np.round(counts), atol=1e-9)
        assert ph.ACCEL_LSB == pytest.approx(0.0005987, abs=1e-7)  # method.md §1
        assert ph.GYRO_LSB == pytest.approx(0.00763, abs=1e-5)
        t_counts = (r.temp_c - ph.TEMP_OFFSET_C) / ph.TEMP_LSB
        np.testing.assert_allclose(t_counts, np.round(t_counts), atol=1e-6)
    # the smallest step of a slowly varying quantised signal is one LSB
    steps = np.abs(np.diff(ph.quantise(np.linspace(0, 0.01, 1000), ph.ACCEL_LSB)))
    assert steps[steps > 0].min() == pytest.approx(ph.ACCEL_LSB)


def test_sample_rate_and_times() -> None:
    s = simulate(SessionSpec(seed=4))
    for r in s.records:
        dt = np.diff(r.t_ms)
        np.testing.assert_allclose(dt, 1000.0 / ph.FS_HZ)
        assert 0.0 <= r.t_ms[0] < 20.0
    starts = [float(r.meta["power_on_s"]) for r in s.records]
    assert starts == sorted(starts) and starts[0] == 600.0
    assert [r.name for r in s.records][-1] == "x_up_2"


def test_closed_forms_of_method_md_give_the_truth() -> None:
    """§3 and §4 on noiseless records return every base constant: the truth follows §2."""
    s = simulate(_quiet(SessionSpec(seed=8, turns=1)))
    rec = _by_name(s)
    g, n = s.g, 1
    m = {k: np.mean(rec[k].accel, axis=0) for k in rec if rec[k].meta["kind"] == "static"}
    w = {k: np.mean(rec[k].gyro, axis=0) for k in m}
    got = {
        "Axx": (m["x_up"][0] - m["x_dn"][0]) / (2 * g) - 1,
        "Azz": (m["z_up"][2] - m["z_dn"][2]) / (2 * g) - 1,
        "Axz": (m["y_up"][0] - m["y_dn"][0]) / (2 * g),
        "Axy": -(m["z_up"][0] - m["z_dn"][0]) / (2 * g),
        "Ayz": -(m["x_up"][1] - m["x_dn"][1]) / (2 * g),
        "Ayx": (m["z_up"][1] - m["z_dn"][1]) / (2 * g),
        "Azy": (m["x_up"][2] - m["x_dn"][2]) / (2 * g),
        "Azx": -(m["y_up"][2] - m["y_dn"][2]) / (2 * g),
        "A0y": (m["x_up"][1] + m["x_dn"][1]) / 2,
        "GAxy": (w["y_up"][0] - w["y_dn"][0]) / 2,
        "GAzx": (w["x_up"][2] - w["x_dn"][2]) / 2,
        "G0z": (w["z_up"][2] + w["z_dn"][2]) / 2,
    }

    def integral(name: str, c: int) -> float:
        r = rec[name]
        return float(np.trapezoid(r.gyro[:, c], r.t_ms / 1000.0))

    # bias·T (and g-sensitivity·T) cancels between the pair only to the extent the attitude
    # is the same; both turns of a pair rest on the same face, so it cancels exactly
    got["Gyy"] = (integral("y_ccw", 1) - integral("y_cw", 1)) / (720 * n) - 1
    got["Gxz"] = (integral("y_ccw", 0) - integral("y_cw", 0)) / (720 * n)
    got["Gxy"] = -(integral("z_ccw", 0) - integral("z_cw", 0)) / (720 * n)
    got["Gzy"] = (integral("x_ccw", 2) - integral("x_cw", 2)) / (720 * n)
    got["Gzx"] = -(integral("y_ccw", 2) - integral("y_cw", 2)) / (720 * n)
    truth = s.base.constants()
    for k, v in got.items():
        assert v == pytest.approx(truth[k], abs=2e-6 if k.startswith("G") else 1e-9), k


def test_every_axis_differs() -> None:
    s = simulate(SessionSpec(seed=9))
    c = s.base.constants()
    for group in (["A0x", "A0y", "A0z"], ["Gxx", "Gyy", "Gzz"], ["G0x", "G0y", "G0z"]):
        vals = [c[k] for k in group]
        assert len({round(v, 9) for v in vals}) == 3 and all(v != 0 for v in vals)


def test_plate_tilt_rests_draw_a_circle_of_g_sin_tilt() -> None:
    s = simulate(_quiet(SessionSpec(seed=12, effect="plate_tilt")))
    tilt = s.effect.params["tilt_rad"]
    r = _by_name(s)["z_ccw"]
    rest = _rests(r.true_rate[:, 2])
    horiz = r.true_force[rest][:, :2]
    np.testing.assert_allclose(np.linalg.norm(horiz, axis=1), s.g * math.sin(tilt), rtol=1e-9)
    angles = np.unique(np.round(np.degrees(np.arctan2(horiz[:, 1], horiz[:, 0])) % 360, 6))
    # quarter turns: the rests sit at four points of the circle, 90° apart
    assert len(angles) == 4
    np.testing.assert_allclose(np.diff(angles), 90.0, atol=1e-6)
    # at heading 0 the static z_up sees gravity's up in the plate frame: (east, north) = (x, y)
    zs = _by_name(s)["z_up"].true_force[0]
    assert zs[0] / s.g == pytest.approx(s.effect.params["up_east_rad"], rel=1e-4)
    assert zs[1] / s.g == pytest.approx(s.effect.params["up_north_rad"], rel=1e-4)


def test_turn_axis_tilt_shows_in_gyro_and_accelerometer() -> None:
    s = simulate(_quiet(SessionSpec(seed=13, effect="turn_axis_tilt")))
    k = "xyz".index(s.effect.params["axis"])
    lean = np.array(s.effect.params["lean_rad"])
    r = _by_name(s)[f"{'xyz'[k]}_ccw"]
    axis_b = r.true_rate[np.argmax(np.abs(r.true_rate[:, k]))]
    axis_b = axis_b / np.linalg.norm(axis_b)
    expect = np.eye(3)[k] + lean
    np.testing.assert_allclose(axis_b, expect / np.linalg.norm(expect), atol=1e-12)
    np.testing.assert_allclose(r.true_force[0] / s.g, axis_b, atol=1e-12)
    # the statics of that face are not leaned
    st = _by_name(s)[f"{'xyz'[k]}_up"].true_force[0]
    np.testing.assert_allclose(st, np.eye(3)[k] * s.g, atol=1e-9)


def test_lever_arm_centripetal_and_tangential() -> None:
    s = simulate(_quiet(SessionSpec(seed=14, effect="lever_arm")))
    rvec = np.array(s.effect.params["r_m"])
    r = _by_name(s)["z_ccw"]
    rate = np.radians(r.true_rate[:, 2])
    t = r.t_ms / 1000.0
    # turning about z with the pivot at the cube's centre: ω̇·(−r_y, r_x) − ω²·(r_x, r_y) on top
    # of gravity (ω̇ by central differences: good to O(dt²))
    base = simulate(_quiet(SessionSpec(seed=14)))
    extra = r.true_force - _by_name(base)["z_ccw"].true_force
    w_dot = np.gradient(rate, t)
    want = w_dot[:, None] * np.array([-rvec[1], rvec[0]]) - rate[:, None] ** 2 * rvec[:2]
    peak = float(np.max(np.abs(want)))
    assert peak > 0.1  # ≥ 0.1 m/s²: a clear effect at these rates and offsets
    inside = np.abs(rate) > 0.3 * np.max(np.abs(rate))  # away from the kinks of ω̇ at the rests
    np.testing.assert_allclose(extra[inside, :2], want[inside], atol=0.01 * peak)
    np.testing.assert_allclose(extra[np.abs(rate) == 0.0], 0.0, atol=1e-12)
    assert np.max(np.abs(extra[:, 2])) < 1e-12


@pytest.mark.parametrize("name", sorted(set(EFFECTS) - {"none"}))
@pytest.mark.slow
def test_each_effect_is_the_only_difference(name: str) -> None:
    """Same seed: same unit, plan and noise; the effect session differs from the control by the
    effect alone (a sensor effect by its formula on the true inputs)."""
    spec = _quiet(SessionSpec(seed=21))
    ctrl = simulate(spec)
    eff = simulate(replace(spec, effect=name))
    assert eff.base.constants() == ctrl.base.constants()
    assert [r.t_ms[0] for r in eff.records] == [r.t_ms[0] for r in ctrl.records]
    diff = max(
        float(np.max(np.abs(np.c_[e.accel - c.accel, e.gyro - c.gyro])))
        for e, c in zip(eff.records, ctrl.records, strict=True)
    )
    assert diff > 1e-3  # the effect shows
    p = eff.effect.params
    if name in ("cross_g2", "abs_leak", "gyro_g2"):
        i, j = "xyz".index(p["axis"]), "xyz".index(p["source"])
        sensor = p["sensor"]
        for e, c in zip(eff.records, ctrl.records, strict=True):
            u = c.true_force[:, j] / eff.g
            want = p["c"] * (np.abs(u) if name == "abs_leak" else u**2)
            got = (e.accel - c.accel if sensor == "accel" else e.gyro - c.gyro)[:, i]
            np.testing.assert_allclose(got, want, atol=1e-12)
    if name.startswith(("bias_step", "bias_drift", "temperature_bias", "dtdt_bias")):
        i = "xyz".index(p["axis"])
        for e, c in zip(eff.records, ctrl.records, strict=True):
            got = (e.accel - c.accel if p["sensor"] == "accel" else e.gyro - c.gyro)[:, i]
            pow_s = float(c.meta["power_on_s"]) + c.t_ms / 1000.0
            if name.startswith("bias_step"):
                want = np.where(pow_s - spec.warmup_s >= p["at_session_s"], p["step"], 0.0)
            elif name.startswith("bias_drift"):
                want = p["per_h"] * pow_s / 3600.0
            elif name.startswith("temperature_bias"):  # gyro, and the accelerometer's
                want = p["per_C"] * (c.temp_c - 25.0)
            else:
                _, rate = ph.chip_temperature(pow_s, ctrl.temp)
                want = p["per_C_per_s"] * rate
            np.testing.assert_allclose(got, want, atol=1e-6)


def test_chip_temperature_rate_is_its_derivative() -> None:
    t = np.linspace(0.0, 2000.0, 20001)
    temp, rate = ph.chip_temperature(t, ph.TempModel(phase=1.0))
    np.testing.assert_allclose(np.gradient(temp, t)[1:-1], rate[1:-1], atol=1e-6)
    assert temp[0] == pytest.approx(22.0 + 0.4 * math.sin(1.0))
    assert 30.0 < temp[-1] < 31.5  # warmed by 9 °C with τ = 500 s
