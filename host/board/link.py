"""Link: open a port by name or URL, read it with host timestamps, decode, send commands.

Ports are anything pyserial opens — ``/dev/ttyACM0``, ``COM3`` — plus this project's URL schemes,
one module per scheme in ``host/transports/`` (``sim://`` the virtual board, ``emu://`` the
emulated board running the real firmware, ``replay://`` a capture played back).

Every read is stamped with the host's monotonic clock right after ``read()`` returns and can be
appended to an IMUCAP01 capture (``host/wire/capture.py``), so that a session can be decoded again
and its device-to-host time mapping recomputed offline.
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import serial

from host.errors import BadURLError, UserError
from host.wire.capture import CaptureWriter
from host.wire.frames import Frame, encode_frame
from host.wire.stream import DecoderStats, StreamDecoder

TRANSPORTS_PACKAGE = "host.transports"
DEFAULT_BAUD = 115200
#: this project's URL schemes (host/transports): their errors name the bad option themselves
OWN_SCHEMES = ("sim://", "emu://", "replay://")


def register_transports() -> None:
    """Make pyserial find ``host/transports/protocol_<scheme>.py`` for ``<scheme>://`` URLs."""
    if TRANSPORTS_PACKAGE not in serial.protocol_handler_packages:
        serial.protocol_handler_packages.append(TRANSPORTS_PACKAGE)


class LinkLost(UserError):
    """The port vanished (cable pulled, board reset into nothing, emulator killed)."""


class LinkTimeout(UserError):
    """The board stopped sending."""


def open_port(url: str, baud: int = DEFAULT_BAUD, timeout_s: float = 0.05) -> serial.SerialBase:
    """Open a serial device or URL; raise UserError with what to do if it cannot be opened."""
    register_transports()
    try:
        return serial.serial_for_url(url, baudrate=baud, timeout=timeout_s)
    except ValueError as exc:  # unknown URL scheme or bad parameters
        if url.startswith(OWN_SCHEMES):  # a bad option: the message names it
            raise UserError(f"cannot open {url!r}: {exc}") from None
        raise UserError(
            f"cannot open {url!r}: {exc}; use a serial device (e.g. /dev/ttyACM0), sim:// "
            "(virtual board) or emu:// (emulated board)"
        ) from None
    except (serial.SerialException, OSError) as exc:
        if isinstance(exc, BadURLError):  # a bad sim:// option: the message names it
            raise UserError(f"cannot open {url!r}: {exc}") from None
        raise UserError(
            f"cannot open {url!r}: {exc}; check the USB cable and the port name "
            "(python3 -m serial.tools.list_ports lists them), or use sim:// to try without a board"
        ) from None


class Link:
    """A port being read: timestamped chunks in, decoded frames out, commands back.

    ``frames()`` yields ``(arrival_ns, frame)`` where arrival_ns is the host monotonic time of
    the read that completed the frame. A vanished port raises :class:`LinkLost`; no data for
    ``stall_s`` seconds raises :class:`LinkTimeout`.
    """

    def __init__(
        self,
        port: serial.SerialBase,
        capture: str | Path | None = None,
        stall_s: float = 2.0,
    ) -> None:
        self.port = port
        self.decoder = StreamDecoder()
        self.capture = CaptureWriter(capture) if capture else None
        self.stall_s = stall_s
        self._tx_seq = 0
        self._last_rx = time.monotonic()

    @classmethod
    def open(cls, url: str, baud: int = DEFAULT_BAUD, **kw: Any) -> Link:
        return cls(open_port(url, baud), **kw)

    @property
    def stats(self) -> DecoderStats:
        return self.decoder.stats

    def read_chunk(self) -> tuple[int, bytes]:
        """One read: (host monotonic ns right after it returned, the bytes; maybe empty)."""
        try:
            data = self.port.read(getattr(self.port, "in_waiting", 0) or 1)
        except (serial.SerialException, OSError) as exc:
            raise LinkLost(
                f"the board disconnected ({exc}); reconnect it — accepted records are kept"
            ) from None
        t_ns = time.monotonic_ns()
        if data:
            self._last_rx = time.monotonic()
            if self.capture:
                self.capture.write(t_ns, data)
        elif time.monotonic() - self._last_rx > self.stall_s:
            raise LinkTimeout(
                f"no data from the board for {self.stall_s:.1f} s; check the cable and that "
                "the firmware is running (python3 -m host flash)"
            )
        return t_ns, data

    def frames(self) -> Iterator[tuple[int, Frame]]:
        """Decoded frames as they arrive, forever (until the port fails or stalls)."""
        while True:
            t_ns, data = self.read_chunk()
            if data:
                for f in self.decoder.feed(data):
                    yield t_ns, f

    def send(self, msg: str, **fields: int) -> int:
        """Send a host command; return the seq it was sent with (ACKs name it)."""
        seq = self._tx_seq
        self._tx_seq = (self._tx_seq + 1) & 0xFFFF
        try:
            self.port.write(encode_frame(msg, seq, **fields))
        except (serial.SerialException, OSError) as exc:
            raise LinkLost(f"cannot write to the board ({exc}); reconnect it") from None
        return seq

    def close(self) -> None:
        if self.capture:
            self.capture.close()
        try:
            self.port.close()
        except (serial.SerialException, OSError):
            pass

    def __enter__(self) -> Link:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
