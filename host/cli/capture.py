"""``python3 -m host capture FILE --port URL``: record a port's bytes with host times (IMUCAP01).

The port and the timestamped reads are :class:`host.board.link.Link`.
"""

from __future__ import annotations

import argparse
import json
import math
import shutil
import signal
import sys
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from host.board.link import DEFAULT_BAUD, Link
from host.cli.options import Command
from host.errors import UserError
from host.wire.frames import IMU_SAMPLE, SENSOR_ERROR_CODES, Frame, error_text


@dataclass(frozen=True)
class CaptureOptions:
    """``capture``: the file to write, the port and its baud, how long, s of host time (None:
    until Ctrl+C)."""

    file: Path
    port: str
    baud: int = DEFAULT_BAUD
    seconds: float | None = None


def cli_capture(p: argparse.ArgumentParser) -> Command[CaptureOptions]:
    """Fill in the ``capture`` subparser; returns the command."""
    p.add_argument("file", type=Path, help="IMUCAP01 capture file to write")
    p.add_argument("--port", required=True, help="serial device or URL (sim://, emu://, ...)")
    p.add_argument(
        "--baud", type=int, default=DEFAULT_BAUD,
        help=f"the port's baud rate (default {DEFAULT_BAUD}, the firmware's; sim:// and emu:// "
        "take any)",
    )  # fmt: skip
    p.add_argument(
        "--seconds", type=float, default=None,
        help="how long to record, s of host time (default: until Ctrl+C, which keeps the file)",
    )  # fmt: skip
    return Command(capture_options, run_capture)


def capture_options(ns: argparse.Namespace) -> CaptureOptions:
    """The ``capture`` options from its arguments."""
    return CaptureOptions(file=ns.file, port=ns.port, baud=ns.baud, seconds=ns.seconds)


def run_capture(args: CaptureOptions) -> int:
    """Record until ``--seconds`` or Ctrl+C; a status line on stderr once a second (redrawn in
    place on a terminal); the decoder counters as JSON on stdout at the end."""
    if args.seconds is not None and (not math.isfinite(args.seconds) or args.seconds <= 0):
        raise UserError(
            f"--seconds {args.seconds:g}: give a recording time above 0 s (or leave it out to "
            "record until Ctrl+C)"
        )
    if args.file.exists() or args.file.is_symlink():
        raise UserError(
            f"{args.file}: exists; a capture is never overwritten: give a new file name "
            "(or move that one away)"
        )
    tty = sys.stderr.isatty()
    until = f"{args.seconds:g} s" if args.seconds is not None else "Ctrl+C stops"
    print(f"recording {args.port} into {args.file} ({until})", file=sys.stderr)
    with Link.open(args.port, args.baud, capture=args.file) as link:
        start = time.monotonic()
        end = start + args.seconds if args.seconds is not None else math.inf
        n_samples = 0
        sensor_error: Frame | None = None
        next_status = start + 1.0
        # Ctrl+C is taken between reads, never between writing a chunk to the file and
        # counting its samples (the printed count is what the file holds); a read returns
        # within the port's timeout (50 ms), so the stop is prompt.
        stop = _StopOnCtrlC()
        with stop:
            while time.monotonic() < end and not stop.requested:
                _, data = link.read_chunk()
                for f in link.decoder.feed(data):
                    if f.type == IMU_SAMPLE:
                        n_samples += 1
                    elif f.name == "ERROR" and f.fields["code"] in SENSOR_ERROR_CODES:
                        sensor_error = sensor_error or f
                now = time.monotonic()
                if now >= next_status:
                    next_status = now + 1.0
                    _status(now - start, n_samples, link, tty)
        if tty:
            sys.stderr.write("\n")
        elapsed = time.monotonic() - start
    stats = link.stats.as_dict() | {"samples": n_samples, "file": str(args.file)}
    print(f"stopped; {args.file} holds {n_samples} samples", file=sys.stderr)
    print(json.dumps(stats))
    if sensor_error is not None:
        raise UserError(
            f"the board's sensor failed: it reports {error_text(sensor_error)}; {n_samples} "
            f"samples recorded in {args.file}; check the IMU, then power-cycle the board"
        )
    if n_samples == 0:
        raise UserError(
            f"no samples from the board in {elapsed:.1f} s ({args.file} holds what came); "
            "is it streaming? (python3 -m host flash checks its HELLO)"
        )
    return stop.status  # 0 when --seconds ran out; Ctrl+C 130 (the file is whole either way)


class _StopOnCtrlC:
    """While entered, SIGINT (Ctrl+C), SIGTERM and SIGHUP set :attr:`requested` instead of
    ending the program mid-write (the previous handlers are restored on exit)."""

    SIGNALS = tuple(
        getattr(signal, s) for s in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, s)
    )

    def __init__(self) -> None:
        self.requested = False
        #: the exit status the signal asks for (128 + its number: Ctrl+C 130, as every command)
        self.status = 0
        self._old: dict[int, Any] = {}

    def _on_signal(self, signum: int, _frame: Any) -> None:
        self.requested = True
        self.status = 128 + int(signum)

    def __enter__(self) -> _StopOnCtrlC:
        if threading.current_thread() is threading.main_thread():  # signals go to it only
            self._old = {s: signal.signal(s, self._on_signal) for s in self.SIGNALS}
        return self

    def __exit__(self, *_exc: object) -> None:
        for s, old in self._old.items():
            signal.signal(s, old)


def _status(elapsed_s: float, n_samples: int, link: Link, tty: bool) -> None:
    """One status line on stderr: redrawn in place (cut to the width) on a terminal."""
    st = link.stats
    line = (
        f"{elapsed_s:7.1f} s  {n_samples} samples  {st.crc_errors} CRC errors  "
        f"{st.lost_frames} frames lost"
    )
    if tty:
        cols = shutil.get_terminal_size().columns
        sys.stderr.write("\r" + line[: cols - 1] + "\x1b[K")
    else:
        sys.stderr.write(line + "\n")
    sys.stderr.flush()
