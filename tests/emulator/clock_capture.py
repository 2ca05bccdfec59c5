"""The sixty-second real-time capture that ``test_emu_clock.py`` checks, run in a process of its
own: the AVR emulated at real time for 60 s (light on the CPU, ≈ 5 s), read through Link into
an IMUCAP01 capture by a reader the test process's own work cannot delay.

``python -m tests.emulator.clock_capture DIR``: build the firmware into ``DIR/fw``, capture
into ``DIR/emu60.cap``, then write ``DIR/summary.json`` (the emulator's summary, or the
error): its appearance says the capture is done. It ends by itself (60 emulated s; at most
100 s of reading).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
import traceback
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[2]
CAPTURE = "emu60.cap"
SUMMARY = "summary.json"
SECONDS = 60
#: the capture started by this process, held for its lifetime (a dropped Popen of a running
#: process is a ResourceWarning in the session's summary)
_STARTED: list[subprocess.Popen[bytes]] = []


def run_directory() -> Path:
    """This test run's capture directory: the same in every xdist worker of one run
    (``PYTEST_XDIST_TESTRUNUID``), the process's own otherwise."""
    uid = os.environ.get("PYTEST_XDIST_TESTRUNUID") or f"pid{os.getpid()}"
    return Path(tempfile.gettempdir()) / f"imu-bench-emu60-{uid}"


def start(directory: Path) -> bool:
    """Start the capture into ``directory`` unless this run has started it already (the
    directory exists); True when this call started it."""
    try:
        directory.mkdir()
    except FileExistsError:
        return False
    env = {**os.environ, "PYTHONPATH": str(ROOT), "OPENBLAS_NUM_THREADS": "1"}
    with open(directory / "log.txt", "wb") as log:
        proc = subprocess.Popen(
            [sys.executable, "-m", "tests.emulator.clock_capture", str(directory)],
            cwd=ROOT, env=env, stdin=subprocess.DEVNULL, stdout=log, stderr=log,
        )  # fmt: skip
    _STARTED.append(proc)
    return True


def wait(directory: Path, timeout_s: float) -> dict[str, Any]:
    """The capture's summary once it is done (``{"summary": ..., "hung_up": ...}``); an
    AssertionError with the capture's log if it failed or is not done within ``timeout_s``."""
    done = directory / SUMMARY
    deadline = time.monotonic() + timeout_s
    while not done.exists():
        if time.monotonic() > deadline:
            log = (directory / "log.txt").read_text(errors="replace")[-3000:]
            raise AssertionError(f"the capture in {directory} not done in {timeout_s} s:\n{log}")
        time.sleep(0.2)
    result: dict[str, Any] = json.loads(done.read_text())
    assert "error" not in result, result["error"]
    return result


def capture(directory: Path) -> dict[str, Any]:
    """60 s through Link (IMUCAP01) at ``speed=realtime``, read until the board stops
    answering after 60 emulated s (it hands over every byte it sent before it hangs up), so
    the capture holds every sample however late this host reads. (A 60 s wall-clock deadline
    dropped what was still in the pty, or not yet emulated, when it passed: 2933 samples once
    under load, 1.2 s short.)"""
    from host.bench import build
    from host.board.link import Link, LinkLost

    elf = build.build_firmware(directory / "fw")
    url = f"emu://?elf={elf}&speed=realtime&seed=8&seconds={SECONDS}"
    hung_up = False
    with Link.open(url, capture=directory / CAPTURE) as link:
        deadline = time.monotonic() + 100.0  # only if the emulator never ended
        try:
            while time.monotonic() < deadline:
                link.read_chunk()
        except LinkLost:
            hung_up = True
        port = link.port
    return {"summary": port.emulator_summary, "hung_up": hung_up}


def main(directory: Path) -> None:
    try:
        result = capture(directory)
    except Exception:  # the test reports it
        result = {"error": traceback.format_exc()}
    tmp = directory / (SUMMARY + ".tmp")
    tmp.write_text(json.dumps(result))
    tmp.replace(directory / SUMMARY)


if __name__ == "__main__":
    main(Path(sys.argv[1]))
