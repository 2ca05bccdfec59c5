"""A damaged capture loses the read the damage hit, not the rest (issue 31): the IMUCAP01
reader resynchronises on its own read headers. Random damage — one flipped bit, one byte
inserted, one byte deleted — over many captures; every other read must come through with its
bytes and its host time, whole or streamed in pieces, and the place skipped is reported. (One
honest exception: a flipped bit in a read's time that a flipped bit in its neighbour's time
would explain as well: the neighbour may be lost too.)"""

from __future__ import annotations

import contextlib
import io
import re
import struct
from pathlib import Path

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from host.wire import capture

#: reads as a port gives them: 1..400 bytes, host times rising by 1 µs .. 0.5 s
read_lists = st.lists(
    st.tuples(st.integers(1_000, 500_000_000), st.binary(min_size=1, max_size=400)),
    min_size=4,
    max_size=40,
)
damages = st.tuples(st.sampled_from(["flip", "insert", "delete"]), st.integers(0), st.integers(0))


def write(reads: list[tuple[int, bytes]], t0: int = 10**12) -> tuple[bytes, list[int], list]:
    """The capture file of ``reads`` (gaps, bytes); the file offset of each read's header; the
    reads as (host ns, bytes)."""
    out, starts, timed, t = bytearray(capture.MAGIC), [], [], t0
    for gap, data in reads:
        t += gap
        starts.append(len(out))
        out += struct.pack("<QI", t, len(data)) + data
        timed.append((t, data))
    return bytes(out), starts, timed


def damaged(raw: bytes, starts: list[int], kind: str, where: int, what: int) -> tuple[bytes, int]:
    """``raw`` with one damage from the second read's header to the one before the last
    (the first and last reads have no neighbour on one side to check a damaged time
    against: either of two reads may then be the one lost); returns it and the offset."""
    at = starts[1] + where % (starts[-2] - starts[1])
    out = bytearray(raw)
    if kind == "flip":
        out[at] ^= 1 << (what % 8)
    elif kind == "insert":
        out.insert(at, what % 256)
    else:
        del out[at]
    return bytes(out), at


def reads_of(cap: capture.Capture) -> list[tuple[int, bytes]]:
    ends = cap.chunk_end.tolist()
    return [
        (int(t), cap.data[(ends[i - 1] if i else 0) : ends[i]])
        for i, t in enumerate(cap.chunk_ns.tolist())
    ]


def _zeros(*sizes: int) -> list[tuple[int, bytes]]:
    """Reads of ``sizes`` zero bytes, 1 µs apart: short reads whose bytes and shifted headers
    look alike, where a wrong resynchronisation finds plausible headers most easily."""
    return [(1000, bytes(n)) for n in sizes]


# cases a random search found, each once lost more than the read it hit: reads shorter than a
# header with one bit flipped (the reader then lost three reads); a zero byte inserted in a
# length (the shifted headers' times, ×256, still rise: a false read swallowed the rest); the
# first byte of a time deleted (the read before and the header after share a byte); a bit
# flipped in a length so that the read ends exactly at the end of the file, or exactly at the
# header after the next two (it swallowed them, their headers chaining on); a byte inserted in a
# length, read as one flipped bit that swallowed the next read whose header chained on exactly
@pytest.mark.slow
@example(reads=_zeros(1, 1, 3, 3, 4, 5, 6, 13, 13, 17, 1, 8, 1), damage=("insert", 181, 22),
         pieces=1)  # fmt: skip
@example(reads=_zeros(1, 1, 7, 7, 1, 1), damage=("flip", 72, 5), pieces=1)
@example(reads=_zeros(*[1] * 16, 3, 3, 4, 5, 5, 5, 5, 5, 6, 8, 9, 10, 18, 1),
         damage=("insert", 165, 0), pieces=1)  # fmt: skip
@example(reads=_zeros(2, 1, 1, 1), damage=("delete", 0, 0), pieces=1)
@example(reads=_zeros(1, 1, 1, 1), damage=("delete", 9, 0), pieces=1)
@example(reads=_zeros(1, 1, 1, 5, 5, 5), damage=("flip", 610, 6), pieces=1)
@example(reads=_zeros(1, 4, 4, 4, 8, 1, 1), damage=("flip", 4768, 5), pieces=1)
@settings(max_examples=500, deadline=None)
@given(reads=read_lists, damage=damages, pieces=st.integers(1, 700))
def test_one_damage_loses_at_most_the_read_it_hit(
    reads: list[tuple[int, bytes]], damage: tuple[str, int, int], pieces: int
) -> None:
    raw, starts, want = write(reads)
    bad, at = damaged(raw, starts, *damage)
    hit = max(k for k, s in enumerate(starts) if s <= at)
    cap = capture.parse(bad)
    got = reads_of(cap)
    lost = [k for k, r in enumerate(want) if r not in got]
    if damage[0] == "flip" and at < starts[hit] + 8:
        # a flipped bit in a time: the two reads' lengths agree, one time is out of order;
        # when one flipped bit in either time explains the file, the neighbour may go too
        assert set(lost) <= {hit - 1, hit, hit + 1} and len(lost) <= 2, (lost, hit)
    else:
        assert lost in ([], [hit]), (lost, hit, cap.skipped)
    kept = [r for r in want if r in got]  # in their order, each once
    assert [r for r in got if r in want] == kept
    if cap.skipped:  # what was skipped is said: one place, in the read hit or at its end
        after = starts[hit + 1] if hit + 1 < len(starts) else len(raw)
        before = starts[max(hit - 1, 0)]
        assert len(cap.skipped) == 1 and before <= cap.skipped[0][0] <= after + 1
    if at < starts[hit] + 12 and damage[0] != "flip":  # a header shifted: never unnoticed
        assert cap.skipped or lost == [] or cap.truncated_bytes
    # streamed in pieces: the same bytes, times and places
    u = capture.CaptureUnwrapper(times=True)
    data = b"".join(u.feed(bad[i : i + pieces]) for i in range(0, len(bad), pieces))
    data += u.finish()
    assert data == cap.data and u.skipped == list(cap.skipped)
    assert u.truncated_bytes == cap.truncated_bytes
    if data:
        offsets = np.arange(len(data))
        assert np.array_equal(u.arrival_ns_at(offsets), cap.arrival_ns_at(offsets))


@settings(max_examples=100, deadline=None)
@given(reads=read_lists, cut=st.integers(1, 30))
@pytest.mark.slow
def test_a_cut_off_end_is_a_cut_not_damage(reads: list[tuple[int, bytes]], cut: int) -> None:
    raw, starts, want = write(reads)
    size = len(raw) - cut
    whole = [k for k in range(len(want)) if (starts + [len(raw)])[k + 1] <= size]
    cap = capture.parse(raw[:size])
    assert reads_of(cap) == want[: len(whole)] and not cap.skipped
    assert cap.truncated_bytes == size - (starts + [len(raw)])[len(whole)]


def test_the_warning_says_what_was_skipped_and_where() -> None:
    text = capture.damage_text("x.cap", 0, ((1234, 310),))
    assert text.startswith("warning: x.cap: 1 damaged place(s) in the file (byte 1234: 310")
    assert capture.damage_text("x.cap", 0, ()) == ""
    assert "cut-off read" in capture.damage_text("x.cap", 20, ())


def board_capture(tmp_path: Path, seconds: int = 120) -> tuple[Path, list[int]]:
    """A static recording as the board sends it, one read per second (host time = device
    time); the file and each read's header offset."""
    from host.bench.noise import capture_bytes

    t = np.arange(seconds * 50) / 50.0
    data = np.tile([0.0, 0.0, 9.81, 0.0, 0.0, 0.0], (t.size, 1))
    raw = capture_bytes(t, data, np.full(t.size, 25.0))
    starts, pos = [], len(capture.MAGIC)
    while pos < len(raw):
        starts.append(pos)
        pos += 12 + struct.unpack_from("<QI", raw, pos)[1]
    path = tmp_path / "static.cap"
    path.write_bytes(raw)
    return path, starts


def test_import_of_a_damaged_capture_reports_the_session_it_holds(tmp_path: Path) -> None:
    """One flipped bit in a read's length (once: 'a cut-off read', 923 of 3 051 frames) and
    one in a read's time (a 3.4e9 s session): import now reads 119 of 120 seconds and says
    what it skipped."""
    from host.__main__ import main

    path, starts = board_capture(tmp_path)
    raw = bytearray(path.read_bytes())
    raw[starts[40] + 11] ^= 0x40  # the length's high byte: 1 GiB
    raw[starts[80] + 7] ^= 0x40  # the time's high byte: +146 years
    path.write_bytes(bytes(raw))
    err, out = io.StringIO(), io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
        with contextlib.suppress(SystemExit):
            main(["import", str(path), "--serial", "D1", "--out", str(tmp_path / "D1")])
    text = err.getvalue() + out.getvalue()
    m = re.search(r"static\.cap: (\d+) samples, ([\d.]+) s", text)
    assert m, text
    assert 117 * 50 <= int(m.group(1)) <= 118 * 50 + 1  # two reads of 50 samples lost
    assert 118.0 <= float(m.group(2)) <= 120.0
    assert "2 damaged place(s)" in text and "Traceback" not in text
