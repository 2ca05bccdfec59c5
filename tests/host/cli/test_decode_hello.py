"""``decode`` follows every HELLO (issue 31): a board that comes back at another full scale
(±2 g, then ±16 g) is scaled by the HELLO before each sample, raw or as a capture with arrival
times; a HELLO of another spec stops decode with one line, as ``calibrate`` does."""

from __future__ import annotations

import contextlib
import io
import json
import struct
from pathlib import Path

import numpy as np
import pytest

from host.wire import sensor
from host.wire.capture import MAGIC
from host.wire.frames import encode_frame, encode_imu_samples
from host.wire.protocol_gen import SPEC_FINGERPRINT


def hello(afs: int, fs: int, fingerprint: int = SPEC_FINGERPRINT) -> bytes:
    return encode_frame(
        "HELLO", 0, fw_major=0, fw_minor=1, fw_patch=0, protocol_version=2,
        spec_fingerprint=fingerprint, who_am_i=0x68, product_id=0x58, accel_fs_sel=afs,
        gyro_fs_sel=fs, dlpf_cfg=4, smplrt_div=19, mode=0, timer_resolution_ns=500,
        baud=115200, reset_cause=1, streaming=1,
    )  # fmt: skip


def samples(seq: int, t0_us: int, az_counts: int, gx_counts: int, n: int = 10) -> bytes:
    counts = np.tile([0, 0, az_counts, 0, gx_counts, 0, 0], (n, 1))
    return encode_imu_samples(seq, t0_us + 20_000 * np.arange(n), counts)


def decode(path: Path, *extra: str) -> tuple[int, list[dict], str]:
    from host.__main__ import main

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            rc = main(["decode", str(path), *extra])
        except SystemExit as exc:
            rc = int(exc.code or 0)
    rows = [json.loads(line) for line in out.getvalue().splitlines()] if not extra else []
    return rc, rows, err.getvalue()


@pytest.mark.parametrize("as_capture", [False, True])
def test_a_second_hello_at_another_full_scale_rescales_what_follows(
    tmp_path: Path, as_capture: bool
) -> None:
    # 1 g and 10 °/s before (±2 g, ±250 °/s) and after the board came back at ±16 g, ±2000 °/s
    parts = [
        hello(0, 0), samples(0, 0, 16384, 1310),
        hello(3, 3), samples(0, 0, 2048, 164),
    ]  # fmt: skip
    path = tmp_path / "two.cap"
    if as_capture:
        t = 10**12
        body = b"".join(struct.pack("<QI", t + k * 10**8, len(p)) + p for k, p in enumerate(parts))
        path.write_bytes(MAGIC + body)
    else:
        path.write_bytes(b"".join(parts))
    rc, rows, err = decode(path)
    assert rc == 0, err
    assert len(rows) == 20
    az = np.array([r["az"] for r in rows])
    gx = np.array([r["gx"] for r in rows])
    assert np.allclose(az, sensor.G0, atol=0.01), az  # ±16 g read as ±2 g would be 1.2 m/s²
    assert np.allclose(gx, 10.0, atol=0.1), gx


def test_a_hello_of_another_spec_is_one_line_naming_it(tmp_path: Path) -> None:
    path = tmp_path / "foreign.bin"
    path.write_bytes(hello(0, 0) + samples(0, 0, 16384, 0) + hello(0, 0, fingerprint=0x1234))
    rc, _, err = decode(path)
    assert rc == 2 and "0x00001234" in err and "byte" in err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err
    rc, _, err = decode(path, "--stats")  # counting frames needs no spec
    assert rc == 0, err


@pytest.mark.filterwarnings("error::RuntimeWarning")
def test_arrival_times_beyond_a_signed_64_bit_number_are_printed_unsigned(tmp_path: Path) -> None:
    """A capture whose reads say 2⁶⁴ − 1 s ns (a nonsense clock, warned about): each sample's
    ``t_host_ns`` is that arrival as read, not cast to int64 and wrapped below zero (it printed
    −1000000000 with a warning from numpy)."""
    t = 2**64 - 10**9
    parts = [hello(0, 0), samples(0, 0, 16384, 1310)]
    body = b"".join(struct.pack("<QI", t + k * 10**8, len(p)) + p for k, p in enumerate(parts))
    path = tmp_path / "far.cap"
    path.write_bytes(MAGIC + body)
    rc, rows, err = decode(path)
    assert rc == 0 and "not trustworthy" in err, err
    host = [r["t_host_ns"] for r in rows]
    assert len(host) == 10 and all(h > 2**63 for h in host), host
