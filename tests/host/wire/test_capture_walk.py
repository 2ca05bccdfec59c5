"""The capture reader walks its chain of read headers block-wise (issue 31, decode at memory
speed): the walk must find exactly the headers the walk one header at a time finds — written
here as the reference — on captures of short reads, damaged at random, with reads whose bytes
hold headers of their own (chains that are not the capture's); and the reader taking its
undamaged reads many at a time must give the same reads, bytes and damage reports as the reader
taking every read one by one (its careful walk, the one it falls back on where the chain
breaks)."""

from __future__ import annotations

import struct

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from host.wire import capture
from host.wire.resync import MAX_READ, _path, header_chain

HEADER = struct.Struct("<QI")


def walk_one_by_one(buf: bytes | bytearray, pos: int) -> tuple[list[int], list[int]]:
    """The reference: from ``pos``, each header where the one before ends, by its length alone,
    up to the first that is not whole or whose length is not 1 to MAX_READ."""
    at, lengths = [], []
    while pos + HEADER.size <= len(buf):
        n = HEADER.unpack_from(buf, pos)[1]
        if not 0 < n <= MAX_READ:
            break
        at.append(pos)
        lengths.append(n)
        pos += HEADER.size + n
    return at, lengths


def body(reads: list[tuple[int, bytes]]) -> bytes:
    """Read headers and bytes, back to back (a capture without its magic)."""
    return b"".join(HEADER.pack(t, len(d)) + d for t, d in reads)


@st.composite
def captures(draw: st.DrawFn) -> tuple[bytes, list[tuple[int, bytes]], bool]:
    """An IMUCAP01 capture of short reads (as a board's link makes them), its host times near
    a 2**40 ns boundary (the walk's blocks look at the sixth byte of a time) with gaps up to
    2**36 ns; some reads hold headers of their own, chained and timed like the capture's (as a
    capture of a capture would); the reads, (host ns, bytes) each; whether a read holds
    headers."""
    t = draw(st.integers(1, 2**20)) * 2**40 - draw(st.integers(0, 2**37))
    reads, nested = [], False
    for _ in range(draw(st.integers(1, 120))):
        t += draw(st.integers(0, 2**36))
        kind = draw(st.sampled_from(["bytes", "zeros", "nested"]))
        if kind == "nested":
            inner = [
                (t + k, b"\0" * draw(st.integers(1, 6))) for k in range(draw(st.integers(1, 12)))
            ]
            data = body(inner)[draw(st.integers(0, 3)) :] + draw(st.binary(max_size=6))
            nested = True
        elif kind == "zeros":
            data = bytes(draw(st.integers(1, 60)))
        else:
            data = draw(st.binary(min_size=1, max_size=60))
        if data:
            reads.append((t, data))
    return capture.MAGIC + body(reads), reads, nested


damages = st.lists(
    st.tuples(st.sampled_from(["flip", "insert", "delete"]), st.integers(0), st.integers(0)),
    max_size=3,
)


def damaged(raw: bytes, damage: list[tuple[str, int, int]]) -> bytes:
    """``raw`` with each damage at a place after the magic: a bit flipped, a byte inserted or
    deleted."""
    out = bytearray(raw)
    for kind, where, what in damage:
        at = len(capture.MAGIC) + where % max(len(out) - len(capture.MAGIC), 1)
        if kind == "flip" and at < len(out):
            out[at] ^= 1 << (what % 8)
        elif kind == "insert":
            out.insert(at, what % 256)
        elif at < len(out):
            del out[at]
    return bytes(out)


@pytest.mark.slow
@settings(max_examples=300, deadline=None)
@given(cap=captures(), damage=damages, start=st.integers(0))
def test_the_walk_finds_the_headers_the_walk_one_by_one_finds(
    cap: tuple[bytes, list], damage: list[tuple[str, int, int]], start: int
) -> None:
    """From a header or from any byte (then mostly along headers that are not the capture's)."""
    raw, reads, _ = cap
    buf = bytearray(damaged(raw, damage)[len(capture.MAGIC) :])
    for pos in (0, start % max(len(buf), 1)):
        at, lengths = header_chain(buf, pos)
        want_at, want_n = walk_one_by_one(buf, pos)
        assert at.tolist() == want_at and lengths.tolist() == want_n
    if not damage:  # the capture's own chain, whatever its reads hold
        assert len(header_chain(buf, 0)[0]) == len(reads)


@settings(max_examples=300, deadline=None)
@given(st.lists(st.integers(0, 200), min_size=1, max_size=200))
def test_the_path_is_the_nodes_followed_from_the_first(hops: list[int]) -> None:
    """Graphs whose paths merge and branch, pruned or doubled: node i points at i + 1 + hop."""
    m = len(hops)
    succ = np.minimum(np.arange(m) + 1 + np.asarray(hops), m)
    want, i = [], 0
    while i < m:
        want.append(i)
        i = int(succ[i])
    assert _path(succ).tolist() == want


class OneByOne(capture.CaptureUnwrapper):
    """The reader taking every read one by one: its careful walk alone."""

    def _take_clean(self, buf: bytearray, pos: int, out: list[np.ndarray]) -> int:
        return pos


def unwrap(u: capture.CaptureUnwrapper, raw: bytes, pieces: int) -> tuple:
    data = b"".join(u.feed(raw[i : i + pieces]) for i in range(0, len(raw), pieces))
    data += u.finish()
    ns, ends = u.reads()
    return data, ns.tolist(), ends.tolist(), u.skipped, u.truncated_bytes


@pytest.mark.slow
@settings(max_examples=150, deadline=None)
@given(cap=captures(), damage=damages, pieces=st.sampled_from([1, 7, 64, 500, 1 << 20]))
def test_reads_taken_at_once_are_those_taken_one_by_one(
    cap: tuple[bytes, list], damage: list[tuple[str, int, int]], pieces: int
) -> None:
    """Same bytes, reads (host times, ends) and damage reports, fed in pieces of any size."""
    raw = damaged(cap[0], damage)
    got = unwrap(capture.CaptureUnwrapper(times=True), raw, pieces)
    assert got == unwrap(OneByOne(times=True), raw, pieces)
    if not damage and not cap[2]:  # (a read holding a chain of its own may pass for reads)
        assert got[1] == [t for t, _ in cap[1]] and got[0] == b"".join(d for _, d in cap[1])
