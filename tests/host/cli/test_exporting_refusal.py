"""No export of a unit that did not pass (issue 43 item 4): each cause of a verdict that is
not a pass — a failed self-test, a value out of tolerance, a value undecided under the
decision rule, a value not determined, a record of the method not measured — makes every one
of the five formats (ardupilot, px4, imucal, c-header, and kalibr given the result) exit 1
with one line naming it and write nothing; ``--allow-fail`` writes the file marked FAILED."""

from __future__ import annotations

import dataclasses
import json
import math
from collections.abc import Callable
from pathlib import Path

import pytest

from host.calib.codec import result_to_json
from host.calib.exporting import FORMATS
from host.calib.result import CalibrationResult
from host.session.records import STATIC_NAMES, TURN_NAMES
from tests.host.calib.test_exporting import _noise_doc, _result
from tests.host.cli.cli_run import run

FIVE = (*FORMATS, "kalibr")
assert len(FIVE) == 5


def _undecided() -> CalibrationResult:
    """Gxx inside ±0.03 (0.025), its U (2 × 0.005) across the limit: '?' when guarded."""
    r = _result(Gxx=0.025)
    ps = tuple(dataclasses.replace(p, stderr=0.005) if p.name == "Gxx" else p
               for p in r.parameters)  # fmt: skip
    return dataclasses.replace(r, parameters=ps)


def _missing() -> CalibrationResult:
    names = [n for n in STATIC_NAMES + TURN_NAMES if n != "z_dn"]
    return dataclasses.replace(_result(), records=tuple(names))


#: cause -> (the result, words the one line names it by)
CAUSES: dict[str, tuple[Callable[[], CalibrationResult], str]] = {
    "self-test": (lambda: dataclasses.replace(_result(), self_test="fail"),
                  "the sensor failed its self-test"),
    "out of tolerance": (lambda: _result(Gxx=0.05), "outside tolerance: Gxx"),
    "undecided": (_undecided, "undecided under guarded acceptance: Gxx"),
    "not determined": (lambda: _result(A0y=math.nan), "not determined: A0y"),
    "record missing": (_missing, "records of the method not measured: z_dn"),
}  # fmt: skip


def _argv(rj: Path, fmt: str, out: Path, noise: Path) -> list[str]:
    more = ["--noise", str(noise)] if fmt == "kalibr" else []
    return ["export", str(rj), "--to", fmt, "--out", str(out), *more]


@pytest.mark.parametrize("cause", CAUSES)
def test_every_format_refuses_a_result_that_did_not_pass(tmp_path: Path, cause: str) -> None:
    make, words = CAUSES[cause]
    result = make()
    assert not result.all_passed
    rj = tmp_path / "EXP1_result.json"
    rj.write_text(result_to_json(result), encoding="utf-8")
    noise = tmp_path / "noise.json"
    noise.write_text(json.dumps(_noise_doc()), encoding="utf-8")
    for fmt in FIVE:
        out = tmp_path / f"cal.{fmt}"
        rc, text, err = run(_argv(rj, fmt, out, noise))
        assert rc == 1, (cause, fmt, err)
        assert err.count("\n") == 1 and words in err and "--allow-fail" in err, err
        assert text == "" and not out.exists()
        rc, _, err = run([*_argv(rj, fmt, out, noise), "--allow-fail"])
        if cause == "not determined" and fmt != "kalibr":
            assert rc == 2 and not out.exists()  # allowed, but no format can carry NaN
            continue
        assert rc == 0, err
        written = out.read_text(encoding="utf-8")
        assert "FAILED calibration, exported with --allow-fail" in written and words in written


def test_the_same_unit_passing_is_exported_unmarked(tmp_path: Path) -> None:
    """The control: the values of the causes' result, passing, go out in all five formats
    with no FAILED mark (so the refusals above are the causes', not the files')."""
    rj = tmp_path / "EXP1_result.json"
    rj.write_text(result_to_json(_result()), encoding="utf-8")
    noise = tmp_path / "noise.json"
    noise.write_text(json.dumps(_noise_doc()), encoding="utf-8")
    for fmt in FIVE:
        out = tmp_path / f"cal.{fmt}"
        rc, _, err = run(_argv(rj, fmt, out, noise))
        assert rc == 0, err
        assert "FAILED" not in out.read_text(encoding="utf-8")
    # simple acceptance passes the undecided Gxx (0.025 within ±0.03): exported
    simple = dataclasses.replace(_undecided(), decision_rule="simple")
    rj.write_text(result_to_json(simple), encoding="utf-8")
    rc, _, err = run(_argv(rj, "px4", tmp_path / "cal.px4", noise))
    assert rc == 0, err
