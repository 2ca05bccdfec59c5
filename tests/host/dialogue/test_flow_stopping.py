"""``calibrate --plan adaptive`` on the virtual board: a face ends when the σ of its mean meets
the target (at least the method's 10 s, at most ``--static-seconds``), turn pairs about an axis
continue until its gyro scale meets it, and every such record says why it stopped."""

from __future__ import annotations

import contextlib
import io
import json
import re
from pathlib import Path

import pytest

from host.calib.provenance import Provenance
from host.dialogue import flow
from host.dialogue.console import ScriptedConsole
from host.session.directory import read_session
from host.session.records import STATIC_NAMES, STOPPED_KEY
from host.workbench.stopping import TURN_PAIRS_MAX
from tests.host.dialogue.flat_options import flat_options
from tests.host.dialogue.test_flow_pty import emu_missing


def _run(tmp: Path, **kw: object) -> tuple[str, Path]:
    o = flat_options(
        port="sim://?seed=4&noise_seed=4&speed=max", serial="ST1", out=tmp / "ST1", turns=1,
        warmup_s=0.0,
        yes=True, ready_s=0.0, plan="adaptive", max_extra=0, closing=False, **kw,  # type: ignore[arg-type]
    )  # fmt: skip
    con = ScriptedConsole()
    with contextlib.redirect_stdout(io.StringIO()):
        flow.run_dialogue(o, con, None)
    return con.text, tmp / "ST1"


@pytest.mark.slow
def test_faces_stop_when_their_mean_is_precise_enough(tmp_path: Path) -> None:
    text, out = _run(tmp_path, static_seconds=40.0, target=0.5)
    recs = read_session(out).records
    for name in STATIC_NAMES:
        r = recs[name]
        assert 9.9 <= r.duration_s <= 12.0, (name, r.duration_s)  # the minimum, far below 40 s
        assert r.meta[STOPPED_KEY].startswith("σ of the mean met its target at 1"), r.meta
    # a loose target: one pair about each axis, and the cw turn of it says so
    assert {n for n in recs if "_c" in n} == {f"{a}_{d}" for a in "xyz" for d in ("ccw", "cw")}
    for a in "xyz":
        assert re.match(
            r"gyro scale σ/tolerance \S+ met the target 0.5", recs[f"{a}_cw"].meta[STOPPED_KEY]
        )
    assert "Each face ends when its mean is precise enough" in text
    # the report's procedure says why each stopped; the result file keeps it
    report = (out / "ST1_result.txt").read_text()
    assert "Stopped when they had enough (--plan adaptive):" in report
    assert re.search(r"\n    z_dn: σ of the mean met its target at 1\d s", report)
    doc = json.loads((out / "ST1_result.json").read_text())
    assert Provenance.from_dict(doc["provenance"]).stopped == {
        n: r.meta[STOPPED_KEY] for n, r in recs.items() if STOPPED_KEY in r.meta
    }


@pytest.mark.slow
def test_a_target_out_of_reach_measures_the_maximum_and_says_so(tmp_path: Path) -> None:
    _, out = _run(tmp_path, static_seconds=11.0, target=1e-4)
    recs = read_session(out).records
    for name in STATIC_NAMES:
        assert recs[name].duration_s == pytest.approx(11.0, abs=0.1)
        assert "the maximum, target not met" in recs[name].meta[STOPPED_KEY]
    # each axis's turns: pairs up to the maximum while another pair lowers the σ, or one pair
    # when the model's misfit alone sets it (issue 46: never plan what does not help)
    for a in "xyz":
        cws = sorted(n for n in recs if n.startswith(f"{a}_cw"))
        assert sum(n.startswith(f"{a}_ccw") for n in recs) == len(cws)
        first = recs[f"{a}_cw"].meta[STOPPED_KEY]
        if len(cws) == TURN_PAIRS_MAX:
            assert "another pair follows" in first
            assert f"the maximum of {TURN_PAIRS_MAX} pairs" in recs[cws[-1]].meta[STOPPED_KEY]
        else:
            assert len(cws) == 1, cws
            assert "the model's misfit sets" in first and "another pair does not lower" in first


@pytest.mark.emulator
@pytest.mark.slow
@pytest.mark.skipif(emu_missing() is not None, reason=str(emu_missing()))
def test_the_adaptive_dialogue_runs_end_to_end_on_the_real_firmware(tmp_path: Path) -> None:
    """``emu://``: the firmware in the emulator, its virtual operator placing and turning."""
    o = flat_options(
        port="emu://", serial="EM1", out=tmp_path / "EM1", turns=1, warmup_s=0.0, yes=True,
        ready_s=0.0, plan="adaptive", target=10.0, max_extra=1, static_seconds=3.0,
        hello_timeout_s=30.0,
    )  # fmt: skip
    con = ScriptedConsole()
    with contextlib.redirect_stdout(io.StringIO()):
        rc = flow.run_dialogue(o, con, None)
    assert rc in (0, 1), con.text[-2000:]
    recs = read_session(tmp_path / "EM1").records
    assert set(STATIC_NAMES) <= set(recs)
    for name in STATIC_NAMES:  # 3 s is the maximum (and the minimum: shorter than 10 s)
        assert recs[name].duration_s == pytest.approx(3.0, abs=0.1)
        assert recs[name].meta[STOPPED_KEY].startswith("σ of the mean met its target at 3 s")
    for a in "xyz":
        assert "met the target 10" in recs[f"{a}_cw"].meta[STOPPED_KEY]
    assert re.search(r"Adaptive plan: worst σ/tolerance \S+ \(\w+\): target 10 met", con.text)
    assert "Results:" in con.text
