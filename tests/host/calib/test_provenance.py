"""Provenance in every file (issue 28): a result of simulated records says so as a field of
its JSON (format v3), in the report's first lines and in every export format, also after
``calibrate --from-dir``; older result files still read; a failed result is not exported
without ``--allow-fail``."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from host.__main__ import main
from host.bench.plan import write_session
from host.calib.codec import read_result, result_from_json, result_to_dict, result_to_json
from host.calib.exporting import FORMATS
from host.errors import ResultFileError
from host.workbench.scenarios import hidden_effect_case

URL = "sim://?speed=max"
#: the board the records name: the dialogue adds the unit's serial to a virtual board's URL
BOARD = f"{URL}&serial=PV1"


@pytest.fixture(scope="module")
def live(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A live session on the virtual board at full speed: its directory."""
    d = tmp_path_factory.mktemp("live") / "PV1"
    argv = ["calibrate", "--port", URL, "--serial", "PV1", "--out", str(d), "--yes",
            "--warmup", "0", "--static-seconds", "3", "--turns", "1", "--no-archive"]  # fmt: skip
    assert main(argv) in (0, 1)
    return d


@pytest.mark.slow
def test_live_sim_result_says_simulated_everywhere(
    live: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    doc = json.loads((live / "PV1_result.json").read_text(encoding="utf-8"))
    assert doc["format_version"] == 3
    assert doc["simulated"] is True and doc["simulated_by"] == [BOARD]
    assert doc["provenance"]["simulated"] is True and doc["provenance"]["ports"] == [BOARD]
    report = (live / "PV1_result.txt").read_text(encoding="utf-8").splitlines()
    assert report[1] == f"*** SIMULATED BOARD {BOARD}: not a measurement of a unit ***"
    capsys.readouterr()
    for fmt, (_, ext) in FORMATS.items():
        out = tmp_path / f"PV1{ext}"
        rc = main(["export", str(live), "--to", fmt, "--out", str(out), "--allow-fail"])
        assert rc == 0, capsys.readouterr().err
        text = out.read_text(encoding="utf-8")
        head = "\n".join(text.splitlines()[:4])  # said at the top, not buried
        assert f"*** SIMULATED BOARD {BOARD}: not a measurement of a unit ***" in head, (fmt, head)
        if fmt == "imucal":
            assert json.loads(text)["comment"].startswith("*** SIMULATED BOARD sim://")


def test_demo_records_recomputed_keep_the_simulated_mark(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``demo hidden-effect`` writes records with ``# source: sim`` and no port: the mark
    survived only as far as the records (issue 28)."""
    case = hidden_effect_case("temperature", 4)
    write_session(tmp_path, "DEMO", dict(case.records))
    assert "# source: sim" in (tmp_path / "DEMO_x_up.txt").read_text(encoding="utf-8")
    assert main(["calibrate", "--from-dir", str(tmp_path), "--no-archive"]) in (0, 1)
    out = capsys.readouterr().out
    mark = "*** SIMULATED BOARD simulator (source: sim): not a measurement of a unit ***"
    assert out.splitlines()[1] == mark
    res = read_result(tmp_path / "DEMO_result.json")
    assert res.simulated and res.provenance is not None
    assert res.provenance.simulated_by == ("simulator (source: sim)",)
    assert mark in (tmp_path / "DEMO_result.txt").read_text(encoding="utf-8")


def test_older_files_read_and_an_edited_mark_is_refused(tmp_path: Path) -> None:
    from host.calib.calibration import calibrate_from_records
    from host.session.directory import read_session

    write_session(tmp_path, "DEMO", dict(hidden_effect_case("temperature", 4).records))
    doc = json.loads(result_to_json(calibrate_from_records(read_session(tmp_path))))
    v2 = {k: v for k, v in doc.items() if k not in ("simulated", "simulated_by", "provenance")}
    v2["format_version"] = 2
    old = result_from_json(json.dumps(v2))
    assert old.loaded_version == 2 and old.provenance is None
    assert old.simulated  # from its note, as v2 files said it
    v2["notes"] = [n for n in v2["notes"] if not n.startswith("SIMULATED BOARD")]
    assert not result_from_json(json.dumps(v2)).simulated
    # a v3 file edited to look like a unit's: the two marks disagree
    doc["simulated"] = False
    with pytest.raises(ResultFileError, match="'simulated' and provenance.simulated disagree"):
        result_from_json(json.dumps(doc))


def test_unit_records_carry_no_mark(tmp_path: Path) -> None:
    from host.calib.calibration import calibrate_from_records
    from host.session.directory import read_session

    real = Path(__file__).resolve().parents[4] / "shared" / "data" / "imucal-example"
    res = calibrate_from_records(read_session(real))
    assert not res.simulated and res.simulated_line == ""
    assert res.provenance is not None and res.provenance.sensor == "unknown sensor"
    assert "SIMULATED" not in json.dumps(result_to_dict(res))


def test_the_adaptive_plans_target_is_read_from_the_headers_and_kept() -> None:
    """The records' ``plan_target`` is the provenance's target (the last record's), kept
    through the result file's dict; a session without one has none and its dict no key;
    :func:`host.calib.values.target_line` says met or NOT met on the values' σ/tolerance."""
    import numpy as np

    from host.calib.provenance import Provenance, plan_target
    from host.calib.values import ParameterResult, target_line
    from host.session.records import TARGET_KEY, Record

    def rec(name: str, meta: dict[str, str]) -> Record:
        z = np.zeros((2, 3))
        return Record(name, np.array([0.0, 20.0]), z, z, np.zeros(2), meta)

    assert plan_target({"x_up": rec("x_up", {})}) is None
    recs = {"x_up": rec("x_up", {TARGET_KEY: "0.05"}), "x_dn": rec("x_dn", {TARGET_KEY: "0.02"})}
    assert plan_target(recs) == 0.02
    assert plan_target({"x_up": rec("x_up", {TARGET_KEY: "soon"})}) is None
    pv = Provenance(target=0.02)
    assert Provenance.from_dict(pv.to_dict()).target == 0.02
    assert "target" not in Provenance().to_dict()
    params = [ParameterResult("base", "gyro", "x", "k", "Gxx", 0.0, 0.003, "", 0.1),
              ParameterResult("base", "gyro", "y", "k", "Gyy", 0.0, 0.001, "", 0.1)]  # fmt: skip
    assert "≤ 0.05: met (0.03, Gxx)" in target_line(params, 0.05)
    assert "≤ 0.02: NOT met (0.03, Gxx)" in target_line(params, 0.02)
