"""Frames: encode and decode the wire format of ``protocol/spec.json``.

Three layers, as in pyubx2:

1. **Definitions as data**: :data:`MESSAGES` is built from the generated table
   ``host/protocol_gen.py`` (never edited by hand).
2. **An immutable frame object**: :class:`Frame` (type, seq, payload; fields decoded on demand).
3. **A reader that only syncs, checks and yields**: :class:`StreamDecoder` takes bytes in chunks
   of any size and returns the frames completed by them; :class:`FrameReader` wraps anything
   with ``read(n)`` and yields ``(raw_bytes, frame)``.

A bulk path, :func:`decode_bulk`, decodes a whole capture with numpy and gives exactly the frames
and counters the streaming path gives for the same bytes followed by :meth:`StreamDecoder.flush`.

Resynchronisation rule (both paths): candidates are the positions of the sync bytes, examined
in order. A candidate whose length byte is impossible for its type, or whose CRC fails, is
rejected and the search restarts at the *next byte* after its first sync byte; a valid frame is
consumed whole, so sync bytes inside it are never examined.

Length (over 600 lines): the three decoder layers and the bulk twin that must give exactly the
streaming path's frames and counters (property-tested); together they keep the resync rule in
one file.
"""

from __future__ import annotations

import binascii
import struct
import sys
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType
from typing import Protocol

import numpy as np

from host.errors import UserError
from host.wire import protocol_gen as gen
from host.wire import sensor
from host.wire.capture import CaptureUnwrapper
from host.wire.segments import SegmentTracker, segments

SYNC = gen.SYNC
HEADER_LEN = 6
CRC_LEN = 2
OVERHEAD = HEADER_LEN + CRC_LEN
MAX_PAYLOAD = gen.MAX_PAYLOAD
#: the message types by name, from the generated table (never a number written by hand)
TYPES: Mapping[str, int] = MappingProxyType({v[0]: k for k, v in gen.MESSAGES.items()})
IMU_SAMPLE = TYPES["IMU_SAMPLE"]
#: the sensor counts of an IMU_SAMPLE in wire order (the spec's fields with unit ``count``)
IMU_FIELDS = tuple(name for name, _, unit in gen.MESSAGES[IMU_SAMPLE][3] if unit == "count")


@dataclass(frozen=True)
class FieldDef:
    """One payload field: name, type code from the spec, offset in the payload, unit."""

    name: str
    code: str
    offset: int
    unit: str


@dataclass(frozen=True)
class MessageDef:
    """One message type of the spec, with a compiled codec for its payload."""

    type: int
    name: str
    direction: str
    length: int
    fields: tuple[FieldDef, ...]

    @property
    def dtype(self) -> np.dtype:
        """numpy dtype of the payload (mixed byte orders exactly as on the wire)."""
        return np.dtype([(f.name, gen.FIELD_TYPES[f.code][1]) for f in self.fields])

    def unpack(self, payload: bytes) -> dict[str, int]:
        """Payload bytes -> {field: int}."""
        return {f.name: _unpack_field(f.code, payload, f.offset) for f in self.fields}

    def pack(self, values: Mapping[str, int]) -> bytes:
        """{field: int} -> payload bytes; every field must be given."""
        missing = [f.name for f in self.fields if f.name not in values]
        extra = sorted(set(values) - {f.name for f in self.fields})
        if missing or extra:
            raise ValueError(f"{self.name}: missing fields {missing}, unknown fields {extra}")
        return b"".join(_STRUCTS[f.code].pack(int(values[f.name])) for f in self.fields)


_STRUCTS = {
    "u8": struct.Struct("<B"),
    "i8": struct.Struct("<b"),
    "u16le": struct.Struct("<H"),
    "i16le": struct.Struct("<h"),
    "u16be": struct.Struct(">H"),
    "i16be": struct.Struct(">h"),
    "u32le": struct.Struct("<I"),
    "i32le": struct.Struct("<i"),
    "i32be": struct.Struct(">i"),
}


def _unpack_field(code: str, payload: bytes, offset: int) -> int:
    return int(_STRUCTS[code].unpack_from(payload, offset)[0])


def _build_messages() -> dict[int, MessageDef]:
    out: dict[int, MessageDef] = {}
    for mtype, (name, direction, length, fields) in gen.MESSAGES.items():
        defs, off = [], 0
        for fname, code, unit in fields:
            defs.append(FieldDef(fname, code, off, unit))
            off += gen.FIELD_TYPES[code][0]
        out[mtype] = MessageDef(mtype, name, direction, length, tuple(defs))
    return out


#: type -> definition, from the generated table
MESSAGES: Mapping[int, MessageDef] = MappingProxyType(_build_messages())
#: name -> definition
BY_NAME: Mapping[str, MessageDef] = MappingProxyType({m.name: m for m in MESSAGES.values()})
#: type -> expected payload length (a lookup table over all 256 types; -1 = unknown type)
_EXPECTED_LEN = np.full(256, -1, dtype=np.int16)
for _m in MESSAGES.values():
    _EXPECTED_LEN[_m.type] = _m.length
#: in the length tables per sender: a type that sender never sends (protocol/README.md:
#: device → host 0x00–0x7F, host → device 0x80–0xFF); such a candidate is no frame, like an
#: impossible length (a CRC-16 collision on line noise must not become a false host command)
IMPOSSIBLE = -2
#: who sent the stream being decoded -> type -> expected payload length (-1 unknown type)
LENGTHS_FROM: Mapping[str, np.ndarray] = MappingProxyType(
    {
        "device": np.where(np.arange(256) >= 0x80, IMPOSSIBLE, _EXPECTED_LEN).astype(np.int16),
        "host": np.where(np.arange(256) < 0x80, IMPOSSIBLE, _EXPECTED_LEN).astype(np.int16),
        "any": _EXPECTED_LEN,
    }
)

_T_US = next(f for f in MESSAGES[IMU_SAMPLE].fields if f.name == "t_us")


def sample_t_us(payload: bytes) -> int:
    """The device time (µs, 32-bit, wraps) of an IMU_SAMPLE payload, by the spec's field."""
    return _unpack_field(_T_US.code, payload, _T_US.offset)


_IMU_DEFS = {f.name: f for f in MESSAGES[IMU_SAMPLE].fields}
_FLAGS = _IMU_DEFS["flags"]


def sample_counts(payload: bytes) -> tuple[int, ...]:
    """The raw counts of an IMU_SAMPLE payload in :data:`IMU_FIELDS` order, by the spec."""
    return tuple(_unpack_field(_IMU_DEFS[n].code, payload, _IMU_DEFS[n].offset) for n in IMU_FIELDS)


def sample_flags(payload: bytes) -> int:
    """The flag bits of an IMU_SAMPLE payload (spec enum ``sample_flags``)."""
    return _unpack_field(_FLAGS.code, payload, _FLAGS.offset)


#: ERROR codes that mean the sensor stopped delivering (BAD_COMMAND answers a bad command)
SENSOR_ERROR_CODES = frozenset(
    code for name, code in gen.ENUMS["error_code"].items() if name != "BAD_COMMAND"
)


def error_text(f: Frame) -> str:
    """An ERROR frame in words: "ERROR SENSOR_ABSENT (detail 0x00, 3 times)"."""
    fl = f.fields
    names = {v: k for k, v in gen.ENUMS["error_code"].items()}
    return (
        f"ERROR {names.get(fl['code'], fl['code'])} (detail {fl['detail']:#04x}, "
        f"{fl['count']} times)"
    )


#: STATUS.flags bit: the firmware reads the sensor at the 1 MHz clock after a bad burst
SPI_LOW_CLOCK = gen.ENUMS["status_flags"]["SPI_LOW_CLOCK"]


def bus_meta(status_flags: int | None) -> dict[str, str]:
    """Record header line naming the SPI clock the sensor was read at, from the newest STATUS
    ``flags`` seen by the end of the measurement (None: no STATUS seen since HELLO -> no line):
    ``sensor_spi_clock: 8 MHz``, or ``1 MHz (SPI_LOW_CLOCK …)`` once the firmware has fallen
    back after a garbled read (it stays at 1 MHz until reset)."""
    if status_flags is None:
        return {}
    if status_flags & SPI_LOW_CLOCK:
        why = "SPI_LOW_CLOCK: fell back after garbled 8 MHz reads; check the IMU's wiring"
        return {"sensor_spi_clock": f"1 MHz ({why})"}
    return {"sensor_spi_clock": "8 MHz"}


def status_text(f: Frame) -> str | None:
    """What a STATUS frame's flags tell the user, or None when there is nothing to tell."""
    fl = f.fields
    if not fl["flags"] & SPI_LOW_CLOCK:
        return None
    return (
        f"the SPI bus to the sensor is marginal: {fl['bad_bursts']} sensor reads came back "
        "garbled at 8 MHz (dropped, counted as lost samples) and the board now reads at 1 MHz; "
        "the data stay good, but check the IMU's wiring and connector"
    )


def crc16(data: bytes | bytearray | memoryview) -> int:
    """CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF) as the envelope uses it."""
    return binascii.crc_hqx(data, gen.CRC_INIT)


@dataclass(frozen=True, slots=True)
class Frame:
    """One checked frame: type, sequence number and payload bytes."""

    type: int
    seq: int
    payload: bytes

    @property
    def name(self) -> str:
        """Message name from the spec, or ``UNKNOWN_0xNN``."""
        m = MESSAGES.get(self.type)
        return m.name if m else f"UNKNOWN_0x{self.type:02X}"

    @property
    def known(self) -> bool:
        return self.type in MESSAGES

    @property
    def fields(self) -> dict[str, int]:
        """Decoded payload fields (empty for unknown types)."""
        m = MESSAGES.get(self.type)
        return m.unpack(self.payload) if m else {}

    def to_bytes(self) -> bytes:
        """The frame as it travels on the wire."""
        return _envelope(self.type, self.seq, self.payload)


def _envelope(mtype: int, seq: int, payload: bytes) -> bytes:
    body = struct.pack("<BBH", mtype, len(payload), seq & 0xFFFF) + payload
    return SYNC + body + struct.pack("<H", crc16(body))


def encode_frame(msg: str | int, seq: int, **fields: int) -> bytes:
    """Encode one frame of message ``msg`` (name or type) with sequence number ``seq``."""
    m = BY_NAME[msg] if isinstance(msg, str) else MESSAGES[msg]
    return _envelope(m.type, seq, m.pack(fields))


def encode_imu_samples(
    seq0: int, t_us: np.ndarray, counts: np.ndarray, flags: np.ndarray | int = 0
) -> bytes:
    """Encode N IMU_SAMPLE frames at once (vectorised; for simulators and tests).

    ``t_us`` (N,) device microseconds (taken mod 2^32), ``counts`` (N, 7) int16 in the order
    ax, ay, az, temp, gx, gy, gz, ``flags`` (N,) or a scalar. Sequence numbers run from ``seq0``.
    """
    t = np.asarray(t_us).astype(np.int64) & 0xFFFFFFFF
    n = t.shape[0]
    c = np.asarray(counts, dtype=np.int16).reshape(n, 7)
    rec = np.zeros(n, dtype=_WIRE_IMU)
    rec["sync"] = tuple(SYNC)
    rec["type"] = IMU_SAMPLE
    rec["len"] = MESSAGES[IMU_SAMPLE].length
    rec["seq"] = (seq0 + np.arange(n)) & 0xFFFF
    rec["t_us"] = t
    for i, name in enumerate(IMU_FIELDS):
        rec[name] = c[:, i]
    rec["flags"] = flags
    raw = rec.view(np.uint8).reshape(n, _IMU_FRAME_LEN)
    rec["crc"] = _crc_rows(raw[:, 2 : 2 + 4 + MESSAGES[IMU_SAMPLE].length])
    return rec.tobytes()


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

    An IMUCAP01 capture (``python -m host capture``, a session's ``SERIAL_session.cap``) is
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


# --------------------------------------------------------------------------- bulk (numpy)

_IMU_LEN = MESSAGES[IMU_SAMPLE].length
_IMU_FRAME_LEN = _IMU_LEN + OVERHEAD
_WIRE_IMU_FIELDS = (
    [("sync", "u1", (2,)), ("type", "u1"), ("len", "u1"), ("seq", "<u2")]
    + [(f.name, gen.FIELD_TYPES[f.code][1]) for f in MESSAGES[IMU_SAMPLE].fields]
    + [("crc", "<u2")]
)
_WIRE_IMU = np.dtype(_WIRE_IMU_FIELDS)
assert _WIRE_IMU.itemsize == _IMU_FRAME_LEN
#: the same with one pad byte, so that rows have an even width (16-bit word views)
_WIRE_IMU_PADDED = np.dtype([*_WIRE_IMU_FIELDS, ("pad", "u1")])

#: the decoded samples array: wire values, native byte order, plus the frame's offset in the
#: stream, its segment (between device resets) and ``lost``: the frames lost on the link since
#: the previous sample (:func:`host.wire.segments.segments`; 0 where a segment starts)
SAMPLE_DTYPE = np.dtype(
    [("seq", "u2"), ("t_us", "u4")]
    + [(n, "i2") for n in IMU_FIELDS]
    + [("flags", "u1"), ("offset", "i8"), ("segment", "i4"), ("lost", "i4")]
)


def _crc_byte_table() -> np.ndarray:
    t = np.zeros(256, dtype=np.uint16)
    for b in range(256):
        c = b << 8
        for _ in range(8):
            c = ((c << 1) ^ gen.CRC_POLY) if c & 0x8000 else (c << 1)
        t[b] = c & 0xFFFF
    return t


_CRC_TABLE = _crc_byte_table()


def _crc_rows(rows: np.ndarray) -> np.ndarray:
    """CRC-16/CCITT-FALSE of each row of a (M, K) uint8 array (vectorised over rows)."""
    crc = np.full(rows.shape[0], gen.CRC_INIT, dtype=np.uint16)
    for k in range(rows.shape[1]):
        crc = (crc << 8) ^ _CRC_TABLE[(crc >> 8) ^ rows[:, k]]
    return crc


class _PairCRC:
    """CRC of fixed-length messages from 16-bit words: one table lookup per two bytes.

    The CRC is affine over GF(2): crc(m) = crc(0…0) ⊕ ⊕_k T_k[word_k], where T_k is the CRC
    (init 0) of word k followed by zeros. K bytes -> K/2 lookups of 65536-entry tables.
    """

    def __init__(self, nbytes: int) -> None:
        self.nbytes = nbytes
        self.npairs = nbytes // 2
        single = np.zeros((nbytes, 256), dtype=np.uint16)
        for i in range(nbytes):
            c = _CRC_TABLE[np.arange(256)]  # register after byte i, starting from 0
            for _ in range(nbytes - 1 - i):  # followed by zero bytes
                c = (c << 8) ^ _CRC_TABLE[c >> 8]
            single[i] = c
        self.pairs = [
            (single[2 * k][:, None] ^ single[2 * k + 1][None, :]).reshape(-1)
            for k in range(self.npairs)
        ]
        self.last = single[nbytes - 1] if nbytes % 2 else None
        self.zero = int(_crc_rows(np.zeros((1, nbytes), dtype=np.uint8))[0])

    def rows(self, rows: np.ndarray, start: int) -> np.ndarray:
        """CRCs of ``rows[:, start : start + nbytes]``; rows (M, W) uint8 C-contiguous, W even,
        ``start`` even."""
        words = rows.view(">u2")
        crc = np.full(rows.shape[0], self.zero, dtype=np.uint16)
        for k in range(self.npairs):
            crc ^= self.pairs[k][words[:, start // 2 + k]]
        if self.last is not None:
            crc ^= self.last[rows[:, start + self.nbytes - 1]]
        return crc


_IMU_CRC = _PairCRC(4 + _IMU_LEN)


def _windows(buf: np.ndarray, width: int) -> np.ndarray:
    """Read-only (n - width + 1, width) view: row i is buf[i : i + width] (no copy)."""
    return np.lib.stride_tricks.sliding_window_view(buf, width)


@dataclass
class BulkResult:
    """What :func:`decode_bulk` found: IMU samples as an array, other frames as objects."""

    samples: np.ndarray  # SAMPLE_DTYPE
    others: list[tuple[int, Frame]]  # (byte offset, frame) for non-IMU frames
    stats: DecoderStats = field(default_factory=DecoderStats)


#: the longest frame on the wire (bytes): a candidate starting this far before the end of the
#: bytes at hand is complete, so its verdict cannot change with what follows
MAX_FRAME = HEADER_LEN + MAX_PAYLOAD + CRC_LEN


@dataclass
class _Before:
    """What the counters' rules remember of the bytes already decoded."""

    last_seq: int | None = None
    last_t_us: int | None = None  # of the current segment's last IMU sample
    segment: int = 0  # the current segment's number
    lost_since_sample: int = 0  # frames lost after the last IMU sample


class ChunkedDecoder:
    """The bulk decoder in bounded memory: :meth:`feed` bytes in chunks of any size, get a
    :class:`BulkResult` of the frames now final; :meth:`flush` at the end. Concatenated, the
    results are exactly :func:`decode_bulk` of all the bytes (offsets count from the first
    byte fed; counters are per call: add them up). Holds at most the bytes of one call plus
    ``min_batch``."""

    def __init__(self, sender: str = "device", min_batch: int = 1 << 16) -> None:
        self.sender = sender
        self.min_batch = max(min_batch, 2 * MAX_FRAME)
        self._buf = bytearray()
        self._base = 0  # stream offset of _buf[0]
        self._before = _Before()
        self.stats = DecoderStats()  # running totals

    @property
    def pending(self) -> int:
        """Bytes held back: a frame may start in them."""
        return len(self._buf)

    def feed(self, data: bytes | bytearray | memoryview) -> BulkResult:
        self._buf += data
        if len(self._buf) < self.min_batch:
            return BulkResult(np.zeros(0, SAMPLE_DTYPE), [], DecoderStats())
        return self._decode(len(self._buf) - MAX_FRAME + 1)

    def flush(self) -> BulkResult:
        """End of input: decode what is held back."""
        return self._decode(None)

    def _decode(self, limit: int | None) -> BulkResult:
        result, consumed = _decode_bulk_bytes(self._buf, self.sender, limit, self._before)
        result.samples["offset"] += self._base
        result.others = [(off + self._base, f) for off, f in result.others]
        del self._buf[:consumed]
        self._base += consumed
        for k, v in result.stats.as_dict().items():
            setattr(self.stats, k, getattr(self.stats, k) + v)
        return result


def decode_bulk(data: bytes | bytearray | memoryview, sender: str = "device") -> BulkResult:
    """Decode a whole capture at once; same frames and counters as streaming + flush
    (``sender`` as :class:`StreamDecoder`'s).

    ``data``: raw bytes as read from a port, or a whole IMUCAP01 capture file (recognised by
    its magic; the frames are decoded from the bytes it recorded, ``offset`` counts in those,
    and a cut-off last record counts as ``bytes_discarded``)."""
    from host.wire.capture import MAGIC, parse

    cut = 0
    if bytes(data[: len(MAGIC)]) == MAGIC:
        cap = parse(bytes(data))
        data, cut = cap.data, cap.truncated_bytes
    result, _ = _decode_bulk_bytes(data, sender)
    result.stats.bytes_discarded += cut
    return result


def _decode_bulk_bytes(
    data: bytes | bytearray | memoryview,
    sender: str,
    limit: int | None = None,
    before: _Before | None = None,
) -> tuple[BulkResult, int]:
    """Decode ``data``; with ``limit``, only the frames starting before it (every such
    candidate is complete in ``data`` when ``limit <= len(data) - MAX_FRAME + 1``, so they are
    final whatever follows). ``before``: the counters' state after the preceding bytes.
    Returns the result (offsets relative to ``data``) and how many bytes it consumed."""
    lengths = LENGTHS_FROM[sender]
    buf = np.frombuffer(data, dtype=np.uint8)
    n = buf.size
    stats = DecoderStats()
    if limit is None or limit >= n:
        limit = n
    if n < 2:
        stats.bytes_discarded = limit
        return BulkResult(np.zeros(0, SAMPLE_DTYPE), [], stats), limit
    cand = np.flatnonzero((buf[:-1] == SYNC[0]) & (buf[1:] == SYNC[1]))
    cand = cand[(cand + HEADER_LEN <= n) & (cand < limit)]
    mtype = buf[cand + 2]
    length = buf[cand + 3].astype(np.int64)
    expected = lengths[mtype]
    ok_len = (length <= MAX_PAYLOAD) & (expected != IMPOSSIBLE)
    ok_len &= (expected < 0) | (length == expected)
    end = cand + HEADER_LEN + length + CRC_LEN
    ok = ok_len & (end <= n)
    cand, mtype, length, end = cand[ok], mtype[ok], length[ok], end[ok]
    crc_ok = np.zeros(cand.size, dtype=bool)
    stored = buf[np.minimum(end - 2, n - 1)].astype(np.uint16) | (
        buf[np.minimum(end - 1, n - 1)].astype(np.uint16) << 8
    )
    # IMU samples, the bulk of any capture: copy each candidate's bytes (plus one pad byte, so
    # rows have an even width) and check all CRCs from 16-bit words
    is_imu = (mtype == IMU_SAMPLE) & (length == _IMU_LEN)
    imu_cand = np.flatnonzero(is_imu)
    imu_rows = np.zeros((0, _IMU_FRAME_LEN + 1), dtype=np.uint8)
    if imu_cand.size:
        padded = np.zeros(n + 1, dtype=np.uint8)
        padded[:n] = buf
        imu_rows = _windows(padded, _IMU_FRAME_LEN + 1)[cand[imu_cand]]
    crc_ok[imu_cand] = _IMU_CRC.rows(imu_rows, 2) == stored[imu_cand]
    other_cand = np.flatnonzero(~is_imu)
    for ln in np.unique(length[other_cand]):
        idx = other_cand[length[other_cand] == ln]
        rows = _windows(buf, 4 + int(ln))[cand[idx] + 2]
        crc_ok[idx] = _crc_rows(rows) == stored[idx]

    # choose the frames the sequential scan would consume: a valid frame is taken unless it
    # starts inside one already taken (rare overlaps are resolved greedily, in order)
    vs, ve = cand[crc_ok], end[crc_ok]
    take = np.ones(vs.size, dtype=bool)
    if vs.size > 1:
        prev_max_end = np.maximum.accumulate(ve)[:-1]
        conflict = np.flatnonzero(vs[1:] < prev_max_end) + 1
        if conflict.size:
            last_end = 0
            for i in range(vs.size):  # rare: only when a valid frame sits inside another
                if vs[i] < last_end:
                    take[i] = False
                else:
                    last_end = int(ve[i])
    taken = np.flatnonzero(crc_ok)
    if not take.all():
        vs, ve, taken = vs[take], ve[take], taken[take]
    vtype = mtype[taken]
    # CRC failures are counted only for candidates the scan examines (not inside a taken frame)
    bad = cand[~crc_ok]
    if bad.size and not vs.size:
        stats.crc_errors = int(bad.size)
    elif bad.size:
        k = np.searchsorted(vs, bad, side="right") - 1
        inside = (k >= 0) & (bad < np.where(k >= 0, ve[np.maximum(k, 0)], 0))
        stats.crc_errors = int(np.count_nonzero(~inside))
    consumed = max(limit, int(ve[-1])) if ve.size else limit
    stats.frames = int(vs.size)
    stats.unknown_types = int(np.count_nonzero(_EXPECTED_LEN[vtype] < 0))
    stats.bytes_discarded = int(consumed - np.sum(ve - vs))

    seq = (buf[vs + 4].astype(np.int64) | (buf[vs + 5].astype(np.int64) << 8)).astype(np.int64)
    imu_idx = np.flatnonzero(vtype == IMU_SAMPLE)
    taken_mask = np.zeros(cand.size, dtype=bool)
    taken_mask[taken] = True
    imu_taken = taken_mask[imu_cand]
    wire = (imu_rows if imu_taken.all() else imu_rows[imu_taken]).view(_WIRE_IMU_PADDED)[:, 0]
    t_us = wire["t_us"].astype(np.int64)
    segment0 = 0
    if before is not None and before.last_seq is not None:
        # the rules see the last frame before these bytes first (as the IMU sample it was
        # when its segment has a last sample time): its own verdict was counted already
        prev_imu = before.last_t_us is not None
        seq = np.concatenate(([before.last_seq], seq))
        imu_idx = np.concatenate(([0], imu_idx + 1)) if prev_imu else imu_idx + 1
        if prev_imu:
            t_us = np.concatenate((np.asarray([before.last_t_us], np.int64), t_us))
        reset, gaps = segments(seq, imu_idx, t_us)
        seq, reset, gaps = seq[1:], reset[1:], gaps[1:]
        imu_idx = imu_idx[1:] - 1 if prev_imu else imu_idx - 1
        t_us = t_us[1:] if prev_imu else t_us
    else:
        reset, gaps = segments(seq, imu_idx, t_us)
    if before is not None:
        segment0 = before.segment
        if seq.size:
            seg_of = np.cumsum(reset)
            before.last_seq = int(seq[-1])
            if imu_idx.size and seg_of[imu_idx[-1]] == seg_of[-1]:
                before.last_t_us = int(t_us[-1])
            elif seg_of[-1] > 0:  # a reset after the last sample forgets its time
                before.last_t_us = None
            before.segment += int(seg_of[-1])
    stats.resets = int(np.count_nonzero(reset))
    stats.lost_frames = int(np.sum(gaps))
    segment = segment0 + np.cumsum(reset)
    samples = np.zeros(imu_idx.size, dtype=SAMPLE_DTYPE)
    for name in ("seq", "t_us", *IMU_FIELDS, "flags"):
        samples[name] = wire[name]
    samples["offset"] = vs[imu_idx]
    samples["segment"] = segment[imu_idx]
    lost_so_far = np.cumsum(gaps)[imu_idx]
    samples["lost"] = np.diff(lost_so_far, prepend=0)
    if before is not None:  # frames lost after the last sample of the bytes before count too
        after = int(np.sum(gaps)) - (int(lost_so_far[-1]) if imu_idx.size else 0)
        if imu_idx.size:
            samples["lost"][0] += before.lost_since_sample
            before.lost_since_sample = after
        else:
            before.lost_since_sample += after
    others = [
        (int(vs[i]), Frame(int(vtype[i]), int(seq[i]), bytes(buf[vs[i] + HEADER_LEN : ve[i] - 2])))
        for i in np.flatnonzero(vtype != IMU_SAMPLE)
    ]
    return BulkResult(samples, others, stats), consumed


class BulkReader:
    """Decode a stream of any length in bounded memory at the bulk decoder's speed: iterate
    to get, per chunk read, the :class:`BulkResult` of the frames now final and each sample's
    arrival time (ns; None for a raw capture). An IMUCAP01 capture is recognised by its magic
    and unwrapped (:class:`host.wire.capture.CaptureUnwrapper`). Together the results are
    :func:`decode_file`'s; :attr:`stats` totals the counters, :attr:`truncated_bytes` is the
    cut-off last read of a capture (counted in ``bytes_discarded``)."""

    def __init__(self, stream: Readable, chunk: int = 1 << 22, sender: str = "device") -> None:
        self.stream = stream
        self.chunk = chunk
        self.decoder = ChunkedDecoder(sender)
        self.is_capture = False
        self.truncated_bytes = 0
        self._unwrap: CaptureUnwrapper | None = None

    @property
    def stats(self) -> DecoderStats:
        return self.decoder.stats

    def __iter__(self) -> Iterator[tuple[BulkResult, np.ndarray | None]]:
        from host.wire.capture import MAGIC, CaptureUnwrapper

        head = b""
        while len(head) < len(MAGIC):
            data = self.stream.read(len(MAGIC) - len(head))
            if not data:
                break
            head += data
        if head == MAGIC:
            self.is_capture = True
            self._unwrap = CaptureUnwrapper(times=True)
            head = self._unwrap.feed(head)
        data = head
        while True:
            if self._unwrap is not None:
                data = self._unwrap.feed(data)
            yield self._result(self.decoder.feed(data))
            data = self.stream.read(self.chunk)
            if not data:
                break
        if self._unwrap is not None:
            self.truncated_bytes = self._unwrap.truncated_bytes
        last = self.decoder.flush()
        last.stats.bytes_discarded += self.truncated_bytes
        self.decoder.stats.bytes_discarded += self.truncated_bytes
        yield self._result(last)

    def _result(self, r: BulkResult) -> tuple[BulkResult, np.ndarray | None]:
        if self._unwrap is None:
            return r, None
        arrivals = self._unwrap.arrival_ns_at(r.samples["offset"] + _IMU_FRAME_LEN - 1)
        self._unwrap.forget_before(self.decoder._base)
        return r, arrivals


# --------------------------------------------------------------------------- physical units


def samples_to_physical(
    samples: np.ndarray, afs_sel: int = 0, fs_sel: int = 0, product_id: int | None = None
) -> dict:
    """Raw sample counts -> physical units: ax..az m/s², gx..gz °/s, temp °C (arrays)."""
    out: dict[str, np.ndarray] = {}
    for a in ("ax", "ay", "az"):
        out[a] = sensor.accel_mps2(samples[a], afs_sel, product_id)
    for g in ("gx", "gy", "gz"):
        out[g] = sensor.gyro_dps(samples[g], fs_sel)
    out["temp"] = sensor.temp_c(samples["temp"])
    return out


# --------------------------------------------------------------------------- capture files


def full_scale_from_hello(others: list[tuple[int, Frame]]) -> tuple[int, int]:
    """Full-scale selections from the first HELLO frame whose codes an MPU-6000 has, or the
    defaults (±2 g, ±250 °/s) without HELLO; UserError when every HELLO is impossible."""
    bad: tuple[int, int] | None = None
    for _, f in others:
        if f.name == "HELLO":
            afs, fs = f.fields["accel_fs_sel"], f.fields["gyro_fs_sel"]
            if afs in sensor.ACCEL_LSB_PER_G and fs in sensor.GYRO_LSB_PER_DPS:
                return afs, fs
            bad = bad or (afs, fs)
    if bad is not None:
        raise UserError(
            f"the capture's HELLO reports full-scale codes AFS_SEL {bad[0]}, FS_SEL {bad[1]}; "
            "an MPU-6000 has 0 to 3, so the samples cannot be scaled: the firmware is not "
            "this project's (decode --stats still counts the frames)"
        )
    return 0, 0


def product_id_from_hello(others: list[tuple[int, Frame]]) -> int | None:
    """PRODUCT_ID (the sensor's revision: C4/C5 count half the accelerometer LSB/g) from the
    first HELLO frame, or None without HELLO (the datasheet's sensitivity then)."""
    return next((f.fields["product_id"] for _, f in others if f.name == "HELLO"), None)


def decode_file(path: Path) -> tuple[BulkResult, np.ndarray | None]:
    """Decode a raw capture or an IMUCAP01 capture; second value: each sample's arrival ns."""
    from host.wire import capture

    raw = capture.read_capture_bytes(path)
    arrivals = None
    if raw.startswith(capture.MAGIC):
        cap = capture.parse(raw, source=str(path))
        if cap.truncated_bytes:
            print(
                f"warning: {path}: the last {cap.truncated_bytes} bytes are a cut-off read "
                "(the recording was interrupted); decoded everything before them",
                file=sys.stderr,
            )
        result = decode_bulk(cap.data)
        arrivals = cap.arrival_ns_at(result.samples["offset"] + _IMU_FRAME_LEN - 1)
    else:
        result = decode_bulk(raw)
    return result, arrivals


def baud_from_hello(others: list[tuple[int, Frame]], default: int = 115200) -> int:
    """The link's baud rate from the first HELLO frame stating one (``others`` as in
    :attr:`BulkResult.others`), else ``default``, baud."""
    for _, f in others:
        if f.name == "HELLO" and f.fields["baud"]:
            return f.fields["baud"]
    return default
