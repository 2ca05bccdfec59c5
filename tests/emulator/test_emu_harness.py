"""The emulator harness itself, proven with its own small test firmware (testapp/testapp.c) and
pure-Python checks of the stimulus format and the emu:// URL grammar."""

from __future__ import annotations

import numpy as np
import pytest
import serial
from emu_helpers import collect, of_type, sample_counts, seq_gaps

from host.bench import build
from host.bench.emulator import EmulatedBoard
from host.bench.stimulus import read_stimulus, write_stimulus
from host.errors import UserError
from host.transports.protocol_emu import parse_url
from host.wire.frames import encode_frame


# ------------------------------------------------------------------ no simavr needed
def test_stimulus_round_trip(tmp_path):
    t = np.array([0.0, 0.5, 1.0])
    f = np.arange(9.0).reshape(3, 3)
    w = -np.arange(9.0).reshape(3, 3)
    path = tmp_path / "s.bin"
    write_stimulus(path, t, f, w, 30.0)
    raw = path.read_bytes()
    assert raw[:8] == b"IMUSTIM1" and len(raw) == 16 + 3 * 8 * 8
    rec = read_stimulus(path)
    assert rec.shape == (3, 8)
    np.testing.assert_array_equal(rec[:, 0], t)
    np.testing.assert_array_equal(rec[:, 1:4], f)
    np.testing.assert_array_equal(rec[:, 4:7], w)
    np.testing.assert_array_equal(rec[:, 7], 30.0)


def test_stimulus_rejects_decreasing_time(tmp_path):
    with pytest.raises(ValueError):
        write_stimulus(tmp_path / "s.bin", [1.0, 0.0], np.zeros((2, 3)), np.zeros((2, 3)), 25.0)


def test_url_grammar():
    kw = parse_url(
        "emu://?seconds=2.5&realtime=1&fault=no-drdy&fault_at=3&seed=7&noise_seed=7&stimulus=/x"
    )
    assert kw == {
        "seconds": 2.5,
        "realtime": True,
        "fault": "no-drdy",
        "fault_at": 3.0,
        "seed": 7,
        "stimulus": "/x",
    }
    assert parse_url("emu://") == {}
    with pytest.raises(ValueError):
        parse_url("emu://?fault=melted")
    with pytest.raises(ValueError):
        parse_url("emu://?colour=red")


def test_missing_toolchain_is_one_clear_line(monkeypatch):
    monkeypatch.setattr(build, "SIMAVR_HEADER", build.Path("/nonexistent/sim_avr.h"))
    with pytest.raises(UserError) as err:
        build.build_emulator()
    assert str(err.value) == (
        "emu:// needs simavr: apt-get install simavr libsimavr-dev gcc-avr avr-libc"
    )


def test_bad_fault_name():
    with pytest.raises(UserError):
        EmulatedBoard("x.elf", fault="melted")


# ------------------------------------------------------------------ with the test firmware
@pytest.mark.emulator
def test_testapp_streams_counts_and_answers_ping(emu_bin, testapp_elfs, tmp_path):
    """The PING is answered inside the run whatever the machine's load: the stimulus comes
    through a pipe and its second half is written only after the PING, so emulated time cannot
    run past the end of the stream before the PING is in the pty (a stimulus *file* let a fast
    emulator finish its 4 s before a descheduled host had sent it)."""
    good, _ = testapp_elfs
    # a different value on every axis, changing at 4 Hz
    t = np.arange(0.0, 4.0, 0.25)
    k = np.arange(t.size)[:, None]
    f = np.array([1.0, -2.0, 9.0]) + 0.01 * k * np.array([1, 2, 3])
    w = np.array([5.0, -7.0, 11.0]) + 0.5 * k * np.array([1, -1, 2])
    temp = 28.0 + 0.1 * k[:, 0]
    first = t <= 1.0  # emulated time stops at 1 s (>= 35 samples) until the rest is written
    pongs = []

    board = EmulatedBoard(good, emulator=emu_bin, stimulus="pipe", samplelog=True, reglog=True,
                          workdir=tmp_path)  # fmt: skip
    with board:
        pipe = board.stimulus_pipe
        assert pipe is not None
        write_stimulus(pipe, t[first], f[first], w[first], temp[first])
        pipe.flush()

        def ping_once(ser, frames):
            if len(of_type(frames, "IMU_SAMPLE")) >= 20 and not pongs:
                ser.write(encode_frame("PING", 1, nonce=0xC0FFEE42))
                ser.flush()
                pongs.append("sent")
                rest = ~first
                write_stimulus(pipe, t[rest], f[rest], w[rest], temp[rest], header=False)
                pipe.close()  # the stream ends with its last record, at t = 3.75 s

        frames = collect(board, max_wall_s=60, on_frames=ping_once)
    assert pongs == ["sent"]
    s = board.summary
    assert s["stop_reason"] == "stimulus ended"
    assert s["spi_violations"] == 0 and s["bus_conflicts"] == 0
    assert not s["rules_broken"], "\n".join(s["rules_broken"])
    assert not seq_gaps(frames)
    got = sample_counts(frames)
    log = board.samplelog()
    read = log[log["read"] == 1]
    want = np.stack([read[k] for k in ("ax", "ay", "az", "temp", "gx", "gy", "gz")], axis=1)
    assert len(got) >= 150 and len(got) <= len(want)
    np.testing.assert_array_equal(got, want[: len(got)])
    pong = of_type(frames, "PONG")
    assert pong and pong[0].fields["nonce"] == 0xC0FFEE42
    assert s["uart_rx_bytes"] == 12


@pytest.mark.emulator
def test_rule_breaking_testapp_is_caught(emu_bin, testapp_elfs, tmp_path):
    _, bad = testapp_elfs
    with EmulatedBoard(bad, emulator=emu_bin, seconds=1.0, reglog=True, workdir=tmp_path) as board:
        collect(board, max_wall_s=30)
    s = board.summary
    # 7 register writes + WHO_AM_I at fosc/2 = 8 MHz, baro /CS left low on every transaction
    assert s["spi_violations"] == 8
    assert s["first_violation_reg"] == 0x75
    assert s["bus_conflicts"] == s["cs_transactions"] > 0
    # the same two, as named rules with their datasheet / schematic reference
    assert {k for k, n in s["rules"].items() if n} == {"SPI_CLOCK", "BARO_CS"}
    assert s["rules"]["SPI_CLOCK"] == 8 and s["rules"]["BARO_CS"] == s["bus_conflicts"]
    assert s["rules_broken"][0].startswith("SPI_CLOCK (PS p.15): ")
    viol = [a for a in board.reglog() if a.violation]
    assert len(viol) == 8 and all(a.spi_hz == 8e6 for a in viol)


@pytest.mark.emulator
def test_stimulus_through_a_pipe(emu_bin, testapp_elfs, tmp_path):
    good, _ = testapp_elfs
    board = EmulatedBoard(good, emulator=emu_bin, stimulus="pipe", samplelog=True, workdir=tmp_path)
    with board:
        assert board.stimulus_pipe is not None
        write_stimulus(board.stimulus_pipe, [0.0], [[0.0, 0.0, 9.80665]], [[0.0, 0.0, 0.0]], 25.0)
        more = ([0.3, 0.6], [[4.903325, 0, 0]] * 2, [[0, 0, 100.0]] * 2, 25.0)
        write_stimulus(board.stimulus_pipe, *more, header=False)
        board.stimulus_pipe.close()  # the stream ends with its last record, at t = 0.6 s
        frames = collect(board, max_wall_s=30)
    assert board.summary["stop_reason"] == "stimulus ended"
    assert 0.6 < board.summary["sim_seconds"] < 0.63
    counts = sample_counts(frames)
    assert counts[0].tolist() == [0, 0, 16384, -3920, 0, 0, 0]
    # samples after t = 0.3 s hold the second record (0.5 g on X, 100 deg/s about Z)
    assert counts[-1].tolist() == [8192, 0, 0, -3920, 0, 0, 13100]


@pytest.mark.emulator
def test_emu_url_opens_and_closes(emu_bin, testapp_elfs):
    good, _ = testapp_elfs
    serial.protocol_handler_packages.append("host.transports")
    ser = serial.serial_for_url(f"emu://?elf={good}&seconds=0.5", baudrate=115200, timeout=0.05)
    data = b""
    try:
        while True:
            try:
                chunk = ser.read(ser.in_waiting or 1)
            except (serial.SerialException, OSError):  # hung up: emu_helpers.collect
                break
            if not chunk and ser.board is not None and not ser.board.running:
                break
            data += chunk
    finally:
        ser.close()
    assert data.startswith(b"\xa5\x5a\x02")  # HELLO first
    assert ser.emulator_summary is not None
    assert ser.emulator_summary["sim_seconds"] >= 0.5


@pytest.mark.emulator
def test_board_starts_after_the_startup_time_so_an_open_never_loses_hello(emu_bin, testapp_elfs):
    """Opening the port resets the AVR, which then waits its 65 ms start-up time (fuses SUT=11)
    before running: a host's open() (tty setup, input flush) cannot throw away the first frames.
    """
    import os
    import time

    from host.bench.emulator import EmulatedBoard

    good, _ = testapp_elfs
    board = EmulatedBoard(good, emulator=emu_bin, seconds=1.0)
    with board:
        assert board.port
        # times are taken *before* the open, so a descheduled test can only make the measured
        # silence longer, never shorter: no wall-clock assumption about this process
        before_open = time.monotonic()
        fd = os.open(board.port, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
        try:
            data = b""
            first_byte_after = None
            while len(data) < 64:  # (the test's time limit bounds this)
                try:
                    chunk = os.read(fd, 4096)
                except BlockingIOError:
                    if not board.running:
                        break
                    time.sleep(0.002)
                    continue
                except OSError:  # the emulator ended
                    break
                if not chunk:
                    break
                if first_byte_after is None:
                    first_byte_after = time.monotonic() - before_open
                data += chunk
        finally:
            os.close(fd)
    assert first_byte_after is not None and first_byte_after >= 0.065, first_byte_after
    assert data.startswith(b"\xa5\x5a\x02")  # the HELLO, first
