"""``python -m host decode FILE``: a capture's samples as JSONL or CSV, or the decoder counters.

The decoding is :mod:`host.wire.frames` (:func:`~host.wire.frames.decode_file`); the device→host
clock map of an IMUCAP01 capture is :func:`host.timing.clock.build_timeline`.
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

from host.timing import clock
from host.wire.frames import (
    IMU_FIELDS,
    baud_from_hello,
    decode_file,
    full_scale_from_hello,
    samples_to_physical,
)


def cli_decode(p: argparse.ArgumentParser) -> Any:
    p.add_argument(
        "file", type=Path, help="raw byte capture or IMUCAP01 capture with arrival times"
    )
    fmt = p.add_mutually_exclusive_group()
    fmt.add_argument("--jsonl", action="store_true", help="one JSON object per sample (default)")
    fmt.add_argument("--csv", action="store_true", help="CSV with a header row")
    p.add_argument("--stats", action="store_true", help="print only the decoder counters (JSON)")
    return run_decode


def _clock_summary(seg: Any) -> dict[str, Any]:
    """One segment's device-to-host clock map, for --stats."""
    out: dict[str, Any] = {"samples": seg.stop - seg.start, "lost_frames": seg.lost_frames}
    out["missed_samples"] = seg.missed_samples
    if seg.clock is not None:
        m = seg.clock.overall
        out |= {
            "skew_ppm": round(m.skew_ppm, 3),
            "offset_ns": round(m.host0_ns + m.offset_ns - m.b * m.device0_us),
            "latency_median_us": round(m.latency_median_us, 1),
            "floor_spread_us": round(m.floor_spread_us, 1),
            "windows": len(seg.clock.maps),
        }
    return out


_OUT_COLUMNS = ["seq", "t_us", "flags"] + [f"{n}_raw" for n in IMU_FIELDS]
_PHYS = ["ax", "ay", "az", "gx", "gy", "gz", "temp"]
_DIGITS = {"ax": 5, "ay": 5, "az": 5, "gx": 4, "gy": 4, "gz": 4, "temp": 3}


#: a device clock further off the host's than this (ppm) means the arrival times are nonsense
#: (a ceramic resonator is within ±5000 ppm, a crystal ±100)
MAX_PLAUSIBLE_SKEW_PPM = 10_000.0


def run_decode(args: argparse.Namespace) -> int:
    result, arrivals = decode_file(args.file)
    s = result.samples
    timeline = None
    if arrivals is not None:
        timeline = clock.build_timeline(
            s,
            arrivals,
            baud=baud_from_hello(result.others),
        )
    if timeline is not None:
        for k, seg in enumerate(timeline.segments):
            skew = seg.clock.overall.skew_ppm if seg.clock is not None else 0.0
            if not abs(skew) <= MAX_PLAUSIBLE_SKEW_PPM:
                print(
                    f"warning: {args.file}: segment {k}: the device clock runs {skew:+.0f} ppm "
                    "against the host's arrival times (a board's is within ±"
                    f"{MAX_PLAUSIBLE_SKEW_PPM:g}): the arrival times do not belong to these "
                    "samples (capture edited or joined?); t_host_ns is not trustworthy",
                    file=sys.stderr,
                )
    if args.stats:
        out: dict[str, Any] = result.stats.as_dict()
        if timeline is not None:
            out["clock"] = [_clock_summary(seg) for seg in timeline.segments]
        print(json.dumps(out))
        return 0
    phys = samples_to_physical(s, *full_scale_from_hello(result.others))
    cols = _OUT_COLUMNS + _PHYS + (["t_host_ns"] if timeline is not None else [])
    raw_cols = [s["seq"], s["t_us"], s["flags"]] + [s[n] for n in IMU_FIELDS]
    phys_cols = [np.round(phys[k], _DIGITS[k]) for k in _PHYS]
    table = [c.tolist() for c in raw_cols + phys_cols]
    if timeline is not None:
        h = timeline.host_ns
        # unmapped or out of int64's range (nonsense arrival times, warned above): the arrival
        ok = np.isfinite(h) & (np.abs(h) < 2.0**62)
        mapped = np.where(ok, np.rint(np.where(ok, h, 0.0)), 0.0).astype(np.int64)
        mapped[~ok] = np.asarray(arrivals, dtype=np.uint64)[~ok].astype(np.int64)
        table.append(mapped.tolist())
    stdout = sys.stdout
    try:
        if args.csv:
            w = csv.writer(stdout, lineterminator="\n")
            w.writerow(cols)
            w.writerows(zip(*table, strict=True))
        else:
            for row in zip(*table, strict=True):
                stdout.write(json.dumps(dict(zip(cols, row, strict=True))) + "\n")
    except BrokenPipeError:  # e.g. piped into head
        sys.stderr.close()
    return 0
