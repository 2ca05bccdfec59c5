"""``python3 -m host flash``: build, flash and verify the firmware, then check its HELLO.

The work is :func:`host.board.flash.flash`; this module only reads the options.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from pathlib import Path

from host.board.flash import BOOTLOADER_BAUD, DEFAULT_PORT, HELLO_TIMEOUT_S, flash


def cli_flash(p: argparse.ArgumentParser) -> Callable[[argparse.Namespace], int]:
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
    return run_flash


def run_flash(args: argparse.Namespace) -> int:
    flash(args.port, args.hex, args.baud, hello_timeout_s=args.hello_timeout)
    return 0
