"""``replay://`` — play a capture back as if it were the board.

URL grammar::

    replay://PATH[?speed=realtime|max|FACTOR][&loop=0|1]

``PATH`` is a raw byte capture or an IMUCAP01 capture (host/wire/capture.py). With
``speed=realtime`` (the default) each recorded read is released at its recorded host time
relative to the open;
``FACTOR`` plays faster (2 = twice as fast); ``max`` releases everything at once. Writes are
accepted and ignored (a capture cannot answer commands). At the end of the capture, reads
return nothing, like a board that stopped sending (or start again with ``loop=1``).
"""

from __future__ import annotations

import time
import urllib.parse
from typing import Any

import serial
from serial.serialutil import Timeout

from host.wire import capture


class Serial(serial.SerialBase):
    """A read-only serial port backed by a capture file."""

    def open(self) -> None:
        if not self.portstr:
            raise serial.SerialException("replay:// needs a capture path")
        self._parse(self.portstr)
        self._cap = capture.read(self._path)
        self._t0 = time.monotonic()
        self._pos = 0
        self.is_open = True

    def _parse(self, url: str) -> None:
        parts = urllib.parse.urlsplit(url)
        if parts.scheme != "replay":
            raise serial.SerialException(f"expected replay://PATH, got {url!r}")
        self._path = urllib.parse.unquote(parts.netloc + parts.path)
        q = urllib.parse.parse_qs(parts.query)
        speed = q.get("speed", ["realtime"])[0]
        self._speed = 0.0 if speed == "max" else 1.0 if speed == "realtime" else float(speed)
        self._loop = q.get("loop", ["0"])[0] == "1"

    def _available_end(self) -> int:
        """Offset in the capture's data up to which bytes have 'arrived' by now."""
        cap = self._cap
        if self._speed == 0.0 or cap.chunk_ns.size <= 1:
            return len(cap.data)
        elapsed_ns = (time.monotonic() - self._t0) * 1e9 * self._speed
        rel = cap.chunk_ns.astype("int64") - int(cap.chunk_ns[0])
        k = int((rel <= elapsed_ns).sum())
        return int(cap.chunk_end[k - 1]) if k else 0

    @property
    def in_waiting(self) -> int:
        return max(0, self._available_end() - self._pos)

    def read(self, size: int = 1) -> bytes:
        if not self.is_open:
            raise serial.PortNotOpenError()
        timeout = Timeout(self.timeout)  # type: ignore[arg-type]  # None: no limit (the stub omits it)
        while True:
            end = min(self._available_end(), self._pos + size)
            if end > self._pos:
                out = self._cap.data[self._pos : end]
                self._pos = end
                return out
            if self._pos >= len(self._cap.data) and self._loop:
                self._pos, self._t0 = 0, time.monotonic()
                continue
            if timeout.expired():
                return b""
            time.sleep(0.001)

    def write(self, data: Any) -> int:
        return len(data)

    def close(self) -> None:
        self.is_open = False

    def reset_input_buffer(self) -> None:
        self._pos = self._available_end()

    def reset_output_buffer(self) -> None:
        pass

    def _reconfigure_port(self) -> None:
        pass
