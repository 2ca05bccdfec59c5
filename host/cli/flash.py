"""``python3 -m host flash``: build, flash and verify the firmware, then check its HELLO.

The work is :func:`host.board.flash.flash`; this module only reads the options.
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass
from pathlib import Path

from host.board.flash import BOOTLOADER_BAUD, DEFAULT_PORT, HELLO_TIMEOUT_S, flash
from host.cli.options import Command


@dataclass(frozen=True)
class FlashOptions:
    """``flash``: the port, the hex (None: built), the bootloader's baud, how long to wait for
    the HELLO after flashing, s."""

    port: str = DEFAULT_PORT
    hex: Path | None = None
    baud: int = BOOTLOADER_BAUD
    hello_timeout_s: float = HELLO_TIMEOUT_S


def cli_flash(p: argparse.ArgumentParser) -> Command[FlashOptions]:
    """Fill in the ``flash`` subparser; returns the command."""
    p.add_argument(
        "--port",
        default=DEFAULT_PORT,
        help=f"serial device (default {DEFAULT_PORT}) or emu://?flash=PATH (emulated board)",
    )
    p.add_argument(
        "--hex", type=Path, help="Intel hex to flash (default: make -C firmware, its build/ hex)"
    )
    p.add_argument(
        "--baud", type=int, default=BOOTLOADER_BAUD, help="bootloader baud (default 115200)"
    )
    p.add_argument(
        "--hello-timeout",
        type=float,
        default=HELLO_TIMEOUT_S,
        help="seconds to wait for HELLO after flashing",
    )
    return Command(flash_options, run_flash)


def flash_options(ns: argparse.Namespace) -> FlashOptions:
    """The ``flash`` options from its arguments."""
    return FlashOptions(port=ns.port, hex=ns.hex, baud=ns.baud, hello_timeout_s=ns.hello_timeout)


def run_flash(opts: FlashOptions) -> int:
    """Runner of ``python3 -m host flash``."""
    flash(opts.port, opts.hex, opts.baud, hello_timeout_s=opts.hello_timeout_s)
    return 0
