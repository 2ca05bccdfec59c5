"""Sensor identity (PRODUCT_ID: revisions C4/C5 count half the accelerometer LSB/g) and the bus
flag on the host side: the scale follows HELLO's identity everywhere counts become m/s², the
virtual boards can be told the revision, and a STATUS saying the bus fell back to 1 MHz is
shown to the user."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import serial
from hypothesis import example, given, settings
from hypothesis import strategies as st

from host.board.driver import Board
from host.board.link import register_transports
from host.ingest.importing import read_capture_stream
from host.session.records import SENSOR_KEYS
from host.transports import protocol_emu
from host.wire import sensor
from host.wire.frames import SPI_LOW_CLOCK, bus_meta, encode_frame, encode_imu_samples, status_text
from host.wire.protocol_gen import SPEC_FINGERPRINT
from host.wire.stream import StreamDecoder

register_transports()
ROOT = Path(__file__).resolve().parents[3]
HALF = (0x14, 0x15, 0x54, 0x55)


def test_every_revision_name_and_number_reads_back() -> None:
    for pid, name in sensor.PRODUCT_REVISIONS.items():
        assert sensor.product_id_of(name) == pid
        assert sensor.product_id_of(name.lower().replace(" ", "_")) == pid
        assert sensor.product_id_of(f"{pid:#04x}") == pid
        assert sensor.revision_name(pid) == name
    assert sensor.revision_name(0x42) == "unknown 0x42"
    assert sensor.revision_name(None) == "not reported"
    for bad in ("E7", "", "0x100", "-1", "D 11"):
        with pytest.raises(ValueError, match="unknown MPU-6000 revision.*C4, C5, D6"):
            sensor.product_id_of(bad)


@settings(max_examples=200, derandomize=True)
@given(
    afs=st.sampled_from(sorted(sensor.ACCEL_LSB_PER_G)),
    pid=st.integers(0, 255),
    g=st.floats(-1.9, 1.9),
)
@example(afs=0, pid=0x55, g=1.0)
@pytest.mark.slow
def test_c4_c5_count_half_the_lsb_per_g_at_every_full_scale(afs: int, pid: int, g: float) -> None:
    lsb = sensor.accel_lsb_per_g(afs, pid)
    assert lsb == sensor.ACCEL_LSB_PER_G[afs] / (2 if pid in HALF else 1)
    assert sensor.accel_range_g(afs, pid) * lsb == sensor.ACCEL_RANGE_G[afs] * 16384 / 2**afs
    # counts -> m/s² -> counts round trip on that part, within half an LSB
    c = sensor.accel_counts(np.array([g * sensor.G0]), afs, pid)
    back = sensor.accel_mps2(c, afs, pid)
    assert abs(back[0] - g * sensor.G0) <= 0.5 * sensor.G0 / lsb + 1e-12


def _sim_z_counts(url: str) -> tuple[int, float]:
    port = serial.serial_for_url(url, timeout=0.1)
    try:
        frames = StreamDecoder().feed(port.read(27 * 60 + 200))
    finally:
        port.close()
    pid = next(f for f in frames if f.name == "HELLO").fields["product_id"]
    return pid, float(np.median([f.fields["az"] for f in frames if f.name == "IMU_SAMPLE"]))


def test_sim_board_is_the_revision_asked_and_counts_accordingly() -> None:
    base = "sim://?seed=3&noise_seed=3&speed=max&truth=ideal&earth_rate=0"
    pid, az_d8 = _sim_z_counts(base)  # 1 g of the local gravity, ≈ 16384 counts
    assert pid == sensor.DEFAULT_PRODUCT_ID and abs(az_d8 - 16384) < 40
    pid, az = _sim_z_counts(base + "&revision=C5")
    assert pid == 0x55 and abs(az - az_d8 / 2) <= 1
    with pytest.raises(serial.SerialException, match="unknown MPU-6000 revision 'Q9'"):
        serial.serial_for_url("sim://?revision=Q9")


def test_emu_url_takes_the_revision_for_the_chip_whatever_the_stimulus() -> None:
    assert protocol_emu.parse_url("emu://?revision=c4&stimulus=rest")["product_id"] == 0x54
    assert protocol_emu.parse_url("emu://?revision=0x17")["product_id"] == 0x17
    assert "product_id" not in protocol_emu.parse_url("emu://")
    with pytest.raises(ValueError, match="emu:// option revision='X1'"):
        protocol_emu.parse_url("emu://?revision=X1")


def _status(flags: int, bad: int, seq: int = 0) -> bytes:
    return encode_frame(
        "STATUS", seq, uptime_ms=1000, samples=50, missed=0, dropped=0, crc_errors=0,
        spi_faults=0, fifo_overflows=0, tx_queue_max=1, bad_bursts=bad, flags=flags,
    )  # fmt: skip


def test_status_text_speaks_only_of_a_set_flag() -> None:
    clean, low = StreamDecoder().feed(_status(0, 0) + _status(SPI_LOW_CLOCK, 3, 1))
    assert status_text(clean) is None
    text = status_text(low)
    assert text is not None and "3 sensor reads" in text and "1 MHz" in text


@given(st.integers(0, 0xFF))
def test_only_an_unknown_product_id_is_warned_of(pid: int) -> None:
    text = sensor.revision_warning(pid)
    assert (text is None) == (pid in sensor.PRODUCT_REVISIONS)
    if text is not None:
        assert f"{pid:#04x}" in text and "D8 0x58" in text and "C5 0x55" in text
    assert sensor.revision_warning(None) is None  # not reported: nothing to warn of


def test_the_record_header_names_the_spi_clock_the_status_tells() -> None:
    assert bus_meta(None) == {}  # no STATUS seen: no claim
    assert bus_meta(0) == {"sensor_spi_clock": "8 MHz"}
    low = bus_meta(SPI_LOW_CLOCK | 0x80)["sensor_spi_clock"]
    assert low.startswith("1 MHz (SPI_LOW_CLOCK") and bus_meta(0x80) == bus_meta(0)


@pytest.mark.parametrize(("revision", "warned"), [("0x33", True), ("C5", False), ("D8", False)])
def test_board_warns_once_of_an_unknown_product_id(revision: str, warned: bool) -> None:
    """An unknown revision is said once (not at every restart); the records still name it."""
    warnings: list[str] = []
    board = Board(f"sim://?seed=3&noise_seed=3&speed=max&revision={revision}", warn=warnings.append)
    info = board.connect()
    try:
        acq = board.acquire(1.5)  # STATUS comes every second
        again = board.reopen()  # the port opened again: the board restarts, HELLO again
    finally:
        board.close()
    unknown = [w for w in warnings if "no known MPU-6000 revision" in w]
    assert len(unknown) == (1 if warned else 0), warnings
    assert again.product_id == info.product_id and again.reset_cause & 0x02  # DTR reset
    assert info.meta()["sensor_revision"] == sensor.revision_name(info.product_id)
    assert acq.status_flags == 0 and bus_meta(acq.status_flags) == {"sensor_spi_clock": "8 MHz"}


def _capture(tmp_path: Path, product_id: int, flags: int) -> Path:
    hello = encode_frame(
        "HELLO", 0, fw_major=0, fw_minor=1, fw_patch=0, protocol_version=2,
        spec_fingerprint=SPEC_FINGERPRINT,
        who_am_i=0x68, product_id=product_id, accel_fs_sel=0, gyro_fs_sel=0, dlpf_cfg=4,
        smplrt_div=19, mode=0, timer_resolution_ns=500, baud=115200, reset_cause=1, streaming=1,
    )  # fmt: skip
    n = 20
    counts = np.tile([100, -200, 8192, -3920, 10, -20, 30], (n, 1))
    data = encode_imu_samples(1, 20_000 * np.arange(n), counts)
    path = tmp_path / "c.cap"
    path.write_bytes(hello + data + _status(flags, 1 if flags else 0, n + 1))
    return path


@pytest.mark.slow
def test_decode_scales_by_the_revision_and_warns_of_the_low_clock(tmp_path: Path) -> None:
    def decode(path: Path) -> subprocess.CompletedProcess[str]:
        cmd = [sys.executable, "-m", "host", "decode", str(path), "--csv"]
        return subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT)

    c5 = decode(_capture(tmp_path, 0x55, SPI_LOW_CLOCK))
    d8 = decode(_capture(tmp_path, 0x58, 0))
    assert c5.returncode == d8.returncode == 0
    header = c5.stdout.splitlines()[0].split(",")
    az = header.index("az")
    z_c5 = float(c5.stdout.splitlines()[1].split(",")[az])
    z_d8 = float(d8.stdout.splitlines()[1].split(",")[az])
    assert z_c5 == pytest.approx(sensor.G0, abs=1e-3)  # 8192 counts = 1 g on a C5
    assert z_d8 == pytest.approx(sensor.G0 / 2, abs=1e-3)
    assert "marginal" in c5.stderr and "1 MHz" in c5.stderr
    assert "marginal" not in d8.stderr
    # a PRODUCT_ID that is no known revision: said once, scaled as a revision D part
    odd = decode(_capture(tmp_path, 0x33, 0))
    assert odd.returncode == 0 and odd.stderr.count("0x33 is no known MPU-6000 revision") == 1
    assert "no known" not in c5.stderr + d8.stderr
    assert odd.stdout.splitlines()[1] == d8.stdout.splitlines()[1]


def test_imported_capture_names_its_sensor_and_scales_by_it(tmp_path: Path) -> None:
    stream = read_capture_stream(_capture(tmp_path, 0x54, 0))
    named = {k: stream.meta[k] for k in SENSOR_KEYS if k in stream.meta}
    assert named == sensor.identity_meta(None, 0x54)
    assert stream.meta["sensor_revision"] == "C4"
    np.testing.assert_allclose(stream.accel[0], np.array([100, -200, 8192]) / 8192 * sensor.G0)
    # the bus the data came over, from the capture's STATUS
    assert stream.meta["sensor_spi_clock"] == "8 MHz"
    low = read_capture_stream(_capture(tmp_path, 0x58, SPI_LOW_CLOCK)).meta["sensor_spi_clock"]
    assert low.startswith("1 MHz (SPI_LOW_CLOCK")
