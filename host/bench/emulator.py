"""The emulated APM 2.6 board from Python: build it, run it, feed it physics, read its logs.

``firmware/emulator/apm_emu`` (C, on libsimavr) runs the real firmware ELF on an emulated
ATmega2560 with an MPU-6000 model on SPI and UART0 on a pseudo-terminal (see
``firmware/emulator/README.md``). This module builds it on demand into
``firmware/build/emulator/`` (rebuilt when its sources are newer), starts it
(:class:`EmulatedBoard`), and writes the stimulus stream it reads (:func:`write_stimulus`).

    with EmulatedBoard(seconds=60, reglog=True, samplelog=True) as board:
        ser = serial.Serial(board.port, 115200)   # opening the pty = DTR reset, the AVR starts
        ...
    board.summary["speed"], board.reglog(), board.samplelog()

``emu://`` URLs (``host/transports/protocol_emu.py``) wrap the same class as a pyserial port;
:class:`SimStimulus` feeds a running board's stimulus pipe from the physics simulator
(:class:`host.sim.Simulator`), a bounded horizon ahead of the emulated time.

Length (over 600 lines): the emulator's build, its stimulus file, its log readers and the running
board share its file formats and paths; split apart, each format would be written in two places.
"""

from __future__ import annotations

import contextlib
import fcntl
import json
import os
import shutil
import signal
import subprocess
import tempfile
import termios
import threading
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

import numpy as np
from serial.serialutil import Timeout

from host.board.firmware import build_firmware_hex, build_lock
from host.errors import UserError

ROOT = Path(__file__).resolve().parents[2]
EMULATOR_SRC = ROOT / "firmware" / "emulator"
DEFAULT_EMU_BUILD = ROOT / "firmware" / "build" / "emulator"
MISSING = "emu:// needs simavr: apt-get install simavr libsimavr-dev gcc-avr avr-libc"
SIMAVR_HEADER = Path("/usr/include/simavr/sim_avr.h")

STIM_MAGIC = b"IMUSTIM1"
STIM_FIELDS = 8
#: faults that stop the sensor (a session must end on them)
SENSOR_FAULTS = ("absent", "stuck-miso", "no-drdy")
#: ``marginal-bus``: above 1 MHz SCLK every byte the chip sends arrives one bit late; the
#: firmware's burst check must see it and carry on at the 1 MHz clock (a session succeeds)
BUS_FAULTS = ("marginal-bus",)
FAULTS = SENSOR_FAULTS + BUS_FAULTS


def toolchain_problem(need_avr: bool = True) -> str | None:
    """None when the emulator can be built and run here, else the one-line reason."""
    if not SIMAVR_HEADER.exists() or shutil.which("cc") is None or shutil.which("make") is None:
        return MISSING
    libs = ("/usr/lib/x86_64-linux-gnu", "/usr/lib/aarch64-linux-gnu", "/usr/lib", "/usr/local/lib")
    if not any(Path(d, "libsimavr.so").exists() or Path(d, "libsimavr.a").exists() for d in libs):
        return MISSING
    if need_avr and shutil.which("avr-gcc") is None:
        return MISSING
    return None


def require_toolchain(need_avr: bool = True) -> None:
    problem = toolchain_problem(need_avr)
    if problem:
        raise UserError(problem)


def _make(args: Sequence[str], what: str) -> None:
    r = subprocess.run(["make", "--no-print-directory", *args], capture_output=True, text=True)
    if r.returncode != 0:
        tail = "\n".join((r.stdout + r.stderr).strip().splitlines()[-15:])
        raise UserError(f"building {what} failed:\n{tail}")


def build_emulator(build_dir: str | Path | None = None) -> Path:
    """Build ``apm_emu`` (make decides whether the sources are newer) and return its path."""
    require_toolchain(need_avr=False)
    out = Path(build_dir) if build_dir else DEFAULT_EMU_BUILD
    with build_lock(out):
        _make(["-C", str(EMULATOR_SRC), f"BUILD={out.resolve()}"], "the emulator")
    return out / "apm_emu"


def build_testapp(build_dir: str | Path | None = None) -> tuple[Path, Path]:
    """Build the harness self-test firmware: (good, bad) ELF paths (see testapp/testapp.c)."""
    require_toolchain(need_avr=True)
    out = Path(build_dir) if build_dir else DEFAULT_EMU_BUILD
    with build_lock(out):
        _make(["-C", str(EMULATOR_SRC), "testapp", f"BUILD={out.resolve()}"], "the test app")
    return out / "testapp.elf", out / "testapp_bad.elf"


def build_firmware(build_dir: str | Path | None = None, make_args: Sequence[str] = ()) -> Path:
    """Build the real firmware (``make -C firmware BUILD=dir``) and return ``dir/imu_bench.elf``.

    ``make_args`` are extra make variables, e.g. ``["BAUD=500000"]``.
    """
    require_toolchain(need_avr=True)
    elf = build_firmware_hex(build_dir, make_args).with_suffix(".elf")
    if not elf.exists():
        raise UserError(f"building the firmware did not produce {elf}")
    return elf


# ---------------------------------------------------------------------------------- stimulus
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


# ---------------------------------------------------------------------------------- logs
@dataclass(frozen=True)
class RegAccess:
    """One MPU-6000 register access seen on the emulated SPI bus."""

    t_us: float  # simulated time since the emulator started
    op: str  # "R" or "W"
    reg: int
    value: int
    spi_hz: float
    violation: bool  # a non-sensor register at more than 1 MHz


def read_reglog(path: str | Path) -> list[RegAccess]:
    out = []
    with open(path) as f:
        next(f, None)
        for line in f:
            t, op, reg, val, hz, viol = line.rstrip("\n").split(",")
            out.append(RegAccess(float(t), op, int(reg, 16), int(val, 16), float(hz), viol == "1"))
    return out


SAMPLELOG_DTYPE = np.dtype(
    [("idx", "<u8"), ("t_us", "<f8"), ("ax", "<i2"), ("ay", "<i2"), ("az", "<i2"),
     ("temp", "<i2"), ("gx", "<i2"), ("gy", "<i2"), ("gz", "<i2"), ("read", "u1")]
)  # fmt: skip
COUNT_FIELDS = ("ax", "ay", "az", "temp", "gx", "gy", "gz")


def read_samplelog(path: str | Path) -> np.ndarray:
    """Every sample the MPU model produced: structured array (``SAMPLELOG_DTYPE``); ``read`` is 1
    when the firmware burst-read all 14 bytes of it while it was in the output registers."""
    with open(path) as f:
        lines = f.readlines()[1:]
    if not lines:  # the chip produced nothing (asleep, absent, never configured)
        return np.zeros(0, dtype=SAMPLELOG_DTYPE)
    rows = np.loadtxt(lines, delimiter=",", ndmin=2)
    out = np.zeros(rows.shape[0], dtype=SAMPLELOG_DTYPE)
    for i, name in enumerate(SAMPLELOG_DTYPE.names or ()):
        out[name] = rows[:, i]
    return out


# ---------------------------------------------------------------------------------- board
class EmulatedBoard:
    """Run ``apm_emu`` with a firmware ELF; ``.port`` is the pseudo-terminal to open.

    The emulated CPU is held until the pty is first opened (like plugging in the USB cable;
    ``wait_open=False`` starts at once), and every later re-open resets the AVR (DTR).

    Options mirror the emulator's (README.md): ``elf`` (default: build the real firmware),
    ``stimulus`` (a stimulus file path, or ``"pipe"`` to write records into ``.stimulus_pipe``
    while it runs, or None = at rest, Z up, 25 °C), ``seconds`` (simulated; None = until the
    stimulus ends or :meth:`stop`), ``realtime``, ``reglog`` / ``samplelog`` (True = a file in
    ``workdir``, or a path), ``fault`` (:data:`FAULTS`) from ``fault_at`` s,
    ``noise_accel`` (m/s²) / ``noise_gyro`` (°/s) with ``seed``, ``clock_ppm``, ``product_id``
    (what the chip's PRODUCT_ID reads: its revision; None = the emulator's default, rev D8),
    ``extra_args``.

    Boot like the real board (``boot=True``): the stk500v2 bootloader in the boot section runs
    first after every reset (≈ 0.8 s, in real time), then the application; ``elf`` (an ``.elf``
    or ``.hex``) is then optional. ``flash`` = a persistent flash image file (implies ``boot``):
    loaded at start if it exists, written back after avrdude programs it and at exit; an ``elf``
    given as well is programmed over it at start. See ``host/flash.py``.
    """

    def __init__(
        self,
        elf: str | Path | None = None,
        *,
        stimulus: str | Path | None = None,
        seconds: float | None = None,
        realtime: bool = False,
        reglog: bool | str | Path = False,
        samplelog: bool | str | Path = False,
        fault: str | None = None,
        fault_at: float = 0.0,
        noise_accel: float = 0.0,
        noise_gyro: float = 0.0,
        seed: int | None = None,
        clock_ppm: float = 0.0,
        product_id: int | None = None,
        wait_open: bool = True,
        dtr_reset: bool = True,
        workdir: str | Path | None = None,
        emulator: str | Path | None = None,
        extra_args: Sequence[str] = (),
        start_timeout_s: float = 30.0,
        boot: bool = False,
        flash: str | Path | None = None,
    ) -> None:
        if fault is not None and fault not in FAULTS:
            raise UserError(f"emulator fault must be one of {', '.join(FAULTS)}, not {fault!r}")
        self.elf = Path(elf) if elf else None
        self.stimulus = stimulus
        self.seconds = seconds
        self.realtime = realtime
        self.fault = fault
        self.fault_at = fault_at
        self.noise_accel = noise_accel
        self.noise_gyro = noise_gyro
        self.seed = seed
        self.clock_ppm = clock_ppm
        self.product_id = product_id
        self.wait_open = wait_open
        self.dtr_reset = dtr_reset
        self.emulator = Path(emulator) if emulator else None
        self.extra_args = list(extra_args)
        self.start_timeout_s = start_timeout_s
        self.flash = Path(flash) if flash else None
        self.boot = boot or self.flash is not None
        self._own_workdir = workdir is None
        self.workdir = Path(workdir) if workdir else Path(tempfile.mkdtemp(prefix="apm_emu_"))
        self.reglog_path = self._log_path(reglog, "reglog.csv")
        self.samplelog_path = self._log_path(samplelog, "samplelog.csv")
        self.summary_path = self.workdir / "summary.json"
        self.port: str | None = None
        self.summary: dict[str, Any] | None = None
        self.stimulus_pipe: IO[bytes] | None = None
        self.stderr_text = ""
        self._proc: subprocess.Popen[bytes] | None = None
        self._lines: list[str] = []
        self._reader: threading.Thread | None = None
        self._stderr_file: IO[bytes] | None = None

    def _log_path(self, opt: bool | str | Path, name: str) -> Path | None:
        if opt is True:
            return self.workdir / name
        if opt:
            return Path(opt)
        return None

    # -- lifecycle
    def command(self) -> list[str]:
        assert self.emulator is not None and (self.elf is not None or self.boot)
        cmd = [str(self.emulator), "--summary-file", str(self.summary_path)]
        if self.elf is not None:
            cmd += ["--hex" if self.elf.suffix.lower() == ".hex" else "--elf", str(self.elf)]
        if self.boot:
            cmd.append("--boot")
        if self.flash is not None:
            cmd += ["--flash-file", str(self.flash)]
        if self.stimulus == "pipe":
            cmd += ["--stimulus", "-"]
        elif self.stimulus is not None:
            cmd += ["--stimulus", str(self.stimulus)]
        if self.seconds is not None:
            cmd += ["--seconds", repr(float(self.seconds))]
        if self.realtime:
            cmd.append("--realtime")
        if self.reglog_path:
            cmd += ["--reglog", str(self.reglog_path)]
        if self.samplelog_path:
            cmd += ["--samplelog", str(self.samplelog_path)]
        if self.fault:
            cmd += ["--fault", self.fault, "--fault-at", repr(float(self.fault_at))]
        if self.noise_accel:
            cmd += ["--noise-accel", repr(float(self.noise_accel))]
        if self.noise_gyro:
            cmd += ["--noise-gyro", repr(float(self.noise_gyro))]
        if self.seed is not None:
            cmd += ["--seed", str(int(self.seed))]
        if self.clock_ppm:
            cmd += ["--clock-ppm", repr(float(self.clock_ppm))]
        if self.product_id is not None:
            cmd += ["--product-id", f"{int(self.product_id):#04x}"]
        if not self.wait_open:
            cmd.append("--no-wait")
        if not self.dtr_reset:
            cmd.append("--no-dtr-reset")
        return cmd + self.extra_args

    def start(self) -> EmulatedBoard:
        if self._proc is not None:
            return self
        if self.emulator is None:
            self.emulator = build_emulator()
        if self.elf is None and not self.boot:
            self.elf = build_firmware()
        if self.elf is not None and not self.elf.exists():
            raise UserError(f"firmware ELF {self.elf} does not exist")
        if isinstance(self.stimulus, str | Path) and self.stimulus != "pipe":
            if not Path(self.stimulus).exists():
                raise UserError(f"stimulus file {self.stimulus} does not exist")
        self.workdir.mkdir(parents=True, exist_ok=True)
        self._stderr_file = open(self.workdir / "stderr.txt", "w+b")
        self._proc = subprocess.Popen(
            self.command(),
            stdin=subprocess.PIPE if self.stimulus == "pipe" else subprocess.DEVNULL,
            stdout=subprocess.PIPE,
            stderr=self._stderr_file,
        )
        self.stimulus_pipe = self._proc.stdin
        assert self._proc.stdout is not None
        first = self._readline_with_timeout(self._proc.stdout, self.start_timeout_s)
        if not first.startswith("PTY "):
            self._proc.kill()
            self._proc.wait()
            raise UserError(f"the emulator did not start: {self._stderr_tail() or first!r}")
        self.port = first.split(None, 1)[1].strip()
        self._reader = threading.Thread(target=self._drain, daemon=True)
        self._reader.start()
        return self

    @staticmethod
    def _readline_with_timeout(stream: IO[bytes], timeout_s: float) -> str:
        result: list[bytes] = []
        t = threading.Thread(target=lambda: result.append(stream.readline()), daemon=True)
        t.start()
        t.join(timeout_s)
        return result[0].decode(errors="replace") if result else ""

    def _drain(self) -> None:
        assert self._proc is not None and self._proc.stdout is not None
        for raw in self._proc.stdout:
            self._lines.append(raw.decode(errors="replace").rstrip("\n"))

    def _stderr_tail(self) -> str:
        if self._stderr_file is None:
            return ""
        self._stderr_file.flush()
        self._stderr_file.seek(0)
        text = self._stderr_file.read().decode(errors="replace")
        self.stderr_text = text
        lines = [ln for ln in text.splitlines() if ln.strip() and not ln.startswith("Loaded ")]
        return lines[-1] if lines else ""

    @property
    def pid(self) -> int | None:
        """Process id of the running emulator (None before :meth:`start`)."""
        return self._proc.pid if self._proc is not None else None

    @property
    def running(self) -> bool:
        return self._proc is not None and self._proc.poll() is None

    def wait(self, timeout_s: float | None = None) -> dict[str, Any]:
        """Wait for the emulator to end by itself (``seconds`` reached, stimulus ended)."""
        assert self._proc is not None
        self._proc.wait(timeout_s)
        return self._finish()

    def stop(self, timeout_s: float = 10.0) -> dict[str, Any]:
        """Stop the emulator (SIGTERM: it writes its logs and summary) and return the summary."""
        if self._proc is None:
            return self.summary or {}
        if self._proc.poll() is None:
            with contextlib.suppress(BrokenPipeError, OSError):
                if self.stimulus_pipe:
                    self.stimulus_pipe.close()
            self._proc.send_signal(signal.SIGTERM)
            with contextlib.suppress(OSError):  # a paused (SIGSTOP) emulator: let it end
                self._proc.send_signal(signal.SIGCONT)
            try:
                self._proc.wait(timeout_s)
            except subprocess.TimeoutExpired:
                self._proc.kill()
                self._proc.wait()
        return self._finish()

    def _finish(self) -> dict[str, Any]:
        assert self._proc is not None
        if self._reader:
            self._reader.join(5)
        summary = None
        for line in self._lines:
            if line.startswith("SUMMARY "):
                summary = json.loads(line[8:])
        if summary is None and self.summary_path.exists():
            with contextlib.suppress(ValueError):
                summary = json.loads(self.summary_path.read_text())
        self._stderr_tail()
        if self._stderr_file:
            self._stderr_file.close()
            self._stderr_file = None
        if summary is None:
            summary = {"error": f"no summary (exit status {self._proc.returncode})"}
        self.summary = summary
        return summary

    def __enter__(self) -> EmulatedBoard:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    # -- results
    def reglog(self) -> list[RegAccess]:
        if not self.reglog_path:
            raise UserError("start the EmulatedBoard with reglog=True to get a register log")
        return read_reglog(self.reglog_path)

    def samplelog(self) -> np.ndarray:
        if not self.samplelog_path:
            raise UserError("start the EmulatedBoard with samplelog=True to get a sample log")
        return read_samplelog(self.samplelog_path)

    def cleanup(self) -> None:
        """Remove the work directory (when this object made it)."""
        if self._own_workdir:
            shutil.rmtree(self.workdir, ignore_errors=True)


def wait_for(cond: Any, timeout_s: float, poll_s: float = 0.01) -> bool:
    """Poll ``cond()`` until true or ``timeout_s`` passes (test helper)."""
    timeout = Timeout(timeout_s)
    while not timeout.expired():
        if cond():
            return True
        time.sleep(poll_s)
    return bool(cond())


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
    """Feed an emulated board's stimulus pipe from a running :class:`host.sim.Simulator`.

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
        sim: Any,  # host.sim.Simulator (not imported at module level: numpy-only users)
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
