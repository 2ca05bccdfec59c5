"""Helpers for the emulated-board tests: run a board, collect the frames it sends."""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np
import serial

from host.bench.emulator import EmulatedBoard
from host.wire.frames import Frame
from host.wire.stream import StreamDecoder

BAUD = 115200


def collect(
    board: EmulatedBoard,
    max_wall_s: float = 60.0,
    on_frames: Callable[[serial.Serial, list[Frame]], bool | None] | None = None,
) -> list[Frame]:
    """Open the board's pty (= power-on / DTR reset) and decode until the emulator ends, the
    wall-clock budget runs out, or ``on_frames(ser, frames_so_far)`` returns True."""
    assert board.port
    ser = serial.Serial(board.port, BAUD, timeout=0.02)
    dec = StreamDecoder()
    frames: list[Frame] = []
    deadline = time.monotonic() + max_wall_s
    try:
        while time.monotonic() < deadline:
            try:
                chunk = ser.read(ser.in_waiting or 1)
            except (serial.SerialException, OSError):
                # the emulator ended and hung the pty up (after the host read everything it
                # sent: drain_to_host): read() says so as SerialException, but the hang-up can
                # land between two reads, and then in_waiting's ioctl raises EIO (OSError)
                break
            if chunk:
                new = dec.feed(chunk)
                frames += new
                if new and on_frames and on_frames(ser, frames):
                    break
            elif not board.running:
                break
    finally:
        ser.close()
    return frames


def of_type(frames: list[Frame], name: str) -> list[Frame]:
    return [f for f in frames if f.name == name]


def sample_counts(frames: list[Frame]) -> np.ndarray:
    """(N, 7) int array ax ay az temp gx gy gz of the IMU_SAMPLE frames."""
    keys = ("ax", "ay", "az", "temp", "gx", "gy", "gz")
    return np.array([[f.fields[k] for k in keys] for f in of_type(frames, "IMU_SAMPLE")], dtype=int)


def seq_gaps(frames: list[Frame]) -> list[tuple[int, int]]:
    """(previous, next) seq pairs that are not consecutive (mod 2^16)."""
    return [
        (a.seq, b.seq)
        for a, b in zip(frames, frames[1:], strict=False)
        if (a.seq + 1) & 0xFFFF != b.seq
    ]
