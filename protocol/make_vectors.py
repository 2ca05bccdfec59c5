#!/usr/bin/env python3
"""Write ``protocol/vectors.json``: frames (bytes) with the fields they must decode to.

Both sides run them: the host decoder must decode each ``hex`` to ``fields``, and the
firmware's encoder, compiled for the host, must produce ``hex`` byte for byte from ``fields``.
Values differ on every axis (a swapped axis fails) and cover sign, wrap and extreme values.

    python protocol/make_vectors.py           # rewrite
    python protocol/make_vectors.py --check   # exit 1 if vectors.json is stale
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from host.wire.frames import BY_NAME, encode_frame  # noqa: E402

OUT = ROOT / "protocol" / "vectors.json"

# fmt: off
CASES: list[tuple[str, str, int, dict[str, int]]] = [
    ("sample_level_z_up", "IMU_SAMPLE", 0, dict(t_us=20000, ax=-123, ay=245, az=16390, temp=-2480, gx=-31, gy=57, gz=-12, flags=0)),
    ("sample_extremes", "IMU_SAMPLE", 0xFFFF, dict(t_us=0xFFFFFFFF, ax=-32768, ay=32767, az=-1, temp=1, gx=32767, gy=-32768, gz=256, flags=7)),
    ("sample_missed", "IMU_SAMPLE", 513, dict(t_us=123456789, ax=1, ay=2, az=3, temp=4, gx=5, gy=6, gz=7, flags=1)),
    ("hello", "HELLO", 0, dict(fw_major=0, fw_minor=1, fw_patch=2, protocol_version=2, spec_fingerprint=0xDEADBEEF, who_am_i=0x68, product_id=0x55, accel_fs_sel=0, gyro_fs_sel=0, dlpf_cfg=4, smplrt_div=19, mode=0, timer_resolution_ns=500, baud=115200, reset_cause=2, streaming=1)),
    ("status", "STATUS", 4660, dict(uptime_ms=60001, samples=3000, missed=2, dropped=3, crc_errors=4, spi_faults=5, fifo_overflows=6, tx_queue_max=7, bad_bursts=0x0809, flags=1)),
    ("error_absent", "ERROR", 7, dict(code=1, detail=0xFF, count=300)),
    ("dmp_quat", "DMP_QUAT", 9, dict(t_us=40000, q0=1073741824, q1=-1, q2=-1073741824, q3=123456)),
    ("ack", "ACK", 10, dict(cmd_type=0x84, cmd_seq=0xBEEF, status=1)),
    ("pong", "PONG", 11, dict(nonce=0x12345678, t_us=99999)),
    ("ping", "PING", 12, dict(nonce=0xCAFEF00D)),
    ("start", "START_STREAM", 13, {}),
    ("stop", "STOP_STREAM", 14, {}),
    ("set_rate", "SET_RATE", 15, dict(smplrt_div=9, dlpf_cfg=3)),
    ("get_config", "GET_CONFIG", 16, {}),
    ("get_status", "GET_STATUS", 17, {}),
    ("self_test", "SELF_TEST", 18, {}),
    ("self_test_result", "SELF_TEST_RESULT", 19, dict(status=2, self_test_x=0x4C, self_test_y=0x4D, self_test_z=0x6A, self_test_a=0x56, samples=32, ax_off=-12, ay_off=25, az_off=4101, gx_off=-7, gy_off=9, gz_off=-3, ax_on=1805, ay_on=1843, az_on=6240, gx_on=5370, gy_on=-5620, gz_on=4700, ax_end=-32768, ay_end=32767, az_end=4099, gx_end=-6, gy_end=8, gz_end=-258)),
]
# fmt: on


def vectors() -> list[dict]:
    out = []
    for name, msg, seq, fields in CASES:
        out.append(
            {
                "name": name,
                "message": msg,
                "type": BY_NAME[msg].type,
                "seq": seq,
                "fields": fields,
                "hex": encode_frame(msg, seq, **fields).hex(),
            }
        )
    return out


def render() -> str:
    return json.dumps(vectors(), indent=1) + "\n"


if __name__ == "__main__":
    text = render()
    if "--check" in sys.argv:
        stale = not OUT.exists() or OUT.read_text() != text
        if stale:
            print("stale: protocol/vectors.json (run: python protocol/make_vectors.py)")
        sys.exit(1 if stale else 0)
    OUT.write_text(text)
    print(f"wrote {len(CASES)} vectors to {OUT.relative_to(ROOT)}")
