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

    Damage is contained to the read it hits, for reads of any length: a read header is taken
    when it is plausible (its length 1 to :data:`MAX_READ` — the writer never writes an empty
    read —, its time not before the previous read's nor more than :data:`MAX_GAP_NS` after)
    and :data:`RESYNC_CHAIN` more headers chain on from it, each where the one before ends.
    Where the chain breaks, the bytes there are parsed the way that keeps the most reads less
    what its damaged places cost (:func:`_best_path`): a flipped bit or a byte inserted or
    deleted loses the read it hit (its bytes are kept when its own header checks), and
    :attr:`skipped` lists each place (file offset, bytes skipped; 0 where a read was cut
    short). A read is held until the headers after it have come, so memory stays below about
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
        end = q + _REC.size + n
        t_next = _REC.unpack_from(buf, end)[0]
        bits = n & ~15  # the header found must leave a read of at least one byte
        while bits:
            bit = bits & -bits  # each bit set, the lowest first
            bits ^= bit
            c, t_c = end - bit, t
            while c < end - _REC.size:
                t2, n2 = _REC.unpack_from(buf, c)
                if not (0 < n2 <= MAX_READ and t_c <= t2 <= t_next):
                    break
                c, t_c = c + _REC.size + n2, t2
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
            if pos + _REC.size <= len(buf):
                if (clean := self._take_clean(buf, pos, out)) != pos:
                    pos, depth = clean, -1
                    continue
                if depth < 0:
                    t_chk, n_chk = _REC.unpack_from(buf, pos)
                    chk, depth = pos, 0 if self._plausible(t_chk, n_chk) else -2
                while 0 <= depth < RESYNC_CHAIN:
                    end = chk + _REC.size + n_chk
                    if end + _REC.size > len(buf):
                        break
                    t2, n2 = _REC.unpack_from(buf, end)
                    if not (0 < n2 <= MAX_READ and t_chk <= t2 <= t_chk + MAX_GAP_NS):
                        depth = -2  # broken
                        break
                    chk, depth, t_chk, n_chk = end, depth + 1, t2, n2
                if depth >= RESYNC_CHAIN:
                    t, n = _REC.unpack_from(buf, pos)
                    if not self._bridges(buf, pos, t, n):
                        out.append(self._take(buf, t, pos + _REC.size, pos + _REC.size + n))
                        pos += _REC.size + n
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
                self._retry_at = self._base + len(buf) + max(_REC.size, (len(buf) - pos) // 4)
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
        size, unpack, rec = len(buf), _REC.unpack_from, _REC.size
        at: list[int] = []
        times: list[int] = []
        lengths: list[int] = []
        p, prev = pos, self._prev_t
        while p + rec <= size:
            t, n = unpack(buf, p)
            if not (0 < n <= MAX_READ and (prev is None or prev <= t <= prev + MAX_GAP_NS)):
                break
            at.append(p)
            times.append(t)
            lengths.append(n)
            p, prev = p + rec + n, t
        k = len(at) - RESYNC_CHAIN  # the reads with a chain of headers after them
        if k <= 0:
            return pos
        n_ = np.asarray(lengths[:k], dtype=np.int64)
        t_ = np.asarray(times[: k + 1], dtype=np.uint64)
        end = np.asarray(at[:k], dtype=np.int64) + rec + n_
        # a bridge starts, for a bit (16 or more) set in a read's length, with a plausible
        # header that many bytes before its end: the reads before the first such are clean
        read, bit = np.nonzero((n_[:, None] >> _BITS) & 1)
        if read.size:
            c = end[read] - (np.int64(1) << _BITS[bit])
            head = np.frombuffer(buf, np.uint8, count=size)[c[:, None] + np.arange(rec)]
            t2 = head[:, :8].copy().view("<u8")[:, 0]
            n2 = head[:, 8:].copy().view("<u4")[:, 0]
            maybe = (n2 > 0) & (n2 <= MAX_READ) & (t2 >= t_[read]) & (t2 <= t_[read + 1])
            del head
            if maybe.any():
                k = int(read[np.argmax(maybe)])
                if k == 0:
                    return pos
        out.append(np.stack((end[:k] - n_[:k], end[:k]), axis=1))
        self._prev_t = times[k - 1]
        if self._times:
            self._reads_ns += times[:k]
            self._reads_end += (self.total + np.cumsum(n_[:k])).tolist()
        self.total += int(np.sum(n_[:k]))
        return at[k - 1] + rec + lengths[k - 1]

    def _repair(self, buf: bytearray, pos: int, final: bool, out: list[np.ndarray]) -> int | None:
        """Where the chain of headers breaks at or after ``pos``: the parse of the bytes from
        ``pos`` that keeps the most reads less what its damaged places cost (:func:`_best_path`;
        a chain of headers shifted by a lost byte wins over a false header that swallows it);
        its reads are passed on up to :data:`RESYNC_CHAIN` before the end of the bytes at hand
        (the rest is read again). Returns the position reading goes on from, or None when
        more bytes must decide."""
        n_buf = len(buf)
        lookahead = (RESYNC_CHAIN + 2) * (MAX_READ + _REC.size)
        limit = min(n_buf, pos + lookahead)
        p, t, n = _candidates(buf, pos, limit, self._prev_t)
        forced = n_buf >= pos + lookahead
        if p.size > _MAX_CANDIDATES:
            p, t, n = p[:_MAX_CANDIDATES], t[:_MAX_CANDIDATES], n[:_MAX_CANDIDATES]
            limit, forced = int(p[-1]), True
        at_eof = final and limit == n_buf
        path, tail_links = _best_path(p, t, n, pos, limit, at_eof, self._prev_t)
        if not (at_eof or forced) and tail_links < RESYNC_CHAIN:
            return None  # the reads to come decide
        keep = path if at_eof else path[: max(len(path) - max(tail_links, 1), 0)]
        if not keep and not at_eof:
            keep = path[:1]
            if not keep:  # nothing plausible in the whole window: skip it
                self._skip(pos, limit - _REC.size - pos)
                return limit - _REC.size
        here = pos
        for k, i in enumerate(keep):
            q = int(p[i])
            if q > here:
                self._skip(here, q - here)
            end = q + _REC.size + int(n[i])
            nxt = int(p[path[k + 1]]) if k + 1 < len(path) else None
            if nxt is not None and nxt < end:
                # the next header starts inside it: cut there, unless by one byte (the read
                # lost one, or the header its first: the same bytes; passed on whole, they
                # are right in the second case, and the next read's time is in both)
                cut = end if end - nxt == 1 else nxt
                out.append(self._take(buf, int(t[i]), q + _REC.size, cut))
                self._skip(nxt, 0)
                here = nxt
            elif end > n_buf:  # a cut-off last read (final): not passed on
                return q
            else:
                out.append(self._take(buf, int(t[i]), q + _REC.size, end))
                here = end
        if at_eof and n_buf - here >= _REC.size:
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
                self._reads_ns.append(t)
                self._reads_end.append(self.total)
        return np.array([(start, end)], dtype=np.int64)

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


#: the bits of a read's length that a bridge may have flipped (16 up to :data:`MAX_READ`)
_BITS = np.arange(4, MAX_READ.bit_length(), dtype=np.int64)


def _gather(buf: bytearray, spans: list[np.ndarray]) -> bytes:
    """The bytes of ``buf`` in each (start, end) row of ``spans`` (in order, apart), joined:
    long reads by slices of a view, many short ones through one mask (a slice costs as much
    as copying a few hundred bytes)."""
    s = np.concatenate(spans) if spans else np.zeros((0, 2), np.int64)
    s = s[s[:, 1] > s[:, 0]]
    if s.size == 0:
        return b""
    if s[-1, 1] - s[0, 0] >= 256 * len(s):
        with memoryview(buf) as view:
            return b"".join([view[a:b] for a, b in s.tolist()])
    lo, hi = int(s[0, 0]), int(s[-1, 1])
    edge = np.zeros(hi - lo + 1, np.int8)  # +1 where a read starts, -1 where it ends
    edge[s[:, 0] - lo] = 1
    edge[s[:, 1] - lo] -= 1
    keep = np.cumsum(edge[:-1], dtype=np.int8).view(bool)
    arr = np.frombuffer(buf, np.uint8, count=hi - lo, offset=lo)
    data = arr[keep].tobytes()
    del arr
    return data


#: what a damaged place costs, in reads, when the reader weighs parses. Bytes skipped cost more
#: than a read: a lone plausible header among damaged bytes (one more read, one more skip)
#: never wins. A read cut short where one damage explains it (a flipped bit of its length,
#: a byte lost) costs less than a read: the read whose length swallowed the next one, its
#: header chaining on, is cut there and both kept. A chance header inside a read, where its
#: length would have to be one bit off, must then chain on exactly to win: a coincidence
#: of 50 bits or more.
_SKIP = 1.25
_CUT = 0.75
#: the most header candidates weighed at once after damage (bounds the work on hostile bytes)
_MAX_CANDIDATES = 512
#: how far after the last read kept a header weighed after damage may be, ns (a year: a
#: capture is not paused longer inside one damaged place)
_MAX_SPAN_NS = 52 * MAX_GAP_NS


def _candidates(
    buf: bytearray, lo: int, hi: int, prev_t: int | None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Positions in buf[lo:hi] where a plausible header starts (length 1 to :data:`MAX_READ`,
    time not before ``prev_t`` nor :data:`_MAX_SPAN_NS` after it), with their times (ns) and
    lengths."""
    if hi - lo < _REC.size:
        z = np.zeros(0, np.int64)
        return z, z.astype(np.uint64), z
    arr = np.frombuffer(buf, dtype=np.uint8, count=hi, offset=0)[lo:]
    m = arr.size - _REC.size + 1
    n = np.zeros(m, np.uint64)
    for b in range(4):
        n |= arr[8 + b : 8 + b + m].astype(np.uint64) << np.uint64(8 * b)
    ok = (n > 0) & (n <= MAX_READ)
    idx = np.flatnonzero(ok)
    t = np.zeros(idx.size, np.uint64)
    for b in range(8):
        t |= arr[idx + b].astype(np.uint64) << np.uint64(8 * b)
    if prev_t is not None:
        # no later than the window's reads could carry it (a week each, a year at most)
        keep = (t >= np.uint64(prev_t)) & (t - np.uint64(prev_t) <= np.uint64(_MAX_SPAN_NS))
        idx, t = idx[keep], t[keep]
    return (idx + lo).astype(np.int64), t, n[idx].astype(np.int64)


def _best_path(
    p: np.ndarray,
    t: np.ndarray,
    n: np.ndarray,
    pos: int,
    limit: int,
    at_eof: bool,
    prev_t: int | None,
) -> tuple[list[int], int]:
    """The parse of the bytes pos..limit into reads at the candidate headers (positions
    ``p``, times ``t``, lengths ``n``) that keeps the most reads less :data:`_SKIP` per
    place skipped and :data:`_CUT` per read cut short (bytes before the first read count
    as skipped);
    times never fall nor jump more than :data:`MAX_GAP_NS`. ``at_eof``: limit is the end of
    the file (a read cut off there is a cut, not damage); else reads may run past it. Returns
    the candidates' indices in order and how many links without damage end it (the first read
    comes at most :data:`MAX_GAP_NS` after ``prev_t``)."""
    m = p.size
    if m == 0:
        return [], 0
    ends = p + _REC.size + n.astype(np.int64)
    score = np.empty(m)
    back = np.full(m, -1, np.int64)
    gap = np.uint64(MAX_GAP_NS)
    for c in range(m):
        best = -np.inf
        if prev_t is None or int(t[c]) - prev_t <= MAX_GAP_NS:
            best = 1.0 if p[c] == pos else 1.0 - _SKIP
        if c:
            # a read ends where the next starts, or before it (bytes skipped), or inside it
            # where one damage explains it: a byte lost (in its data or the next header), or
            # one bit of its length flipped (never to a read of no bytes: none is written)
            cut = p[c] - p[:c] - _REC.size
            flip = n[:c] ^ np.maximum(cut, 0)
            fits = (
                (ends[:c] <= p[c])
                | ((ends[:c] - p[c] == 1) & (cut >= 0))
                | ((cut > 0) & ((flip & (flip - 1)) == 0))
            )
            ok = fits & (t[:c] <= t[c]) & (t[c] - t[:c] <= gap)
            if ok.any():
                cost = np.where(ends[:c] == p[c], 0.0, np.where(cut >= n[:c], _SKIP, _CUT))
                s = np.where(ok, score[:c] + 1.0 - cost, -np.inf)
                b = int(np.argmax(s))
                if s[b] > best:
                    best, back[c] = float(s[b]), b
        score[c] = best
    if at_eof:
        # the last read: ends at the end (0); runs past it (a cut: not passed on, -1); leaves
        # less than a header (a cut-off header, 0); leaves more (damage)
        term = np.where(ends > limit, -1.0, np.where(limit - ends < _REC.size, 0.0, -_SKIP))
    else:
        term = np.where(ends + _REC.size > limit, 0.0, -_SKIP)
    total = score + term
    c = int(np.argmax(total))
    if total[c] < (0.0 if at_eof and limit - pos < _REC.size else -_SKIP):
        return [], 0
    path = [c]
    while back[path[-1]] >= 0:
        path.append(int(back[path[-1]]))
    path.reverse()
    links = 0
    k = len(path) - 1
    while term[c] >= 0 and k > 0 and ends[path[k - 1]] == p[path[k]]:
        links, k = links + 1, k - 1
    return path, links


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
