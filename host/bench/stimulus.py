"""The emulated board's stimulus: the physical truth its MPU-6000 model senses.

A stimulus stream is a 16-byte header (``IMUSTIM1``) and records of 8 float64: time, specific
force, angular rate, temperature (:func:`write_stimulus`, :func:`read_stimulus`). The emulator
(:class:`host.bench.emulator.EmulatedBoard`) reads it from a file, or from a pipe that
:class:`SimStimulus` feeds from the physics simulator (:class:`host.bench.sim.Simulator`), a
bounded horizon ahead of the emulated time.
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import termios
import threading
import time
from pathlib import Path
from typing import IO, Any

import numpy as np
from serial.serialutil import Timeout

from host.bench.emulator import EmulatedBoard
from host.errors import UserError

STIM_MAGIC = b"IMUSTIM1"
STIM_FIELDS = 8


def write_stimulus(
    path_or_file: str | Path | IO[bytes],
    t_s: np.ndarray,
    f_mps2: np.ndarray,
    w_dps: np.ndarray,
    temp_c: np.ndarray | float,
    header: bool = True,
) -> None:
    """Write a stimulus stream: a 16-byte header (``IMUSTIM1``, u32le 8, u32le 0), then one
    record of 8 little-endian float64 per time ``t_s, fx, fy, fz, wx, wy, wz, temp_c``.

    ``t_s`` (N,) seconds since the emulator started (increasing), ``f_mps2`` (N, 3) specific force
    in m/s² and ``w_dps`` (N, 3) angular rate in °/s, both in the MPU-6000 chip axes, ``temp_c``
    (N,) or a scalar. The emulator holds each record until the next one's time. To stream more
    records into an open pipe later, call again with ``header=False``.
    """
    t = np.asarray(t_s, dtype=np.float64).reshape(-1)
    n = t.shape[0]
    f = np.asarray(f_mps2, dtype=np.float64).reshape(n, 3)
    w = np.asarray(w_dps, dtype=np.float64).reshape(n, 3)
    temp = np.broadcast_to(np.asarray(temp_c, dtype=np.float64), (n,))
    if n > 1 and np.any(np.diff(t) < 0):
        raise ValueError("stimulus times must not decrease")
    rec = np.empty((n, STIM_FIELDS), dtype="<f8")
    rec[:, 0] = t
    rec[:, 1:4] = f
    rec[:, 4:7] = w
    rec[:, 7] = temp
    data = rec.tobytes()
    if header:
        data = STIM_MAGIC + np.array([STIM_FIELDS, 0], dtype="<u4").tobytes() + data
    if isinstance(path_or_file, str | Path):
        Path(path_or_file).write_bytes(data)
    else:
        path_or_file.write(data)
        path_or_file.flush()


def read_stimulus(path: str | Path) -> np.ndarray:
    """Read a stimulus file back: (N, 8) float64 array ``t, fx, fy, fz, wx, wy, wz, temp``."""
    raw = Path(path).read_bytes()
    if raw[:8] != STIM_MAGIC:
        raise UserError(f"{path}: not a stimulus stream (no IMUSTIM1 header)")
    return np.frombuffer(raw[16:], dtype="<f8").reshape(-1, STIM_FIELDS)


# ---------------------------------------------------------------------------------- simulator

#: stimulus records per second from the simulator: the MPU-6000's internal sample rate (the
#: emulated chip's output samples, 50 Hz by default, each pick the last record before them)
STIM_RECORD_HZ = 1000.0
#: simulated seconds of records generated and written at once
STIM_CHUNK_S = 0.016
#: bytes the stimulus pipe holds (Linux minimum, one page): 64 records = 64 ms at 1 kHz
STIM_PIPE_BYTES = 4096
RECORD_BYTES = 8 * STIM_FIELDS
_STIM_HEADER = STIM_MAGIC + np.array([STIM_FIELDS, 0], dtype="<u4").tobytes()


class SimStimulus:
    """Feed an emulated board's stimulus pipe from a running :class:`host.bench.sim.Simulator`.

    The simulator (built at :data:`STIM_RECORD_HZ`, its clocks exact: the emulator has its own)
    is run ahead of the emulated time by a bounded horizon: records are generated
    :data:`STIM_CHUNK_S` at a time and written into a pipe of :data:`STIM_PIPE_BYTES` that the
    emulator reads unbuffered, so the writer blocks when the emulator is ≈ 64–80 ms of emulated
    time behind (never more), and the emulator blocks (emulated time stops) when the records
    run dry. ``speed`` None runs as fast as the emulator consumes; N lets the horizon advance
    at most N× the wall clock (from :meth:`start`), so emulated time follows N× real time.

    Change the cube's motion with ``sim.set_motion(m, horizon_s)`` while holding :attr:`lock`:
    the records from :attr:`horizon_s` on are not generated yet, so the motion starts "now" from
    the host's point of view, at most one horizon after the emulated time. :meth:`emulated_s`
    (a lower bound of the emulator's time, from the pipe's fill level) and
    :meth:`wait_emulated` tell when the emulator has got past a time.

    :meth:`hold_at` stops the records at a time until :meth:`release`: the emulator then waits
    there (its time stands still), however long the host takes — so where the host's next
    command lands in emulated time does not depend on how fast the host is.
    """

    def __init__(
        self,
        board: EmulatedBoard,
        sim: Any,  # host.bench.sim.Simulator (not imported at module level: numpy-only users)
        speed: float | None = None,
        chunk_s: float | None = None,
    ) -> None:
        if board.stimulus_pipe is None:
            raise ValueError("SimStimulus needs an EmulatedBoard started with stimulus='pipe'")
        self.sim = sim
        self.speed = speed
        if chunk_s is None:  # paced: small chunks, so emulated time follows the wall clock closely
            chunk_s = (
                STIM_CHUNK_S if speed is None else min(STIM_CHUNK_S, max(0.002 * speed, 0.002))
            )
        self.chunk_s = chunk_s
        self.lock = threading.RLock()
        #: the exception that ended the writer (BrokenPipeError when the emulator ended), or None
        self.error: BaseException | None = None
        self._pipe: IO[bytes] | None = board.stimulus_pipe
        board.stimulus_pipe = None  # ours now: closed after the writer thread ended
        self._fd = self._pipe.fileno()
        self._written = 0  # records written into the pipe
        self._t_first: float | None = None
        self._stop = threading.Event()
        self._hold_s: float | None = None  # no record at or beyond this time until release()
        self._released = threading.Event()
        self._thread: threading.Thread | None = None
        self._wall0 = time.monotonic()
        with contextlib.suppress(OSError, AttributeError):
            fcntl.fcntl(self._fd, fcntl.F_SETPIPE_SZ, STIM_PIPE_BYTES)

    def start(self) -> SimStimulus:
        """Write the header and start the writer thread (the emulator reads the header and the
        first records right after it printed its pty, before the pty is opened)."""
        self._write_all(_STIM_HEADER)
        self._wall0 = time.monotonic()
        self._thread = threading.Thread(target=self._run, name="sim-stimulus", daemon=True)
        self._thread.start()
        return self

    def restart_clock(self) -> None:
        """Pace from now (``speed`` N): call when the emulated CPU starts (the pty's first open)."""
        with self.lock:
            self._wall0 = time.monotonic() - self.horizon_s / self.speed if self.speed else 0.0

    @property
    def running(self) -> bool:
        return self._thread is not None and self._thread.is_alive()

    @property
    def horizon_s(self) -> float:
        """Simulated time up to which records are generated, s since the emulator started."""
        return float(self.sim.t_next)

    def emulated_s(self) -> float:
        """A lower bound of the emulated time, s since the emulator started (it has read every
        record written but those still in the pipe, and reads one record ahead)."""
        written = self._written
        if self._t_first is None or written < 2:
            return 0.0
        queued = 0
        if self._pipe is not None:
            buf = bytearray(4)
            with contextlib.suppress(OSError):
                fcntl.ioctl(self._fd, termios.FIONREAD, buf)
                queued = int.from_bytes(buf, "little")
        consumed = written - -(-queued // RECORD_BYTES)
        return self._t_first + max(consumed - 2, 0) * float(self.sim.period_s)

    def wait_emulated(
        self, t_s: float, timeout_s: float = 5.0, idle: Any = None, poll_s: float = 0.0005
    ) -> bool:
        """Wait until the emulated time has passed ``t_s`` (s); False on timeout or when the
        writer ended. ``idle()`` is called while waiting (e.g. to keep the pty read: a full pty
        stops the emulator)."""
        timeout = Timeout(timeout_s)
        while self.emulated_s() < t_s:
            if not self.running or timeout.expired():
                return False
            if idle is not None:
                idle()
            time.sleep(poll_s)
        return True

    def stop(self, join_s: float = 5.0) -> None:
        """End the writer (call after the emulator was stopped: a blocked write then fails) and
        close the pipe."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(join_s)
        if self._pipe is not None and not self.running:
            with contextlib.suppress(OSError):
                self._pipe.close()
            self._pipe = None

    def request_stop(self) -> None:
        """Ask the writer to end at its next chunk (without waiting)."""
        self._stop.set()
        self._released.set()

    def hold_at(self, t_s: float) -> None:
        """Write no record later than ``t_s`` (s since the emulator started) until
        :meth:`release`: the emulator stops there (≈ one record period before ``t_s``) and waits,
        whatever the wall clock does. A later call moves the hold."""
        with self.lock:
            self._hold_s = float(t_s)
            self._released.clear()

    def release(self) -> None:
        """End a :meth:`hold_at`: the records (and the emulated time) go on."""
        with self.lock:
            self._hold_s = None
        self._released.set()

    @property
    def holding(self) -> bool:
        """True while a :meth:`hold_at` is in force."""
        return self._hold_s is not None

    # -- the writer thread
    def _write_all(self, data: bytes) -> None:
        view = memoryview(data)
        while view:
            n = os.write(self._fd, view)
            view = view[n:]

    def _run(self) -> None:
        try:
            while not self._stop.is_set():
                with self.lock:
                    t_end = self.horizon_s + self.chunk_s
                    held = False
                    if self._hold_s is not None and t_end > self._hold_s:
                        # records strictly before the hold; none left to write: wait
                        t_end = self._hold_s
                        held = t_end <= self.horizon_s
                    delay = 0.0
                    if self.speed is not None and not held:
                        allowed = (time.monotonic() - self._wall0) * self.speed
                        delay = (t_end - allowed) / self.speed
                    if delay <= 0 and not held:
                        series = self.sim.outputs_until(t_end)
                if held:
                    self._released.wait(0.05)
                    continue
                if delay > 0:
                    self._stop.wait(min(delay, 0.05))
                    continue
                n = series.t_s.shape[0]
                if n == 0:
                    continue
                rec = np.empty((n, STIM_FIELDS), dtype="<f8")
                rec[:, 0] = series.t_s
                rec[:, 1:4] = series.specific_force
                rec[:, 4:7] = series.rate_dps
                rec[:, 7] = series.temp_c
                if self._t_first is None:
                    self._t_first = float(series.t_s[0])
                self._write_all(rec.tobytes())
                self._written += n
        except OSError as exc:  # EPIPE: the emulator ended; EBADF: closed under us
            self.error = exc
