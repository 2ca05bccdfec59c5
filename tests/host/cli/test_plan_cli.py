"""``python3 -m host plan DIR`` (host/cli/plan.py): the ranking as a user reads it."""

from __future__ import annotations

import argparse
import dataclasses
import functools
import json
import math
import shlex
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from host.__main__ import build_parser, main
from tests.independent.simulate import SessionSpec, write_session


@pytest.fixture(scope="module")
def session_without_y_turns(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp("plan") / "S"
    write_session(d, SessionSpec(seed=11, static_s=5.0))
    for name in ("y_ccw", "y_cw"):
        (d / f"IND01_{name}.txt").unlink()
    return d


@pytest.mark.slow
def test_the_table_names_the_record_and_fits_80_columns(
    session_without_y_turns: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["plan", str(session_without_y_turns), "--top", "4"]) == 0
    out = capsys.readouterr().out
    lines = out.splitlines()
    assert all(len(line) <= 80 for line in lines), max(lines, key=len)
    assert "Gyy is not determined" in lines[0] or "not determined" in lines[0]
    first = next(line for line in lines if line.startswith(" 1 "))
    assert "y turns" in first and "determines" in first
    assert sum(1 for line in lines if line[:3].strip().isdigit()) == 4


@pytest.mark.slow
def test_json_ranks_every_candidate(
    session_without_y_turns: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["plan", str(session_without_y_turns), "--json"]) == 0
    obj = json.loads(capsys.readouterr().out)
    ranked = obj["ranked"]
    assert len(ranked) == 6 + 12 + 3  # faces, 45° attitudes, turn pairs
    assert ranked[0]["records"] == ["y_ccw", "y_cw"]
    assert "Gyy" in ranked[0]["determines"]
    assert obj["worst_now"] is None  # undetermined now: not a number


def test_bad_top_is_one_line(
    session_without_y_turns: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["plan", str(session_without_y_turns), "--top", "0"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--top" in err[0]


def test_missing_directory_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["plan", str(tmp_path / "nothing")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "nothing" in err[0]


@functools.cache
def _parser() -> argparse.ArgumentParser:
    """The command line's parser, built once (it takes ~45 ms: every command's options)."""
    return build_parser()[0]


@settings(max_examples=200, deadline=None)
@given(st.text(max_size=12))
def test_place_seconds_parse_or_refuse(text: str) -> None:
    """Any text for --place-s is a finite number of seconds ≥ 0, or argparse's exit 2."""
    parser = _parser()
    try:
        args = parser.parse_args(["plan", "D", "--place-s", text])
    except SystemExit as exc:
        assert exc.code == 2
        return
    assert math.isfinite(args.place_s) and 0.0 <= args.place_s <= 3600.0  # 1e300 s: refused


@pytest.mark.slow
def test_separate_names_a_record_within_80_columns(
    session_without_y_turns: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    d = str(session_without_y_turns)
    assert main(["plan", d, "--separate", "time_drift:accel:x", "temperature_bias:accel:x",
                 "--top", "3"]) == 0  # fmt: skip
    lines = capsys.readouterr().out.splitlines()
    assert all(len(line) <= 80 for line in lines), max(lines, key=len)
    assert lines[0].startswith("to tell time_drift:accel:x from temperature_bias:accel:x")
    assert sum(1 for line in lines if line[:3].strip().isdigit()) == 3


@pytest.mark.parametrize(
    "a, b, words",
    [
        # was: ten records ranked, each separating them by Δχ² 0
        ("scale_asymmetry:gyro:z", "scale_asymmetry:gyro:z", "the same explanation twice"),
        ("time_drift:accel:x", "bias:gyro:z", "--separate bias:gyro:z: already in the model base"),
    ],
)
def test_separate_needs_two_explanations_the_model_lacks(
    session_without_y_turns: Path, capsys: pytest.CaptureFixture[str], a: str, b: str, words: str
) -> None:
    assert main(["plan", str(session_without_y_turns), "--separate", a, b]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and words in err, err


def test_separate_with_an_unknown_term_is_one_line(
    session_without_y_turns: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    d = str(session_without_y_turns)
    assert main(["plan", d, "--separate", "no_such_term", "time_drift:accel:x"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no_such_term" in err[0]
    assert main(["plan", d, "--separate", "time_drift:accel:x"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "two explanations or more" in err[-1]


@pytest.mark.slow
@pytest.mark.timeout(300)
def test_diagnose_leads_to_the_record_that_separates_its_equals(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """diagnose names the planner's next record and, for its group of equals (a gyro scale
    asymmetry and a quadratic scale), the plan command that separates them; that command, run
    as printed, puts the turns at another pace first."""
    d = tmp_path / "S"
    write_session(d, SessionSpec(seed=3, effect="scale_asymmetry"))
    assert main(["model", "diagnose", str(d), "--brief"]) == 0
    # commands are broken between words with " \\" and a 4-space indent: pasted, they run
    text = capsys.readouterr().out.replace(" \\\n    ", " ").replace("\\\n", "")
    assert "next record: " in text and f"python3 -m host plan {d}" in text
    cmd = next(line for line in text.splitlines() if "--separate" in line).split()
    assert cmd[:4] == ["python3", "-m", "host", "plan"]
    a, b = cmd[cmd.index("--separate") + 1 :][:2]
    assert {a.split(":")[0], b.split(":")[0]} == {"scale_asymmetry", "scale_nonlinearity"}
    assert main(cmd[3:] + ["--top", "2"]) == 0
    first = next(line for line in capsys.readouterr().out.splitlines() if line.startswith(" 1 "))
    assert "as fast" in first


def test_a_record_with_a_noted_heading_says_how_to_place_it() -> None:
    """The ranking tells the operator where the cube goes for a record whose heading is noted
    (the arrow at 45° to the vertical, made level, along the fence) and that the record
    carries it; a list without such a record says nothing of headings."""
    from host.cli.plan import format_separation
    from host.workbench.separate import Separating, Separation, heading_candidates

    noted = next(c for c in heading_candidates(10.0) if c.label.startswith("tilt_45_3 "))
    unnoted = dataclasses.replace(noted, label="tilt_45_3 (up −x+y)", headings=())
    plain = Separating(unnoted, 120.0, 100.0)
    s = Separation("a", "b", 0.0, (plain, Separating(noted, 150.0, 90.0)), others=("c",))
    lines = format_separation(s, 2).splitlines()
    assert all(len(line) <= 80 for line in lines), max(lines, key=len)
    assert lines[0].startswith("to tell a from b and from c:")
    text = " ".join(lines)
    assert "heading noted: put tilt_45_3 against the fence, its X arrow pointing right" in text
    assert "placement_heading_deg: 0" in text
    assert "heading" not in format_separation(s, 1)


@pytest.mark.slow
@pytest.mark.timeout(300)
def test_diagnose_asks_about_every_member_of_a_group_of_three(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Statics without a heading on a unit whose accel reads (f/g)² of another axis: the
    group holds the plate's tilt, a face lean and the signal; diagnose prints the plan command
    for all three, and that command, run as printed, names a 45° attitude first."""
    d = tmp_path / "S"
    write_session(d, SessionSpec(seed=3000, effect="cross_g2"))
    assert main(["model", "diagnose", str(d), "--brief"]) == 0
    text = capsys.readouterr().out.replace(" \\\n    ", " ").replace("\\\n", "")
    line = next(x for x in text.splitlines() if "--separate" in x)
    args = shlex.split(line)[3:]
    members = args[args.index("--separate") + 1 :]
    assert len(members) == 3 and "plate_tilt:accel:xyz" in members
    assert any(m.startswith("face_error:accel:") for m in members)
    assert any("follows (specific force" in m for m in members)
    assert main([*args, "--top", "1"]) == 0
    first = next(x for x in capsys.readouterr().out.splitlines() if x.startswith(" 1 "))
    assert "tilt_45_" in first
