"""Capture files: the bytes read from a port, with the host time of each read.

Format (``IMUCAP01``, documented in protocol/README.md): the 8 bytes ``IMUCAP01``, then records
of (uint64 LE host monotonic time in ns taken right after ``read()`` returned, uint32 LE byte
count n, the n bytes as read). A plain byte file without the magic is a raw capture.

A capture whose last record is cut short (the program was killed mid-write) keeps every
complete record and reports the cut; nothing already written is lost.
"""

from __future__ import annotations

import os
import stat
import struct
from dataclasses import dataclass
from pathlib import Path
from typing import BinaryIO

import numpy as np

from host.errors import UserError, write_error

MAGIC = b"IMUCAP01"
_REC = struct.Struct("<QI")


@dataclass(frozen=True)
class Capture:
    """A parsed capture: the concatenated bytes and, per read, its host time and end offset."""

    data: bytes
    chunk_ns: np.ndarray  # (K,) uint64 host monotonic ns of each read
    chunk_end: np.ndarray  # (K,) int64 offset in ``data`` one past each read's last byte
    truncated_bytes: int = 0  # bytes of a cut-off last record that were ignored

    def arrival_ns_at(self, offsets: np.ndarray) -> np.ndarray:
        """Host time (ns) of the read that delivered the byte at each offset of ``data``."""
        k = np.searchsorted(self.chunk_end, np.asarray(offsets), side="right")
        k = np.minimum(k, self.chunk_ns.size - 1)
        return self.chunk_ns[k]


def parse(raw: bytes, source: str = "capture") -> Capture:
    """Parse IMUCAP01 bytes (with the magic)."""
    if not raw.startswith(MAGIC):
        raise UserError(f"{source}: not an IMUCAP01 capture (magic missing)")
    pos = len(MAGIC)
    times: list[int] = []
    ends: list[int] = []
    parts: list[bytes] = []
    total = 0
    truncated = 0
    while pos < len(raw):
        if pos + _REC.size > len(raw):
            truncated = len(raw) - pos
            break
        t_ns, n = _REC.unpack_from(raw, pos)
        pos += _REC.size
        if pos + n > len(raw):
            truncated = len(raw) - pos + _REC.size
            break
        parts.append(raw[pos : pos + n])
        pos += n
        total += n
        times.append(t_ns)
        ends.append(total)
    return Capture(
        b"".join(parts),
        np.asarray(times, dtype=np.uint64),
        np.asarray(ends, dtype=np.int64),
        truncated,
    )


#: captures above this size are refused (decoding holds the capture and its samples in memory):
#: 512 MiB is ≈ 90 hours of the board's 50 Hz stream
MAX_CAPTURE_BYTES = 512 << 20


def read_capture_bytes(path: str | os.PathLike[str], limit: int = MAX_CAPTURE_BYTES) -> bytes:
    """The bytes of a capture *file*, refusing what cannot be one: a FIFO, a device (reading
    ``/dev/zero`` never ends; opening a FIFO blocks until a writer comes), a directory, a file
    above ``limit`` bytes. UserError naming the file and what to do."""
    p = Path(path)
    try:
        st = p.stat()  # stat never blocks, opening a FIFO does
    except FileNotFoundError:
        raise UserError(f"{p}: no such file; give the path of a capture") from None
    except OSError as exc:
        raise UserError(f"{p}: cannot read ({exc.strerror or exc})") from None
    if stat.S_ISDIR(st.st_mode):
        raise UserError(f"{p}: is a directory; give the path of a capture file")
    if not stat.S_ISREG(st.st_mode):
        raise UserError(
            f"{p}: not a regular file (a device or a pipe); to record a port use "
            "'python -m host capture --port PORT FILE', then decode FILE"
        )
    if st.st_size > limit:
        raise UserError(
            f"{p}: {st.st_size / 2**20:.0f} MiB is more than the {limit / 2**20:.0f} MiB decode "
            "reads at once; record shorter captures (capture --seconds)"
        )
    try:
        with open(p, "rb") as f:
            return f.read(limit + 1)[:limit]
    except OSError as exc:
        raise UserError(f"{p}: cannot read ({exc.strerror or exc})") from None


def read(path: str | os.PathLike[str]) -> Capture:
    """Read a capture file; a raw byte file becomes one chunk with time 0."""
    p = Path(path)
    raw = read_capture_bytes(p)
    if raw.startswith(MAGIC):
        return parse(raw, source=str(p))
    return Capture(raw, np.zeros(1, np.uint64), np.asarray([len(raw)], np.int64))


class CaptureUnwrapper:
    """Incremental IMUCAP01 parser: ``feed`` the file's bytes in any pieces (magic first),
    get back the recorded port bytes they complete (read times are dropped)."""

    def __init__(self) -> None:
        self._buf = bytearray()
        self._magic_left = len(MAGIC)

    def feed(self, data: bytes) -> bytes:
        self._buf += data
        if self._magic_left:
            k = min(self._magic_left, len(self._buf))
            del self._buf[:k]
            self._magic_left -= k
        out = bytearray()
        while len(self._buf) >= _REC.size:
            _, n = _REC.unpack_from(self._buf, 0)
            if len(self._buf) < _REC.size + n:
                break
            out += self._buf[_REC.size : _REC.size + n]
            del self._buf[: _REC.size + n]
        return bytes(out)


class CaptureWriter:
    """Append reads to an IMUCAP01 file as they happen (flushed per read, so a crash keeps them)."""

    def __init__(self, path: str | os.PathLike[str]) -> None:
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._f: BinaryIO | None = open(self.path, "wb")  # noqa: SIM115 - closed in close()
        self._f.write(MAGIC)
        self._f.flush()

    def write(self, t_ns: int, data: bytes) -> None:
        """Record one read: host monotonic ns taken right after it returned, and its bytes."""
        if self._f is None or not data:
            return
        try:
            self._f.write(_REC.pack(t_ns, len(data)) + data)
            self._f.flush()
        except OSError as exc:
            raise write_error(self.path, exc, "what was read before is in it") from None

    def close(self) -> None:
        if self._f is not None:
            self._f.close()
            self._f = None

    def __enter__(self) -> CaptureWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
