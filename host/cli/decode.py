"""``python3 -m host decode FILE``: a capture's samples as JSONL or CSV, or the decoder counters.

The input streams through in chunks (:class:`host.wire.bulk.BulkReader`): a capture of any
size, a FIFO or an endless device decodes in bounded memory, and rows are written as they are
decoded. The device→host clock map of an IMUCAP01 capture is built as the samples stream in
(:class:`host.timing.timeline.TimelineBuilder`: the same map as
:func:`host.timing.timeline.build_timeline` of the whole file).
"""

from __future__ import annotations

import argparse
import json
import stat
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, TextIO

import numpy as np

from host.cli.options import Command
from host.errors import UserError
from host.wire import capture, sensor
from host.wire.bulk import (
    SAMPLE_DTYPE,
    BulkReader,
    BulkResult,
    baud_from_hello,
    foreign_text,
    full_scale_from_hello,
    product_id_from_hello,
    samples_to_physical,
    unreadable,
)
from host.wire.frames import BY_NAME, IMU_FIELDS, Frame, status_text
from host.wire.segments import repeated, repeated_text

if TYPE_CHECKING:  # (imported where a capture's arrival times need the clock map)
    from host.timing import timeline


@dataclass(frozen=True)
class DecodeOptions:
    """``decode``: the input; CSV rows (else JSON lines), or only the decoder counters."""

    file: Path
    csv: bool = False
    stats: bool = False


def cli_decode(p: argparse.ArgumentParser) -> Command[DecodeOptions]:
    """Fill in the ``decode`` subparser; returns the command."""
    p.add_argument(
        "file",
        type=Path,
        help="raw byte capture or IMUCAP01 capture with arrival times (a file of any size, "
        "a FIFO or a device: read in chunks until it ends)",
    )
    fmt = p.add_mutually_exclusive_group()
    fmt.add_argument("--jsonl", action="store_true", help="one JSON object per sample (default)")
    fmt.add_argument("--csv", action="store_true", help="CSV with a header row")
    p.add_argument("--stats", action="store_true", help="print only the decoder counters (JSON)")
    return Command(decode_options, run_decode)


def decode_options(ns: argparse.Namespace) -> DecodeOptions:
    """The ``decode`` options from its arguments."""
    return DecodeOptions(file=ns.file, csv=ns.csv, stats=ns.stats)


def _clock_summary(seg: timeline.Segment) -> dict[str, Any]:
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
            "windows": seg.clock.windows,
        }
    return out


_OUT_COLUMNS = ["seq", "t_us", "flags"] + [f"{n}_raw" for n in IMU_FIELDS]
_PHYS = ["ax", "ay", "az", "gx", "gy", "gz", "temp"]
_DIGITS = {"ax": 5, "ay": 5, "az": 5, "gx": 4, "gy": 4, "gz": 4, "temp": 3}


#: a device clock further off the host's than this (ppm) means the arrival times are nonsense
#: (a ceramic resonator is within ±5000 ppm, a crystal ±100)
MAX_PLAUSIBLE_SKEW_PPM = 10_000.0
#: samples held back until a HELLO says how to scale them (a capture started on a running
#: board sees HELLO only after a reset); beyond, the firmware's ±2 g, ±250 °/s apply
HOLD_FOR_HELLO = 1 << 18
#: segments listed under "clock" by --stats (a garbled stream can reset at every frame)
MAX_LISTED_SEGMENTS = 1000


class _Decode:
    """The decode command's pipeline over the chunks of one input: scale, map, write."""

    def __init__(self, args: DecodeOptions, out: TextIO) -> None:
        self.args = args
        self.path = args.file
        self.out = out
        self.hellos: list[tuple[int, Frame]] = []
        self.config: tuple[int, int, int | None] | None = None  # AFS_SEL, FS_SEL, PRODUCT_ID
        #: where the scaling changes: (port byte offset of a HELLO, its config), by offset
        self.scales: list[tuple[int, tuple[int, int, int | None]]] = []
        self.bus_warning: str | None = None
        self.held: list[tuple[np.ndarray, np.ndarray | None]] = []
        self.held_n = 0
        self.timeline: timeline.TimelineBuilder | None = None
        self.warned_segments = 0
        self.capture = False
        self.writer: Any = None
        self.cols: list[str] = []
        #: CRC-valid frames of another length than this spec's, not HELLO: named at the end
        self.foreign: list[tuple[int, int, int]] = []
        self.repeated = 0  # samples dropped as repeats of one before (segments.repeated)

    def add(self, result: BulkResult, arrivals: np.ndarray | None) -> None:
        twice = repeated(result.samples)  # a capture's read written twice: kept once
        if twice.any():
            self.repeated += int(twice.sum())
            keep = ~twice
            result = BulkResult(result.samples[keep], result.others, result.stats, result.foreign)
            arrivals = None if arrivals is None else arrivals[keep]
        stop = None if self.args.stats else unreadable(result)
        if stop is not None:  # the samples before it are decoded; none after it
            keep = result.samples["offset"] < stop[0]
            others = [(o, f) for o, f in result.others if o < stop[0]]
            result = BulkResult(result.samples[keep], others, result.stats)
            arrivals = None if arrivals is None else arrivals[keep]
        self._add(result, arrivals)
        hello = BY_NAME["HELLO"].type  # (a HELLO's stops the decoding: named below)
        self.foreign += [x for x in result.foreign if self.args.stats or x[1] != hello]
        if stop is not None:
            self._drain()
            raise UserError(
                f"{self.path}: byte {stop[0]}: {stop[1]}; decoding stops there (the samples "
                "before it are written): the samples after it were not measured with scales "
                "this program can read — decode them with the host of that firmware and sensor "
                "(decode --stats still counts the frames)"
            )

    def _add(self, result: BulkResult, arrivals: np.ndarray | None) -> None:
        self.capture = arrivals is not None
        new = [(o, f) for o, f in result.others if f.name == "HELLO"]
        if new and not self.args.stats:
            from host.board.hello import check_spec  # (imports the link, pyserial: when needed)

            for o, f in new:
                check_spec(
                    f.fields["spec_fingerprint"],
                    who=f"{self.path}: the firmware whose HELLO is at byte {o}",
                    remedy="its frames cannot be read as this spec's; decode it with the host "
                    "of that firmware's version (decode --stats still counts the frames)",
                    protocol_version=f.fields["protocol_version"],
                )
        self.hellos += new
        if self.config is not None:  # a later HELLO: the samples after it scale by it
            self.scales += [(o, cfg) for o, f in new if (cfg := _hello_config(f)) is not None]
        for _, f in result.others:  # the board's word on its bus (STATUS.flags), the latest
            if f.name == "STATUS" and (text := status_text(f)):
                self.bus_warning = text
        if self.config is None:
            self.held.append((result.samples, arrivals))
            self.held_n += result.samples.size
            valid = any(
                f.fields["accel_fs_sel"] in sensor.ACCEL_LSB_PER_G
                and f.fields["gyro_fs_sel"] in sensor.GYRO_LSB_PER_DPS
                for _, f in self.hellos
            )
            stats_only = self.args.stats and (self.hellos or not self.capture)  # needs no scale
            if valid or stats_only or self.held_n > HOLD_FOR_HELLO:
                self._decide()
            return
        self._samples(result.samples, arrivals)

    def _decide(self) -> None:
        """Scaling and baud from the HELLO frames seen (the first valid one, as
        :func:`~host.wire.bulk.full_scale_from_hello`), then release what was held."""
        self.config = (
            (0, 0, None)
            if self.args.stats
            else (*full_scale_from_hello(self.hellos), product_id_from_hello(self.hellos))
        )
        # the first valid HELLO scales what came before it; each later one what follows it
        valid = [(o, cfg) for o, f in self.hellos if (cfg := _hello_config(f)) is not None]
        self.scales = [(-1, self.config), *valid[1:]]
        if self.capture:
            from host.timing import timeline

            self.timeline = timeline.TimelineBuilder(
                baud=baud_from_hello(self.hellos),
                keep_segments=MAX_LISTED_SEGMENTS,
                map_samples=not self.args.stats,  # --stats prints the maps, no sample
            )
        held, self.held = self.held, []
        for s, a in held:
            self._samples(s, a)

    def _samples(self, s: np.ndarray, arrivals: np.ndarray | None) -> None:
        if self.timeline is None:
            self._write(s, None, None)
            return
        for block in self.timeline.add(s, arrivals):
            self._write(block.samples, block.host_ns, block.arrival_ns)
        self._warn()

    def _drain(self) -> None:
        """Write every sample held (for a HELLO, for the clock map)."""
        if self.config is None:
            self._decide()
        if self.timeline is not None:
            for block in self.timeline.finish():
                self._write(block.samples, block.host_ns, block.arrival_ns)
            self._warn()
        self._write(np.zeros(0, SAMPLE_DTYPE), None, None)  # the CSV header, with no samples

    def finish(self, reader: BulkReader) -> int:
        self._drain()
        if text := foreign_text(self.path, self.foreign):
            print(f"warning: {text}", file=sys.stderr)
        if self.repeated:
            print(f"warning: {self.path}: {repeated_text(self.repeated)}", file=sys.stderr)
        if self.bus_warning:
            print(f"warning: {self.path}: {self.bus_warning}", file=sys.stderr)
        if self.config is not None and (unknown := sensor.revision_warning(self.config[2])):
            print(f"warning: {self.path}: {unknown}", file=sys.stderr)
        if warning := capture.damage_text(self.path, reader.truncated_bytes, reader.skipped):
            print(warning, file=sys.stderr)
        if self.args.stats:
            stats: dict[str, Any] = reader.stats.as_dict()
            if self.timeline is not None:
                stats["clock"] = [_clock_summary(g) for g in self.timeline.segments]
                if self.timeline.segments_dropped:
                    stats["clock_segments_not_listed"] = self.timeline.segments_dropped
            print(json.dumps(stats), file=self.out)
        return 0

    def _warn(self) -> None:
        """One warning per segment whose clock says its arrival times are not its own."""
        assert self.timeline is not None
        segs = self.timeline.segments
        while self.warned_segments < len(segs):
            k = self.warned_segments
            seg = segs[k]
            self.warned_segments += 1
            if seg.clock is None:
                continue
            skew = seg.clock.overall.skew_ppm
            if not abs(skew) <= MAX_PLAUSIBLE_SKEW_PPM:
                print(
                    f"warning: {self.path}: segment {k}: the device clock runs {skew:+.0f} ppm "
                    "against the host's arrival times (a board's is within ±"
                    f"{MAX_PLAUSIBLE_SKEW_PPM:g}): the arrival times do not belong to these "
                    "samples (capture edited or joined?); t_host_ns is not trustworthy",
                    file=sys.stderr,
                )
        while self.timeline.implausible:
            from host.timing.timeline import MAX_HELD_SAMPLES

            k = self.timeline.implausible.pop(0)
            print(
                f"warning: {self.path}: segment {k}: its device times are no board's (more "
                f"than {MAX_HELD_SAMPLES} samples for one clock window); t_host_ns are "
                "the arrival times",
                file=sys.stderr,
            )

    def _write(self, s: np.ndarray, host_ns: np.ndarray | None, arr: np.ndarray | None) -> None:
        if self.args.stats or (s.size == 0 and self.writer is not None):
            return
        assert self.config is not None
        if self.writer is None:
            self.cols = _OUT_COLUMNS + _PHYS + (["t_host_ns"] if self.capture else [])
            if self.args.csv:
                import csv

                self.writer = csv.writer(self.out, lineterminator="\n")
                self.writer.writerow(self.cols)
            else:
                self.writer = True
        if s.size == 0:
            return
        phys = self._physical(s)
        raw_cols = [s["seq"], s["t_us"], s["flags"]] + [s[n] for n in IMU_FIELDS]
        phys_cols = [np.round(phys[k], _DIGITS[k]) for k in _PHYS]
        table = [c.tolist() for c in raw_cols + phys_cols]
        if host_ns is not None and arr is not None:
            # unmapped or out of int64's range (nonsense arrival times, warned): the arrival
            ok = np.isfinite(host_ns) & (np.abs(host_ns) < 2.0**62)
            mapped = np.where(ok, np.rint(np.where(ok, host_ns, 0.0)), 0.0).astype(np.int64)
            column = mapped.tolist()
            for i in np.flatnonzero(~ok).tolist():  # as read (was: cast to int64, wrapped < 0)
                column[i] = int(arr[i])
            table.append(column)
        if self.args.csv:
            self.writer.writerows(zip(*table, strict=True))
        else:
            cols = self.cols
            self.out.write(
                "".join(
                    json.dumps(dict(zip(cols, row, strict=True))) + "\n"
                    for row in zip(*table, strict=True)
                )
            )

    def _physical(self, s: np.ndarray) -> dict[str, np.ndarray]:
        """The samples in physical units, each by the HELLO before it (:attr:`scales`)."""
        assert self.config is not None
        if len(self.scales) <= 1:
            return samples_to_physical(s, *self.config)
        starts = np.asarray([o for o, _ in self.scales])
        which = np.searchsorted(starts, s["offset"], side="right") - 1
        out = {k: np.empty(s.size) for k in _PHYS}
        for k in np.unique(which).tolist():
            rows = which == k
            part = samples_to_physical(s[rows], *self.scales[max(k, 0)][1])
            for name in _PHYS:
                out[name][rows] = part[name]
        return out


def _hello_config(f: Frame) -> tuple[int, int, int | None] | None:
    """A HELLO's scaling (AFS_SEL, FS_SEL, PRODUCT_ID), None when an MPU-6000 has no such
    codes."""
    afs, fs = f.fields["accel_fs_sel"], f.fields["gyro_fs_sel"]
    if afs in sensor.ACCEL_LSB_PER_G and fs in sensor.GYRO_LSB_PER_DPS:
        return afs, fs, f.fields["product_id"]
    return None


#: freed blocks up to this size stay with the allocator for the next chunk's arrays (bytes)
KEEP_FREED = 32 << 20


def _keep_freed_memory() -> None:
    """Let glibc's allocator reuse the memory of one chunk's arrays for the next. By default
    an array above 128 KiB (up to 32 MiB as it learns) is mapped fresh and its pages returned
    when freed, and the heap is trimmed above twice that, so each 4 MiB chunk's temporaries
    fault their pages in again: on 1.5 M frames 43 k page faults of which this saves 18 k,
    8 % of the run's CPU time. Peak memory stays the same (what is kept is what the next
    chunk takes again: benchmarks/decode_memory.py). Without ``mallopt`` nothing changes."""
    import ctypes  # (numpy has imported it already)

    try:
        mallopt = ctypes.CDLL(None).mallopt
    except (OSError, AttributeError):
        return
    m_trim_threshold, m_mmap_threshold = -1, -3  # glibc's malloc.h
    mallopt(m_mmap_threshold, KEEP_FREED)
    mallopt(m_trim_threshold, 2 * KEEP_FREED)


def run_decode(args: DecodeOptions) -> int:
    path: Path = args.file
    _keep_freed_memory()
    try:
        mode = path.stat().st_mode
    except OSError:
        mode = 0
    if stat.S_ISFIFO(mode):
        print(f"decode: waiting for a writer on the FIFO {path} (Ctrl+C to stop)", file=sys.stderr)
    elif stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        print(f"decode: reading the device {path} until it ends (Ctrl+C to stop)", file=sys.stderr)
    with capture.open_stream(path) as stream:
        reader = BulkReader(stream)
        job = _Decode(args, sys.stdout)
        try:
            for result, arrivals in reader:
                job.add(result, arrivals)
            return job.finish(reader)
        except BrokenPipeError:  # e.g. piped into head: stop reading
            sys.stderr.close()
            return 0
