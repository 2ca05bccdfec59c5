"""The emulated APM 2.6 board from Python: run it, read its logs.

``firmware/emulator/apm_emu`` (C, on libsimavr) runs the real firmware ELF on an emulated
ATmega2560 with an MPU-6000 model on SPI and UART0 on a pseudo-terminal (see
``firmware/emulator/README.md``). :class:`EmulatedBoard` builds it on demand
(:mod:`host.bench.build`) and starts it; it reads a stimulus stream
(:mod:`host.bench.stimulus`) and writes register-access and sample logs (:func:`read_reglog`,
:func:`read_samplelog`).

    with EmulatedBoard(seconds=60, reglog=True, samplelog=True) as board:
        ser = serial.Serial(board.port, 115200)   # opening the pty = DTR reset, the AVR starts
        ...
    board.summary["speed"], board.reglog(), board.samplelog()

``emu://`` URLs (``host/transports/protocol_emu.py``) wrap the same class as a pyserial port;
:class:`host.bench.stimulus.SimStimulus` feeds a running board's stimulus pipe from the physics
simulator.
"""

from __future__ import annotations

import contextlib
import json
import shutil
import signal
import subprocess
import tempfile
import threading
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

import numpy as np
from serial.serialutil import Timeout

from host.bench.build import build_emulator, build_firmware
from host.errors import UserError

#: the part's self-test: ``pass`` (a healthy part, each axis within a few % of its factory
#: trim) or ``fail`` (accelerometer Y 35 % above its trim, gyroscope Z 45 % below)
SELF_TEST_PARTS = ("pass", "fail")
#: faults that stop the sensor (a session must end on them)
SENSOR_FAULTS = ("absent", "stuck-miso", "no-drdy")
#: ``marginal-bus``: above 1 MHz SCLK every byte the chip sends arrives one bit late; the
#: firmware's burst check must see it and carry on at the 1 MHz clock (a session succeeds)
BUS_FAULTS = ("marginal-bus",)
FAULTS = SENSOR_FAULTS + BUS_FAULTS


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
def _check_fault_and_self_test(fault: str | None, self_test: str) -> None:
    """UserError unless ``fault`` is None or one of :data:`FAULTS` and ``self_test`` one of
    :data:`SELF_TEST_PARTS`."""
    if fault is not None and fault not in FAULTS:
        raise UserError(f"emulator fault must be one of {', '.join(FAULTS)}, not {fault!r}")
    if self_test not in SELF_TEST_PARTS:
        raise UserError(f"emulator self_test must be pass or fail, not {self_test!r}")


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
    ``self_test`` (:data:`SELF_TEST_PARTS`: how the part answers its self-test), ``extra_args``.

    Boot like the real board (``boot=True``): the stk500v2 bootloader in the boot section runs
    first after every reset (≈ 0.8 s, in real time), then the application; ``elf`` (an ``.elf``
    or ``.hex``) is then optional. ``flash`` = a persistent flash image file (implies ``boot``):
    loaded at start if it exists, written back after avrdude programs it and at exit; an ``elf``
    given as well is programmed over it at start. See ``host/board/flash.py``.
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
        self_test: str = "pass",
        wait_open: bool = True,
        dtr_reset: bool = True,
        workdir: str | Path | None = None,
        emulator: str | Path | None = None,
        extra_args: Sequence[str] = (),
        start_timeout_s: float = 30.0,
        boot: bool = False,
        flash: str | Path | None = None,
    ) -> None:
        _check_fault_and_self_test(fault, self_test)
        self.elf = Path(elf) if elf else None
        self.stimulus = stimulus
        self.seconds = seconds
        self.realtime = realtime
        self.fault = fault
        self.self_test = self_test
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
        self._not_started()

    def _not_started(self) -> None:
        """The state before :meth:`start`: no port, process, summary or stimulus pipe yet."""
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
        if self.self_test != "pass":
            cmd += ["--self-test", self.self_test]
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
        if self._proc.stdout is not None and not (self._reader and self._reader.is_alive()):
            self._proc.stdout.close()  # read to its end (else left open: a ResourceWarning)
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
