"""The full parameter covariance in the result file (issues 28/29): its diagonal is the
standard errors squared, it survives the JSON and the archive stores it as 'full' (it stored
only the diagonal); and on sessions of the independent simulator its off-diagonal terms are
right — a combination of two correlated parameters scatters as the full covariance says, not
as their σ alone say."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from host.calib.calibration import calibrate_from_records
from host.calib.codec import result_from_json, result_to_json
from host.calib.report import write_results
from host.errors import ResultFileError
from host.session.directory import read_session
from tests.independent.simulate import SessionSpec, write_session


@pytest.fixture(scope="module")
def session_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp("cov")
    write_session(d, SessionSpec(seed=29, static_s=5.0, turns=1, warmup_s=0))
    return d


def test_the_covariance_is_the_fits_and_round_trips(session_dir: Path, tmp_path: Path) -> None:
    res = calibrate_from_records(read_session(session_dir))
    c = np.array(res.covariance)
    n = len(res.parameters)
    assert c.shape == (n, n) and np.allclose(c, c.T, equal_nan=True)
    se = np.array([p.stderr for p in res.parameters])
    np.testing.assert_allclose(np.diag(c), se**2, rtol=1e-12)
    s = np.sqrt(np.diag(c))
    rho = c / np.outer(s, s)
    assert np.all(np.abs(rho) <= 1 + 1e-9)
    assert np.abs(rho - np.eye(n)).max() > 0.3  # not a diagonal matrix in disguise
    assert np.linalg.eigvalsh(c).min() > -1e-12 * np.abs(c).max()
    back = result_from_json(result_to_json(res))
    np.testing.assert_array_equal(np.array(back.covariance), c)
    # reordered parameters in the file: the matrix follows the names
    doc = json.loads(result_to_json(res))
    doc["covariance"]["names"] = doc["covariance"]["names"][::-1]
    doc["covariance"]["matrix"] = [row[::-1] for row in doc["covariance"]["matrix"][::-1]]
    np.testing.assert_array_equal(np.array(result_from_json(json.dumps(doc)).covariance), c)
    doc["covariance"]["names"] = doc["covariance"]["names"][1:]
    with pytest.raises(ResultFileError, match="covariance"):
        result_from_json(json.dumps(doc))
    # the archive reads it as the full matrix now
    from host.archive.entry import entry_from_directory

    write_results(res, tmp_path)
    entry = entry_from_directory(tmp_path, records_dir=session_dir)
    assert entry.covariance_kind == "full"
    assert np.allclose(np.array(entry.covariance, dtype=float), c, equal_nan=True)


def test_an_undetermined_parameter_has_nan_rows() -> None:
    from host.session.directory import Session
    from tests.host.calib_truth import make_records

    statics = ("x_up", "x_dn", "y_up", "y_dn", "z_up", "z_dn")
    res = calibrate_from_records(Session("S", make_records(statics)))
    names = [p.name for p in res.parameters]
    c = np.array(res.covariance)
    i = names.index("Gxx")
    assert not res.parameter("Gxx").determined
    assert np.all(np.isnan(c[i])) and np.all(np.isnan(c[:, i]))
    j = names.index("A0x")
    assert math.isfinite(c[j, j]) and c[j, j] == pytest.approx(res.parameter("A0x").stderr ** 2)
    assert "NaN" not in result_to_json(res)


@pytest.mark.slow
def test_correlated_pairs_scatter_as_the_full_covariance_says(tmp_path: Path) -> None:
    """40 independent sessions (white noise, quantisation, no effect): for the five most
    correlated pairs of the base model (|ρ| ≈ 0.44), the pull of ε_i/σ_i − sign(ρ)·ε_j/σ_j
    with the full covariance has mean square ≈ 1 (χ² on 200 values); with the σ alone it
    would be ≈ 0.56, outside that band."""
    pairs = [("Azy", "A0z"), ("GAxx", "G0x"), ("Ayz", "A0y"), ("G0z", "GAzx"), ("G0y", "GAyx")]
    full, diag = [], []
    for seed in range(40):
        d = tmp_path / f"s{seed}"
        write_session(d, SessionSpec(seed=100 + seed, static_s=5.0, turns=1, warmup_s=0))
        res = calibrate_from_records(read_session(d))
        truth = json.loads((d / "truth.json").read_text())["constants"]
        names = [p.name for p in res.parameters]
        c = np.array(res.covariance)
        for a, b in pairs:
            i, j = names.index(a), names.index(b)
            si, sj = math.sqrt(c[i, i]), math.sqrt(c[j, j])
            rho = c[i, j] / (si * sj)
            assert abs(rho) > 0.2, (a, b, rho)
            x = (res.parameter(a).value - truth[a]) / si - np.sign(rho) * (
                res.parameter(b).value - truth[b]
            ) / sj
            full.append(x / math.sqrt(2 - 2 * abs(rho)))
            diag.append(x / math.sqrt(2))
    from scipy.stats import chi2

    n = len(full)
    lo, hi = chi2.ppf([0.001, 0.999], n) / n
    assert lo < np.mean(np.square(full)) < hi
    assert np.mean(np.square(diag)) < lo  # the diagonal alone overstates the scatter
