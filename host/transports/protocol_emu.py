"""``emu://`` — the emulated APM 2.6 (real firmware on simavr, MPU-6000 model) as a pyserial port.

URL grammar (all options optional, ``&``-separated)::

    emu://[?elf=PATH][&seconds=N][&realtime=0|1][&stimulus=PATH][&fault=absent|stuck-miso|no-drdy]
          [&fault_at=S][&noise_accel=SIGMA][&noise_gyro=SIGMA][&seed=S][&clock_ppm=PPM]
          [&reglog=PATH][&samplelog=PATH][&workdir=DIR]

- ``elf``: firmware to run (default: ``make -C firmware`` into ``firmware/build/`` first).
- ``seconds``: simulated seconds before the board stops answering (default: until the stimulus
  ends, or until the port is closed without one).
- ``realtime``: 1 paces simulated time to the wall clock; default 0 runs as fast as the host
  reads (tens of times real time), so device time runs ahead of host time.
- ``stimulus``: a stimulus file (``host.emulator.write_stimulus``); default: at rest, Z up,
  25 °C.
- ``fault``: sensor fault from ``fault_at`` simulated seconds on (default 0): ``absent`` (no
  answer on SPI, no data-ready), ``stuck-miso`` (every byte read is 0xFF), ``no-drdy`` (the INT
  line never rises).
- ``noise_accel`` (m/s²), ``noise_gyro`` (°/s), ``seed``: white noise added before quantisation.
- ``clock_ppm``: MPU-6000 sample clock error against the AVR crystal.
- ``reglog``, ``samplelog``: write the register-access / produced-sample CSV logs there.

Opening the port starts the emulator and opens its pseudo-terminal (the open is the DTR reset:
the AVR starts from reset); closing stops it. After ``close()``, ``port.emulator_summary`` holds
the emulator's summary (speed, SPI violations, bus conflicts, samples, CPU cycles per sample);
while open, ``port.board`` is the :class:`host.emulator.EmulatedBoard`.

Needs simavr, libsimavr-dev, gcc-avr and avr-libc; without them ``open()`` raises
:class:`host.errors.UserError` saying so.
"""

from __future__ import annotations

import urllib.parse as urlparse
from typing import Any

from serial.serialposix import Serial as PosixSerial
from serial.serialutil import SerialException

from host.emulator import FAULTS, EmulatedBoard

_FLOAT = ("seconds", "fault_at", "noise_accel", "noise_gyro", "clock_ppm")
_PATH = ("elf", "stimulus", "reglog", "samplelog", "workdir")


def parse_url(url: str) -> dict[str, Any]:
    """``emu://?...`` -> keyword arguments for :class:`EmulatedBoard` (ValueError if bad)."""
    parts = urlparse.urlsplit(url)
    if parts.scheme != "emu":
        raise ValueError(f"expected an emu:// URL, not {url!r}")
    if parts.netloc or parts.path not in ("", "/"):
        raise ValueError(f"emu:// takes only ?options, not {parts.netloc + parts.path!r}")
    kw: dict[str, Any] = {}
    for key, values in urlparse.parse_qs(parts.query, keep_blank_values=True).items():
        value = values[-1]
        try:
            if key in _FLOAT:
                kw[key] = float(value)
            elif key in _PATH:
                kw[key] = value
            elif key == "realtime":
                kw[key] = value.lower() in ("1", "true", "yes", "")
            elif key == "seed":
                kw[key] = int(value, 0)
            elif key == "fault":
                if value not in FAULTS:
                    raise ValueError(f"fault must be one of {', '.join(FAULTS)}")
                kw[key] = value
            else:
                raise ValueError("unknown option")
        except ValueError as exc:
            raise ValueError(f"emu:// option {key}={value!r}: {exc}") from None
    return kw


class Serial(PosixSerial):
    """pyserial port whose ``open()`` starts an emulated board and opens its pty."""

    board: EmulatedBoard | None = None
    emulator_summary: dict[str, Any] | None = None

    def open(self) -> None:
        if self.port is None:
            raise SerialException("Port must be configured before it can be used.")
        if self.is_open:
            raise SerialException("Port is already open.")
        kwargs = parse_url(self.port)
        board = EmulatedBoard(**kwargs)
        board.start()  # UserError (missing simavr, build failure) propagates as is
        url = self.portstr
        self.portstr = board.port
        try:
            super().open()
        except BaseException:
            board.stop()
            raise
        finally:
            self.portstr = url
        self.board = board
        self.emulator_summary = None

    def close(self) -> None:
        super().close()
        board, self.board = self.board, None
        if board is not None:
            self.emulator_summary = board.stop()

    def from_url(self, url: str) -> str:
        parse_url(url)
        return url
