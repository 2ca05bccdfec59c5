"""A live session always makes progress or ends (issue 17): a board that keeps talking
(STATUS, ERROR) but sends no samples is a stalled board; a sensor ERROR frame during a
measurement stops it with the board's reason; under ``--yes`` both end the session with
exit 2 and the ``--resume`` hint, keeping the records already accepted.

The board is ``sim://`` at ``speed=max`` behind :class:`SensorDies`, which lets the frames
through until the sensor "fails", then drops every IMU_SAMPLE (and optionally adds ERROR frames
as the firmware's fault state does, once a second). The real firmware's faults (``emu://``) are
in tests/emulator/test_emu_faults.py.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import pytest

from host.calib.records import read_record
from host.dialogue.console import CTRL_C, ScriptedConsole
from host.errors import UserError
from host.wire import protocol_gen as gen
from host.wire.frames import IMU_SAMPLE, StreamDecoder, _envelope, encode_frame
from tests.host.test_session import LINEAR, Ports, opts, run

SPI_FAULT = gen.ENUMS["error_code"]["SPI_FAULT"]


class SensorDies:
    """Wraps a sim port: after ``after_s`` simulated seconds no IMU sample passes any more;
    every ``error_every_s`` host seconds an ERROR frame ``code`` is added (None: none)."""

    def __init__(
        self, inner: Any, after_s: float, code: int | None = None, error_every_s: float = 0.3
    ) -> None:
        self.inner = inner
        self.after_s = after_s
        self.code = code
        self.error_every_s = error_every_s
        self.dec = StreamDecoder()
        self.next_error = 0.0
        self.dead_since: float | None = None

    @property
    def in_waiting(self) -> int:
        return 0

    def read(self, n: int = 1) -> bytes:
        data = self.inner.read(max(n, 64))
        if self.inner.sim_time < self.after_s:
            return bytes(data)
        if self.dead_since is None:
            self.dead_since = time.monotonic()
        out = b"".join(raw for raw, f in self.dec.feed_raw(data) if f.type != IMU_SAMPLE)
        now = time.monotonic()
        if self.code is not None and now >= self.next_error:
            self.next_error = now + self.error_every_s
            out += encode_frame("ERROR", 0, code=self.code, detail=0x2A, count=1)
        time.sleep(0.01)  # a board's pace, not a busy loop
        return out

    def __getattr__(self, name: str) -> Any:
        return getattr(self.inner, name)


def dies(after_s: float, code: int | None = None) -> Ports:
    return Ports(wrap=lambda p: SensorDies(p, after_s, code))


@pytest.mark.timeout(60)
def test_yes_stalled_board_ends_with_resume_hint(tmp_path: Path) -> None:
    """STATUS keeps arriving, samples do not (the no-drdy hang): exit within the stall time."""
    o = opts(tmp_path, f"sim://?seed=21&{LINEAR}", static_seconds=3.0, sample_stall_s=1.5)
    ports = dies(after_s=5.0)
    t0 = time.monotonic()
    with pytest.raises(UserError) as err:
        run(o, ScriptedConsole(), ports)
    msg = str(err.value)
    assert "no samples from the board for 1.5 s" in msg
    assert "--resume" in msg and "--serial S1" in msg
    assert time.monotonic() - t0 < 30
    # the first static (3 s of sim time before the sensor died at 5 s) is kept, whole
    kept = sorted(p.name for p in (tmp_path / "S1").glob("S1_*_*.txt"))
    assert kept == ["S1_x_up.txt"]
    assert read_record(tmp_path / "S1" / "S1_x_up.txt").duration_s > 2.9


@pytest.mark.timeout(60)
def test_sensor_error_frame_stops_the_measurement_with_its_reason(tmp_path: Path) -> None:
    o = opts(tmp_path, f"sim://?seed=22&{LINEAR}", static_seconds=3.0, sample_stall_s=30.0)
    con = ScriptedConsole()
    t0 = time.monotonic()
    with pytest.raises(UserError, match=r"x_dn: the board reports ERROR SPI_FAULT \(detail 0x2a"):
        run(o, con, dies(after_s=5.0, code=SPI_FAULT))
    # the ERROR stopped it, not the (here 30 s) stall timer
    assert time.monotonic() - t0 < 20
    assert "the measurement of x_dn is discarded" in con.text


@pytest.mark.timeout(60)
def test_bad_command_error_is_not_a_sensor_fault(tmp_path: Path) -> None:
    """ERROR BAD_COMMAND answers a command: reported, but samples flowing is what counts."""

    class Noisy(SensorDies):
        """Sends the board a command it does not know every 0.5 s (it answers ERROR
        BAD_COMMAND, in its own sequence)."""

        def read(self, n: int = 1) -> bytes:
            if time.monotonic() >= self.next_error:
                self.next_error = time.monotonic() + 0.5
                self.inner.write(_envelope(0x90, 0, b""))
            return bytes(self.inner.read(n))

    o = opts(tmp_path, f"sim://?seed=23&{LINEAR}", static_seconds=2.0, turns=1)
    con = ScriptedConsole()
    rc, _ = run(o, con, Ports(wrap=lambda p: Noisy(p, 0.0)))
    assert rc in (0, 1)
    assert "ERROR BAD_COMMAND" in con.text


@pytest.mark.timeout(60)
def test_interactive_sensor_fault_offers_again_or_stop(tmp_path: Path) -> None:
    """Without --yes the operator decides: N stops with the resume hint."""
    o = opts(tmp_path, f"sim://?seed=24&{LINEAR}", static_seconds=3.0, yes=False,
             sample_stall_s=1.0)  # fmt: skip
    # serial given; keys: stage 1 Y, place x_up, save Y, place x_dn (the sensor dies), stop N
    con = ScriptedConsole(["y", " ", "y", " ", "n", CTRL_C])
    with pytest.raises(UserError, match=r"x_dn: no samples .* continue with: .*--resume"):
        run(o, con, dies(after_s=5.0))
    assert "Measure again <Y> or stop <N>?" in con.text
    assert (tmp_path / "S1" / "S1_x_up.txt").exists()


@pytest.mark.timeout(60)
def test_disk_full_in_a_live_session_names_the_record_and_prints_the_resume_hint(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Was: the error named a hidden temp file and the session ended without the hint."""
    import errno
    import os

    real = os.fsync
    calls = {"k": 0}

    def fsync(fd: int) -> None:
        calls["k"] += 1
        if calls["k"] == 2:  # the second record finds the disk full
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        real(fd)

    monkeypatch.setattr(os, "fsync", fsync)
    o = opts(tmp_path, f"sim://?seed=25&{LINEAR}", static_seconds=2.0)
    with pytest.raises(UserError) as err:
        run(o, ScriptedConsole(), Ports())
    msg = str(err.value)
    out = tmp_path / "S1"
    assert f"cannot write {out / 'S1_x_dn.txt'}: the disk is full" in msg
    assert ".tmp" not in msg
    assert f"1 accepted records are kept in {out}; continue with:" in msg and "--resume" in msg
    assert sorted(p.name for p in out.glob("S1_*_*.txt")) == ["S1_x_up.txt"]
