"""Records whose time stamps repeat or step in 30–100 ms quanta (what ``import`` writes from a
logger stamping 0.1 s) go through ``calibrate --from-dir``, ``model diagnose`` and ``model
ladder`` like any other session: no division by a zero time step (issue 31, item 9)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from host.__main__ import main
from host.bench.plan import write_session
from host.session.records import Record
from host.workbench.scenarios import hidden_effect_case


@pytest.fixture(scope="module", params=[100.0, 30.0])
def quantised(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A session whose every record's t_ms is floored to the quantum (ms)."""
    q = request.param
    d = tmp_path_factory.mktemp(f"q{q:.0f}")
    recs = {
        n: Record(r.name, np.floor(np.asarray(r.t_ms) / q) * q, r.accel, r.gyro, r.temp, r.meta)
        for n, r in hidden_effect_case("temperature", 2).records.items()
    }
    write_session(d, "Q1", recs)
    return d


@pytest.mark.slow
def test_calibrate_and_diagnose_quantised_time_stamps(
    quantised: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # a verdict, not an error: the hidden temperature bias widens U, so the guarded decision
    # rule may end on FAIL (exit 1); an error would be exit 2 and no result file
    assert main(["calibrate", "--from-dir", str(quantised), "--no-archive"]) in (0, 1)
    assert "Verdict: " in capsys.readouterr().out
    assert (quantised / "Q1_result.json").exists()
    assert main(["model", "diagnose", str(quantised)]) == 0
    out = capsys.readouterr().out
    # the hidden effect is still found: the derivative did not turn the turns into noise
    assert "temperature_bias" in out and "== verdict: missing_effect" in out


@pytest.mark.slow
def test_ladder_quantised_time_stamps(quantised: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["model", "ladder", str(quantised)]) == 0
    assert "final model:" in capsys.readouterr().out
