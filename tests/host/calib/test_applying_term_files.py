"""A result is data (issue 28): ``apply()`` and ``verify()`` never run a file a result JSON
names; a custom term comes only from a term file the caller passes, and only when its SHA-256
is the one the result stored."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from host.calib.applying import apply, verify
from host.calib.calibration import CalibrationOptions, calibrate_from_records
from host.calib.codec import result_from_json, result_to_json
from host.errors import TermFileMismatch, UserError
from host.session.directory import read_session
from tests.host.sim_sessions import write_sim_session

TERM_FILE = """\
from pathlib import Path
from host.model.terms import term

Path({marker!r}).write_text("ran")


@term(sensors=("gyro",))
def warm(sig, sensor, axis):
    '''Rate bias proportional to the chip temperature's offset, °/s per °C.'''
    return (sig.temp_c - sig.temp_mean_c)[:, None]
"""


@pytest.fixture(scope="module")
def session_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_sim_session(tmp_path_factory.mktemp("data"), "TF1", seed=28)


def _term_file(d: Path, marker: Path) -> Path:
    f = d / "warm_terms.py"
    f.write_text(TERM_FILE.format(marker=str(marker)), encoding="utf-8")
    return f


def test_a_result_naming_a_term_file_applies_without_running_it(
    session_dir: Path, tmp_path: Path
) -> None:
    marker = tmp_path / "marker"
    evil = _term_file(tmp_path, marker)
    res = calibrate_from_records(read_session(session_dir))
    doc = json.loads(result_to_json(res))
    doc["term_files"] = [str(evil)]  # an edited result file names a Python file
    edited = result_from_json(json.dumps(doc))
    assert edited.term_files == (str(evil),)
    rec = read_session(session_dir).records["x_up"]
    a, w = apply(edited, rec.accel, rec.gyro)
    verify(edited, read_session(session_dir))
    assert not marker.exists()  # loaded, applied and verified; the file never ran
    a0, w0 = apply(res, rec.accel, rec.gyro)
    assert np.array_equal(a, a0) and np.array_equal(w, w0)


def test_custom_terms_only_from_the_callers_file_with_the_stored_hash(
    session_dir: Path, tmp_path: Path
) -> None:
    marker = tmp_path / "marker"
    f = _term_file(tmp_path, marker)
    res = calibrate_from_records(
        read_session(session_dir), CalibrationOptions(model="base,warm:gyro", term_files=[f])
    )
    marker.unlink()
    assert res.model == "base,warm:gyro"
    assert (
        list(res.term_sha256) == [str(f.resolve())] and len(res.term_sha256[str(f.resolve())]) == 64
    )
    back = result_from_json(result_to_json(res))
    assert back.term_sha256 == res.term_sha256
    rec = read_session(session_dir).records["x_up"]

    # not passed: one error naming the term and the file, nothing run
    with pytest.raises(TermFileMismatch, match=r"custom term\(s\) warm.*warm_terms\.py") as err:
        apply(back, rec.accel, rec.gyro, temp_c=rec.temp, allow_undetermined=True)
    assert isinstance(err.value, ValueError) and isinstance(err.value, UserError)
    assert not marker.exists()

    # the same file, passed by the caller: it runs, and its term is applied
    a, w = apply(
        back, rec.accel, rec.gyro, temp_c=rec.temp, term_files=[f], allow_undetermined=True
    )
    assert marker.exists() and a.shape == rec.accel.shape
    # and its term is applied: 1 °C warmer moves each rate by -(its coefficient)
    _, w1 = apply(back, rec.accel, rec.gyro, temp_c=rec.temp + 1.0, term_files=[f])
    coef = np.array([back.parameter(f"warm.gyro.{ax}").value for ax in "xyz"])
    assert np.all(np.isfinite(coef))
    assert np.mean(w1 - w, axis=0) == pytest.approx(-coef, rel=0.05, abs=1e-9)

    # a changed file (one byte): refused before it runs
    marker.unlink()
    f.write_text(TERM_FILE.format(marker=str(marker)) + "# edited\n", encoding="utf-8")
    with pytest.raises(TermFileMismatch, match=r"warm_terms\.py: this term file \(sha256 "):
        apply(back, rec.accel, rec.gyro, temp_c=rec.temp, term_files=[f], allow_undetermined=True)
    with pytest.raises(TermFileMismatch):
        verify(back, read_session(session_dir), term_files=[f])
    assert not marker.exists()
