"""Allan deviation, noise figures and the recording planner (host.model.recording, .allan and
the ``noise`` command).

The recordings are simulated with a known white noise, bias instability and rate random walk
(host.bench.noise), a different value on every channel, quantised to the MPU-6000's LSB.
"""

from __future__ import annotations

import json
import math

import allantools
import numpy as np
import pytest

from host.__main__ import main
from host.bench.noise import NoiseTruth, capture_bytes, static_noise
from host.bench.physics import Environment
from host.errors import UserError
from host.model import allan, recording
from host.session.directory import write_record
from host.session.records import Record
from host.wire import sensor

TRUTH = NoiseTruth.mpu6000()
RATE = 50.0


def true_figures(truth: NoiseTruth, j: int, rate_hz: float = RATE) -> tuple[float, ...]:
    """(N, B, K) of channel j; N includes the white quantisation noise LSB²/12 the sensor adds."""
    lsb = sensor.G0 / sensor.ACCEL_LSB_PER_G[0] if j < 3 else 1.0 / sensor.GYRO_LSB_PER_DPS[0]
    n_eff = math.sqrt(truth.white[j] ** 2 + lsb**2 / 12.0 / rate_hz)
    return n_eff, truth.flicker[j], truth.random_walk[j]


@pytest.fixture(scope="module")
def long_run() -> recording.NoiseAnalysis:
    t, x, temp = static_noise(TRUTH, 4 * 3600.0, np.random.default_rng(3))
    return recording.analyse(t, x, temp)


@pytest.mark.timeout(300)  # 4 h of 50 Hz samples, six Allan deviations
@pytest.mark.slow
def test_figures_come_back_within_their_intervals(long_run: recording.NoiseAnalysis) -> None:
    for j, name in enumerate(allan.CHANNELS):
        for q, truth in zip(allan.QUANTITIES, true_figures(TRUTH, j), strict=True):
            f = long_run.channels[name].figures[q]
            assert f.value is not None, (name, q, f.warning)
            assert f.ci[0] <= truth <= f.ci[1], (name, q, truth, f.value, f.ci)
            assert f.ci[0] <= f.value <= f.ci[1]
            # an interval that says something (rate random walk rests on few long averages)
            assert f.ci[1] / f.ci[0] < (10.0 if q == "rate_random_walk" else 2.0), (name, q, f.ci)
    assert not long_run.warnings


def test_a_short_recording_warns_for_what_it_cannot_resolve() -> None:
    t, x, temp = static_noise(TRUTH, 600.0, np.random.default_rng(8))
    an = recording.analyse(t, x, temp)
    gx = an.channels["gx"].figures
    rrw = gx["rate_random_walk"]
    assert rrw.value is None and "record longer" in (rrw.warning or "")
    # the bound is an honest upper bound of the true value
    assert rrw.ci[0] == 0.0 and rrw.ci[1] >= TRUTH.random_walk[3]
    assert any(w.startswith("gx: rate random walk not reached") for w in an.warnings)
    assert gx["white_noise_density"].value is not None


@pytest.mark.timeout(300)  # plans from one simulation and checks on a second, longer one
def test_planned_length_gives_the_requested_precision() -> None:
    t, x, temp = static_noise(TRUTH, 1800.0, np.random.default_rng(21))
    first = recording.analyse(t, x, temp, channels=allan.CHANNELS)
    precision = 0.25
    j = allan.CHANNELS.index("gz")
    ch = first.channels["gz"]
    seconds = allan.plan_duration(ch.coef, 1, precision, first.rate_hz)
    assert seconds is not None and 600.0 < seconds < 6 * 3600.0
    # a fresh recording of the advised length, gz only
    t2, x2, temp2 = static_noise(TRUTH, seconds, np.random.default_rng(22))
    second = recording.analyse(t2, x2[:, [j]], temp2, channels=("gz",))
    f = second.channels["gz"].figures["bias_instability"]
    assert f.value is not None
    achieved = allan.relative_precision((f.ci[0] / f.value, f.ci[1] / f.value))
    assert achieved <= precision * 1.15, (achieved, seconds)
    assert f.ci[0] <= TRUTH.flicker[j] <= f.ci[1]
    # and half the advised length does not reach it
    t3, x3, temp3 = static_noise(TRUTH, seconds / 3.0, np.random.default_rng(23))
    third = recording.analyse(t3, x3[:, [j]], temp3, channels=("gz",))
    g = third.channels["gz"].figures["bias_instability"]
    assert g.value is None or allan.relative_precision((g.ci[0] / g.value, g.ci[1] / g.value)) > (
        precision
    )


@pytest.mark.timeout(200)  # two analyses of a one-hour warm-up
@pytest.mark.slow
def test_temperature_drift_is_reported_not_read_as_rate_random_walk() -> None:
    warm = NoiseTruth(
        white=TRUTH.white,
        flicker=TRUTH.flicker,
        random_walk=(0.0,) * 6,
        temp_coef=(0.0, 0.004, 0.0, 0.03, 0.0, -0.02),  # m/s²/°C, °/s/°C
    )
    env = Environment(room_c=22.0, rise_c=12.0, tau_s=900.0, room_amp_c=0.0)
    t, x, temp = static_noise(warm, 3600.0, np.random.default_rng(5), environment=env)
    an = recording.analyse(t, x, temp)
    assert an.span_c > 5.0
    flagged = {c for c, d in an.thermal.items() if d.significant}
    assert flagged == {"ay", "gx", "gz"}
    assert an.thermal["gx"].coefficient == pytest.approx(0.03, rel=0.05)
    assert an.thermal["gz"].coefficient == pytest.approx(-0.02, rel=0.05)
    assert any("temperature drift" in w for w in an.warnings)
    kept = recording.analyse(t, x, temp, remove_thermal=False)
    for c in ("gx", "gz"):
        k_kept = kept.channels[c].figures["rate_random_walk"]
        k = an.channels[c].figures["rate_random_walk"]
        # kept in, the warm-up reads as a large rate random walk; removed, it is gone
        assert k_kept.value is not None
        assert k.value is None or k.value < k_kept.value / 5.0, (c, k, k_kept)


@pytest.mark.timeout(200)  # one-hour capture through the command
@pytest.mark.slow
def test_command_json_keys_units_and_noise_file(tmp_path, capsys) -> None:
    t, x, temp = static_noise(TRUTH, 3600.0, np.random.default_rng(11))
    cap = tmp_path / "static.cap"
    cap.write_bytes(capture_bytes(t, x, temp))
    saved = tmp_path / "S1_noise.json"
    assert main(["noise", str(cap), "--json", "--save", str(saved)]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert set(doc["channels"]) == set(allan.CHANNELS)
    units = {
        "gx": ("deg/s/sqrt(Hz)", "deg/s", "deg/s^2/sqrt(Hz)"),
        "ax": ("m/s^2/sqrt(Hz)", "m/s^2", "m/s^3/sqrt(Hz)"),
    }
    for c in allan.CHANNELS:
        expected = units["gx" if c.startswith("g") else "ax"]
        for q, unit in zip(allan.QUANTITIES, expected, strict=True):
            fig = doc["channels"][c][q]
            assert fig["unit"] == unit
            assert len(fig["ci"]) == 2 and fig["ci"][0] <= fig["ci"][1]
    # white noise is resolved in an hour on every channel and matches the truth
    for j, c in enumerate(allan.CHANNELS):
        fig = doc["channels"][c]["white_noise_density"]
        assert fig["ci"][0] <= true_figures(TRUTH, j)[0] <= fig["ci"][1]
    # the noise file gives the workbench its floor: the Allan deviation at the record length
    floor = recording.record_mean_floor(recording.load_noise_file(saved), 60.0)
    for j, c in enumerate(allan.CHANNELS):
        direct = allantools.oadev(x[:, j], rate=RATE, data_type="freq", taus=[60.0])[1][0]
        assert floor[c] == pytest.approx(direct, rel=0.35), c


@pytest.mark.slow
def test_record_file_plot_and_plan(tmp_path, capsys) -> None:
    t, x, temp = static_noise(TRUTH, 900.0, np.random.default_rng(12))
    path = tmp_path / "S2_z_up.txt"
    write_record(path, Record("z_up", t * 1000.0, x[:, :3], x[:, 3:], temp))
    png = tmp_path / "allan.png"
    pytest.importorskip("matplotlib")
    assert main(["noise", str(path), "--plot", str(png), "--plan", "30%"]) == 0
    out = capsys.readouterr().out
    assert "record z_up" in out and "plan: to get each figure to +-30 %" in out
    assert "°/√h" in out and "µg/√Hz" in out and "deg" not in out
    assert png.stat().st_size > 10_000


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (["noise", "/nonexistent/x.cap"], "no such file"),
        (["noise", "FILE", "--plan", "abc"], "--plan"),
        (["noise", "FILE", "--ci", "2"], "--ci"),
    ],
)
def test_bad_input_is_one_line_exit_2(tmp_path, capsys, args, needle) -> None:
    short = tmp_path / "S3_x_up.txt"
    t, x, temp = static_noise(TRUTH, 1.0, np.random.default_rng(1))
    write_record(short, Record("x_up", t * 1000.0, x[:, :3], x[:, 3:], temp))
    argv = [str(short) if a == "FILE" else a for a in args]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and needle in err[0]


def test_too_short_a_recording_is_refused(tmp_path, capsys) -> None:
    short = tmp_path / "S3_x_up.txt"
    t, x, temp = static_noise(TRUTH, 1.0, np.random.default_rng(1))
    write_record(short, Record("x_up", t * 1000.0, x[:, :3], x[:, 3:], temp))
    assert main(["noise", str(short)]) == 2
    err = capsys.readouterr().err.strip()
    assert "50 samples" in err and "record longer" in err


def test_noise_file_with_a_newer_version_is_refused(tmp_path) -> None:
    p = tmp_path / "n.json"
    p.write_text(json.dumps({"format": "imu-bench noise", "format_version": 99, "channels": {}}))
    with pytest.raises(UserError, match="update the host software"):
        recording.load_noise_file(p)


@pytest.mark.parametrize(
    ("doc", "words"),
    [
        ([1, 2, 3], "not an imu-bench noise file"),  # a JSON list: no keys at all
        ("imu-bench noise", "not an imu-bench noise file"),
        ({"format": "imu-bench noise", "format_version": True, "channels": {}}, "vTrue"),
    ],
)
def test_a_noise_file_of_another_shape_is_named_not_read(tmp_path, doc, words) -> None:
    """A JSON document that is no noise object says so in words (it said "'list' object has
    no attribute 'get'"), and a boolean version is no version (JSON true read as v1)."""
    p = tmp_path / "n.json"
    p.write_text(json.dumps(doc))
    with pytest.raises(UserError, match=words) as err:
        recording.load_noise_file(p)
    assert "object has no attribute" not in str(err.value)


def test_allan_deviation_equals_the_library_on_every_tau() -> None:
    """The overlapping Allan deviation from cumulative sums is the library's, at every τ of the
    grid, on data with a large mean and a random walk (the sum's round-off would show)."""
    from host.model import allan

    rng = np.random.default_rng(9)
    x = 40.0 + np.cumsum(rng.normal(size=50_000)) * 1e-3 + rng.normal(size=50_000)
    curve = allan.allan_curve(x, 200.0)
    m = allan.tau_grid(x.size)
    taus, ref, _, _ = allantools.oadev(x, rate=200.0, data_type="freq", taus=m / 200.0)
    np.testing.assert_allclose(curve.tau_s, taus, rtol=1e-15)
    np.testing.assert_allclose(curve.adev, ref, rtol=1e-12)


def test_greenhall_edf_and_local_slopes_equal_the_library_and_polyfit() -> None:
    """Greenhall's degrees of freedom (the sum split once per (alpha, m), the full and the
    shortened sums, the table's closed form) and the slopes of every point at once give what
    allantools and np.polyfit give, on every branch of Greenhall."""
    from host.model import allan

    for alpha in (0, -1, -2):
        for m in (1, 2, 7, 33, 34, 80, 400, 1000):
            for n in (60, 101, 250, 1_000, 2_500, 4_000, 123_457):
                if 2 * m + 1 > n:
                    continue
                ref = float(allantools.edf_greenhall(alpha, 2, m, n + 1, overlapping=True))
                assert allan.edf(alpha, m, n) == pytest.approx(ref, rel=1e-12), (alpha, m, n)
    rng = np.random.default_rng(4)
    tau = np.unique(np.rint(np.logspace(0, 4, 40))) / 50.0
    dev = np.exp(rng.normal(size=tau.size)) * tau**-0.5
    got = allan.local_slopes(tau, dev)
    lt = np.log10(tau)
    for i in range(tau.size):
        sel = np.abs(lt - lt[i]) <= 0.3
        if np.count_nonzero(sel) < 3:
            assert np.isnan(got[i])
        else:
            want = np.polyfit(lt[sel], np.log10(dev[sel]), 1)[0]
            assert got[i] == pytest.approx(want, abs=1e-12)


def test_a_gap_is_not_counted_as_recording_time() -> None:
    """20 min of samples with a 10-minute gap in the middle: 20 min, and the gap is said."""
    from host.model.recording import analyse

    rate = 10.0
    t = np.arange(int(20 * 60 * rate)) / rate
    t[t.size // 2 :] += 600.0
    data = np.random.default_rng(3).standard_normal((t.size, 6))
    an = analyse(t, data)
    assert an.duration_s == pytest.approx(1200.0, rel=1e-6)
    assert any("gaps in the sample times" in w for w in an.warnings)
