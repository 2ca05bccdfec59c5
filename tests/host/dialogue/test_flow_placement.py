"""The placement the dialogue asks for is the placement the model assumes and the placement the
simulated operator makes (issue 25, "placement is data").

One short ``--yes`` session on ``sim://``, and one on ``emu://`` (the real firmware in the
emulator, the same virtual operator placing the cube): every prompt is read as the operator
reads it (which arrow of the cube points where, and the heading number), and compared with
things written apart from the prompt's own code: the heading in the record's header, the plate's
axes the model derives from that header (:func:`host.model.geometry.plate_axes`), the face the
accelerometer measured gravity on, and the attitude the virtual bench put the cube in
(:func:`host.bench.physics.pose`).
"""

from __future__ import annotations

import contextlib
import io
import re
from pathlib import Path

import numpy as np
import pytest

from host.bench.physics import pose
from host.dialogue import flow, options
from host.dialogue.console import ScriptedConsole
from host.model.geometry import plate_axes
from host.session.directory import read_record
from host.session.records import HEADING_KEY, STATIC_NAMES, TURN_NAMES
from tests.host.dialogue.flat_options import flat_options
from tests.host.dialogue.test_flow_pty import emu_missing

#: the operator's words -> the room direction (east, north) of the arrow, with the fence
#: running left to right in front of the operator (east = right, north = toward the fence)
ROOM = {
    "pointing right, along the fence": (1.0, 0.0),
    "pointing at the fence": (0.0, 1.0),
    "pointing left, along the fence": (-1.0, 0.0),
    "pointing at you, away from the fence": (0.0, -1.0),
}
PROMPT = re.compile(
    r"Put the cube (?:on the base with )?(?P<face>[XYZ]) (?P<side>up|down), against the fence, "
    r"its (?P<arrow>[XYZ]) arrow (?P<where>[^(]+) \(placement heading (?P<deg>-?\d+)°\)\. "
    r"Press any key\."
)


def _dialogue(port: str, out: Path, serial: str) -> str:
    """A whole ``--yes`` session on ``port`` into ``out``; what the operator was shown."""
    o = flat_options(
        port=port, serial=serial, out=out, static_seconds=2.0, turns=1, warmup_s=0.0,
        yes=True, ready_s=0.0, hello_timeout_s=30.0,
    )  # fmt: skip
    con = ScriptedConsole()
    with contextlib.redirect_stdout(io.StringIO()):
        rc = flow.run_dialogue(o, con, None)
    assert rc in (0, 1), con.text[-2000:]
    return con.text


def _assert_prompts_match_records_model_and_bench(text: str, out: Path, serial: str) -> None:
    """Each prompt, read as the operator reads it, against the record's header, the model's
    plate axes from that header, and the attitude the virtual bench put the cube in."""
    prompts = [m for m in PROMPT.finditer(text)]
    names = [*STATIC_NAMES, *TURN_NAMES, options.CLOSING_NAME]
    assert len(prompts) == len(names), text
    for name, m in zip(names, prompts, strict=True):
        rec = read_record(out / f"{serial}_{name}.txt")
        axis = name[0]
        assert m["face"].lower() == axis
        assert (m["side"] == "down") == name.endswith("_dn")
        # the header carries the number the operator was told
        assert HEADING_KEY in rec.meta
        assert rec.placement_heading_deg == float(m["deg"]) % 360.0
        arrow = np.eye(3)["xyz".index(m["arrow"].lower())]
        want = np.array(ROOM[m["where"]])
        # the model: the arrow's room direction from the header's heading
        east, north = plate_axes(rec.up, np.radians([rec.placement_heading_deg]))
        got = np.array([east[0] @ arrow, north[0] @ arrow])
        np.testing.assert_allclose(got, want, atol=1e-12, err_msg=name)
        # the measurement: gravity lies along the face the prompt named
        acc = rec.accel.mean(axis=0)
        assert acc @ rec.up > 0.99 * np.linalg.norm(acc), (name, acc)
        # the simulated operator: the bench's attitude (rows = east, north, up in body axes)
        r = pose(f"{axis}_{'up' if name in TURN_NAMES else name.split('_')[1]}")
        np.testing.assert_allclose([r[0] @ arrow, r[1] @ arrow], want, atol=1e-12, err_msg=name)


@pytest.mark.slow
def test_every_prompt_names_the_placement_the_record_and_the_model_carry(
    tmp_path: Path,
) -> None:
    text = _dialogue("sim://?seed=5&noise_seed=5&speed=max", tmp_path / "P1", "P1")
    _assert_prompts_match_records_model_and_bench(text, tmp_path / "P1", "P1")


@pytest.mark.emulator
@pytest.mark.slow
@pytest.mark.skipif(emu_missing() is not None, reason=str(emu_missing()))
def test_on_the_real_firmware_every_prompt_names_the_placement_the_record_carries(
    tmp_path: Path,
) -> None:
    """``emu://``: the firmware measures, the host's dialogue prompts and writes the headers;
    the same virtual operator places the cube as told."""
    text = _dialogue("emu://", tmp_path / "E1", "E1")
    _assert_prompts_match_records_model_and_bench(text, tmp_path / "E1", "E1")


def test_a_header_heading_is_read_and_a_bad_one_refused(tmp_path: Path) -> None:
    from host.session.records import Record, RecordError

    def rec(value: str | None) -> Record:
        meta = {} if value is None else {HEADING_KEY: value}
        z = np.zeros((2, 3))
        return Record("x_up", np.array([0.0, 20.0]), z, z, np.zeros(2), meta)

    assert rec(None).placement_heading_deg is None
    assert rec("-90").placement_heading_deg == 270.0
    with pytest.raises(RecordError, match=HEADING_KEY):
        _ = rec("east").placement_heading_deg
