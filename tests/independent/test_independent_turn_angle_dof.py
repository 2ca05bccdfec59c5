"""A σ that is itself estimated, on sessions the bench's physics did not write: the hand's
turn-angle error (each turn record long by a normal draw, 0.5° std) is a variance component the
fit reads from three closures, so the gyro scales' σ rest on about 3 degrees of freedom. Over
100 independent sessions, (fitted − truth)/σ of Gxx, Gyy, Gzz then scatters like Student's t
on the dof each parameter reports, not like a normal variable: read through t(ν) into a normal
score it has unit spread and no far outliers; read as a normal z it is far too wide (a
coverage of k = 2 would be a false promise)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from scipy import stats as sps

from host.model.components import fit_with_components
from host.model.dataset import load_dataset
from host.model.spec import parse_model
from tests.independent.simulate import SessionSpec, write_session

SESSIONS = 100
SCALES = ("Gxx", "Gyy", "Gzz")


def _pulls(tmp: Path, seed: int) -> list[tuple[float, float]]:
    """(pull, dof) of each gyro scale of one independent session."""
    d = tmp / f"s{seed}"
    write_session(d, SessionSpec(seed=seed, static_s=3.0, turns=1, warmup_s=60.0,
                                 turn_angle_sd_deg=0.5))  # fmt: skip
    truth = json.loads((d / "truth.json").read_text())["constants"]
    fit = fit_with_components(load_dataset(d), parse_model("base")).fit
    out = []
    for name in SCALES:
        p = fit.parameter(name)
        out.append(((p.value - truth[name]) / p.stderr, p.dof))
    return out


@pytest.mark.slow
@pytest.mark.timeout(600)
def test_gyro_scale_pulls_scatter_as_t_on_their_dof(tmp_path: Path) -> None:
    got = np.array([_pulls(tmp_path, 300 + k) for k in range(SESSIONS)])  # (n, 3, 2)
    pull, dof = got[..., 0], got[..., 1]
    assert np.all(np.isfinite(pull))
    # the turn angle is read from three closures: the scales' σ carry few dof
    assert np.all(dof < 30) and np.median(dof) < 8
    score = sps.norm.isf(sps.t.sf(pull, dof))  # t(ν) → N(0, 1)
    raw_sd, t_sd = pull.std(axis=0), score.std(axis=0)
    print(f"raw sd {np.round(raw_sd, 2)}, through t(ν) {np.round(t_sd, 2)}, "
          f"max |score| {np.abs(score).max():.2f}, median dof {np.median(dof):.1f}")  # fmt: skip
    assert np.all(raw_sd > 1.2)  # as a normal z it is too wide: the test can tell
    assert np.all((t_sd > 0.8) & (t_sd < 1.25)), t_sd
    assert np.abs(score).max() < 4.0
    # and the two-sided 95.45 % interval on t(ν) covers as it says (binomial 4 σ on 300)
    covered = np.abs(pull) <= sps.t.isf((1 - math.erf(2 / math.sqrt(2))) / 2, dof)
    assert abs(covered.mean() - 0.9545) < 4 * math.sqrt(0.9545 * 0.0455 / covered.size)
