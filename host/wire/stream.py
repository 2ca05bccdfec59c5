"""The streaming decoder: bytes in chunks of any size -> checked frames, with the counters.

The reader layer (the third, as in pyubx2, over :mod:`host.wire.frames`): it only syncs, checks
and yields. :class:`StreamDecoder` takes bytes in chunks of any size and returns the frames
completed by them; :class:`FrameReader` wraps anything with ``read(n)`` and yields
``(raw_bytes, frame)``. Losses and resets are counted by the counters' rules
(:mod:`host.wire.segments`). Its numpy twin is :mod:`host.wire.bulk`.

Resynchronisation rule (both paths): candidates are the positions of the sync bytes, examined
in order. A candidate whose length byte is impossible for its type, or whose CRC fails, is
rejected and the search restarts at the *next byte* after its first sync byte; a valid frame is
consumed whole, so sync bytes inside it are never examined.
"""

from __future__ import annotations

import binascii
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Protocol

from host.wire.capture import CaptureUnwrapper
from host.wire.frames import (
    CRC_LEN,
    HEADER_LEN,
    IMPOSSIBLE,
    IMU_SAMPLE,
    LENGTHS_FROM,
    MAX_PAYLOAD,
    SYNC,
    Frame,
    sample_t_us,
)
from host.wire.segments import SegmentTracker

# --------------------------------------------------------------------------- stats


@dataclass
class DecoderStats:
    """Counters of what the decoder saw; names match ``decode --stats``."""

    frames: int = 0
    crc_errors: int = 0
    bytes_discarded: int = 0
    unknown_types: int = 0
    lost_frames: int = 0
    resets: int = 0

    def as_dict(self) -> dict[str, int]:
        return dict(self.__dict__)


# --------------------------------------------------------------------------- streaming


class StreamDecoder:
    """Incremental decoder: feed bytes in chunks of any size, get the frames they complete.

    Never raises on any input. Output and counters do not depend on the chunking.
    """

    def __init__(self, sender: str = "device") -> None:
        """``sender``: ``device`` (the default: a board's stream; types 0x80–0xFF are never
        frames), ``host`` (commands), ``any``."""
        self._buf = bytearray()
        self.stats = DecoderStats()
        self._segments = SegmentTracker()
        self._lengths = LENGTHS_FROM[sender]

    @property
    def pending(self) -> int:
        """Bytes held back waiting for the rest of a possible frame."""
        return len(self._buf)

    def feed(self, chunk: bytes | bytearray | memoryview) -> list[Frame]:
        """Add bytes; return the frames they complete, in order."""
        return [f for _, f in self.feed_raw(chunk)]

    def feed_raw(self, chunk: bytes | bytearray | memoryview) -> list[tuple[bytes, Frame]]:
        """Like :meth:`feed`, with each frame's raw bytes."""
        self._buf += chunk
        return self._scan(final=False)

    def flush(self) -> list[tuple[bytes, Frame]]:
        """End of input: what is held back can never complete; resync through it."""
        out = self._scan(final=True)
        self.stats.bytes_discarded += len(self._buf)
        self._buf.clear()
        return out

    def _scan(self, final: bool) -> list[tuple[bytes, Frame]]:
        buf = self._buf
        n = len(buf)
        out: list[tuple[bytes, Frame]] = []
        pos = 0  # everything before pos is consumed (frames or discarded bytes)
        search = 0
        stats = self.stats
        while True:
            p = buf.find(SYNC, search)
            if p < 0:
                # keep a trailing first sync byte: it may start a frame
                keep_from = n - 1 if n > pos and buf[n - 1] == SYNC[0] and not final else n
                stats.bytes_discarded += keep_from - pos
                pos = keep_from
                break
            if p + HEADER_LEN <= n:
                mtype = buf[p + 2]
                length = buf[p + 3]
                expected = self._lengths[mtype]
                if (
                    length > MAX_PAYLOAD
                    or expected == IMPOSSIBLE
                    or (expected >= 0 and length != expected)
                ):
                    search = p + 1
                    continue
                end = p + HEADER_LEN + length + CRC_LEN
            else:
                end = n + 1  # not even the header yet
            if end > n:  # the candidate is not complete: wait for more, or at the end resync
                if final:
                    search = p + 1
                    continue
                stats.bytes_discarded += p - pos
                pos = p
                break
            if binascii.crc_hqx(buf[p + 2 : end - 2], 0xFFFF) != buf[end - 2] | (buf[end - 1] << 8):
                stats.crc_errors += 1
                search = p + 1
                continue
            stats.bytes_discarded += p - pos
            raw = bytes(buf[p:end])
            seq = raw[4] | (raw[5] << 8)
            payload = raw[HEADER_LEN:-CRC_LEN]
            stats.frames += 1
            if expected < 0:
                stats.unknown_types += 1
            reset, lost = self._segments.update(
                seq, sample_t_us(payload) if mtype == IMU_SAMPLE else None
            )
            stats.resets += reset
            stats.lost_frames += lost
            out.append((raw, Frame(mtype, seq, payload)))
            pos = search = end
        del buf[:pos]
        return out


class Readable(Protocol):
    def read(self, n: int = ..., /) -> bytes: ...


class FrameReader:
    """Yield ``(raw_bytes, frame)`` from anything with ``read(n)`` (a port, a file, a socket).

    An IMUCAP01 capture (``python3 -m host capture``, a session's ``SERIAL_session.cap``) is
    recognised by its magic and unwrapped: the frames come from the bytes it recorded.
    Stops at end of input (``read`` returning ``b""``); for a live port with a timeout, an
    empty read just means no data yet, so pass ``stop_on_empty=False`` and break yourself.
    """

    def __init__(self, stream: Readable, chunk: int = 4096, stop_on_empty: bool = True) -> None:
        self.stream = stream
        self.chunk = chunk
        self.stop_on_empty = stop_on_empty
        self.decoder = StreamDecoder()

    @property
    def stats(self) -> DecoderStats:
        return self.decoder.stats

    def __iter__(self) -> Iterator[tuple[bytes, Frame]]:
        from host.wire.capture import MAGIC, CaptureUnwrapper

        head: bytes | None = b""  # the first bytes, until they tell if this is IMUCAP01
        unwrap: CaptureUnwrapper | None = None
        while True:
            data = self.stream.read(self.chunk)
            if not data:
                if not self.stop_on_empty:
                    continue
                if head:  # shorter than the magic: plain bytes
                    yield from self.decoder.feed_raw(head)
                if unwrap is not None:  # the last read (held until the end was known)
                    yield from self.decoder.feed_raw(unwrap.finish())
                yield from self.decoder.flush()
                return
            if head is not None:
                head += data
                if len(head) < len(MAGIC) and MAGIC.startswith(head):
                    continue
                data, head = head, None
                if data.startswith(MAGIC):
                    unwrap = CaptureUnwrapper()
            if unwrap is not None:
                data = unwrap.feed(data)
            yield from self.decoder.feed_raw(data)
