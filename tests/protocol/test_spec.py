"""The spec, its generated outputs and the shared vectors agree."""

from __future__ import annotations

import json
import struct
import subprocess
import sys
from pathlib import Path

import crcmod.predefined
import pytest

from host.wire import protocol_gen
from host.wire.bulk import decode_bulk
from host.wire.frames import BY_NAME, MESSAGES, crc16, encode_frame
from host.wire.stream import StreamDecoder

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "protocol"))
import generate  # noqa: E402

VECTORS = json.loads((ROOT / "protocol" / "vectors.json").read_text())


@pytest.mark.parametrize("script", ["generate.py", "make_vectors.py"])
def test_generated_outputs_are_fresh(script: str) -> None:
    """The generated header/table/doc and the shared vectors match spec.json."""
    r = subprocess.run(
        [sys.executable, str(ROOT / "protocol" / script), "--check"],
        capture_output=True,
        text=True,
    )
    assert r.returncode == 0, r.stdout


def test_fingerprint_matches_spec_and_ignores_formatting() -> None:
    spec = generate.load_spec()
    assert protocol_gen.SPEC_FINGERPRINT == generate.fingerprint(spec)
    reordered = json.loads(json.dumps(spec, sort_keys=True))
    assert generate.fingerprint(reordered) == generate.fingerprint(spec)
    spec["messages"][0]["fields"][1][0] = "ax_renamed"
    assert generate.fingerprint(spec) != protocol_gen.SPEC_FINGERPRINT


def test_firmware_header_carries_every_type_length_and_the_fingerprint() -> None:
    header = (ROOT / "firmware" / "src" / "protocol_gen.h").read_text()
    assert f"#define PROTO_SPEC_FINGERPRINT 0x{protocol_gen.SPEC_FINGERPRINT:08X}ul" in header
    for m in MESSAGES.values():
        assert f"#define PROTO_TYPE_{m.name} 0x{m.type:02X}u" in header
        assert f"#define PROTO_LEN_{m.name} {m.length}u" in header


def test_spec_envelope_is_what_the_issue_fixes() -> None:
    assert protocol_gen.SYNC == b"\xa5\x5a"
    assert BY_NAME["IMU_SAMPLE"].type == 0x01 and BY_NAME["IMU_SAMPLE"].length == 19
    assert all(m.length <= 64 for m in MESSAGES.values())


def test_crc_is_ccitt_false() -> None:
    assert crc16(b"123456789") == 0x29B1
    ref = crcmod.predefined.mkCrcFun("crc-ccitt-false")
    for v in VECTORS:
        raw = bytes.fromhex(v["hex"])
        assert ref(raw[2:-2]) == int.from_bytes(raw[-2:], "little"), v["name"]


def test_imu_vector_built_by_hand_from_the_issue_table() -> None:
    """Independent of the encoder: build the first vector's bytes from the envelope table."""
    v = next(v for v in VECTORS if v["name"] == "sample_level_z_up")
    f = v["fields"]
    body = bytes([0x01, 19]) + struct.pack("<H", v["seq"]) + struct.pack("<I", f["t_us"])
    body += struct.pack(">7h", *(f[k] for k in ("ax", "ay", "az", "temp", "gx", "gy", "gz")))
    body += bytes([f["flags"]])
    crc = crcmod.predefined.mkCrcFun("crc-ccitt-false")(body)
    assert bytes.fromhex(v["hex"]) == b"\xa5\x5a" + body + struct.pack("<H", crc)


@pytest.mark.parametrize("v", VECTORS, ids=[v["name"] for v in VECTORS])
def test_vector_decodes_to_its_fields_on_both_paths(v: dict) -> None:
    raw = bytes.fromhex(v["hex"])
    sender = MESSAGES[v["type"]].direction  # a board's stream never carries host commands
    (frame,) = StreamDecoder(sender).feed(raw)
    assert frame.type == v["type"] and frame.seq == v["seq"]
    assert frame.fields == v["fields"]
    assert frame.to_bytes() == raw
    assert encode_frame(v["message"], v["seq"], **v["fields"]) == raw
    bulk = decode_bulk(raw, sender)
    assert bulk.stats.frames == 1 and bulk.stats.bytes_discarded == 0
    if v["message"] == "IMU_SAMPLE":
        s = bulk.samples[0]
        assert {k: int(s[k]) for k in v["fields"]} == v["fields"]
    else:
        assert bulk.others[0][1].fields == v["fields"]
