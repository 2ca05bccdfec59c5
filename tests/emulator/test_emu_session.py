"""The live calibration program against the emulated board (the real firmware in simavr), its
MPU-6000 fed by the physics simulator whose operator follows the program's prompts
(``emu://``, ``stimulus=sim``: host/transports/protocol_emu.py, host.bench.stimulus.SimStimulus).

Truth comparisons use ``effects=linear,noise&earth_rate=0`` as tests/host/dialogue/test_flow.py does
for ``sim://``: the other effects are outside the linear model of method.md §2. The dialogue
helpers are those of tests/host/dialogue/test_flow.py; the pty-driven dialogue (repeat, Esc, range
alarm, Ctrl+C and resume) runs on both boards in tests/host/dialogue/test_flow_pty.py.

Durations: statics of 10 s (the program warns they are short; the tolerances still hold),
1 turn (7 s windows), ``--ready-seconds 0``; at ``speed=max`` the emulator runs ≈ 30–40× real
time with the simulator feeding it, so a whole session takes ≈ 5 s of wall time.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from host.board.driver import Board
from host.dialogue.console import ScriptedConsole
from host.session.directory import read_record
from host.session.records import STATIC_NAMES, TURN_NAMES
from host.transports.protocol_emu import HINT_HOLD_S, HINT_SYNC_S, truth_for_url
from tests.host.dialogue.test_flow import Ports, opts, run

pytestmark = [
    pytest.mark.emulator,
    pytest.mark.skipif(sys.platform == "win32", reason="needs a POSIX pty"),
]

ROOT = Path(__file__).resolve().parents[2]
LINEAR = "effects=linear,noise&earth_rate=0"
#: calibration tolerances (scale and misalignment 1e-3 by default)
TOL = {"A0": 3e-3, "G0": 0.01, "GA": 0.005}


def truth_errors(url: str, got: dict[str, float]) -> dict[str, tuple[float, str]]:
    """Worst |recovered − true| / tolerance per group (S = scale & misalignment): (ratio, name)."""
    truth = truth_for_url(url)
    assert truth is not None
    worst: dict[str, tuple[float, str]] = {}
    for name, want in truth.constants().items():
        group = name[:2] if name[:2] in TOL else "S"
        ratio = abs(got[name] - want) / TOL.get(name[:2], 1e-3)
        if ratio > worst.get(group, (-1.0, ""))[0]:
            worst[group] = (ratio, name)
    return worst


# --------------------------------------------------------------------------- the URL


def test_simulator_options_of_the_url() -> None:
    """Plain emu:// is simulator-driven; stimulus=rest or a file is not (pure Python)."""
    from host.bench.options import SimOptions
    from host.transports.protocol_emu import parse_sim_options, parse_url

    assert parse_sim_options("emu://") == SimOptions()
    o = parse_sim_options(
        "emu://?seed=7&noise_seed=7&speed=4&truth=ideal&effects=linear,noise&earth_rate=0"
    )
    assert o == SimOptions(7, 4.0, "ideal", ("linear", "noise"), earth_rate=False, noise_seed=7)
    assert parse_sim_options("emu://?speed=realtime") == SimOptions(speed=1.0)
    assert parse_sim_options("emu://?stimulus=rest") is None
    assert parse_sim_options("emu://?stimulus=/x.stim") is None
    assert parse_url("emu://?speed=max&seed=3&noise_seed=3&operator=manual") == {"seed": 3}
    for bad in ("speed=0", "speed=fast", "truth=perfect", "operator=robot", "tilt=x"):
        with pytest.raises(ValueError, match="emu:// option"):
            parse_sim_options(f"emu://?{bad}")
    a, b = truth_for_url("emu://?seed=5&noise_seed=5"), truth_for_url("emu://?seed=5&noise_seed=5")
    assert a is not None and b is not None and a.constants() == b.constants()
    assert truth_for_url("emu://?stimulus=rest") is None


# --------------------------------------------------------------------------- the CLI, --yes


@pytest.mark.slow
def test_full_calibration_recovers_the_simulator_truth(tmp_path: Path, fw_elf: Path) -> None:
    """``python3 -m host calibrate --port emu://... --yes``: the real firmware measures the
    simulated cube through the whole dialogue, and the constants are the simulator's."""
    # seed 4: with 1 turn the gyro misalignments come out within ≈ 0.5e-3; some seeds reach
    # ≈ 1e-3 with 1 turn on sim:// just the same (the method, not the emulator: same numbers)
    url = f"emu://?elf={fw_elf}&seed=4&noise_seed=4&{LINEAR}"
    t0 = time.monotonic()
    proc = subprocess.run(
        [sys.executable, "-m", "host", "calibrate", "--port", url, "--serial", "E1", "--yes",
         "--warmup", "0", "--static-seconds", "10", "--turns", "1", "--ready-seconds", "0",
         "--json", "--out", "E1"],
        cwd=tmp_path, capture_output=True, text=True, timeout=180,
        env=dict(os.environ, PYTHONPATH=str(ROOT)), start_new_session=True,
    )  # fmt: skip
    wall = time.monotonic() - t0
    print(f"\nemu:// calibration (6 × 10 s statics, 6 × 1 turn): {wall:.1f} s wall")
    assert proc.returncode == 0, proc.stderr[-3000:]
    got = json.loads(proc.stdout)["constants"]
    worst = truth_errors(url, got)
    print("worst error / tolerance per group:", worst)
    for group, (ratio, name) in worst.items():
        assert ratio < 1.0, (group, name, ratio)
    out = tmp_path / "E1"
    for name in (*STATIC_NAMES, *TURN_NAMES, "x_up_2"):  # the closing check last
        rec = read_record(out / f"E1_{name}.txt")
        m = rec.meta
        assert m["lost_frames"] == "0" and m["missed_samples"] == "0", name
        assert m["port"] == url and m["firmware"] == "0.1.0"
        assert m["sensor_spi_clock"] == "8 MHz"  # a clean bus: no fallback (STATUS.flags)
        dt = np.diff(rec.t_ms)
        assert np.all(np.abs(dt - 20.0) < 0.1), name  # the firmware's own clock, exact AVR
        window = 7.0 if name in TURN_NAMES else 10.0
        assert window - 0.05 < rec.duration_s < window, name
    assert "Board: firmware 0.1.0" in proc.stderr


# --------------------------------------------------------------------------- a slow host


@pytest.mark.slow
@pytest.mark.timeout(120)  # one emulator run through the board driver
def test_the_start_beep_lands_at_the_same_emulated_instant_however_slow_the_host(
    fw_elf: Path,
) -> None:
    """After an operator hint the emulated time waits for the program's start beep (the PING
    of ``Board.acquire``, its next I/O): a host that is slow between the hint and the beep — as
    a loaded machine makes it — gets its measurement window at the same emulated instant after
    the hint as a quick one; a host that reads the board while it waits lets the time go on.
    (Before, at ``speed=max`` the emulator ran on meanwhile: a host 0.3 s slow moved the beep
    by 4.6–5.5 s of emulated time, and under load a turn, which starts 0.8–1.3 s after the
    hint, could be cut by the window's start: the calibration then failed.)
    """
    url = f"emu://?elf={fw_elf}&seed=4&noise_seed=4&{LINEAR}"
    board = Board(url)
    info = board.connect()
    delays: dict[float, list[float]] = {0.0: [], 0.3: []}
    try:
        for k, name in enumerate(("x_up", "y_up", "z_up", "x_dn", "y_dn", "z_dn")):
            slow_s = (0.0, 0.3)[k % 2]
            board.hint("place", name=name)
            hint_s = board.port.hints[-1][0]  # the emulated instant of the change, s
            time.sleep(slow_s)  # the slow host this test is about (not a wait for a result)
            acq = board.acquire(0.1)
            delays[slow_s].append(acq.beep_t_us / 1e6 - hint_s)
        # a person, not --yes: the dialogue reads the board while it waits for a key; the
        # reads let the emulated time go on (no "no data from the board" after 2 s)
        board.hint("place", name="z_up")
        hint_s = board.port.hints[-1][0]
        t_end = time.monotonic() + 2.5  # longer than the link's 2 s stall limit
        while time.monotonic() < t_end:
            board.pump()  # LinkTimeout here if the time stood still
        waited_s = board.port.sim_time - hint_s
    finally:
        board.close()
    assert waited_s > 1.0, waited_s
    print("\nbeep after the hint, s (quick host, 0.3 s slow host):", delays)
    # the beep (PONG) at the held instant: the emulator has got HINT_SYNC_S past the change;
    # it stops at the first sample period at or after HINT_HOLD_S, the PING's 12 bytes and
    # the 1 ms host poll follow (the device clock starts 0.24 ms after the emulated CPU)
    late = HINT_HOLD_S + 1.0 / info.rate_hz + 0.004
    for slow_s, ds in delays.items():
        assert all(HINT_SYNC_S - 0.001 <= d <= late for d in ds), (slow_s, ds)


# --------------------------------------------------------------------------- port trouble


@pytest.mark.slow
def test_emulator_killed_and_paused_mid_measurement(tmp_path: Path, fw_elf: Path) -> None:
    """The emulator process is killed during y_up (the port vanishes: LinkLost) and paused
    with SIGSTOP during z_up (a stalled device: LinkTimeout). Each time the session says so,
    keeps the accepted records, re-opens the port — which starts the emulator again with the
    same simulated sensor — and measures the interrupted orientation again."""
    url = f"emu://?elf={fw_elf}&seed=4&noise_seed=4&{LINEAR}"
    ports = Ports()
    events: dict[str, Any] = {"kept": {}}

    def board_pid() -> int:
        pid = ports.opened[0].board.pid
        assert pid is not None
        return int(pid)

    class Spy(ScriptedConsole):
        progress_calls: dict[str, int] = {}

        def progress(self, text: str) -> None:
            name = text.split(" ", 1)[0]
            k = self.progress_calls[name] = self.progress_calls.get(name, 0) + 1
            if k == 2 and name == "y_up" and "killed" not in events:
                for kept in ("x_up", "x_dn"):
                    events["kept"][kept] = (tmp_path / "S1" / f"S1_{kept}.txt").read_bytes()
                events["killed"] = board_pid()
                os.kill(events["killed"], signal.SIGKILL)
            elif k == 2 and name == "z_up" and "paused" not in events:
                events["paused"] = board_pid()
                events["paused_at"] = time.monotonic()
                os.kill(events["paused"], signal.SIGSTOP)

        def say(self, text: str = "") -> None:
            if "no data from the board" in text and "paused_at" in events:
                events["timeout_after_s"] = time.monotonic() - events["paused_at"]
            super().say(text)

    con = Spy()
    o = opts(tmp_path, url, static_seconds=20.0, turns=1, json=True, hello_timeout_s=30.0,
             reconnect_timeout_s=30.0)  # fmt: skip
    t0 = time.monotonic()
    try:
        rc, stdout = run(o, con, ports)
    finally:  # never leave a stopped process behind
        if "paused" in events:
            try:
                os.kill(events["paused"], signal.SIGCONT)
            except ProcessLookupError:
                pass
    after = events.get("timeout_after_s", float("nan"))
    print(
        f"\nsession with a kill and a pause: {time.monotonic() - t0:.1f} s wall; "
        f"timeout message {after:.2f} s after SIGSTOP"
    )
    assert rc in (0, 1), con.text[-2000:]
    text = con.text
    # the kill: a clear message, the measurement discarded, the accepted records kept
    assert "!!! the board disconnected" in text
    assert "The measurement in progress is discarded; accepted records are kept." in text
    assert text.count("The board is back") == 2
    assert "Measuring y_up again." in text and "Measuring z_up again." in text
    # the pause: the timeout message within ~2 s of the silence
    assert 1.9 < events["timeout_after_s"] < 3.5
    assert "!!! no data from the board for 2.0 s" in text
    out = tmp_path / "S1"
    for name, data in events["kept"].items():
        assert (out / f"S1_{name}.txt").read_bytes() == data  # not measured again
    assert len(list(out.glob("S1_*_*.txt"))) == 13  # with the closing check (x_up_2)
    # the sensor did not change with the emulator: the constants are still the truth's
    worst = truth_errors(url, json.loads(stdout)["constants"])
    print("worst error / tolerance per group:", worst)
    assert all(ratio < 1.0 for ratio, _ in worst.values()), worst
    assert ports.opened[0].board is None  # closed at the end: no emulator left running
    for pid in (events["killed"], events["paused"]):
        with pytest.raises(ProcessLookupError):
            os.kill(pid, 0)
