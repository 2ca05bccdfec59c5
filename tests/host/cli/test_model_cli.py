"""``python3 -m host model diagnose|add|ladder`` and ``demo hidden-effect`` (host/cli/model.py)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from host.__main__ import main
from host.bench.plan import write_session
from host.workbench.scenarios import hidden_effect_case


@pytest.fixture(scope="module")
def temp_dir(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, str]:
    d = tmp_path_factory.mktemp("hidden")
    case = hidden_effect_case("temperature", 2)
    write_session(d, "U7", dict(case.records))
    return d, case.term


@pytest.mark.slow
def test_diagnose_text_and_json(
    temp_dir: tuple[Path, str], capsys: pytest.CaptureFixture[str]
) -> None:
    d, term = temp_dir
    assert main(["model", "diagnose", str(d)]) == 0
    out = capsys.readouterr().out
    assert "== 1. compare" in out and "== verdict: missing_effect" in out
    assert f"{term}: SIGNIFICANT" in out and " σ" in out
    assert main(["model", "diagnose", str(d), "--json"]) == 0
    obj = json.loads(capsys.readouterr().out)
    assert obj["verdict"] == "missing_effect"
    assert obj["candidates"][0]["label"] == term
    assert obj["recommended"] == term
    assert obj["fit"]["rms_z"] > 1.2


@pytest.mark.slow
def test_add_shows_the_error_falling(
    temp_dir: tuple[Path, str], capsys: pytest.CaptureFixture[str]
) -> None:
    d, term = temp_dir
    assert main(["model", "add", str(d), term, "--model", "base"]) == 0
    out = capsys.readouterr().out
    assert "RMS z" in out and "→" in out and "× smaller" in out and "new coefficients" in out
    assert main(["model", "add", str(d), term, "--json"]) == 0
    obj = json.loads(capsys.readouterr().out)
    assert obj["after"]["rms_z"] < obj["before"]["rms_z"] / 2


@pytest.mark.slow
def test_ladder(temp_dir: tuple[Path, str], capsys: pytest.CaptureFixture[str]) -> None:
    d, term = temp_dir
    assert main(["model", "ladder", str(d)]) == 0
    out = capsys.readouterr().out
    assert "start: bias" in out and "temperature_bias:gyro" in out and "final model" in out


def test_ladder_model_is_the_start_or_refused(
    temp_dir: tuple[Path, str], capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """``ladder --model M`` climbs from M (it was accepted and ignored: the ladder started from
    bias); given beside a different ``--start`` it is refused in one line."""
    import host.cli.model as cli_model
    import host.workbench.ladder as ladder_module

    d, _ = temp_dir
    starts: list[str] = []

    def climb(ds: object, start: str, *a: object, **k: object) -> list:
        starts.append(start)  # the start it was given; it climbs nowhere
        return [ladder_module.LadderStep("", start, 0, 0.0, 1, 1.0, 0.0, float("nan"))]

    monkeypatch.setattr(cli_model, "ladder", climb)
    assert main(["model", "ladder", str(d), "--model", "base,time_drift:gyro"]) == 0
    assert "final model: base, time_drift:gyro" in capsys.readouterr().out
    assert main(["model", "ladder", str(d)]) == 0
    assert starts == ["base,time_drift:gyro", "bias"]
    capsys.readouterr()
    assert main(["model", "ladder", str(d), "--model", "base", "--start", "bias"]) == 2
    err = capsys.readouterr().err
    assert "--model base and --start bias" in err and "Traceback" not in err
    assert len(err.strip().splitlines()) == 1


@pytest.mark.slow
def test_term_file_and_plot(temp_dir: tuple[Path, str], tmp_path: Path,
                            capsys: pytest.CaptureFixture[str]) -> None:  # fmt: skip
    pytest.importorskip("matplotlib")
    d, _ = temp_dir
    f = tmp_path / "my_terms.py"
    f.write_text(
        "from host.model.terms import term\n\n"
        "@term(sensors=('gyro',), params={'c3': '{u}/°C³'}, needs='several temperatures')\n"
        "def temperature_cubic(sig, sensor, axis):\n"
        "    '''Gyro bias cubic in chip temperature.'''\n"
        "    return (sig.temp_c - sig.temp_mean_c)[:, None] ** 3\n"
    )
    out_dir = tmp_path / "plots"
    argv = ["model", "diagnose", str(d), "--term-file", str(f), "--plot", str(out_dir), "--brief"]
    assert main(argv) == 0
    out = capsys.readouterr().out
    assert "temperature_cubic:gyro" in out
    pngs = sorted(p.name for p in out_dir.glob("*.png"))
    assert pngs == ["compare_after.png", "compare_before.png", "suspect.png"]
    assert main(["model", "add", str(d), "temperature_cubic:gyro:x", "--term-file", str(f)]) == 0


@pytest.mark.parametrize(
    "argv",
    [
        ["model", "diagnose", "{empty}"],
        ["model", "diagnose", "{dir}", "--model", "base,warp_drive"],
        ["model", "diagnose", "{dir}", "--model", "bias:gyro:q"],
        ["model", "diagnose", "{dir}", "--floor", "gyro=abc"],
        ["model", "add", "{dir}", "bias"],
        ["model", "add", "{dir}", "nope:gyro"],
        ["model", "diagnose", "{dir}", "--term-file", "{empty}/none.py"],
        ["demo", "hidden-effect", "--effect", "gravity_waves"],
    ],
)
def test_bad_input_is_one_line(argv: list[str], temp_dir: tuple[Path, str], tmp_path: Path,
                               capsys: pytest.CaptureFixture[str]) -> None:  # fmt: skip
    d, _ = temp_dir
    argv = [a.format(dir=d, empty=tmp_path) for a in argv]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and err.count("\n") == 1 and "Traceback" not in err


@pytest.mark.slow
def test_demo_hidden_effect(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["demo", "hidden-effect", "--effect", "asymmetry", "--seed", "3",
                 "--out", str(tmp_path)]) == 0  # fmt: skip
    out = capsys.readouterr().out
    assert "FOUND" in out and "CONFOUNDED" in out
    assert len(list((tmp_path / "asymmetry").glob("DEMO_*.txt"))) == 12
    assert main(["model", "diagnose", str(tmp_path / "asymmetry"), "--brief"]) == 0
    assert "scale_asymmetry:accel" in capsys.readouterr().out
    assert main(["demo", "hidden-effect", "--effect", "none", "--seed", "3"]) == 0
    assert "verdict adequate" in capsys.readouterr().out


@pytest.mark.slow
def test_plots_follow_measurement_order_with_one_scale(
    temp_dir: tuple[Path, str], tmp_path: Path
) -> None:
    """Files come back alphabetically; the plots put the records in the order they were
    measured (time since power-on), and before/after share one z scale."""
    from host.cli.figures import measurement_order, write_plots, z_limit
    from host.model.dataset import load_dataset
    from host.model.spec import parse_model
    from host.session.records import STATIC_NAMES
    from host.workbench.ladder import add_term

    d, term = temp_dir
    ds = load_dataset(d)
    assert [s.name for s in ds.signals] != measurement_order(ds)  # alphabetical on disk
    order = measurement_order(ds)
    assert order[:6] == list(STATIC_NAMES)
    assert order[6:] == ["x_ccw", "x_cw", "y_ccw", "y_cw", "z_ccw", "z_cw"]
    a = add_term(ds, parse_model("base"), term)
    lim = z_limit([a.before, a.after])
    assert lim >= max(abs(g.z) for g in a.before.groups) and lim >= 4.0
    pytest.importorskip("matplotlib")
    paths = write_plots(tmp_path / "p", ds, a.before, a.after, term)
    assert [p.name for p in paths] == ["compare_before.png", "compare_after.png", "suspect.png"]
    assert all(p.stat().st_size > 10_000 for p in paths)


def _noise_doc(b_accel: float, b_gyro: float) -> dict:
    """A noise file (format of ``noise --save``) with white noise, the given bias instability
    B per sensor and no rate random walk; a different B on each axis of a sensor."""
    chans = {}
    for c in ("ax", "ay", "az", "gx", "gy", "gz"):
        b = (b_accel if c[0] == "a" else b_gyro) * {"x": 0.5, "y": 1.0, "z": 0.75}[c[1]]
        chans[c] = {
            "white_noise_density": {"value": 0.01, "ci": [0.009, 0.011], "unit": "u"},
            "bias_instability": {"value": b, "ci": [0.9 * b, 1.1 * b], "unit": "u"},
            "rate_random_walk": {"value": 0.0, "ci": [0.0, 0.0], "unit": "u"},
        }
    return {"format": "imu-bench noise", "format_version": 1, "channels": chans}


@pytest.mark.slow
def test_noise_file_gives_the_floor(
    temp_dir: tuple[Path, str], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """--noise NOISE.json: the floor of a record mean is the Allan variance's slow part (the
    bias instability, σ² = B²·2·ln2/π; the white part each record measures itself), the
    largest axis of each sensor; --floor still overrides a sensor."""
    import math

    d, _ = temp_dir
    f = tmp_path / "U7_noise.json"
    f.write_text(json.dumps(_noise_doc(4e-4, 6e-3)))
    assert main(["model", "diagnose", str(d), "--noise", str(f), "--json"]) == 0
    notes = " ".join(json.loads(capsys.readouterr().out)["notes"])
    k = math.sqrt(2 * math.log(2) / math.pi)
    assert f"accel {4e-4 * k:.2g} m/s² (given)" in notes, notes
    assert f"gyro {6e-3 * k:.2g} °/s (given)" in notes
    argv = ["model", "diagnose", str(d), "--noise", str(f), "--floor", "gyro=0.02", "--json"]
    assert main(argv) == 0
    notes = " ".join(json.loads(capsys.readouterr().out)["notes"])
    assert "gyro 0.02 °/s (given)" in notes and f"accel {4e-4 * k:.2g} m/s²" in notes
    # a file that is not a noise file: one line, exit 2
    bad = tmp_path / "bad.json"
    bad.write_text("{}")
    assert main(["model", "diagnose", str(d), "--noise", str(bad)]) == 2
    assert "not a readable noise file" in capsys.readouterr().err


class _Terminal:
    """stderr as a terminal that notes when each piece was written."""

    def __init__(self) -> None:
        import time

        self.clock = time.monotonic
        self.writes: list[tuple[float, str]] = []

    def isatty(self) -> bool:
        return True

    def write(self, s: str) -> int:
        self.writes.append((self.clock(), s))
        return len(s)

    def flush(self) -> None:
        pass

    def fileno(self) -> int:
        raise OSError("not a real terminal")


@pytest.mark.slow
def test_a_slow_ladder_shows_progress_at_least_every_two_seconds(
    temp_dir: tuple[Path, str], monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture
) -> None:
    """Each fit slowed to 0.25 s (a rung of ~20 candidates then takes 5 s, as on a large
    session): the screen never stands still for 2 s, and the rows come as they are found."""
    import sys
    import time

    import host.workbench.ladder as ladder_module

    real_fit = ladder_module.fit_model

    def slow_fit(*a: object, **kw: object) -> object:
        time.sleep(0.25)
        return real_fit(*a, **kw)  # type: ignore[arg-type]

    monkeypatch.setattr(ladder_module, "fit_model", slow_fit)
    term = _Terminal()
    monkeypatch.setattr(sys, "stderr", term)
    d, _ = temp_dir
    start = time.monotonic()
    assert main(["model", "ladder", str(d), "--start", "base"]) == 0
    end = time.monotonic()
    # from the first line (after Python's start and the imports) to the end
    assert term.writes and "reading the records" in term.writes[0][1]
    stamps = [t for t, s in term.writes if s.strip()] + [end]
    gaps = [b - a for a, b in zip(stamps, stamps[1:], strict=False)]
    assert end - start > 4.0  # slow enough to need progress
    assert max(gaps) < 2.0, max(gaps)
    assert any("trying term" in s for _, s in term.writes)
    assert "final model:" in capsys.readouterr().out


@pytest.mark.slow
def test_the_demo_and_the_command_it_prints_give_one_figure(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The demo's before → after and that of the `model add` command it prints for its records
    are the same numbers (the command carries the noise floor the demo used)."""
    import re
    import shlex

    assert main(["demo", "hidden-effect", "--effect", "temperature", "--seed", "4",
                 "--out", str(tmp_path)]) == 0  # fmt: skip
    out = capsys.readouterr().out
    # the additions' before → after lines (a candidate's line has its own RMS z before → after)
    addition = re.compile(r"^  RMS z +([\d.]+) → ([\d.]+)", re.M)
    demo_rms = addition.findall(out)
    assert demo_rms, out
    try_cmd = out.split("try: ", 1)[1].split("\n-- adding", 1)[0]
    argv = shlex.split(try_cmd.replace("\\\n", ""))
    assert argv[:4] == ["python3", "-m", "host", "model"] and "--floor" in argv
    assert main(argv[3:]) == 0
    add_rms = addition.findall(capsys.readouterr().out)
    assert add_rms[0] == demo_rms[0]


@pytest.mark.slow
@pytest.mark.parametrize("command", ["diagnose", "add"])
def test_a_slow_diagnosis_or_addition_shows_it_is_working(
    command: str, temp_dir: tuple[Path, str], monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture,
) -> None:  # fmt: skip
    """A step that cannot count its parts (a diagnosis, a refit) slowed to 3 s: the progress
    line names it and its seconds, never standing still for 2 s, and is gone before the text."""
    import sys
    import time

    import host.cli.model as model_cli

    real = {"diagnose": model_cli.diagnose, "add": model_cli.add_term}[command]

    def slow(*a: object, **kw: object) -> object:
        time.sleep(3.0)
        return real(*a, **kw)  # type: ignore[operator]

    monkeypatch.setattr(model_cli, "diagnose" if command == "diagnose" else "add_term", slow)
    term = _Terminal()
    monkeypatch.setattr(sys, "stderr", term)
    d, spec = temp_dir
    argv = ["model", command, str(d), *([spec] if command == "add" else [])]
    start = time.monotonic()
    assert main(argv) == 0
    end = time.monotonic()
    shown = [(t, s) for t, s in term.writes if f"{command}:" in s]
    assert shown and shown[0][0] - start < 2.0
    stamps = [t for t, _ in shown] + [end]
    assert max(b - a for a, b in zip(stamps, stamps[1:], strict=False)) < 2.0
    assert term.writes[-1][1] == "\r\x1b[K"  # the line cleared before the result is printed
    assert capsys.readouterr().out


@pytest.mark.slow
def test_model_add_prints_the_calibrate_command(
    temp_dir: tuple[Path, str], capsys: pytest.CaptureFixture[str]
) -> None:
    d, term = temp_dir
    assert main(["model", "add", str(d), term]) == 0
    out = capsys.readouterr().out
    lines = out.splitlines()
    i = next(i for i, ln in enumerate(lines) if ln.startswith("ship this model: "))
    cmd = lines[i].removeprefix("ship this model: ")
    while cmd.endswith("\\"):  # a long command is broken as a shell would read it
        i += 1
        cmd = cmd.removesuffix("\\").rstrip() + " " + lines[i].strip()
    assert cmd == f"python3 -m host calibrate --from-dir {d} --model base,{term}"
    # and that command ships exactly the model the workbench showed
    args = cmd.split()[3:]
    assert main([*args, "--json"]) == 0
    res = json.loads(capsys.readouterr().out)
    assert res["model"] == f"base,{term}"
