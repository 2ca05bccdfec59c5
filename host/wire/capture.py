"""Capture files: the bytes read from a port, with the host time of each read.

Format (``IMUCAP01``, documented in protocol/README.md): the 8 bytes ``IMUCAP01``, then records
of (uint64 LE host monotonic time in ns taken right after ``read()`` returned, uint32 LE byte
count n, the n bytes as read). A plain byte file without the magic is a raw capture.

A capture whose last record is cut short (the program was killed mid-write) keeps every
complete record and reports the cut; nothing already written is lost. A damaged read header (a
flipped bit, a byte inserted or lost) loses the read it hit, not the rest: the reader
resynchronises on its own read headers and says what it skipped (:class:`CaptureUnwrapper`,
:func:`damage_text`).
"""

from __future__ import annotations

import os
import stat
from dataclasses import dataclass
from pathlib import Path
from typing import BinaryIO

import numpy as np

from host.errors import UserError, write_error
from host.wire.resync import (
    MAX_CANDIDATES,
    MAX_GAP_NS,
    MAX_READ,
    REC,
    RESYNC_CHAIN,
    best_parse,
    header_candidates,
    header_chain,
)

MAGIC = b"IMUCAP01"


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
        k = np.minimum(_read_of(self.chunk_end, offsets), self.chunk_ns.size - 1)
        return self.chunk_ns[k]


def _read_of(ends: np.ndarray, offsets: np.ndarray | int) -> np.ndarray:
    """For each offset, the number of reads that end at or before it (``ends`` increasing):
    the index of the read holding that byte. Offsets in order (a chunk's samples) are
    counted off the ends, a bisection per read rather than per sample."""
    at = np.asarray(offsets)
    if at.ndim != 1 or at.size < 2 * ends.size or np.any(at[1:] < at[:-1]):
        return np.searchsorted(ends, at, side="right")
    first = np.searchsorted(at, ends, side="left")  # the first offset past each read's end
    return np.repeat(np.arange(ends.size + 1), np.diff(first, prepend=0, append=at.size))


def parse(raw: bytes, source: str = "capture") -> Capture:
    """Parse IMUCAP01 bytes (with the magic); damaged read headers are skipped
    (:class:`CaptureUnwrapper`)."""
    if not raw.startswith(MAGIC):
        raise UserError(f"{source}: not an IMUCAP01 capture (magic missing)")
    u = CaptureUnwrapper(times=True)
    data = u.feed(raw) + u.finish()
    return Capture(
        data,
        *u.reads(),
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


#: captures above this size are refused where a capture is read whole (import, replay://;
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
            "'python3 -m host capture --port PORT FILE', then decode FILE"
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

    Damage is contained to the read it hits, for reads of any length: a read header is taken
    when it is plausible (its length 1 to :data:`MAX_READ` — the writer never writes an empty
    read —, its time not before the previous read's nor more than :data:`MAX_GAP_NS` after)
    and :data:`RESYNC_CHAIN` more headers chain on from it, each where the one before ends.
    Where the chain breaks, the bytes there are parsed the way that keeps the most reads less
    what its damaged places cost (:func:`host.wire.resync.best_parse`): a flipped bit or a
    byte inserted or deleted loses the read it hit (its bytes are kept when its own header
    checks), and :attr:`skipped` lists each place (file offset, bytes skipped; 0 where a read
    was cut short). A read is held until the headers after it have come, so memory stays below about
    5 × :data:`MAX_READ` beyond what is fed.

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
        self._retry_at = 0  # after damage: weigh it again once the file is this long
        self.total = 0  # port bytes passed on so far
        self.skipped: list[tuple[int, int]] = []
        # each read's host time and where its bytes end, in parts (joined when asked for):
        # numpy arrays, not lists of ints, a capture of small reads having millions
        self._reads_ns: list[np.ndarray] = []
        self._reads_end: list[np.ndarray] = []

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

    # ---- the walk ------------------------------------------------------------------------
    def _plausible(self, t: int, n: int) -> bool:
        """A read header's own check: its length 1 to :data:`MAX_READ`, its time not before
        the previous read's nor more than :data:`MAX_GAP_NS` after it."""
        if not 0 < n <= MAX_READ:
            return False
        return self._prev_t is None or self._prev_t <= t <= self._prev_t + MAX_GAP_NS

    def _bridges(self, buf: bytearray, q: int, t: int, n: int) -> bool:
        """Does the read at ``q`` (time ``t``, length ``n``) hold, where one bit cleared in
        its length would end it, a chain of headers that ends where it ends, their times
        between its and the next one's? (A flipped bit in the length made it swallow the
        reads after it.)"""
        end = q + REC.size + n
        t_next = REC.unpack_from(buf, end)[0]
        bits = n & ~15  # the header found must leave a read of at least one byte
        while bits:
            bit = bits & -bits  # each bit set, the lowest first
            bits ^= bit
            c, t_c = end - bit, t
            while c < end - REC.size:
                t2, n2 = REC.unpack_from(buf, c)
                if not (0 < n2 <= MAX_READ and t_c <= t2 <= t_next):
                    break
                c, t_c = c + REC.size + n2, t2
            if c == end:
                return True
        return False

    def _run(self, final: bool) -> bytes:
        buf = self._buf
        out: list[np.ndarray] = []  # the reads passed on: (start, end) rows in buf
        pos = 0
        # the headers from ``pos`` on checked so far: the last one's position, time and
        # length, and how many links lead to it (each header where the one before ends,
        # its length plausible, its time not before nor a week after the one before)
        chk, depth, t_chk, n_chk = 0, -1, 0, 0
        while pos < len(buf):
            if pos + REC.size <= len(buf):
                if (clean := self._take_clean(buf, pos, out)) != pos:
                    pos, depth = clean, -1
                    continue
                if depth < 0:
                    t_chk, n_chk = REC.unpack_from(buf, pos)
                    chk, depth = pos, 0 if self._plausible(t_chk, n_chk) else -2
                while 0 <= depth < RESYNC_CHAIN:
                    end = chk + REC.size + n_chk
                    if end + REC.size > len(buf):
                        break
                    t2, n2 = REC.unpack_from(buf, end)
                    if not (0 < n2 <= MAX_READ and t_chk <= t2 <= t_chk + MAX_GAP_NS):
                        depth = -2  # broken
                        break
                    chk, depth, t_chk, n_chk = end, depth + 1, t2, n2
                if depth >= RESYNC_CHAIN:
                    t, n = REC.unpack_from(buf, pos)
                    if not self._bridges(buf, pos, t, n):
                        out.append(self._take(buf, t, pos + REC.size, pos + REC.size + n))
                        pos += REC.size + n
                        depth -= 1
                        continue
                elif depth >= 0 and not final:
                    break  # the headers to come decide
            elif not final:
                break
            depth = -1
            if not final and self._base + len(buf) < self._retry_at:
                break  # too few new bytes since the last try to change its answer
            moved = self._repair(buf, pos, final, out)
            if moved is None:
                # try again when the bytes after ``pos`` have grown by a quarter
                self._retry_at = self._base + len(buf) + max(REC.size, (len(buf) - pos) // 4)
                break
            self._retry_at = 0
            if moved == pos:
                break
            pos = moved
        if final:
            self._cut = len(buf) - pos
        data = _gather(buf, out)
        del buf[:pos]
        self._base += pos
        return data

    def _take_clean(self, buf: bytearray, pos: int, out: list[np.ndarray]) -> int:
        """Take the reads from ``pos`` on that :meth:`_run` takes one by one, all at once
        where the headers chain on undamaged: each plausible after the one before,
        :data:`RESYNC_CHAIN` more after it, and none of the headers that a bridge
        (:meth:`_bridges`) would start with; returns where reading goes on."""
        # the chain of headers by their lengths alone (host.wire.resync.header_chain), then
        # their times checked at once: the reads stop at the first time not plausible
        at, lengths_a = header_chain(buf, pos)
        if at.size <= RESYNC_CHAIN:
            return pos
        times_a = _field_at(buf, "<u8", 0, at)
        first = times_a[0] if self._prev_t is None else self._prev_t
        prev_a = np.concatenate((np.asarray([first], dtype=np.uint64), times_a[:-1]))
        late = (times_a < prev_a) | (times_a - prev_a > np.uint64(MAX_GAP_NS))
        if late.any():
            cut = int(np.argmax(late))
            at, times_a, lengths_a = at[:cut], times_a[:cut], lengths_a[:cut]
        k = at.size - RESYNC_CHAIN  # the reads with a chain of headers after them
        if k <= 0:
            return pos
        n_ = lengths_a[:k]
        t_ = times_a[: k + 1]
        end = at[:k] + REC.size + n_
        k = _first_bridge(buf, end, n_, t_)  # the reads before it are clean
        if k == 0:
            return pos
        out.append(np.stack((end[:k] - n_[:k], end[:k]), axis=1))
        self._prev_t = int(times_a[k - 1])
        if self._times:
            self._reads_ns.append(t_[:k])
            self._reads_end.append(self.total + np.cumsum(n_[:k]))
        self.total += int(np.sum(n_[:k]))
        return int(end[k - 1])

    def _repair(self, buf: bytearray, pos: int, final: bool, out: list[np.ndarray]) -> int | None:
        """Where the chain of headers breaks at or after ``pos``: the parse of the bytes from
        ``pos`` that keeps the most reads less what its damaged places cost
        (:func:`host.wire.resync.best_parse`; a chain of headers shifted by a lost byte wins
        over a false header that swallows it); its reads are passed on up to
        :data:`RESYNC_CHAIN` before the end of the bytes at hand (the rest is read again).
        Returns the position reading goes on from, or None when more bytes must decide."""
        n_buf = len(buf)
        lookahead = (RESYNC_CHAIN + 2) * (MAX_READ + REC.size)
        limit = min(n_buf, pos + lookahead)
        p, t, n = header_candidates(buf, pos, limit, self._prev_t)
        forced = n_buf >= pos + lookahead
        if p.size > MAX_CANDIDATES:
            p, t, n = p[:MAX_CANDIDATES], t[:MAX_CANDIDATES], n[:MAX_CANDIDATES]
            limit, forced = int(p[-1]), True
        at_eof = final and limit == n_buf
        path, tail_links = best_parse(p, t, n, pos, limit, at_eof, self._prev_t)
        if not (at_eof or forced) and tail_links < RESYNC_CHAIN:
            return None  # the reads to come decide
        keep = path if at_eof else path[: max(len(path) - max(tail_links, 1), 0)]
        if not keep and not at_eof:
            keep = path[:1]
            if not keep:  # nothing plausible in the whole window: skip it
                self._skip(pos, limit - REC.size - pos)
                return limit - REC.size
        here = pos
        for k, i in enumerate(keep):
            q = int(p[i])
            if q > here:
                self._skip(here, q - here)
            end = q + REC.size + int(n[i])
            nxt = int(p[path[k + 1]]) if k + 1 < len(path) else None
            if nxt is not None and nxt < end:
                # the next header starts inside it: cut there, unless by one byte (the read
                # lost one, or the header its first: the same bytes; passed on whole, they
                # are right in the second case, and the next read's time is in both)
                cut = end if end - nxt == 1 else nxt
                out.append(self._take(buf, int(t[i]), q + REC.size, cut))
                self._skip(nxt, 0)
                here = nxt
            elif end > n_buf:  # a cut-off last read (final): not passed on
                return q
            else:
                out.append(self._take(buf, int(t[i]), q + REC.size, end))
                here = end
        if at_eof and n_buf - here >= REC.size:
            self._skip(here, n_buf - here)  # no read in what is left
            return n_buf
        return here

    def _skip(self, pos: int, length: int) -> None:
        """Note ``length`` bytes skipped at ``pos`` of the buffer (one place with the last
        when they touch)."""
        at = self._base + pos
        if self.skipped and sum(self.skipped[-1]) == at:
            self.skipped[-1] = (self.skipped[-1][0], self.skipped[-1][1] + length)
        else:
            self.skipped.append((at, length))

    def _take(self, buf: bytearray, t: int, start: int, end: int) -> np.ndarray:
        """Accept the read buf[start:end] of host time ``t`` (its bytes are copied out once,
        with the others', at the end of :meth:`_run`)."""
        self._prev_t = t
        if start != end:
            self.total += end - start
            if self._times:
                self._reads_ns.append(np.asarray([t], dtype=np.uint64))
                self._reads_end.append(np.asarray([self.total], dtype=np.int64))
        return np.array([(start, end)], dtype=np.int64)

    @property
    def truncated_bytes(self) -> int:
        """After :meth:`finish`: the bytes of a cut-off last read (header included) that were
        not passed on (:attr:`Capture.truncated_bytes`)."""
        return self._cut

    def arrival_ns_at(self, offsets: np.ndarray) -> np.ndarray:
        """Host time (ns) of the read that delivered the port byte at each offset (counted
        from the first port byte; offsets at or after :meth:`forget_before`'s)."""
        ns, ends = self.reads()
        k = np.minimum(_read_of(ends, offsets), max(ends.size - 1, 0))
        return ns[k] if ends.size else np.zeros(np.shape(offsets), np.uint64)

    def forget_before(self, offset: int) -> None:
        """Drop the times of reads that ended at or before ``offset``."""
        ns, ends = self.reads()
        k = min(int(np.searchsorted(ends, offset, side="right")), ends.size - 1)
        if k > 0:
            self._reads_ns, self._reads_end = [ns[k:]], [ends[k:]]

    def reads(self) -> tuple[np.ndarray, np.ndarray]:
        """Each read kept: its host time (ns, uint64) and where its bytes end in the port
        bytes (int64), in order (with ``times=True``)."""
        if len(self._reads_ns) != 1:
            self._reads_ns = [np.concatenate([np.zeros(0, np.uint64), *self._reads_ns])]
            self._reads_end = [np.concatenate([np.zeros(0, np.int64), *self._reads_end])]
        return self._reads_ns[0], self._reads_end[0]


def _field_at(buf: bytearray, dtype: str, field: int, at: np.ndarray) -> np.ndarray:
    """The header field of type ``dtype`` at byte ``field`` of each header at ``at`` in
    ``buf`` (little-endian, read unaligned)."""
    size = np.dtype(dtype).itemsize
    view = np.ndarray((len(buf) - field - size + 1,), dtype, buf, field, (1,))
    got = view[at]
    del view  # a view of buf: it may be resized again
    return got


def _first_bridge(buf: bytearray, end: np.ndarray, n: np.ndarray, t: np.ndarray) -> int:
    """The first read a bridge (:meth:`CaptureUnwrapper._bridges`) may start in: for a bit (16
    or more) set in its length ``n``, a plausible header that many bytes before its ``end``
    with a time between the read's and the next one's (``t`` holds one more); ``end.size``
    when there is none."""
    first = end.size
    for b in range(4, int(n.max(initial=0)).bit_length()):
        r = np.flatnonzero(n[:first] & (1 << b))
        c = end[r] - (1 << b)
        # its length's high byte zero, its time between (unsigned: one test), its length
        # plausible: each tested on what the one before left
        z = np.flatnonzero(_field_at(buf, "u1", 11, c) == 0)
        r, c = r[z], c[z]
        t_r = t[r]
        between = np.flatnonzero(_field_at(buf, "<u8", 0, c) - t_r <= t[r + 1] - t_r)
        n2 = _field_at(buf, "<u4", 8, c[between])
        if (maybe := (n2 > 0) & (n2 <= MAX_READ)).any():
            first = int(r[between[np.argmax(maybe)]])
    return first


def _gather(buf: bytearray, spans: list[np.ndarray]) -> bytes:
    """The bytes of ``buf`` in each (start, end) row of ``spans`` (in order, apart), joined:
    long reads by slices of a view, many short ones through one mask that clears the bytes
    between them (a slice costs as much as copying a few hundred bytes)."""
    s = np.concatenate(spans) if spans else np.zeros((0, 2), np.int64)
    if not (full := s[:, 1] > s[:, 0]).all():
        s = s[full]
    if s.size == 0:
        return b""
    if s[-1, 1] - s[0, 0] >= 256 * len(s):
        with memoryview(buf) as view:
            return b"".join([view[a:b] for a, b in s.tolist()])
    lo, hi = int(s[0, 0]), int(s[-1, 1])
    keep = np.ones(hi - lo, bool)
    # between two reads: a header, or what damage skipped; the gaps of each length up to a
    # few headers' cleared as items of that length at once, longer ones slice by slice
    gap_at = s[:-1, 1] - lo
    gap = s[1:, 0] - lo - gap_at
    sizes = np.flatnonzero(np.bincount(np.clip(gap, 0, _WIDE), minlength=_WIDE + 1)).tolist()
    for size in sizes:
        if size == _WIDE:
            for g in np.flatnonzero(gap >= _WIDE).tolist():
                keep[gap_at[g] : gap_at[g] + gap[g]] = False
        elif size:
            at = gap_at if len(sizes) == 1 else gap_at[gap == size]
            items = np.ndarray((keep.size - size + 1,), f"V{size}", keep, 0, (1,))
            items[at] = np.zeros((), f"V{size}")
    arr = np.frombuffer(buf, np.uint8, count=hi - lo, offset=lo)
    data = arr[keep].tobytes()
    del arr
    return data


#: gaps between reads this long and longer (bytes) are cleared slice by slice
_WIDE = 4 * REC.size


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
            self._f.write(REC.pack(t_ns, len(data)) + data)
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
