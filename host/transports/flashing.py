"""Ports for a flasher: the device that avrdude opens for a port name or URL.

A serial device (``/dev/ttyACM0``) is flashed as it is. A URL scheme of this package serves a
device through its adapter when the adapter has a ``serve_flash(url)`` context manager
(``emu://?flash=PATH``: an emulated board with its bootloader, the flash kept in PATH); a
scheme without one is passed on as it is (avrdude then says it cannot open it). The flash
command (:mod:`host.board.flash`) only ever sees :class:`FlashPort`: it never names a scheme.
"""

from __future__ import annotations

import contextlib
import importlib
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any


@dataclass
class FlashPort:
    """What a flasher opens: ``device``, a path (a serial device or a pseudo-terminal), and
    once the port is no longer served, what its transport reports (``summary``: the emulated
    board's run; None for a serial device)."""

    device: str
    summary: dict[str, Any] | None = None


@contextlib.contextmanager
def flash_port(url: str) -> Iterator[FlashPort]:
    """The device to flash for ``url``, served for as long as the ``with`` block runs.

    Raises :class:`host.errors.UserError` when the transport cannot serve the URL (a bad
    option, a missing flash file, a missing emulator toolchain)."""
    scheme, sep, _ = url.partition("://")
    serve = None
    if sep and scheme.isidentifier():
        try:
            adapter = importlib.import_module(f"{__package__}.protocol_{scheme}")
        except ImportError:
            adapter = None
        serve = getattr(adapter, "serve_flash", None)
    if serve is None:
        yield FlashPort(url)
        return
    with serve(url) as port:
        yield port
