"""A capture as ``noise`` reads it, in bounded memory at any length: decoded once, in chunks,
into a temporary file of samples (22 bytes each), then read back in blocks for each pass of
:func:`host.model.recording.analyse_blocks`, whose phases wait in temporary files too
(:class:`FilePhases`). The samples are those of the longest segment between board resets,
scaled by the HELLO before it, their device times unwrapped across the blocks.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import BinaryIO

import numpy as np

from host.errors import UserError
from host.model import allan
from host.session.spacing import TimingQuality, ValueCounts, spacing_quality
from host.wire.frames import Frame

#: what is kept of a decoded sample: device µs as sent, segment, counts
_FIELDS = ("t_us", "segment", "ax", "ay", "az", "temp", "gx", "gy", "gz")
_ROW = np.dtype([("t_us", "<u4"), ("segment", "<i4")] + [(c, "<i2") for c in _FIELDS[2:]])


class CaptureSamples:
    """The samples of a capture file (raw or IMUCAP01), as :class:`host.model.recording.Blocks`
    of times (s, device clock), channels ax..gz (m/s², °/s) and temperature (°C). Decoding
    writes them to ``work`` (a directory the caller removes); ``note`` says what was read;
    ``block`` samples at a time are read back (a few MiB of arrays)."""

    def __init__(self, path: Path, work: Path, block: int = 1 << 16) -> None:
        from host.wire.bulk import BulkReader, unreadable
        from host.wire.capture import damage_text, open_stream

        self.block = block
        self._file = work / "samples.bin"
        hellos: list[tuple[int, Frame]] = []
        per_segment: dict[int, int] = {}
        starts: dict[int, int] = {}  # byte offset of each segment's first sample
        with open_stream(path) as f, open(self._file, "wb") as out:
            reader = BulkReader(f)
            for result, _ in reader:
                if (stop := unreadable(result)) is not None:  # no scale to read them by
                    why = f"{path}: byte {stop[0]}: {stop[1]}"
                    raise UserError(f"{why}; its samples cannot be scaled as measured")
                s = result.samples
                hellos += [(o, fr) for o, fr in result.others if fr.name == "HELLO"]
                if s.size == 0:
                    continue
                rows = np.empty(s.size, _ROW)
                for name in _FIELDS:
                    rows[name] = s[name]
                rows.tofile(out)
                ids, first, counts = np.unique(s["segment"], return_index=True, return_counts=True)
                for i, k, c in zip(ids.tolist(), first.tolist(), counts.tolist(), strict=True):
                    per_segment[i] = per_segment.get(i, 0) + c
                    starts.setdefault(i, int(s["offset"][k]))
        if warning := damage_text(path, reader.truncated_bytes, reader.skipped):
            print(warning, file=sys.stderr)
        if not per_segment:
            raise UserError(
                f"{path}: no IMU samples in this capture; is it a capture of the board?"
            )
        order = sorted(per_segment)
        longest = max(order, key=lambda i: (per_segment[i], -i))
        # segments follow each other in the stream: the longest starts after those before it
        self._start = sum(per_segment[i] for i in order if i < longest)
        self._size = per_segment[longest]
        note = f"capture ({self._size} samples"
        if len(order) > 1:
            note += f", the longest of {len(order)} segments between board resets"
        self.note = note + ")"
        from host.wire.bulk import full_scale_from_hello, product_id_from_hello

        # the scales of the HELLO the segment began with (the board may have come back at
        # another full scale), else of the first
        before = [h for h in reversed(hellos) if h[0] < starts[longest]] or hellos
        self._scale = (*full_scale_from_hello(before), product_id_from_hello(before))

    @property
    def size(self) -> int:
        return self._size

    def blocks(self) -> Iterator[tuple[np.ndarray, np.ndarray, np.ndarray | None]]:
        from host.wire.bulk import samples_to_physical

        afs, fs, pid = self._scale
        last_raw, last_us = -1, 0
        for a in range(0, self._size, self.block):
            count = min(self.block, self._size - a)
            rows = np.fromfile(
                self._file, _ROW, count=count, offset=(self._start + a) * _ROW.itemsize
            )
            raw = rows["t_us"].astype(np.int64)
            # the device's 32-bit µs counter, unwrapped across the blocks (it only moves on)
            prev = raw[0] if last_raw < 0 else last_raw
            step = np.diff(np.concatenate([[prev], raw])) % (1 << 32)
            t_us = (raw[0] if last_raw < 0 else last_us) + np.cumsum(step)
            last_raw, last_us = int(raw[-1]), int(t_us[-1])
            phys = samples_to_physical(rows, afs, fs, pid)
            data = np.column_stack([phys[c] for c in allan.CHANNELS])
            yield t_us.astype(np.float64) / 1e6, data, phys["temp"]

    def timing(self) -> TimingQuality:
        """The sample spacing (one pass over the blocks)."""
        counts, last = ValueCounts(), None
        for t, _, _ in self.blocks():
            counts.add(np.diff(t if last is None else np.concatenate([[last], t])) * 1000.0)
            last = t[-1]
        return spacing_quality(counts)


class FilePhases:
    """A :class:`host.model.recording.PhaseStore` in a temporary file in ``work``: appended
    in pieces, read back by windows, removed with the directory (or when dropped)."""

    _count = 0

    def __init__(self, work: Path) -> None:
        FilePhases._count += 1
        self._path = work / f"phase{FilePhases._count}.bin"
        self._out: BinaryIO | None = open(self._path, "wb")  # noqa: SIM115 - closed when read

    def append(self, values: np.ndarray) -> None:
        assert self._out is not None, "appended after it was read"
        np.asarray(values, dtype="<f8").tofile(self._out)

    def window(self, a: int, b: int) -> np.ndarray:
        if self._out is not None:
            self._out.close()
            self._out = None
        return np.fromfile(self._path, "<f8", count=max(b - a, 0), offset=8 * a)

    def __del__(self) -> None:
        if self._out is not None:
            self._out.close()
        if self._path.exists():
            os.unlink(self._path)
