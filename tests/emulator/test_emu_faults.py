"""An unattended ``--yes`` session on the real firmware whose sensor fails (issue 17) ends
within a minute with exit 2, one line naming the board's reason and the ``--resume`` hint,
and keeps the records accepted before the fault — from the start and after the first record,
for every sensor fault the emulator injects (``emu://?fault=...``, host/bench/emulator.py
SENSOR_FAULTS; the bus fault the firmware survives is in test_emu_identity.py).

Before this, ``no-drdy`` (and ``absent``/``stuck-miso`` starting after the first record) waited
forever at ``0.0/5 s``: the board keeps sending STATUS and ERROR frames, so the link's silence
timeout never fired.
"""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import pytest

from host.bench.emulator import SENSOR_FAULTS
from tests.host.cli.cli_run import command_after, too_wide

pytestmark = [pytest.mark.emulator, pytest.mark.slow]

ROOT = Path(__file__).resolve().parents[2]
#: emulated seconds at which a late fault starts: after the first 3 s static even when the
#: emulator runs seconds ahead of the session (what the pty holds at a start beep is dropped),
#: and before the session's ≥ 60 s of measurements end
LATE_S = 20.0


# a whole CLI session on the emulated board, itself bounded at 60 s
@pytest.mark.timeout(90)
@pytest.mark.parametrize("fault_at", [0.0, LATE_S], ids=["from-start", "after-records"])
@pytest.mark.parametrize("fault", SENSOR_FAULTS)
def test_yes_session_on_a_failed_sensor_ends_with_exit_2(
    emu_toolchain: None, tmp_path: Path, fault: str, fault_at: float
) -> None:
    url = f"emu://?fault={fault}&fault_at={fault_at:g}"
    out = tmp_path / "F1"
    t0 = time.monotonic()
    proc = subprocess.run(
        [sys.executable, "-m", "host", "calibrate", "--port", url, "--serial", "F1",
         "--out", str(out), "--yes", "--warmup", "0", "--static-seconds", "3", "--turns", "1"],
        cwd=ROOT, capture_output=True, text=True, timeout=60,
    )  # fmt: skip
    took = time.monotonic() - t0
    assert proc.returncode == 2, proc.stdout[-2000:] + proc.stderr
    assert took < 60
    # the dialogue talks on stderr; it ends with one error (its command on lines of its own)
    said = proc.stderr[proc.stderr.find("error: ") :]
    assert proc.stderr.count("error: ") == 1, proc.stderr
    assert "Traceback" not in proc.stderr + proc.stdout
    flat = " ".join(said.split())
    if fault_at == 0.0 and fault != "no-drdy":
        # absent / stuck-miso from reset: WHO_AM_I in HELLO already says so
        assert "WHO_AM_I" in flat and "no sensor answers on SPI" in flat
        return
    assert "the board reports ERROR" in flat or "no samples from the board" in flat
    # the printed command carries every option given (test_session_resume.py reads it back),
    # on lines of its own within 80 columns (a plain one-line error may run longer)
    assert too_wide(said) == [], said
    argv = command_after(said)
    i = argv.index("--serial")
    assert argv[i : i + 10] == ["--serial", "F1", "--out", str(out), "--static-seconds", "3",
                                "--turns", "1", "--warmup", "0"]  # fmt: skip
    assert argv[-2:] == ["--yes", "--resume"]
    kept = sorted(p.name for p in out.glob("F1_*_*.txt"))
    if fault_at > 0:
        assert "F1_x_up.txt" in kept, kept  # accepted before the fault: kept
        assert f"{len(kept)} accepted records are kept" in flat
    else:
        assert kept == []
