"""Capture files: the bytes read from a port, with the host time of each read.

Format (``IMUCAP01``, documented in protocol/README.md): the 8 bytes ``IMUCAP01``, then records
of (uint64 LE host monotonic time in ns taken right after ``read()`` returned, uint32 LE byte
count n, the n bytes as read). A plain byte file without the magic is a raw capture.

A capture whose last record is cut short (the program was killed mid-write) keeps every
complete record and reports the cut; nothing already written is lost.
"""

from __future__ import annotations

import bisect
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


#: captures above this size are refused where a capture is read whole (import, noise, replay://;
#: ``decode`` streams instead): 512 MiB is ≈ 90 hours of the board's 50 Hz stream
MAX_CAPTURE_BYTES = 512 << 20


def read_capture_bytes(path: str | os.PathLike[str], limit: int = MAX_CAPTURE_BYTES) -> bytes:
    """The bytes of a capture *file*, refusing what cannot be one: a FIFO, a device (reading
    ``/dev/zero`` never ends; opening a FIFO blocks until a writer comes), a directory, a file
    above ``limit`` bytes. UserError naming the file and what to do."""
    p = Path(path)
    st = _stat_capture(p)
    if not stat.S_ISREG(st.st_mode):
        raise UserError(
            f"{p}: not a regular file (a device or a pipe); to record a port use "
            "'python -m host capture --port PORT FILE', then decode FILE"
        )
    if st.st_size > limit:
        raise UserError(
            f"{p}: {st.st_size / 2**20:.0f} MiB is more than the {limit / 2**20:.0f} MiB read "
            "at once here ('decode' streams captures of any size); record shorter captures "
            "(capture --seconds)"
        )
    try:
        with open(p, "rb") as f:
            return f.read(limit + 1)[:limit]
    except OSError as exc:
        raise UserError(f"{p}: cannot read ({exc.strerror or exc})") from None


def _stat_capture(p: Path) -> os.stat_result:
    """``p``'s status (stat never blocks, opening a FIFO does); UserError when it is missing,
    unreadable or a directory."""
    try:
        st = p.stat()
    except FileNotFoundError:
        raise UserError(f"{p}: no such file; give the path of a capture") from None
    except OSError as exc:
        raise UserError(f"{p}: cannot read ({exc.strerror or exc})") from None
    if stat.S_ISDIR(st.st_mode):
        raise UserError(f"{p}: is a directory; give the path of a capture file")
    return st


def open_stream(path: str | os.PathLike[str]) -> BinaryIO:
    """Open a capture to read as a stream: a file of any size, a FIFO (opening waits for its
    writer), a device (read until it ends). UserError naming the path when it is missing, a
    directory or unreadable."""
    p = Path(path)
    _stat_capture(p)
    try:
        return open(p, "rb", buffering=0)  # noqa: SIM115 - the caller closes it
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
    get back the recorded port bytes they complete.

    With ``times=True`` it also keeps each read's host time and where its bytes end in the
    port bytes (:meth:`arrival_ns_at`; :meth:`forget_before` drops what is no longer asked
    for). A read's bytes are held until the read is complete, as :func:`parse` does with a
    cut-off last read; a read longer than ``hold`` bytes (no port read is: this only happens
    in a made-up file) is passed on as it comes, so memory stays bounded.
    """

    def __init__(self, times: bool = False, hold: int = 1 << 20) -> None:
        self._buf = bytearray()
        self._magic_left = len(MAGIC)
        self._times = times
        self.hold = hold
        self._body_left = 0  # bytes of the current read still to come
        self._streaming = False  # the current read is being passed on as it comes
        self._header = 0  # bytes of the current read's header taken (while _body_left)
        self.total = 0  # port bytes passed on so far
        self._reads_ns: list[int] = []
        self._reads_end: list[int] = []

    def feed(self, data: bytes | bytearray | memoryview) -> bytes:
        self._buf += data
        if self._magic_left:
            k = min(self._magic_left, len(self._buf))
            del self._buf[:k]
            self._magic_left -= k
        out = bytearray()
        while True:
            if self._body_left:
                if self._streaming or len(self._buf) >= self._body_left:
                    k = min(self._body_left, len(self._buf))
                    out += self._buf[:k]
                    del self._buf[:k]
                    self._body_left -= k
                    self.total += k
                    if self._body_left:
                        break
                    self._streaming = False
                    continue
                if len(self._buf) > self.hold:
                    self._streaming = True
                    continue
                break
            if len(self._buf) < _REC.size:
                break
            t_ns, n = _REC.unpack_from(self._buf, 0)
            del self._buf[: _REC.size]
            if self._times and n:
                self._reads_ns.append(t_ns)
                self._reads_end.append(self.total + n)
            self._body_left = n
        return bytes(out)

    @property
    def truncated_bytes(self) -> int:
        """At the end of the file: the bytes of a cut-off last read (header included) that
        were not passed on (:attr:`Capture.truncated_bytes`)."""
        if self._body_left and not self._streaming:
            return _REC.size + len(self._buf)
        return len(self._buf)

    def arrival_ns_at(self, offsets: np.ndarray) -> np.ndarray:
        """Host time (ns) of the read that delivered the port byte at each offset (counted
        from the first port byte; offsets at or after :meth:`forget_before`'s)."""
        ends = np.asarray(self._reads_end, dtype=np.int64)
        k = np.searchsorted(ends, np.asarray(offsets), side="right")
        k = np.minimum(k, max(ends.size - 1, 0))
        return (
            np.asarray(self._reads_ns, dtype=np.uint64)[k]
            if ends.size
            else np.zeros(np.shape(offsets), np.uint64)
        )

    def forget_before(self, offset: int) -> None:
        """Drop the times of reads that ended at or before ``offset``."""
        k = min(bisect.bisect_right(self._reads_end, offset), len(self._reads_end) - 1)
        if k > 0:
            del self._reads_ns[:k]
            del self._reads_end[:k]


def create_capture_file(path: Path) -> BinaryIO:
    """A new, empty capture file at ``path`` (its directory made): never an existing file, so
    a capture is never overwritten (UserError naming it and what to give instead)."""
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        return open(path, "xb")  # noqa: SIM115 - the caller closes it
    except FileExistsError:
        raise UserError(
            f"{path}: exists; a capture is never overwritten: give a new file name "
            "(or move that one away)"
        ) from None
    except OSError as exc:
        raise write_error(path, exc, "nothing was written") from None


class CaptureWriter:
    """Append reads to an IMUCAP01 file as they happen (flushed per read, so a crash keeps
    them); the file must not exist yet (:func:`create_capture_file`)."""

    def __init__(self, path: str | os.PathLike[str]) -> None:
        self.path = Path(path)
        self._f: BinaryIO | None = create_capture_file(self.path)
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
            self.failed = True
            raise write_error(self.path, exc, "what was read before is in it") from None

    #: a write failed (and was reported): closing does not report it again
    failed = False

    def close(self) -> None:
        """Close the file. After a failed write its unwritten rest cannot be flushed either;
        that was reported already, so closing (often in a ``finally``, where a new error would
        hide the first one and its advice) stays quiet."""
        f, self._f = self._f, None
        if f is None:
            return
        try:
            f.close()
        except OSError as exc:
            if not self.failed:
                self.failed = True
                raise write_error(self.path, exc, "what was read before is in it") from None

    def __enter__(self) -> CaptureWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
