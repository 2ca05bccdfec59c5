"""Wrong input, right words (issue 27): each mistake a lab user made in the first days is
one line naming what was given and what is needed, exit status 2, no traceback."""

from __future__ import annotations

from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from host.bench.plan import write_session
from host.workbench.scenarios import hidden_effect_case
from tests.host.cli.cli_run import run
from tests.host.dialogue.flat_options import flat_options


@pytest.fixture(scope="module")
def session(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A complete session with 10 s statics (the dialogue's default length)."""
    d = tmp_path_factory.mktemp("misuse")
    case = hidden_effect_case("temperature", 3, static_s=10.0)
    write_session(d, "M1", dict(case.records))
    (d / "M1_result.txt").write_text("TEST REPORT, IMU MPU-6000, serial No. M1\n")
    return d


def one_error_line(err: str) -> str:
    lines = [x for x in err.splitlines() if x.startswith("error:")]
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


def test_noise_on_a_turn_record_names_it_and_what_to_give(session: Path) -> None:
    rc, out, err = run(["noise", str(session / "M1_x_cw.txt")])
    assert rc == 2 and out == ""
    line = one_error_line(err)
    assert "turn record" in line and "static record" in line and ".cap" in line


def test_noise_on_the_report_names_it_and_what_to_give(session: Path) -> None:
    rc, _, err = run(["noise", str(session / "M1_result.txt")])
    line = one_error_line(err)
    assert rc == 2 and "calibration report" in line and "static record" in line
    assert "damaged" not in line


def test_thermal_on_short_statics_says_why_and_which_window(session: Path) -> None:
    rc, _, err = run(["thermal", str(session), "--window", "30"])
    line = one_error_line(err)
    assert rc == 2 and "shorter than half of the 30 s" in line and "--window" in line
    window = int(line.split("--window ")[1].split()[0])
    _, _, err = run(["thermal", str(session), "--window", str(window)])
    assert "window" not in err  # the window it names gives window means (what stops it
    # now, if anything, is the records' temperature span)


def test_noise_and_thermal_print_degrees_celsius(session: Path, tmp_path: Path) -> None:
    rc, out, _ = run(["noise", str(session / "M1_x_up.txt")])
    assert rc == 0 and "°C" in out and "degC" not in out and "sqrt" not in out
    # (the thermal file written elsewhere: beside the records, calibrate would read it)
    rc, out, err = run(["thermal", str(session), "--window", "5", "--out", str(tmp_path)])
    assert rc == 0, err
    assert "°C" in out and "degC" not in out and "deg C" not in out
    assert "/°C" in out  # the coefficients' unit: per degree Celsius


def test_out_to_a_missing_directory_makes_it(session: Path, tmp_path: Path) -> None:
    out = tmp_path / "results" / "M1"
    rc, _, err = run(["calibrate", "--from-dir", str(session), "--out", str(out), "--no-archive"])
    assert rc in (0, 1), err
    assert (out / "M1_result.json").is_file()
    (tmp_path / "afile").write_text("x")
    rc, _, err = run(["calibrate", "--from-dir", str(session), "--out",
                      str(tmp_path / "afile" / "M1"), "--no-archive"])  # fmt: skip
    assert rc == 2 and "afile is a file; give --out a directory" in one_error_line(err)


@pytest.mark.parametrize(
    "extra, words",
    [
        # was: read by nothing, a fixed session measured as if they were not given
        (["--target", "0.01"], "--target: only --plan adaptive reads it; add --plan adaptive"),
        (["--max-extra", "3"], "--max-extra: only --plan adaptive reads it"),
        # was: a recomputation that ignored them
        (["--from-dir", "{dir}", "--plan", "adaptive"], "--plan adaptive is for a live calibra"),
        (["--from-dir", "{dir}", "--target", "0.1"], "--target is for a live calibration"),
    ],
)
def test_the_adaptive_plans_options_where_nothing_reads_them(
    session: Path, tmp_path: Path, extra: list[str], words: str
) -> None:
    argv = ["calibrate", "--serial", "M1", "--yes", "--static-seconds", "2", "--warmup", "0",
            "--no-archive", "--out", str(tmp_path / "o")]  # fmt: skip
    if "--from-dir" in extra:
        argv = ["calibrate", "--no-archive", "--out", str(tmp_path / "o")]
    rc, _, err = run([*argv, *(x.format(dir=session) for x in extra)])
    assert rc == 2 and words in one_error_line(err)
    assert not (tmp_path / "o").exists()  # refused before anything was measured or written


@settings(max_examples=60, deadline=None)
@given(st.integers(min_value=-(10**12), max_value=10**12))
def test_max_extra_is_a_bound_an_operator_can_keep_or_one_line(n: int) -> None:
    """Was: --max-extra 1000000 with a target the records cannot meet ran with no end."""
    from host.dialogue.options import MAX_EXTRA
    from host.errors import UserError

    o = flat_options(serial="M1", plan="adaptive", max_extra=n)
    if 0 <= n <= MAX_EXTRA:
        o.check()
    else:
        with pytest.raises(UserError, match=f"--max-extra {n}: give 0 to {MAX_EXTRA} records"):
            o.check()
