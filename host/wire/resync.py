"""Where a capture's reads are: the chain of IMUCAP01 read headers walked block-wise where it
holds, the checks of a read header and, where the chain breaks, the parse of the bytes that
keeps the most reads (:class:`host.wire.capture.CaptureUnwrapper` walks the file with them)."""

from __future__ import annotations

import struct

import numpy as np

#: a read's header: uint64 LE host time (ns), uint32 LE byte count
REC = struct.Struct("<QI")
_LENGTH = struct.Struct("<I")  # a header's length field, at its byte 8


#: a read's plausible length, bytes: a port read is at most the port's buffer (a few KiB); a
#: length above this is damage (a flipped bit), not a read
MAX_READ = 1 << 20
#: after damage, reading resumes at a header followed by this many plausible ones (or by the
#: end of the file)
RESYNC_CHAIN = 3
#: a read's plausible host time: the next read comes at most this long after it, ns (a week:
#: a session that waits for a board to come back waits minutes, not days)
MAX_GAP_NS = 7 * 24 * 3600 * 10**9


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
MAX_CANDIDATES = 512
#: how far after the last read kept a header weighed after damage may be, ns (a year: a
#: capture is not paused longer inside one damaged place)
_MAX_SPAN_NS = 52 * MAX_GAP_NS


def header_candidates(
    buf: bytearray, lo: int, hi: int, prev_t: int | None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Positions in buf[lo:hi] where a plausible header starts (length 1 to :data:`MAX_READ`,
    time not before ``prev_t`` nor :data:`_MAX_SPAN_NS` after it), with their times (ns) and
    lengths."""
    if hi - lo < REC.size:
        z = np.zeros(0, np.int64)
        return z, z.astype(np.uint64), z
    arr = np.frombuffer(buf, dtype=np.uint8, count=hi, offset=0)[lo:]
    m = arr.size - REC.size + 1
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


def _link_scores(
    c: int, p: np.ndarray, t: np.ndarray, n: np.ndarray, ends: np.ndarray, score: np.ndarray
) -> np.ndarray | None:
    """(c,) the score of the best parse ending at each earlier candidate plus the link from
    it to candidate ``c`` (-inf where no link fits), None where none does."""
    # a read ends where the next starts, or before it (bytes skipped), or inside it where one
    # damage explains it: a byte lost (in its data or the next header), or one bit of its
    # length flipped (never to a read of no bytes: none is written)
    cut = p[c] - p[:c] - REC.size
    flip = n[:c] ^ np.maximum(cut, 0)
    fits = (
        (ends[:c] <= p[c])
        | ((ends[:c] - p[c] == 1) & (cut >= 0))
        | ((cut > 0) & ((flip & (flip - 1)) == 0))
    )
    # nor is a read cut at this header when a header inside it chains on exactly to this one:
    # that is the read before this one (the damage hit the cut read's header or data), and
    # the cut would lose it too
    inner = np.flatnonzero((ends[:c] == p[c]) & (t[:c] <= t[c]))
    if inner.size:
        holds = (p[inner] >= p[:c, None] + REC.size) & (t[inner] >= t[:c, None])
        fits &= (ends[:c] <= p[c]) | ~holds.any(axis=1)
    ok = fits & (t[:c] <= t[c]) & (t[c] - t[:c] <= np.uint64(MAX_GAP_NS))
    if not ok.any():
        return None
    cost = np.where(ends[:c] == p[c], 0.0, np.where(cut >= n[:c], _SKIP, _CUT))
    return np.where(ok, score[:c] + 1.0 - cost, -np.inf)


def _parse_scores(
    p: np.ndarray, t: np.ndarray, n: np.ndarray, ends: np.ndarray, pos: int, prev_t: int | None
) -> tuple[np.ndarray, np.ndarray]:
    """(score, back) per candidate: the best parse from ``pos`` whose last read starts there
    and the candidate before it in that parse (-1: none, its first read)."""
    m = p.size
    score = np.empty(m)
    back = np.full(m, -1, np.int64)
    for c in range(m):
        best = -np.inf
        if prev_t is None or int(t[c]) - prev_t <= MAX_GAP_NS:
            best = 1.0 if p[c] == pos else 1.0 - _SKIP
        s = _link_scores(c, p, t, n, ends, score) if c else None
        if s is not None:
            b = int(np.argmax(s))
            if s[b] > best:
                best, back[c] = float(s[b]), b
        score[c] = best
    return score, back


def _end_terms(ends: np.ndarray, limit: int, at_eof: bool) -> np.ndarray:
    """What ending the parse with each candidate's read adds to its score."""
    if at_eof:
        # the last read: ends at the end (0); runs past it (a cut: not passed on, -1); leaves
        # less than a header (a cut-off header, 0); leaves more (damage)
        return np.where(ends > limit, -1.0, np.where(limit - ends < REC.size, 0.0, -_SKIP))
    return np.where(ends + REC.size > limit, 0.0, -_SKIP)


def best_parse(
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
    if p.size == 0:
        return [], 0
    ends = p + REC.size + n.astype(np.int64)
    score, back = _parse_scores(p, t, n, ends, pos, prev_t)
    term = _end_terms(ends, limit, at_eof)
    total = score + term
    c = int(np.argmax(total))
    if total[c] < (0.0 if at_eof and limit - pos < REC.size else -_SKIP):
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


#: headers walked one by one before the walk goes block-wise (a short chain, as after damage,
#: costs no numpy work), and the first block's bytes (each block after is twice as long);
#: reads this long on average (bytes) are walked one by one all along: a step costs less
#: than looking at their bytes
_PROBE = 8
_FIRST_BLOCK = 1 << 16
_LONG_READ = 256


def header_chain(buf: bytearray, pos: int) -> tuple[np.ndarray, np.ndarray]:
    """The read headers from ``pos`` on, each where the one before ends, walked by their
    lengths alone up to the first that is not whole in ``buf`` or whose length is not plausible
    (1 to :data:`MAX_READ`): their positions in ``buf`` and their lengths (bytes, int64).

    Exactly the walk one header at a time, done for a block of bytes at once: the headers in
    it that may be on the chain (the length's high byte zero, the time's sixth byte the block's
    first header's: it changes every 2**40 ns, 18 min, and the chain then goes on in the next
    block) each point at the one after them, and the chain is the path from the first
    (:func:`_path`). Blocks grow twofold: the bytes looked at stay within about twice the
    chain's."""
    size, rec = len(buf), REC.size
    at: list[int] = []
    lengths: list[int] = []
    p, steps = pos, _PROBE
    while True:
        while len(at) < steps:
            if p + rec > size or not 0 < (n := _LENGTH.unpack_from(buf, p + 8)[0]) <= MAX_READ:
                return np.asarray(at, np.int64), np.asarray(lengths, np.int64)
            at.append(p)
            lengths.append(n)
            p += rec + n
        if p - pos < _LONG_READ * len(at):
            break  # short reads: the rest block-wise
        steps *= 2
    parts, part_n = [np.asarray(at, np.int64)], [np.asarray(lengths, np.int64)]
    byte = np.frombuffer(buf, np.uint8, count=size)
    length = np.ndarray((size - rec + 1,), "<u4", buf, 8, (1,))  # at every byte (unaligned)
    block = max(_FIRST_BLOCK, 2 * (p - pos))
    while p + rec <= size and 0 < length[p] <= MAX_READ:
        hi = min(size - rec + 1, p + block)  # the headers that start here are whole in buf
        block *= 2
        c = np.flatnonzero((byte[p + 11 : hi + 11] == 0) & (byte[p + 5 : hi + 5] == byte[p + 5]))
        n = length[p:hi][c]
        if not (ok := n - np.uint32(1) < np.uint32(MAX_READ)).all():  # 1 to MAX_READ
            c, n = c[ok], n[ok]
        nxt = c + rec + n  # where each one's read ends: mostly at the candidate after it
        miss = np.flatnonzero(nxt[:-1] != c[1:])
        if miss.size:
            succ = np.arange(1, c.size + 1)
            j = np.searchsorted(c, nxt[miss])
            succ[miss] = np.where(c[np.minimum(j, c.size - 1)] == nxt[miss], j, c.size)
            on = _path(succ)
            c, n, nxt = c[on], n[on], nxt[on]
        parts.append(c + p)
        part_n.append(n)
        p += int(nxt[-1])
    del byte, length  # views of buf: it may be resized again
    return np.concatenate(parts), np.concatenate(part_n)


def _path(succ: np.ndarray) -> np.ndarray:
    """The path from node 0 in a graph where node i points at ``succ[i]`` (> i; ``succ.size``:
    at none): its nodes in order. Nodes no other node points at are pruned, as long as that
    takes few passes (what is left is then the path); else the path is doubled from its first
    node with jumps of doubling length."""
    m = succ.size
    has_in = np.zeros(m + 1, bool)
    has_in[succ] = True
    has_in[0] = True
    alive = has_in[:m]
    if np.array_equal(succ[(on := np.flatnonzero(alive))[:-1]], on[1:]):
        return on  # (the usual case: each node left points at the next)
    for _ in range(3):
        has_in = np.zeros(m + 1, bool)
        has_in[succ[alive]] = True
        has_in[0] = True
        now = alive & has_in[:m]
        if np.array_equal(now, alive):
            return np.flatnonzero(alive)
        alive = now
    jump = np.append(succ, m)  # node m: none, pointing at itself
    path = np.zeros(1, np.int64)
    while path[-1] != m:
        path = np.concatenate((path, jump[path]))
        jump = jump[jump]
    return path[: np.searchsorted(path, m)]
