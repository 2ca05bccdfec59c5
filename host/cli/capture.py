"""``python -m host capture FILE --port URL``: record a port's bytes with host times (IMUCAP01).

The port and the timestamped reads are :class:`host.board.link.Link`.
"""

from __future__ import annotations

import json
import math
import sys
import time
from pathlib import Path
from typing import Any

from host.board.link import DEFAULT_BAUD, Link
from host.errors import UserError
from host.wire.frames import IMU_SAMPLE, SENSOR_ERROR_CODES, Frame, error_text


def cli_capture(p: Any) -> Any:
    p.add_argument("file", type=Path, help="IMUCAP01 capture file to write")
    p.add_argument("--port", required=True, help="serial device or URL (sim://, emu://, ...)")
    p.add_argument("--baud", type=int, default=DEFAULT_BAUD)
    p.add_argument("--seconds", type=float, default=10.0, help="how long to record (host time)")
    return run_capture


def run_capture(args: Any) -> int:
    if not math.isfinite(args.seconds) or args.seconds <= 0:
        raise UserError(f"--seconds {args.seconds:g}: give a recording time above 0 s")
    with Link.open(args.port, args.baud, capture=args.file) as link:
        end = time.monotonic() + args.seconds
        n_samples = 0
        sensor_error: Frame | None = None
        try:
            while time.monotonic() < end:
                _, data = link.read_chunk()
                for f in link.decoder.feed(data):
                    if f.type == IMU_SAMPLE:
                        n_samples += 1
                    elif f.name == "ERROR" and f.fields["code"] in SENSOR_ERROR_CODES:
                        sensor_error = sensor_error or f
        except KeyboardInterrupt:
            print("stopped; the capture so far is kept", file=sys.stderr)
    stats = link.stats.as_dict() | {"samples": n_samples, "file": str(args.file)}
    print(json.dumps(stats))
    if sensor_error is not None:
        raise UserError(
            f"the board's sensor failed: it reports {error_text(sensor_error)}; {n_samples} "
            f"samples recorded in {args.file}; check the IMU, then power-cycle the board"
        )
    if n_samples == 0:
        raise UserError(
            f"no samples from the board in {args.seconds:g} s ({args.file} holds what came); "
            "is it streaming? (python -m host flash checks its HELLO)"
        )
    return 0
