"""An archive entry read from what calibrate wrote (host/archive/entry.py): the hashes are
those of the files, the identity comes from the records' headers or the options, and a
missing file is one line naming it."""

from __future__ import annotations

import hashlib
import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from host.archive.entry import (
    BENCH_ENV,
    entry_from_directory,
    records_digest,
    result_covariance,
    utc_iso,
)
from host.calib.publish import ComputeSettings, compute_and_write
from host.errors import UserError
from host.session.directory import read_session
from tests.host.sim_sessions import write_sim_session


@pytest.fixture(scope="module")
def calibrated(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = write_sim_session(tmp_path_factory.mktemp("entry") / "E1", "E1", seed=21)
    compute_and_write(read_session(d, None), d, ComputeSettings())
    return d


def _copy(src: Path, dst: Path) -> Path:
    shutil.copytree(src, dst)
    return dst


def _sha(p: Path) -> str:
    return hashlib.sha256(p.read_bytes()).hexdigest()


def _without_record_digests(d: Path) -> None:
    """The result in ``d`` as written before results named their records' digests (format v3
    all the same): its records may then be edited in place and still be archived."""
    path = d / "E1_result.json"
    doc = json.loads(path.read_text())
    del doc["provenance"]["record_sha256"]
    path.write_text(json.dumps(doc))


def test_the_entry_proves_which_files_it_came_from(calibrated: Path, tmp_path: Path) -> None:
    e = entry_from_directory(calibrated, bench="B2", operator="ana")
    doc = json.loads((calibrated / "E1_result.json").read_text())
    assert e.serial == "E1" and (e.bench, e.operator) == ("B2", "ana")
    assert e.result_hash == _sha(calibrated / "E1_result.json")
    assert e.report_hash == _sha(calibrated / "E1_result.txt")
    assert dict(e.record_hashes) == {n: _sha(calibrated / f"E1_{n}.txt") for n in doc["records"]}
    assert e.records_hash == records_digest(e.record_hashes)
    assert [p.name for p in e.parameters] == [p["name"] for p in doc["parameters"]]
    assert [p.value for p in e.parameters] == pytest.approx([p["value"] for p in doc["parameters"]])
    assert e.verdict == ("pass" if doc["all_passed"] else "fail")
    assert e.fit_verdict == doc["fit"]["verdict"]
    # the result file carries the full covariance: kept whole, its diagonal the σ²
    assert e.covariance_kind == "full"
    cov = np.array(e.covariance)
    assert np.allclose(np.sqrt(np.diag(cov)), [p.stderr for p in e.parameters])
    assert np.count_nonzero(cov - np.diag(np.diag(cov))) > 0
    # an older file with the σ only: their diagonal, said so
    del doc["covariance"]
    d = _copy(calibrated, tmp_path / "old")
    (d / "E1_result.json").write_text(json.dumps(doc), encoding="utf-8")
    old = entry_from_directory(d)
    assert old.covariance_kind == "diagonal"
    c0 = np.array(old.covariance)
    assert np.count_nonzero(c0 - np.diag(np.diag(c0))) == 0
    assert e.temp_min_c <= e.temp_mean_c <= e.temp_max_c


def test_identity_from_the_record_headers_and_the_environment(
    calibrated: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    d = _copy(calibrated, tmp_path / "E1")
    rec = d / "E1_x_up.txt"
    head = (
        "# start_time: 2026-05-04T09:30:00.250+02:00\n# firmware: imu-bench 0.3\n"
        "# sensor_revision: C5\n# self_test: fail\n# lot: L42\n"
    )
    rec.write_text(head + rec.read_text())
    compute_and_write(read_session(d, None), d, ComputeSettings())  # fitted on these records
    monkeypatch.setenv(BENCH_ENV, "bench-7")
    e = entry_from_directory(d)
    assert e.measured_at == "2026-05-04T07:30:00.250000Z"
    assert (e.firmware, e.sensor_revision, e.lot, e.bench) == (
        "imu-bench 0.3",
        "C5",
        "L42",
        "bench-7",
    )
    assert e.self_test == "fail" and e.verdict == "fail"
    assert dict(e.record_hashes)["x_up"] == _sha(rec)


def test_records_elsewhere_and_missing_files(calibrated: Path, tmp_path: Path) -> None:
    out = tmp_path / "out"
    out.mkdir()
    for name in ("E1_result.json", "E1_result.txt"):
        shutil.copy(calibrated / name, out / name)
    with pytest.raises(UserError, match=r"E1_\w+.txt: no such file.*--records"):
        entry_from_directory(out)
    assert entry_from_directory(out, records_dir=calibrated).serial == "E1"
    (out / "E1_result.txt").unlink()
    with pytest.raises(UserError, match="E1_result.txt: no such file"):
        entry_from_directory(out, records_dir=calibrated)
    with pytest.raises(UserError, match="no SERIAL_result.json"):
        entry_from_directory(tmp_path)
    with pytest.raises(UserError, match="no such directory"):
        entry_from_directory(tmp_path / "nope")


def test_records_of_another_sitting_are_not_archived_as_the_results(
    calibrated: Path, tmp_path: Path
) -> None:
    """``archive add DIR --records OTHER``: the result names the SHA-256 of every record file it
    was fitted on, so records of the same unit measured in another sitting (or one edited after
    the fit) are refused with a line naming the file; the records it was fitted on are taken."""
    doc = json.loads((calibrated / "E1_result.json").read_text())
    digests = doc["provenance"]["record_sha256"]
    assert digests == {n: _sha(calibrated / f"E1_{n}.txt") for n in doc["records"]}
    other = write_sim_session(tmp_path / "other", "E1", seed=22)  # same unit, another sitting
    with pytest.raises(UserError, match=r"E1_\w+\.txt: not the record the result was fitted"):
        entry_from_directory(calibrated, records_dir=other)
    shutil.copytree(calibrated, tmp_path / "mine")
    edited = tmp_path / "mine" / "E1_z_cw.txt"
    edited.write_text(edited.read_text().replace("\n", "\n", 1) + "\n")
    with pytest.raises(UserError, match="E1_z_cw.txt: not the record"):
        entry_from_directory(tmp_path / "mine")
    e = entry_from_directory(tmp_path / "mine", records_dir=calibrated)
    assert dict(e.record_hashes) == digests
    _without_record_digests(tmp_path / "mine")  # a result written before: nothing to check
    assert entry_from_directory(tmp_path / "mine").serial == "E1"


def test_a_bad_self_test_line_is_refused(calibrated: Path, tmp_path: Path) -> None:
    d = _copy(calibrated, tmp_path / "E1")
    rec = d / "E1_y_up.txt"
    rec.write_text("# self_test: maybe\n" + rec.read_text())
    _without_record_digests(d)
    with pytest.raises(UserError, match="self_test: 'maybe'"):
        entry_from_directory(d)


def test_a_full_covariance_in_the_result_is_taken_in_the_parameters_order() -> None:
    doc = {"covariance": {"names": ["b", "a"], "matrix": [[4.0, 1.0], [1.0, 9.0]]}}
    assert result_covariance(doc, ["a", "b"]) == ((9.0, 1.0), (1.0, 4.0))
    assert result_covariance(doc, ["a", "c"]) is None
    assert result_covariance({}, ["a"]) is None


def test_times_become_utc() -> None:
    assert utc_iso("2026-01-02T03:04:05Z") == "2026-01-02T03:04:05.000000Z"
    assert utc_iso("2026-01-02T03:04:05-05:00") == "2026-01-02T08:04:05.000000Z"
    with pytest.raises(UserError, match="not an ISO 8601 time"):
        utc_iso("yesterday")


@settings(max_examples=200, deadline=None)
@given(st.text(max_size=40))
def test_any_time_text_is_a_time_or_one_line(text: str) -> None:
    try:
        out = utc_iso(text)
    except UserError as exc:
        assert "not an ISO 8601 time" in str(exc)
    else:
        assert out.endswith("Z") and len(out) == 27


cells = st.none() | st.floats() | st.text(max_size=3) | st.lists(st.floats(), max_size=2)


@settings(max_examples=150, deadline=None)
@given(
    st.lists(st.sampled_from(["a", "b", 1, None]), max_size=3),
    st.lists(st.lists(cells, max_size=3) | cells, max_size=3),
)
@pytest.mark.slow
def test_a_malformed_covariance_is_ignored_not_a_crash(names: list, matrix: list) -> None:
    doc = {"covariance": {"names": names, "matrix": matrix}}
    out = result_covariance(doc, ["a"])
    assert out is None or len(out) == 1


#: printable names, and one control character to slip into them (escape, line break, tab, DEL,
#: a C1 control)
_NAMES = st.text(st.characters(whitelist_categories=("L", "N", "P", "S"), whitelist_characters=" "),
                 max_size=12)  # fmt: skip
_CONTROLS = st.sampled_from(["\x1b", "\n", "\r", "\t", "\x00", "\x7f", "\x9b"])


@settings(max_examples=25, deadline=None)
@given(name=_NAMES, control=_CONTROLS, at=st.integers(0, 12), where=st.sampled_from(
    ["--bench", "--operator", "--lot", "$IMU_BENCH_NAME", "header"]))  # fmt: skip
@pytest.mark.slow
def test_a_name_with_a_control_character_never_reaches_the_archive(
    calibrated: Path, tmp_path_factory: pytest.TempPathFactory, name: str, control: str,
    at: int, where: str,
) -> None:  # fmt: skip
    """An escape sequence kept as a bench, an operator or a lot garbles every later listing of
    the lot: wherever it comes from, the entry is refused with a line naming that source; the
    same name without it is kept as given."""
    bad = name[:at] + control + name[at:]
    d = _copy(calibrated, tmp_path_factory.mktemp("names") / "E1")
    options = {"--bench": "bench", "--operator": "operator", "--lot": "lot"}
    with pytest.MonkeyPatch.context() as mp:
        mp.delenv(BENCH_ENV, raising=False)
        if where in options:
            with pytest.raises(UserError, match=f"^{where}: .*control character"):
                entry_from_directory(d, **{options[where]: bad})
            if name.strip():
                e = entry_from_directory(d, **{options[where]: name})
                assert getattr(e, options[where]) == name
        elif where == "header":
            rec = d / "E1_x_up.txt"
            rec.write_text(f"# lot: {bad}\n" + rec.read_text())
            _without_record_digests(d)
            # a header's value is read less the blanks around it: a tab there is one of them
            if control in bad.strip() and "\n" not in bad and "\r" not in bad:
                with pytest.raises(UserError, match="'lot' header line: .*control character"):
                    entry_from_directory(d)
        else:
            mp.setenv(BENCH_ENV, bad.replace("\x00", ""))  # the environment holds no NUL
            if control != "\x00":
                with pytest.raises(UserError, match=r"^\$IMU_BENCH_NAME: .*control character"):
                    entry_from_directory(d)
