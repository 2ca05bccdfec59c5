"""The bulk decoder: a whole capture, or a stream in bounded memory, decoded with numpy.

:func:`decode_bulk` gives exactly the frames and counters the streaming path
(:class:`host.wire.stream.StreamDecoder` followed by its ``flush``) gives for the same bytes,
under the same resynchronisation rule (property-tested); :class:`ChunkedDecoder` and
:class:`BulkReader` do the same in bounded memory, :func:`decode_file` reads a raw or IMUCAP01
capture. IMU samples come out as one array (:data:`SAMPLE_DTYPE`), other frames as objects;
the HELLO frame among them gives the full scales, the sensor's revision and the baud rate.
"""

from __future__ import annotations

import sys
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from host.errors import UserError
from host.wire import sensor
from host.wire.capture import CaptureUnwrapper
from host.wire.frames import (
    BY_NAME,
    CRC_LEN,
    CRC_TABLE,
    HEADER_LEN,
    IMPOSSIBLE,
    IMU_FIELDS,
    IMU_FRAME_LEN,
    IMU_LEN,
    IMU_SAMPLE,
    LENGTHS_FROM,
    MAX_PAYLOAD,
    MESSAGES,
    SYNC,
    WIRE_IMU_FIELDS,
    Frame,
    crc16,
    crc16_rows,
)
from host.wire.segments import repeated, repeated_text, segments
from host.wire.stream import DecoderStats, Readable

#: an IMU_SAMPLE frame with one pad byte, so that rows have an even width (16-bit word views)
_WIRE_IMU_PADDED = np.dtype([*WIRE_IMU_FIELDS, ("pad", "u1")])

#: the decoded samples array: wire values, native byte order, plus the frame's offset in the
#: stream, its segment (between device resets) and ``lost``: the frames lost on the link since
#: the previous sample (:func:`host.wire.segments.segments`; 0 where a segment starts)
SAMPLE_DTYPE = np.dtype(
    [("seq", "u2"), ("t_us", "u4")]
    + [(n, "i2") for n in IMU_FIELDS]
    + [("flags", "u1"), ("offset", "i8"), ("segment", "i4"), ("lost", "i4")]
)


class _PairCRC:
    """The CRC check of fixed-length frames from 16-bit words: one table lookup per two bytes.

    The CRC is affine over GF(2): crc(m) = crc(0…0) ⊕ ⊕_k T_k[word_k], T_k the CRC (init 0)
    of word k followed by zeros, and so is crc(m) ⊕ the stored CRC. A frame's ``nbytes``
    checked bytes start with the known ``prefix`` (type and length: folded into the constant)
    and are followed by the stored CRC (little-endian) and, when that leaves an odd count, one
    pad byte (ignored); the frame checks when the XOR of its words' entries is crc(prefix,
    0…0). An IMU_SAMPLE (seq, 19-byte payload, CRC, pad): 12 lookups of 65536-entry tables,
    no separate read of the stored CRC.
    """

    def __init__(self, prefix: bytes, nbytes: int) -> None:
        self.prefix = len(prefix)
        rest = nbytes - len(prefix)
        self.nwords = (rest + 2 + 1) // 2  # the rest, the stored CRC, a pad byte when odd
        # per byte position: the register from 0 after that byte and the zeros after it
        single = []
        c = CRC_TABLE.copy()  # the last byte's
        for _ in range(rest):
            single.append(c)
            c = (c << 8) ^ CRC_TABLE[c >> 8]  # one zero byte more after it
        byte = single[::-1]
        byte += [np.arange(256, dtype=np.uint16), np.arange(256, dtype=np.uint16) << 8]
        byte += [np.zeros(256, np.uint16)] * (2 * self.nwords - len(byte))
        # indexed by the pair read as one little-endian word (second byte high): a view of
        # the rows in the machine's order on the usual hosts, so no byte swap per lookup
        self.tables = [
            (byte[2 * k][None, :] ^ byte[2 * k + 1][:, None]).reshape(-1)
            for k in range(self.nwords)
        ]
        self.zero = crc16_rows(np.frombuffer(prefix + bytes(rest), np.uint8)[None, :])[0]

    def check(self, rows: np.ndarray, start: int) -> np.ndarray:
        """Does each frame's stored CRC match, its checked bytes at ``rows[:, start:]`` (the
        prefix's bytes there); rows (M, W) uint8 C-contiguous, W even, ``start`` even and
        ``start + nbytes + 3 <= W``."""
        at = start + self.prefix
        # each word's column as the index (take converts it to one contiguous index array
        # anyway: transposing the words first only copies them once more)
        words = rows[:, at : at + 2 * self.nwords].view("<u2")
        acc = self.tables[0].take(words[:, 0])
        for k in range(1, self.nwords):
            acc ^= self.tables[k].take(words[:, k])
        return acc == self.zero


_IMU_CRC = _PairCRC(bytes([IMU_SAMPLE, IMU_LEN]), 4 + IMU_LEN)


def _frames_at(buf: np.ndarray, starts: np.ndarray, width: int) -> np.ndarray:
    """(len(starts), width) uint8: row i is buf[starts[i] : starts[i] + width], zeros past the
    end of ``buf`` (starts increasing). Each row is copied as one item (a 2-D gather copies
    byte by byte)."""
    whole = starts[-1] + width <= buf.size  # else the last rows run past the end
    src = buf if whole else np.concatenate((buf, np.zeros(width, np.uint8)))
    items = np.ndarray((src.size - width + 1,), np.dtype((np.void, width)), src, 0, (1,))
    return items[starts].view(np.uint8).reshape(starts.size, width)


def _windows(buf: np.ndarray, width: int) -> np.ndarray:
    """Read-only (n - width + 1, width) view: row i is buf[i : i + width] (no copy)."""
    return np.lib.stride_tricks.sliding_window_view(buf, width)


@dataclass
class BulkResult:
    """What :func:`decode_bulk` found: IMU samples as an array, other frames as objects."""

    samples: np.ndarray  # SAMPLE_DTYPE
    others: list[tuple[int, Frame]]  # (byte offset, frame) for non-IMU frames
    stats: DecoderStats = field(default_factory=DecoderStats)
    #: CRC-valid frames of a known type but another length than this spec gives it (another
    #: firmware's): (byte offset, type, payload length) each, never decoded (:func:`foreign`)
    foreign: list[tuple[int, int, int]] = field(default_factory=list)


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
        result.foreign = [(off + self._base, t, ln) for off, t, ln in result.foreign]
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
    buf = np.frombuffer(data, dtype=np.uint8)
    n = buf.size
    stats = DecoderStats()
    if limit is None or limit >= n:
        limit = n
    if n < 2:
        stats.bytes_discarded = limit
        return BulkResult(np.zeros(0, SAMPLE_DTYPE), [], stats), limit
    cand, mtype, length, end, alien = _candidates(buf, LENGTHS_FROM[sender], limit)
    crc_ok, imu_cand, imu_rows = _crc_checks(buf, cand, mtype, length, end)
    vs, ve, taken = _taken(cand[crc_ok], end[crc_ok], np.flatnonzero(crc_ok))
    vtype = mtype[taken]
    stats.crc_errors = _crc_errors(cand[~crc_ok], vs, ve)
    consumed = max(limit, int(ve[-1])) if ve.size else limit
    stats.frames = int(vs.size)
    stats.unknown_types = int(np.count_nonzero(LENGTHS_FROM["any"][vtype] < 0))
    stats.bytes_discarded = int(consumed - np.sum(ve - vs))
    imu_idx = np.flatnonzero(vtype == IMU_SAMPLE)
    taken_mask = np.zeros(cand.size, dtype=bool)
    taken_mask[taken] = True
    imu_taken = taken_mask[imu_cand]
    wire = (imu_rows if imu_taken.all() else imu_rows[imu_taken]).view(_WIRE_IMU_PADDED)[:, 0]
    seq = np.empty(vs.size, dtype=np.int64)  # the IMU samples' from their rows, the others'
    seq[imu_idx] = wire["seq"]
    other = np.flatnonzero(vtype != IMU_SAMPLE)
    seq[other] = buf[vs[other] + 4].astype(np.int64) | (buf[vs[other] + 5].astype(np.int64) << 8)
    reset, gaps = _counter_rules(seq, imu_idx, wire["t_us"].astype(np.int64), before, stats)
    samples = _samples_of(wire, vs[imu_idx], imu_idx, reset, gaps, before, stats)
    others = [
        (int(vs[i]), Frame(int(vtype[i]), int(seq[i]), bytes(buf[vs[i] + HEADER_LEN : ve[i] - 2])))
        for i in other
    ]
    return BulkResult(samples, others, stats, _outside(buf, alien, vs, ve)), consumed


def _candidates(
    buf: np.ndarray, lengths: np.ndarray, limit: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Every SYNC pair starting before ``limit`` whose header is whole, of a type the sender
    sends with a length it may have, and whose frame ends inside ``buf``: (start, type,
    payload length, end) each; and the starts of CRC-valid frames of a known type but
    another length (another firmware's)."""
    n = buf.size
    cand = np.flatnonzero((buf[:-1] == SYNC[0]) & (buf[1:] == SYNC[1]))
    cand = cand[: np.searchsorted(cand, min(n - HEADER_LEN, limit - 1), side="right")]
    mtype = buf[cand + 2]
    length = buf[cand + 3].astype(np.int64)
    expected = lengths[mtype]
    ok_len = (length <= MAX_PAYLOAD) & (expected != IMPOSSIBLE)
    other_len = ok_len & (expected >= 0) & (length != expected)
    ok_len &= (expected < 0) | (length == expected)
    end = cand + HEADER_LEN + length + CRC_LEN
    alien = _crc_valid(buf, cand[other_len & (end <= n)], n)
    ok = ok_len & (end <= n)
    return cand[ok], mtype[ok], length[ok], end[ok], alien


def _crc_checks(
    buf: np.ndarray, cand: np.ndarray, mtype: np.ndarray, length: np.ndarray, end: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Whether each candidate's CRC checks; and the IMU samples among them (their indices
    and their bytes, one row each, for the samples array)."""
    crc_ok = np.zeros(cand.size, dtype=bool)
    # IMU samples, the bulk of any capture: copy each candidate's bytes (plus one pad byte, so
    # rows have an even width) and check all CRCs from 16-bit words
    is_imu = (mtype == IMU_SAMPLE) & (length == IMU_LEN)
    imu_cand = np.flatnonzero(is_imu)
    imu_rows = np.zeros((0, IMU_FRAME_LEN + 1), dtype=np.uint8)
    if imu_cand.size:
        imu_rows = _frames_at(buf, cand[imu_cand], IMU_FRAME_LEN + 1)
    crc_ok[imu_cand] = _IMU_CRC.check(imu_rows, 2)
    other_cand = np.flatnonzero(~is_imu)
    # (the lengths present by counting: np.unique would import numpy.ma, 20 ms of start-up)
    for ln in np.flatnonzero(np.bincount(length[other_cand])):
        idx = other_cand[length[other_cand] == ln]
        rows = _windows(buf, 4 + int(ln))[cand[idx] + 2]
        e = end[idx]
        stored = buf[e - 2].astype(np.uint16) | (buf[e - 1].astype(np.uint16) << 8)
        crc_ok[idx] = crc16_rows(rows) == stored
    return crc_ok, imu_cand, imu_rows


def _taken(
    vs: np.ndarray, ve: np.ndarray, taken: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The valid frames (starts ``vs``, ends ``ve``, candidate indices ``taken``) the
    sequential scan would consume: a valid frame is taken unless it starts inside one already
    taken (rare overlaps are resolved greedily, in order; none where each frame ends before
    the next starts)."""
    take = np.ones(vs.size, dtype=bool)
    if vs.size > 1 and np.any(vs[1:] < ve[:-1]):
        prev_max_end = np.maximum.accumulate(ve)[:-1]
        conflict = np.flatnonzero(vs[1:] < prev_max_end) + 1
        if conflict.size:
            last_end = 0
            for i in range(vs.size):  # rare: only when a valid frame sits inside another
                if vs[i] < last_end:
                    take[i] = False
                else:
                    last_end = int(ve[i])
    if not take.all():
        return vs[take], ve[take], taken[take]
    return vs, ve, taken


def _crc_errors(bad: np.ndarray, vs: np.ndarray, ve: np.ndarray) -> int:
    """CRC failures the scan examines: those of candidates ``bad`` not inside a taken frame."""
    if not bad.size:
        return 0
    if not vs.size:
        return int(bad.size)
    k = np.searchsorted(vs, bad, side="right") - 1
    inside = (k >= 0) & (bad < np.where(k >= 0, ve[np.maximum(k, 0)], 0))
    return int(np.count_nonzero(~inside))


def _counter_rules(
    seq: np.ndarray,
    imu_idx: np.ndarray,
    t_us: np.ndarray,
    before: _Before | None,
    stats: DecoderStats,
) -> tuple[np.ndarray, np.ndarray]:
    """The counters' rules over the taken frames (:func:`host.wire.segments.segments`):
    resets and frames lost before each; counted in ``stats``, remembered in ``before``."""
    if before is not None and before.last_seq is not None:
        # the rules see the last frame before these bytes first (as the IMU sample it was
        # when its segment has a last sample time): its own verdict was counted already
        prev_imu = before.last_t_us is not None
        seq1 = np.concatenate(([before.last_seq], seq))
        imu1 = np.concatenate(([0], imu_idx + 1)) if prev_imu else imu_idx + 1
        if prev_imu:
            t_us = np.concatenate((np.asarray([before.last_t_us], np.int64), t_us))
        reset, gaps = segments(seq1, imu1, t_us)
        reset, gaps = reset[1:], gaps[1:]
        t_us = t_us[1:] if prev_imu else t_us
    else:
        reset, gaps = segments(seq, imu_idx, t_us)
    stats.resets = int(np.count_nonzero(reset))
    stats.lost_frames = int(np.sum(gaps))
    if before is not None and seq.size:
        seg_of = np.cumsum(reset) if stats.resets else None  # None: all in one segment
        before.last_seq = int(seq[-1])
        if imu_idx.size and (seg_of is None or seg_of[imu_idx[-1]] == seg_of[-1]):
            before.last_t_us = int(t_us[-1])
        elif stats.resets:  # a reset after the last sample forgets its time
            before.last_t_us = None
    return reset, gaps


def _samples_of(
    wire: np.ndarray,
    offsets: np.ndarray,
    imu_idx: np.ndarray,
    reset: np.ndarray,
    gaps: np.ndarray,
    before: _Before | None,
    stats: DecoderStats,
) -> np.ndarray:
    """The samples array: the wire values, each sample's offset, segment (``before``'s
    numbering) and the frames lost since the previous sample (those after the last sample of
    the bytes before counted on the first)."""
    segment0 = 0 if before is None else before.segment
    if before is not None and reset.size:
        before.segment += stats.resets
    samples = np.empty(imu_idx.size, dtype=SAMPLE_DTYPE)  # every field is written below
    for name in ("seq", "t_us", *IMU_FIELDS, "flags"):
        samples[name] = wire[name]
    samples["offset"] = offsets
    # (no reset, no frame lost: the usual chunk, a constant segment and no losses to place)
    samples["segment"] = (segment0 + np.cumsum(reset))[imu_idx] if stats.resets else segment0
    lost_by_last = 0  # frames lost up to the last sample
    if stats.lost_frames:
        lost_so_far = np.cumsum(gaps)[imu_idx]
        samples["lost"] = np.diff(lost_so_far, prepend=0)
        lost_by_last = int(lost_so_far[-1]) if imu_idx.size else 0
    else:
        samples["lost"] = 0
    if before is not None:  # frames lost after the last sample of the bytes before count too
        after = stats.lost_frames - lost_by_last
        if imu_idx.size:
            samples["lost"][0] += before.lost_since_sample
            before.lost_since_sample = after
        else:
            before.lost_since_sample += after
    return samples


def _crc_valid(buf: np.ndarray, starts: np.ndarray, n: int) -> np.ndarray:
    """The candidates at ``starts`` whose stored CRC matches over the length they claim."""
    good = [
        int(p) for p in starts
        if crc16(buf[p + 2 : (e := p + HEADER_LEN + int(buf[p + 3]) + CRC_LEN) - 2].tobytes())
        == int(buf[e - 2]) | (int(buf[e - 1]) << 8)
    ]  # fmt: skip
    return np.asarray(good, dtype=np.int64)


def _outside(
    buf: np.ndarray, starts: np.ndarray, vs: np.ndarray, ve: np.ndarray
) -> list[tuple[int, int, int]]:
    """(offset, type, payload length) of the frames at ``starts`` that no frame taken
    (``vs``..``ve``) holds: the ones the sequential scan meets."""
    if not starts.size:
        return []
    if vs.size:
        k = np.searchsorted(vs, starts, side="right") - 1
        inside = (k >= 0) & (starts < np.where(k >= 0, ve[np.maximum(k, 0)], 0))
        starts = starts[~inside]
    return [(int(p), int(buf[p + 2]), int(buf[p + 3])) for p in starts]


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
        #: damaged places of a capture skipped: (file offset, bytes) each (at the end)
        self.skipped: tuple[tuple[int, int], ...] = ()
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
        if self._unwrap is not None:  # the last read (held until the end was known)
            yield self._result(self.decoder.feed(self._unwrap.finish()))
            self.truncated_bytes = self._unwrap.truncated_bytes
            self.skipped = tuple(self._unwrap.skipped)
        last = self.decoder.flush()
        last.stats.bytes_discarded += self.truncated_bytes
        self.decoder.stats.bytes_discarded += self.truncated_bytes
        yield self._result(last)

    def _result(self, r: BulkResult) -> tuple[BulkResult, np.ndarray | None]:
        if self._unwrap is None:
            return r, None
        arrivals = self._unwrap.arrival_ns_at(r.samples["offset"] + IMU_FRAME_LEN - 1)
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


def unreadable(result: BulkResult) -> tuple[int, str] | None:
    """The first place in ``result`` after which samples cannot be scaled as they were
    measured, and why: a CRC-valid HELLO of another length than this spec's (another firmware
    version's: its full scales are not where this spec reads them) or a HELLO of another
    sensor (WHO_AM_I not an MPU-6000's 0x68: its counts are not an MPU-6000's); None when
    there is none. Decoding them with this spec's scales would be silently wrong (a ±16 g
    HELLO of 24 bytes gave az = 1.226 m/s² for 9.807)."""
    places: list[tuple[int, str]] = []
    hello = BY_NAME["HELLO"]
    for off, mtype, length in result.foreign:
        if mtype == hello.type:
            why = f"a HELLO with a {length}-byte payload, its CRC valid (this spec's HELLO has"
            places.append((off, f"{why} {hello.length}): another firmware version's"))
    for off, f in result.others:
        if f.name == "HELLO" and (who := f.fields["who_am_i"]) != sensor.WHO_AM_I_MPU6000:
            why = f"a HELLO of another sensor (WHO_AM_I {who:#04x}; an MPU-6000 reads"
            places.append((off, f"{why} {sensor.WHO_AM_I_MPU6000:#04x})"))
    return min(places, default=None)


def foreign_text(path: object, foreign: list[tuple[int, int, int]]) -> str | None:
    """The line naming CRC-valid frames of a known type but another length (other than a
    HELLO, which :func:`unreadable` names): none of them is decoded."""
    if not foreign:
        return None
    off, mtype, length = foreign[0]
    return (
        f"{path}: {len(foreign)} CRC-valid frame(s) of another length than this spec gives "
        f"their type (first at byte {off}: {MESSAGES[mtype].name} with a {length}-byte "
        f"payload, this spec's {MESSAGES[mtype].length}): another firmware's; not decoded"
    )


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
        if warning := capture.damage_text(path, cap.truncated_bytes, cap.skipped):
            print(warning, file=sys.stderr)
        result = decode_bulk(cap.data)
        arrivals = cap.arrival_ns_at(result.samples["offset"] + IMU_FRAME_LEN - 1)
    else:
        result = decode_bulk(raw)
    twice = repeated(result.samples)
    if twice.any():  # a read written twice: kept once
        print(f"warning: {path}: {repeated_text(int(twice.sum()))}", file=sys.stderr)
        result.samples = result.samples[~twice]
        arrivals = None if arrivals is None else arrivals[~twice]
    return result, arrivals


def baud_from_hello(others: list[tuple[int, Frame]], default: int = 115200) -> int:
    """The link's baud rate from the first HELLO frame stating one (``others`` as in
    :attr:`BulkResult.others`), else ``default``, baud."""
    for _, f in others:
        if f.name == "HELLO" and f.fields["baud"]:
            return f.fields["baud"]
    return default
