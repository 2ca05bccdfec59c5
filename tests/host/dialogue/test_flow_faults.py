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

import contextlib
import io
import time
from pathlib import Path
from typing import Any

import pytest

from host.dialogue.console import CTRL_C, ScriptedConsole
from host.errors import UserError
from host.session.directory import read_record
from host.wire import protocol_gen as gen
from host.wire.frames import IMU_SAMPLE, _envelope, encode_frame
from host.wire.stream import StreamDecoder
from tests.host.cli.cli_run import command_after, too_wide
from tests.host.dialogue.test_flow import LINEAR, Ports, opts, run

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
    o = opts(
        tmp_path, f"sim://?seed=21&noise_seed=21&{LINEAR}", static_seconds=3.0, sample_stall_s=1.5
    )
    ports = dies(after_s=5.0)
    t0 = time.monotonic()
    with pytest.raises(UserError) as err:
        run(o, ScriptedConsole(), ports)
    msg = str(err.value)
    assert "no samples from the board for 1.5 s" in msg
    assert command_after(msg)[-1] == "--resume" and "S1" in command_after(msg)
    assert time.monotonic() - t0 < 30
    # the first static (3 s of sim time before the sensor died at 5 s) is kept, whole
    kept = sorted(p.name for p in (tmp_path / "S1").glob("S1_*_*.txt"))
    assert kept == ["S1_x_up.txt"]
    assert read_record(tmp_path / "S1" / "S1_x_up.txt").duration_s > 2.9


@pytest.mark.timeout(60)
def test_sensor_error_frame_stops_the_measurement_with_its_reason(tmp_path: Path) -> None:
    o = opts(
        tmp_path, f"sim://?seed=22&noise_seed=22&{LINEAR}", static_seconds=3.0, sample_stall_s=30.0
    )
    con = ScriptedConsole()
    t0 = time.monotonic()
    with pytest.raises(UserError, match=r"x_dn: the board reports ERROR SPI_FAULT \(detail 0x2a"):
        run(o, con, dies(after_s=5.0, code=SPI_FAULT))
    # the ERROR stopped it, not the (here 30 s) stall timer
    assert time.monotonic() - t0 < 20
    assert "the measurement of x_dn is discarded" in con.text


@pytest.mark.slow
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

    o = opts(tmp_path, f"sim://?seed=23&noise_seed=23&{LINEAR}", static_seconds=2.0, turns=1)
    con = ScriptedConsole()
    rc, _ = run(o, con, Ports(wrap=lambda p: Noisy(p, 0.0)))
    assert rc in (0, 1)
    assert "ERROR BAD_COMMAND" in con.text


@pytest.mark.timeout(60)
def test_interactive_sensor_fault_offers_again_or_stop(tmp_path: Path) -> None:
    """Without --yes the operator decides: N stops with the resume hint."""
    o = opts(tmp_path, f"sim://?seed=24&noise_seed=24&{LINEAR}", static_seconds=3.0, yes=False,
             sample_stall_s=1.0)  # fmt: skip
    # serial given; keys: stage 1 Y, place x_up, save Y, place x_dn (the sensor dies), stop N
    con = ScriptedConsole(["y", " ", "y", " ", "n", CTRL_C])
    with pytest.raises(UserError, match=r"(?s)x_dn: no samples .*\swith:\n.*--resume"):
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
    o = opts(tmp_path, f"sim://?seed=25&noise_seed=25&{LINEAR}", static_seconds=2.0)
    with pytest.raises(UserError) as err:
        run(o, ScriptedConsole(), Ports())
    msg = " ".join(str(err.value).split())  # the sentence, wrapped at words
    out = tmp_path / "S1"
    assert f"cannot write {out / 'S1_x_dn.txt'}: the disk is full" in msg
    assert ".tmp" not in msg
    assert f"1 accepted records are kept in {out}; continue with:" in " ".join(msg.split())
    assert command_after(str(err.value))[-1] == "--resume"
    assert sorted(p.name for p in out.glob("S1_*_*.txt")) == ["S1_x_up.txt"]


class FillingFile:
    """A file on a disk with ``room`` bytes left: the write that does not fit writes what
    fits, then fails with ENOSPC (as a real full disk does)."""

    def __init__(self, f: Any, room: int) -> None:
        self.f = f
        self.room = room

    def write(self, data: bytes) -> int:
        import errno
        import os

        if len(data) > self.room:
            self.f.write(data[: self.room])
            self.f.flush()
            self.room = 0
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        self.room -= len(data)
        return int(self.f.write(data))

    def __getattr__(self, name: str) -> Any:
        return getattr(self.f, name)


def session_records(out: Path) -> dict[str, int]:
    """Record name -> data rows, of every record file in ``out`` (each must read whole)."""
    return {p.stem.split("_", 1)[1]: read_record(p).t_ms.size for p in out.glob("S1_*_*.txt")}


@pytest.mark.timeout(90)
@pytest.mark.slow
def test_disk_full_on_the_session_capture_keeps_what_was_recorded(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The raw capture of a live session (SERIAL_session.cap) meets a full disk mid-session:
    one line naming it, the --resume hint; the records accepted before stay whole and the
    capture keeps every read written before (a cut-off last one is reported, not fatal)."""
    from host.board import driver
    from host.wire import capture
    from host.wire.bulk import decode_bulk

    real_start = driver.DeferredCapture.start

    written = {}

    def start(self: Any, path: Path) -> None:
        real_start(self, path)
        self._f.flush()
        written["before"] = self._f.tell()  # the magic and the reads held until now
        self._f = FillingFile(self._f, 60_000)  # ≈ 40 s of the board's stream

    monkeypatch.setattr(driver.DeferredCapture, "start", start)
    o = opts(tmp_path, f"sim://?seed=26&noise_seed=26&{LINEAR}", static_seconds=2.0, turns=1)
    with pytest.raises(UserError) as err:
        run(o, ScriptedConsole(), Ports())
    said = str(err.value)
    msg = " ".join(said.split())  # the sentence, wrapped at words
    out = tmp_path / "S1"
    cap = out / "S1_session.cap"
    assert f"cannot write {cap}: the disk is full; what was read before is in it" in msg
    assert too_wide(said) == [] and command_after(said)[-1] == "--resume"
    assert "accepted records are kept" in msg
    kept = session_records(out)
    assert kept and all(n >= 2 for n in kept.values())  # each whole, as accepted
    assert f"{len(kept)} accepted records are kept" in msg
    assert cap.stat().st_size == written["before"] + 60_000  # everything that fitted is there
    c = capture.read(cap)  # parses: complete reads kept, the cut-off one reported
    assert c.truncated_bytes > 0 and len(c.data) > 0
    r = decode_bulk(c.data)
    assert r.stats.crc_errors == 0
    # the accepted records' samples came through this capture: it holds at least as many
    assert r.samples.size >= sum(kept.values())


@pytest.mark.timeout(120)
@pytest.mark.slow
def test_a_really_full_disk_in_a_live_session_then_resume(tmp_path: Path) -> None:
    """No injection: the output directory is a 128 KiB tmpfs. Whichever file meets the full disk
    first (the capture or a record), the session ends with one error line and the resume
    hint; with space again, that command finishes the session from the records kept."""
    import subprocess

    from host.__main__ import main

    disk = tmp_path / "disk"
    disk.mkdir()
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=128k", "tmpfs", str(disk)],
                       capture_output=True, check=False)  # fmt: skip
    if r.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here: {r.stderr.decode(errors='replace').strip()}")
    try:
        out = disk / "S1"
        argv = ["calibrate", "--port", f"sim://?seed=27&noise_seed=27&{LINEAR}", "--serial", "S1",
                "--yes",
                "--warmup", "0", "--static-seconds", "4", "--turns", "1",
                "--out", str(out)]  # fmt: skip
        err = io.StringIO()
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
            rc = main(argv)
        said = err.getvalue()[err.getvalue().index("error:") :]
        assert rc == 2 and said.count("error:") == 1, err.getvalue()[-1500:]
        assert "the disk is full" in " ".join(said.split()) and too_wide(said) == []
        assert command_after(said)[-1] == "--resume"
        assert "Traceback" not in err.getvalue()
        kept = session_records(out)  # every record on the disk reads whole
        assert 0 < len(kept) < 10
        assert not [p for p in out.iterdir() if p.name.startswith(".")]  # no temp files left
        # space again (the tmpfs grows), and the printed command finishes the session
        subprocess.run(["mount", "-o", "remount,size=4m", str(disk)], check=True)
        with contextlib.redirect_stderr(io.StringIO()), contextlib.redirect_stdout(io.StringIO()):
            rc = main([*argv, "--resume"])
        assert rc in (0, 1)
        assert set(kept) < set(session_records(out))  # the kept ones were not re-measured
        assert (out / "S1_result.json").exists()
    finally:
        subprocess.run(["umount", "-l", str(disk)], check=False)
