"""Capture files: the bytes read from a port, with the host time of each read.

Format (``IMUCAP01``, documented in protocol/README.md): the 8 bytes ``IMUCAP01``, then records
of (uint64 LE host monotonic time in ns taken right after ``read()`` returned, uint32 LE byte
count n, the n bytes as read). A plain byte file without the magic is a raw capture.

A capture whose last record is cut short (the program was killed mid-write) keeps every
complete record and reports the cut; nothing already written is lost. A damaged read header (a
flipped bit, a byte inserted or lost) loses the read it hit, not the rest: the reader
resynchronises on the next plausible pair of headers and says what it skipped
(:class:`CaptureUnwrapper`, :func:`damage_text`).
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


#: a read's plausible length, bytes: a port read is at most the port's buffer (a few KiB); a
#: length above this is damage (a flipped bit), not a read
MAX_READ = 1 << 20
#: after damage, reading resumes at a header followed by this many plausible ones (or by the
#: end of the file)
RESYNC_CHAIN = 3
#: a read's plausible host time: the next read comes at most this long after it, ns (a week:
#: a session that waits for a board to come back waits minutes, not days)
MAX_GAP_NS = 7 * 24 * 3600 * 10**9


@dataclass(frozen=True)
class Capture:
    """A parsed capture: the concatenated bytes and, per read, its host time and end offset."""

    data: bytes
    chunk_ns: np.ndarray  # (K,) uint64 host monotonic ns of each read
    chunk_end: np.ndarray  # (K,) int64 offset in ``data`` one past each read's last byte
    truncated_bytes: int = 0  # bytes of a cut-off last record that were ignored
    #: damaged places: (file offset, bytes skipped) each, in file order (:func:`damage_text`)
    skipped: tuple[tuple[int, int], ...] = ()

    def arrival_ns_at(self, offsets: np.ndarray) -> np.ndarray:
        """Host time (ns) of the read that delivered the byte at each offset of ``data``."""
        k = np.searchsorted(self.chunk_end, np.asarray(offsets), side="right")
        k = np.minimum(k, self.chunk_ns.size - 1)
        return self.chunk_ns[k]


def parse(raw: bytes, source: str = "capture") -> Capture:
    """Parse IMUCAP01 bytes (with the magic); damaged read headers are skipped
    (:class:`CaptureUnwrapper`)."""
    if not raw.startswith(MAGIC):
        raise UserError(f"{source}: not an IMUCAP01 capture (magic missing)")
    u = CaptureUnwrapper(times=True)
    data = u.feed(raw) + u.finish()
    return Capture(
        data,
        np.asarray(u._reads_ns, dtype=np.uint64),
        np.asarray(u._reads_end, dtype=np.int64),
        u.truncated_bytes,
        tuple(u.skipped),
    )


def damage_text(path: object, truncated: int, skipped: tuple[tuple[int, int], ...] | list) -> str:
    """The warning for a capture's damage (empty when there is none): the places whose bytes
    were skipped (file offsets) and a cut-off end."""
    parts = []
    if skipped:
        where = ", ".join(f"byte {o}: {n or 'nothing'} skipped" for o, n in skipped[:3])
        more = f" and {len(skipped) - 3} more" if len(skipped) > 3 else ""
        parts.append(
            f"{len(skipped)} damaged place(s) in the file ({where}{more}); the reads there are "
            "lost, every read around them is decoded"
        )
    if truncated:
        parts.append(
            f"the last {truncated} bytes are a cut-off read (the recording was interrupted); "
            "decoded everything before them"
        )
    return f"warning: {path}: " + "; ".join(parts) if parts else ""


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
    then :meth:`finish` at the end of the file; each returns the recorded port bytes it
    completes.

    Damage is contained to the read it hits: a read header is taken only when it is plausible
    (its length 1 to :data:`MAX_READ` — the writer never writes an empty read —, its time not
    before the previous read's) and the
    next header, where its length says, is plausible too and not earlier nor more than
    :data:`MAX_GAP_NS` later. Otherwise the bytes are searched for the next such pair of
    headers: a flipped bit or a byte inserted or deleted loses the read it hit (its bytes are
    kept when its own header checks and ends before the next good one), and :attr:`skipped`
    lists each place (file offset, bytes skipped). A read is held until the header after it
    has come, so memory stays below about 5 × :data:`MAX_READ` beyond what is fed.

    With ``times=True`` it also keeps each read's host time and where its bytes end in the
    port bytes (:meth:`arrival_ns_at`; :meth:`forget_before` drops what is no longer asked for).
    """

    def __init__(self, times: bool = False) -> None:
        self._buf = bytearray()
        self._magic_left = len(MAGIC)
        self._times = times
        self._base = len(MAGIC)  # file offset of _buf[0]
        self._prev_t: int | None = None
        self._cut = 0  # at the end: bytes of a cut-off last read
        self.total = 0  # port bytes passed on so far
        self.skipped: list[tuple[int, int]] = []
        self._reads_ns: list[int] = []
        self._reads_end: list[int] = []

    def feed(self, data: bytes | bytearray | memoryview) -> bytes:
        """The port bytes of the reads that ``data`` completes (and checks)."""
        if self._magic_left:
            k = min(self._magic_left, len(data))
            data = data[k:]
            self._magic_left -= k
        self._buf += data
        return self._run(final=False)

    def finish(self) -> bytes:
        """At the end of the file: the port bytes of the reads held back so far."""
        return self._run(final=True)

    # ---- the checks ----------------------------------------------------------------------
    def _next_ok(self, buf: bytearray, end: int, t: int, final: bool) -> bool | None:
        """Is the header at ``end`` (after a read of time ``t``) plausible? None: not yet
        known (more bytes are needed). The end of the file is, and a header cut off there."""
        if end + _REC.size <= len(buf):
            t2, n2 = _REC.unpack_from(buf, end)
            return 0 < n2 <= MAX_READ and t <= t2 <= t + MAX_GAP_NS
        if not final:
            return None
        return end <= len(buf)

    def _chain(self, buf: bytearray, q: int, final: bool) -> tuple[int, str]:
        """Follow the headers from a plausible one at ``q``: how many plausible headers come
        after it (up to :data:`RESYNC_CHAIN`), and how the chain stops: 'long' (that many),
        'end' (exactly at the end of the file), 'broken', or 'more' (bytes still to come)."""
        t, n = _REC.unpack_from(buf, q)
        for steps in range(RESYNC_CHAIN):
            end = q + _REC.size + n
            if end + _REC.size > len(buf):
                if not final:
                    return steps, "more"
                return steps, "end" if end == len(buf) else "broken"
            t2, n2 = _REC.unpack_from(buf, end)
            if not (0 < n2 <= MAX_READ and t <= t2 <= t + MAX_GAP_NS):
                return steps, "broken"
            q, t, n = end, t2, n2
        return RESYNC_CHAIN, "long"

    def _find(self, buf: bytearray, start: int, final: bool) -> tuple[int, bool]:
        """The first position from ``start`` where a plausible header starts a chain of
        :data:`RESYNC_CHAIN` more (one that ends exactly at the end of the file if none
        does; len(buf) if none at all), and True; or the first position that more bytes must
        decide, and False (every position before it is no header)."""
        n_buf = len(buf)
        arr = np.frombuffer(buf, dtype=np.uint8)
        lo = start
        at_end: int | None = None
        while lo + _REC.size <= n_buf:
            hi = min(n_buf - _REC.size + 1, lo + (1 << 16))
            idx = np.arange(lo, hi)
            n = np.zeros(idx.size, np.uint64)
            for b in range(4):
                n |= arr[idx + 8 + b].astype(np.uint64) << np.uint64(8 * b)
            ok = (n > 0) & (n <= MAX_READ)
            if self._prev_t is not None:
                t = np.zeros(idx.size, np.uint64)
                for b in range(8):
                    t |= arr[idx + b].astype(np.uint64) << np.uint64(8 * b)
                prev = np.uint64(self._prev_t)
                ok &= (t >= prev) & (t <= prev + np.uint64(MAX_GAP_NS))
            for q in idx[ok].tolist():
                _, how = self._chain(buf, q, final)
                if how == "more":
                    return q, False
                if how == "long":
                    return q, True
                if how == "end" and at_end is None:
                    at_end = q
            lo = hi
        if not final:
            return max(start, n_buf - _REC.size + 1), False
        return (at_end if at_end is not None else n_buf), True

    # ---- the walk ------------------------------------------------------------------------
    def _run(self, final: bool) -> bytes:
        buf = self._buf
        out: list[bytes] = []
        pos = 0
        while pos + _REC.size <= len(buf):
            t, n = _REC.unpack_from(buf, pos)
            end = pos + _REC.size + n
            own = 0 < n <= MAX_READ and (self._prev_t is None or t >= self._prev_t)
            if own:
                verdict = self._next_ok(buf, end, t, final)
                if verdict is None:
                    break
                at_end = final and end + _REC.size > len(buf)
                if verdict and not (at_end and self._swallows(buf, pos)):
                    out.append(self._take(buf, t, pos + _REC.size, end))
                    pos = end
                    continue
                if final and end > len(buf) and self._find(buf, pos + 1, final)[0] == len(buf):
                    break  # a cut-off last read, not damage
            q, decided = self._find(buf, pos + 1, final)
            if not decided and len(buf) - pos <= (RESYNC_CHAIN + 2) * (MAX_READ + _REC.size):
                break  # more bytes will tell (bounded: past that, q is far enough)
            # the read's own header checks and it ends before the next good header's bytes
            # (or inside them: a byte lost in that header shifts it back, and garbles its
            # time, which the next turn then refuses): kept
            t_q = _REC.unpack_from(buf, q)[0] if q + _REC.size <= len(buf) else t
            if own and end <= min(q + _REC.size, len(buf)):
                if t <= t_q or q < end or (q == end and not self._own_time_bad(buf, t, q)):
                    out.append(self._take(buf, t, pos + _REC.size, end))
                    if q < end:  # the next header overlaps it: noted, nothing skipped
                        self._skip(q, 0)
                    pos = end
            if q > pos:
                self._skip(pos, q - pos)
            pos = q
            if not decided:
                break
        if final:
            self._cut = len(buf) - pos
        del buf[:pos]
        self._base += pos
        return b"".join(out)

    def _swallows(self, buf: bytearray, pos: int) -> bool:
        """The last read (at ``pos``) ends at the end of the file: do its bytes hold a chain
        of headers to that end (its length damaged, the reads after it inside it)?"""
        return self._find(buf, pos + _REC.size, True)[0] < len(buf)

    def _own_time_bad(self, buf: bytearray, t: int, q: int) -> bool:
        """A read of time ``t`` ends exactly where the next good header (at ``q``, of an
        earlier time) starts: the lengths agree, one of the two times is damaged. Is it
        ``t``? Judged by which one bit flip puts back in order with its neighbours (the read
        before, the read after ``q``'s); when both or neither could, by the read before."""
        t_q, n_q = _REC.unpack_from(buf, q)
        lo = self._prev_t if self._prev_t is not None else 0
        nxt = q + _REC.size + n_q
        hi = _REC.unpack_from(buf, nxt)[0] if nxt + _REC.size <= len(buf) else 1 << 64
        mine = any(lo <= t ^ (1 << b) <= t_q for b in range(64))
        theirs = any(t <= t_q ^ (1 << b) <= hi for b in range(64))
        if mine != theirs:
            return mine
        return self._prev_t is not None and t_q >= self._prev_t

    def _skip(self, pos: int, length: int) -> None:
        """Note ``length`` bytes skipped at ``pos`` of the buffer (one place with the last
        when they touch)."""
        at = self._base + pos
        if self.skipped and sum(self.skipped[-1]) == at:
            self.skipped[-1] = (self.skipped[-1][0], self.skipped[-1][1] + length)
        else:
            self.skipped.append((at, length))

    def _take(self, buf: bytearray, t: int, start: int, end: int) -> bytes:
        """Accept the read buf[start:end] of host time ``t``."""
        self._prev_t = t
        if start == end:
            return b""
        self.total += end - start
        if self._times:
            self._reads_ns.append(t)
            self._reads_end.append(self.total)
        return bytes(buf[start:end])

    @property
    def truncated_bytes(self) -> int:
        """After :meth:`finish`: the bytes of a cut-off last read (header included) that were
        not passed on (:attr:`Capture.truncated_bytes`)."""
        return self._cut

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
