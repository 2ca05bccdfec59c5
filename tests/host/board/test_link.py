"""Link, capture files, replay:// and the decode/capture commands."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from host.__main__ import main
from host.board.link import Link, LinkTimeout, open_port
from host.wire import capture
from host.wire.frames import encode_frame, encode_imu_samples
from host.wire.protocol_gen import SPEC_FINGERPRINT

ROOT = Path(__file__).resolve().parents[3]


def sample_bytes(n: int, seq0: int = 0) -> tuple[bytes, np.ndarray]:
    counts = np.tile(np.array([100, -200, 16384, -1000, 131, -262, 393]), (n, 1))
    counts[:, 0] += np.arange(n)
    return encode_imu_samples(seq0, np.arange(n) * 20000, counts), counts


def write_capture(path: Path, data: bytes, chunk: int = 100, t0_ns: int = 10**9) -> None:
    with capture.CaptureWriter(path) as w:
        for i in range(0, len(data), chunk):
            w.write(t0_ns + i * 1000, data[i : i + chunk])


def test_capture_round_trip_and_truncated_tail(tmp_path: Path) -> None:
    data, _ = sample_bytes(50)
    path = tmp_path / "s.cap"
    write_capture(path, data)
    cap = capture.read(path)
    assert cap.data == data and cap.truncated_bytes == 0
    assert cap.chunk_ns[1] - cap.chunk_ns[0] == 100_000
    assert cap.arrival_ns_at(np.array([0, 99, 100])).tolist() == [10**9, 10**9, 10**9 + 100_000]
    raw = path.read_bytes()
    path.write_bytes(raw[:-7])  # killed mid-write
    cut = capture.read(path)
    assert cut.truncated_bytes > 0
    # the cut-off last read (1350 bytes in reads of 100: the last one held 50) is dropped whole
    assert cut.data == data[:1300]
    assert cut.truncated_bytes == 12 + 50 - 7


def run_cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "host", *args], capture_output=True, text=True, cwd=ROOT
    )


@pytest.mark.slow
def test_decode_jsonl_csv_stats(tmp_path: Path) -> None:
    data, counts = sample_bytes(20)
    hello = encode_frame(
        "HELLO", 20, fw_major=0, fw_minor=1, fw_patch=0, protocol_version=1,
        spec_fingerprint=SPEC_FINGERPRINT, who_am_i=0x68, product_id=0x58, accel_fs_sel=0,
        gyro_fs_sel=0,
        dlpf_cfg=4, smplrt_div=19, mode=0, timer_resolution_ns=500, baud=115200, reset_cause=1,
        streaming=1,
    )  # fmt: skip
    raw = tmp_path / "raw.bin"
    raw.write_bytes(b"\x00garbage" + data + hello)
    r = run_cli("decode", str(raw))
    assert r.returncode == 0, r.stderr
    rows = [json.loads(line) for line in r.stdout.splitlines()]
    assert len(rows) == 20
    assert rows[3]["ax_raw"] == counts[3, 0] and rows[3]["gz_raw"] == 393
    assert rows[0]["az"] == pytest.approx(9.80665, abs=1e-4)  # 16384 counts = 1 g at ±2 g
    assert rows[0]["gx"] == pytest.approx(1.0, abs=1e-4)  # 131 counts = 1 °/s at ±250 °/s
    assert rows[0]["temp"] == pytest.approx(-1000 / 340 + 36.53, abs=1e-3)
    assert "t_host_ns" not in rows[0]
    r = run_cli("decode", str(raw), "--csv")
    lines = r.stdout.splitlines()
    assert lines[0].startswith("seq,t_us,flags,ax_raw") and len(lines) == 21
    r = run_cli("decode", str(raw), "--stats")
    assert json.loads(r.stdout) == {
        "frames": 21, "crc_errors": 0, "bytes_discarded": 8,
        "unknown_types": 0, "lost_frames": 0, "resets": 0,
    }  # fmt: skip


@pytest.mark.slow
def test_decode_capture_maps_device_time_to_host_time(tmp_path: Path) -> None:
    """t_host_ns is the sample's mapped host time: far closer to the truth than arrival."""
    from host.bench.linksim import LinkParams, simulate_link

    lc = simulate_link(LinkParams(seconds=30, seed=5))
    path = tmp_path / "s.cap"
    path.write_bytes(lc.to_imucap())
    rows = [json.loads(line) for line in run_cli("decode", str(path)).stdout.splitlines()]
    assert len(rows) == lc.true_host_ns.size
    mapped = np.array([r["t_host_ns"] for r in rows], dtype=float) - lc.true_host_ns
    mapped -= mapped.mean()
    assert np.sqrt(np.mean(mapped**2)) < 60_000  # ns
    cap = capture.read(path)
    arrival = cap.arrival_ns_at(np.arange(lc.true_host_ns.size) * 27 + 26)  # rough: no STATUS
    stats = json.loads(run_cli("decode", str(path), "--stats").stdout)
    (seg,) = stats["clock"]
    assert seg["samples"] == len(rows) and seg["lost_frames"] == 0
    assert seg["skew_ppm"] == pytest.approx(-60, abs=5)  # device clock 60 ppm fast
    assert arrival.size == len(rows)


def test_decode_missing_file_is_one_clear_line(tmp_path: Path) -> None:
    r = run_cli("decode", str(tmp_path / "nope.bin"))
    assert r.returncode == 2
    assert r.stderr.count("\n") == 1 and "no such file" in r.stderr
    assert "Traceback" not in r.stderr


def test_unknown_port_scheme_is_a_clear_error() -> None:
    from host.errors import UserError

    with pytest.raises(UserError, match="cannot open"):
        open_port("nosuchscheme://x")


def test_replay_link_reads_frames_and_writes_a_capture(tmp_path: Path) -> None:
    data, counts = sample_bytes(40)
    src = tmp_path / "src.cap"
    write_capture(src, data)
    out = tmp_path / "out.cap"
    with Link.open(f"replay://{src}?speed=max", capture=out, stall_s=0.3) as link:
        got = []
        with pytest.raises(LinkTimeout):
            for _, f in link.frames():
                got.append(f)
    assert [f.fields["ax"] for f in got] == counts[:, 0].tolist()
    assert capture.read(out).data == data  # the live session's capture holds every byte


def test_capture_command_records_a_replayed_port(tmp_path: Path) -> None:
    data, _ = sample_bytes(30)
    src = tmp_path / "src.bin"
    src.write_bytes(data)
    out = tmp_path / "rec.cap"
    assert (
        main(["capture", str(out), "--port", f"replay://{src}?speed=max", "--seconds", "0.3"]) == 0
    )
    assert capture.read(out).data == data
