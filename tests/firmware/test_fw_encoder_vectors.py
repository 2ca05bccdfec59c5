"""The firmware's frame encoder and command parser (firmware/src/frame.cpp), compiled for the
PC with g++, against the shared vectors in protocol/vectors.json."""

from __future__ import annotations

import json
import shutil
import struct
import subprocess
from pathlib import Path

import pytest
from fwbuild import FIRMWARE, GENERATE, ROOT

VECTORS_PATH = ROOT / "protocol" / "vectors.json"
SPEC = GENERATE.load_spec()
MESSAGES = {m["name"]: m for m in SPEC["messages"]}
STRUCT_CODES = {
    "u8": "<B",
    "i8": "<b",
    "u16le": "<H",
    "i16le": "<h",
    "u16be": ">H",
    "i16be": ">h",
    "u32le": "<I",
    "i32le": "<i",
    "i32be": ">i",
}


@pytest.fixture(scope="module")
def vectors() -> list[dict]:
    assert VECTORS_PATH.exists(), (
        "protocol/vectors.json is missing (python protocol/make_vectors.py)"
    )
    vecs = json.loads(VECTORS_PATH.read_text())
    assert vecs, "no vectors"
    return vecs


@pytest.fixture(scope="module")
def gxx() -> str:
    exe = shutil.which("g++")
    if exe is None:
        pytest.skip("host g++ not installed")
    return exe


def message_of(vec: dict) -> dict:
    by_type = [m for m in SPEC["messages"] if m["type"] == vec["type"]]
    assert len(by_type) == 1, f"{vec['name']}: type {vec['type']} not in spec"
    msg = by_type[0]
    if "message" in vec:
        assert vec["message"] == msg["name"]
    return msg


def pack_payload(msg: dict, fields: dict) -> bytes:
    assert set(fields) == {f[0] for f in msg["fields"]}, f"{msg['name']}: fields differ from spec"
    return b"".join(struct.pack(STRUCT_CODES[f[1]], fields[f[0]]) for f in msg["fields"])


def c_bytes(data: bytes) -> str:
    return "{" + ", ".join(f"0x{b:02x}" for b in data) + "}" if data else "{0}"


def c_arg(code: str, value: int) -> str:
    ctype = GENERATE.FIELD_TYPES[code][1]
    return f"static_cast<{ctype}>(INT64_C({value}))"


def encode_snippet(vec: dict) -> str:
    """C++ that encodes one vector the way the firmware does, leaving the frame in buf / n."""
    msg = message_of(vec)
    name, fields, seq = msg["name"], vec["fields"], vec["seq"]
    lines = [
        f"    // {vec['name']}",
        f'    static_assert(PROTO_TYPE_{name} == {msg["type"]}u, "type");',
    ]
    if name == "IMU_SAMPLE":
        # The firmware passes the 14 bytes burst-read from ACCEL_XOUT_H on unchanged.
        raw = b"".join(
            struct.pack(">h", fields[k]) for k in ("ax", "ay", "az", "temp", "gx", "gy", "gz")
        )
        lines += [
            f"    {{ const uint8_t raw[14] = {c_bytes(raw)};",
            f"      n = frame::encode_imu_sample(buf, {seq}u, UINT32_C({fields['t_us']}), raw, "
            f"{fields['flags']}u); }}",
        ]
    elif msg["direction"] == "device" and msg["fields"]:
        args = ", ".join(c_arg(f[1], fields[f[0]]) for f in msg["fields"])
        lines += [
            f"    proto_put_{name}(frame::payload(buf), {args});",
            f"    n = frame::finish(buf, PROTO_TYPE_{name}, PROTO_LEN_{name}, {seq}u);",
        ]
    else:
        # Host commands (and field-less messages): no generated writer; bytes packed here.
        payload = pack_payload(msg, fields)
        lines += [
            f"    {{ const uint8_t p[] = {c_bytes(payload)};",
            f"      std::memcpy(frame::payload(buf), p, {len(payload)});",
            f'      static_assert(PROTO_LEN_{name} == {len(payload)}u, "len"); }}',
            f"    n = frame::finish(buf, PROTO_TYPE_{name}, PROTO_LEN_{name}, {seq}u);",
        ]
    lines.append("    print_hex(buf, n);")
    return "\n".join(lines)


DRIVER_HEAD = r"""
#include <cinttypes>
#include <cstdint>
#include <cstdio>
#include <cstring>

#include "frame.hpp"

static void print_hex(const uint8_t* p, unsigned n) {
    for (unsigned i = 0; i < n; ++i) std::printf("%02x", p[i]);
    std::printf("\n");
}

static void on_frame(void* ctx, uint8_t type, uint16_t seq, const uint8_t* payload, uint8_t len) {
    ++*static_cast<unsigned*>(ctx);
    std::printf("F %u %u ", unsigned(type), unsigned(seq));
    print_hex(payload, len);
}

int main(int argc, char** argv) {
    uint8_t buf[frame::kMaxFrameLen];
    uint8_t n = 0;
    if (argc > 1 && std::strcmp(argv[1], "parse") == 0) {
        // Feed stdin (hex) to the command parser, byte by byte.
        frame::Parser parser;
        unsigned frames = 0, byte = 0;
        while (std::scanf("%2x", &byte) == 1) parser.feed(uint8_t(byte), on_frame, &frames);
        std::printf("E %u\n", unsigned(parser.crc_errors()));
        return 0;
    }
    const uint8_t check[] = {'1', '2', '3', '4', '5', '6', '7', '8', '9'};
    std::printf("C %04x\n", unsigned(frame::crc16(check, 9)));
"""

DRIVER_TAIL = """
    (void)n;
    return 0;
}
"""


@pytest.fixture(scope="module")
def driver(vectors, gxx, tmp_path_factory) -> Path:
    work = tmp_path_factory.mktemp("encoder")
    src = work / "driver.cpp"
    src.write_text(DRIVER_HEAD + "\n".join(encode_snippet(v) for v in vectors) + DRIVER_TAIL)
    exe = work / "driver"
    base = [
        gxx,
        "-std=gnu++11",
        "-Wall",
        "-Wextra",
        "-Werror",
        "-pedantic",
        "-O1",
        f"-I{FIRMWARE / 'src'}",
        str(src),
        str(FIRMWARE / "src" / "frame.cpp"),
        "-o",
        str(exe),
    ]
    # With the sanitizers when the host toolchain has them: the parser indexes a fixed buffer.
    r = subprocess.run(
        base + ["-fsanitize=address,undefined", "-fno-sanitize-recover=all"],
        capture_output=True,
        text=True,
    )
    if r.returncode != 0:
        r = subprocess.run(base, capture_output=True, text=True)
    assert r.returncode == 0, f"host compile failed:\n{r.stderr}"
    return exe


def run_driver(exe: Path, *args: str, stdin: str = "") -> list[str]:
    r = subprocess.run([str(exe), *args], input=stdin, capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stderr
    return r.stdout.split("\n")[:-1]


@pytest.mark.slow
def test_crc_check_value(driver) -> None:
    assert run_driver(driver)[0] == "C 29b1"  # CRC-16/CCITT-FALSE check value


def test_encoder_matches_vectors(driver, vectors) -> None:
    produced = run_driver(driver)[1:]
    assert len(produced) == len(vectors)
    for vec, got in zip(vectors, produced, strict=True):
        assert got == vec["hex"].lower(), f"{vec['name']}: firmware {got} != vector {vec['hex']}"


def test_vectors_cover_every_message(vectors) -> None:
    assert {message_of(v)["name"] for v in vectors} == set(MESSAGES)


def parse(exe: Path, stream: bytes) -> tuple[list[tuple[int, int, str]], int]:
    lines = run_driver(exe, "parse", stdin=stream.hex())
    frames: list[tuple[int, int, str]] = []
    for ln in lines[:-1]:
        parts = ln.split(" ")
        assert parts[0] == "F"
        frames.append((int(parts[1]), int(parts[2]), parts[3] if len(parts) > 3 else ""))
    tag, errors = lines[-1].split(" ")
    assert tag == "E"
    return frames, int(errors)


def expected(vec: dict) -> tuple[int, int, str]:
    raw = bytes.fromhex(vec["hex"])
    return raw[2], raw[4] | raw[5] << 8, raw[6:-2].hex()


def test_parser_reads_every_vector(driver, vectors) -> None:
    stream = b"".join(bytes.fromhex(v["hex"]) for v in vectors)
    frames, errors = parse(driver, b"\x00\xa5\x13" + stream + b"\x5a\xa5")
    assert frames == [expected(v) for v in vectors]
    assert errors == 0


def test_parser_resynchronises(driver, vectors) -> None:
    good = [bytes.fromhex(v["hex"]) for v in vectors]
    ping = next(g for g, v in zip(good, vectors, strict=True) if message_of(v)["name"] == "PING")
    hello = next(g for g, v in zip(good, vectors, strict=True) if message_of(v)["name"] == "HELLO")
    corrupted = bytearray(hello)
    corrupted[8] ^= 0x40
    stream = (
        bytes(corrupted)
        + ping  # bad CRC, then a good frame right after it
        + hello[:6]
        + ping
        + b"\x00" * 20  # truncated header swallowing a good frame
        + b"\xa5\x5a\x01\xff"
        + ping  # impossible length, then a good frame
        + b"\xa5\xa5\x5a"
        + ping[2:]  # doubled sync byte
    )
    frames, errors = parse(driver, stream)
    want = expected(next(v for v in vectors if message_of(v)["name"] == "PING"))
    assert frames == [want] * 4
    assert errors >= 2  # the corrupted HELLO and the truncated candidate
