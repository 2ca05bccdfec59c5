"""What the dialogue shows (host/dialogue/screens.py): the progress line of a measurement."""

from __future__ import annotations

import re

import numpy as np
import pytest

from host.board.driver import BoardInfo
from host.dialogue.console import Questions, ScriptedConsole
from host.dialogue.screens import measurement_progress, whole_parts
from host.wire import sensor

INFO = BoardInfo(firmware="0.1.0", protocol_version=2, spec_fingerprint=0, who_am_i=0x68,
                 accel_fs_sel=0, gyro_fs_sel=0, dlpf_cfg=4, smplrt_div=19, streaming=True,
                 reset_cause=0)  # fmt: skip


@pytest.mark.parametrize("name", ["x_up", "x_up_2", "z_dn"])
@pytest.mark.parametrize("seconds", [3.0, 10.0, 120.0])
def test_the_progress_line_fits_80_columns_with_whole_numbers(name: str, seconds: float) -> None:
    """The closing record (the longest name) at the widest means a resting unit shows: every
    number whole (a cut '-0.53' would read as another value), within 79 columns."""
    con = ScriptedConsole(columns=80)
    tick = measurement_progress(Questions(con), name, seconds, INFO)
    a = sensor.G0 / INFO.accel_lsb_per_g
    g = 1.0 / sensor.GYRO_LSB_PER_DPS[0]
    means = np.array([-10.124 / a, -0.999 / a, -0.999 / a, 0, -9.999 / g, -9.999 / g, -9.999 / g])
    tick(seconds - 0.1, means * 50, 50)
    line = con.progress_lines[-1]
    assert len(line) <= 79, line
    assert re.search(r" A -10\.12 -1\.00 -1\.00 m/s²", line), line
    # the gyro means whole with their unit, or left out whole
    assert line.endswith(("-10.00 °/s", "-1.00 m/s²")), line


def test_whole_parts_leaves_out_what_does_not_fit_whole() -> None:
    assert whole_parts(20, "head", "A 1 2 3", "G 4 5 6") == "head  A 1 2 3"
    assert whole_parts(80, "head", "A 1 2 3", "G 4 5 6") == "head  A 1 2 3  G 4 5 6"
