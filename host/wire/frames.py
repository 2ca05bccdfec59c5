"""Frames: the wire format of ``protocol/spec.json`` as definitions and codecs.

Two layers, as in pyubx2:

1. **Definitions as data**: :data:`MESSAGES` is built from the generated table
   ``host/wire/protocol_gen.py`` (never edited by hand).
2. **An immutable frame object**: :class:`Frame` (type, seq, payload; fields decoded on demand),
   and the encoders: :func:`encode_frame`, :func:`encode_imu_samples` (vectorised), :func:`crc16`.

The readers that sync, check and yield frames are :mod:`host.wire.stream` (bytes in chunks of
any size) and :mod:`host.wire.bulk` (numpy over a whole capture, the same frames); both use the
IMU frame's wire layout (:data:`WIRE_IMU`) and the CRC table defined here.
"""

from __future__ import annotations

import binascii
import struct
from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType

import numpy as np

from host.wire import protocol_gen as gen

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
    rec = np.zeros(n, dtype=WIRE_IMU)
    rec["sync"] = tuple(SYNC)
    rec["type"] = IMU_SAMPLE
    rec["len"] = MESSAGES[IMU_SAMPLE].length
    rec["seq"] = (seq0 + np.arange(n)) & 0xFFFF
    rec["t_us"] = t
    for i, name in enumerate(IMU_FIELDS):
        rec[name] = c[:, i]
    rec["flags"] = flags
    raw = rec.view(np.uint8).reshape(n, IMU_FRAME_LEN)
    rec["crc"] = crc16_rows(raw[:, 2 : 2 + 4 + MESSAGES[IMU_SAMPLE].length])
    return rec.tobytes()


# --------------------------------------------------------------------------- the IMU frame in numpy

#: an IMU_SAMPLE payload, and its whole frame on the wire (bytes)
IMU_LEN = MESSAGES[IMU_SAMPLE].length
IMU_FRAME_LEN = IMU_LEN + OVERHEAD
#: the fields of an IMU_SAMPLE frame as on the wire: envelope, payload fields, CRC
WIRE_IMU_FIELDS = (
    [("sync", "u1", (2,)), ("type", "u1"), ("len", "u1"), ("seq", "<u2")]
    + [(f.name, gen.FIELD_TYPES[f.code][1]) for f in MESSAGES[IMU_SAMPLE].fields]
    + [("crc", "<u2")]
)
#: numpy dtype of one IMU_SAMPLE frame exactly as on the wire (mixed byte orders)
WIRE_IMU = np.dtype(WIRE_IMU_FIELDS)
assert WIRE_IMU.itemsize == IMU_FRAME_LEN


def _crc_byte_table() -> np.ndarray:
    t = np.zeros(256, dtype=np.uint16)
    for b in range(256):
        c = b << 8
        for _ in range(8):
            c = ((c << 1) ^ gen.CRC_POLY) if c & 0x8000 else (c << 1)
        t[b] = c & 0xFFFF
    return t


#: CRC-16/CCITT-FALSE of each byte value (the register after one byte, from 0)
CRC_TABLE = _crc_byte_table()


def crc16_rows(rows: np.ndarray) -> np.ndarray:
    """CRC-16/CCITT-FALSE of each row of a (M, K) uint8 array (vectorised over rows)."""
    crc = np.full(rows.shape[0], gen.CRC_INIT, dtype=np.uint16)
    for k in range(rows.shape[1]):
        crc = (crc << 8) ^ CRC_TABLE[(crc >> 8) ^ rows[:, k]]
    return crc
