"""The real firmware (firmware/src, built with its Makefile) on the emulated APM 2.6."""

from __future__ import annotations

import numpy as np
import pytest
from emu_helpers import collect, of_type, sample_counts, seq_gaps

from host.bench.build import build_firmware
from host.bench.emulator import EmulatedBoard
from host.bench.stimulus import write_stimulus
from host.wire import sensor
from host.wire.frames import encode_frame
from host.wire.protocol_gen import ENUMS

pytestmark = pytest.mark.emulator

ERR = ENUMS["error_code"]
SMPLRT_DIV, CONFIG, GYRO_CONFIG, ACCEL_CONFIG, PWR_MGMT_1, WHO_AM_I = (
    0x19, 0x1A, 0x1B, 0x1C, 0x6B, 0x75,
)  # fmt: skip
PERIOD_US = 20_000
TIMESTAMP_TOL_US = 16  # 256 CPU cycles of interrupt latency
MCU_HZ = 16e6


def moving_stimulus(path, seconds: float) -> None:
    """Slow, different motion on every axis, a new value every 2 ms: each sample is unique."""
    t = np.arange(0.0, seconds, 0.002)
    f = np.stack([1.0 + 2.0 * np.sin(2 * np.pi * 0.31 * t),
                  -2.0 + 1.5 * np.sin(2 * np.pi * 0.17 * t + 1.0),
                  9.0 + 0.8 * np.cos(2 * np.pi * 0.23 * t)], axis=1)  # fmt: skip
    w = np.stack([40.0 * np.sin(2 * np.pi * 0.5 * t),
                  -25.0 * np.cos(2 * np.pi * 0.3 * t),
                  60.0 * np.sin(2 * np.pi * 0.11 * t + 0.3)], axis=1)  # fmt: skip
    write_stimulus(path, t, f, w, 30.0 + 3.0 * np.sin(2 * np.pi * 0.05 * t))


@pytest.mark.slow
def test_bringup_and_60s_stream(emu_bin, fw_elf, tmp_path):
    seconds = 62.0
    stim = tmp_path / "stim.bin"
    moving_stimulus(stim, seconds + 1.0)
    board = EmulatedBoard(fw_elf, emulator=emu_bin, stimulus=stim, seconds=seconds,
                          reglog=True, samplelog=True, workdir=tmp_path)  # fmt: skip
    with board:
        frames = collect(board, max_wall_s=120)
    s = board.summary
    print(
        f"\nemulator: {s['sim_seconds']:.1f} s simulated in {s['wall_seconds']:.2f} s wall = "
        f"{s['speed']:.1f}x; firmware {s['steady_busy_cycles_per_sample']:.0f} CPU cycles per "
        f"sample ({100 * s['steady_cpu_load']:.2f} % of the 320 000-cycle period); "
        f"DRDY->read {s['drdy_to_read_cycles_mean']:.0f} cycles"
    )

    # every hardware rule of the MPU-6000 model and the board holds (names, pages: the summary)
    assert not s["rules_broken"], "\n".join(s["rules_broken"])
    assert set(s["rules"]) >= {"SPI_MODE", "RESET_WAIT", "SIGNAL_PATH_RESET", "GYRO_STARTUP"}
    # the register traffic: the chip is woken and configured exactly, at a legal SPI clock
    assert s["spi_violations"] == 0, f"first at reg 0x{s['first_violation_reg']:02X}"
    assert s["bus_conflicts"] == 0
    log = board.reglog()
    writes: dict[int, int] = {}
    for a in log:
        if a.op == "W":
            writes[a.reg] = a.value
    assert writes[PWR_MGMT_1] & 0x40 == 0, "never woken (SLEEP still set)"
    assert writes[SMPLRT_DIV] == 19
    assert writes[CONFIG] & 0x07 == 4
    assert writes[GYRO_CONFIG] & 0x18 == 0  # FS_SEL 0: +-250 deg/s
    assert writes[ACCEL_CONFIG] & 0x18 == 0  # AFS_SEL 0: +-2 g
    regs = s["regs"]
    assert (regs["SMPLRT_DIV"], regs["CONFIG"] & 7, regs["GYRO_CONFIG"], regs["ACCEL_CONFIG"]) == (
        19, 4, 0, 0,
    )  # fmt: skip
    assert regs["PWR_MGMT_1"] & 0x40 == 0
    assert any(a.reg == WHO_AM_I and a.op == "R" and a.value == 0x68 for a in log)

    # the stream: every frame, in order, counts equal to what the sensor model produced
    assert not seq_gaps(frames)
    hello = of_type(frames, "HELLO")
    assert hello and hello[0].fields["who_am_i"] == 0x68
    samples = of_type(frames, "IMU_SAMPLE")
    assert len(samples) >= 60 * 50
    produced = board.samplelog()
    read = produced[produced["read"] == 1]
    want = np.stack([read[k] for k in ("ax", "ay", "az", "temp", "gx", "gy", "gz")], axis=1)
    got = sample_counts(frames)
    assert len(want) - 2 <= len(got) <= len(want)
    np.testing.assert_array_equal(got, want[: len(got)])
    assert len(np.unique(got, axis=0)) > 0.9 * len(got)  # the stimulus really moved
    assert s["samples_read"] == len(read)

    # device timestamps: 20 000 us apart, and locked to the sensor's sample instants. The
    # tolerance is interrupt latency: INT6 waits while another ISR (UART, Timer1) runs.
    t_dev = np.array([f.fields["t_us"] for f in samples], dtype=np.int64)
    dt = np.diff(t_dev)
    assert np.all(np.abs(dt - PERIOD_US) <= TIMESTAMP_TOL_US), (dt.min(), dt.max())
    assert abs(np.mean(dt) - PERIOD_US) < 0.01
    offset = t_dev - read["t_us"][: len(samples)]
    assert np.ptp(offset) <= TIMESTAMP_TOL_US, np.ptp(offset)
    assert all(f.fields["flags"] == 0 for f in samples)
    # (no speed assertion: emulator throughput is measured by benchmarks/emulator_bench.py; a
    # wall-clock bound here failed whenever the machine was busy)


@pytest.mark.slow
def test_every_axis_lands_where_it_belongs(emu_bin, fw_elf, tmp_path):
    f = np.array([1.1, -2.2, 9.3])  # m/s^2, chip axes
    w = np.array([11.0, -22.0, 33.0])  # deg/s
    temp = 31.5
    stim = tmp_path / "stim.bin"
    write_stimulus(stim, [0.0, 3.0], [f, f], [w, w], temp)
    with EmulatedBoard(fw_elf, emulator=emu_bin, stimulus=stim, workdir=tmp_path) as board:
        frames = collect(board, max_wall_s=60)
    got = sample_counts(frames)
    assert len(got) >= 100
    want = np.concatenate(
        [sensor.accel_counts(f, 0), sensor.temp_counts(np.array([temp])), sensor.gyro_counts(w, 0)]
    )
    assert want.tolist() == [1838, -3676, 15538, -1710, 1441, -2882, 4323]
    assert np.all(got == want), got[0]


def test_sensor_absent_is_reported_and_retried(emu_bin, fw_elf, tmp_path):
    board = EmulatedBoard(fw_elf, emulator=emu_bin, fault="absent", seconds=6.0, reglog=True,
                          workdir=tmp_path)  # fmt: skip
    with board:
        frames = collect(board, max_wall_s=60)
    errors = of_type(frames, "ERROR")
    absent = [e for e in errors if e.fields["code"] == ERR["SENSOR_ABSENT"]]
    assert len(absent) >= 4, errors
    assert [e.fields["count"] for e in absent] == list(range(1, len(absent) + 1))
    assert not of_type(frames, "IMU_SAMPLE")
    probes = [a.t_us for a in board.reglog() if a.reg == WHO_AM_I and a.op == "R"]
    assert len(probes) >= 4 and probes[-1] - probes[0] > 3e6  # it keeps trying
    assert board.summary["samples_produced"] == 0


def test_stuck_miso_reads_as_absent(emu_bin, fw_elf, tmp_path):
    with EmulatedBoard(fw_elf, emulator=emu_bin, fault="stuck-miso", seconds=3.0,
                       workdir=tmp_path) as board:  # fmt: skip
        frames = collect(board, max_wall_s=60)
    errors = of_type(frames, "ERROR")
    assert errors and all(e.fields["code"] == ERR["SENSOR_ABSENT"] for e in errors)
    assert errors[0].fields["detail"] == 0xFF  # the WHO_AM_I it read


def test_missing_data_ready_is_reported(emu_bin, fw_elf, tmp_path):
    with EmulatedBoard(fw_elf, emulator=emu_bin, fault="no-drdy", seconds=4.0,
                       workdir=tmp_path) as board:  # fmt: skip
        frames = collect(board, max_wall_s=60)
    codes = [e.fields["code"] for e in of_type(frames, "ERROR")]
    assert ERR["DATA_READY_TIMEOUT"] in codes
    assert not of_type(frames, "IMU_SAMPLE")
    assert board.summary["samples_produced"] > 0 and board.summary["drdy_pulses"] == 0


def test_sensor_lost_mid_stream(emu_bin, fw_elf, tmp_path):
    with EmulatedBoard(fw_elf, emulator=emu_bin, fault="absent", fault_at=2.0, seconds=5.0,
                       workdir=tmp_path) as board:  # fmt: skip
        frames = collect(board, max_wall_s=60)
    samples = of_type(frames, "IMU_SAMPLE")
    assert len(samples) >= 50
    errors = of_type(frames, "ERROR")
    assert errors and errors[0].seq > samples[-1].seq


def test_ping_and_dtr_reset(emu_bin, fw_elf, tmp_path):
    board = EmulatedBoard(fw_elf, emulator=emu_bin, workdir=tmp_path)
    nonce = 0x1234ABCD
    with board:

        def ping_after_hello(ser, frames):
            if of_type(frames, "HELLO") and not ping_after_hello.sent:
                ser.write(encode_frame("PING", 7, nonce=nonce))
                ping_after_hello.sent = True
            return bool(of_type(frames, "PONG")) and bool(of_type(frames, "ACK"))

        ping_after_hello.sent = False  # type: ignore[attr-defined]
        first = collect(board, max_wall_s=30, on_frames=ping_after_hello)
        # re-opening the port resets the AVR, like DTR on the real board
        second = collect(board, max_wall_s=30, on_frames=lambda s, fr: bool(of_type(fr, "HELLO")))
    pong = of_type(first, "PONG")
    assert pong and pong[0].fields["nonce"] == nonce
    ack = of_type(first, "ACK")[0].fields
    assert ack["cmd_seq"] == 7 and ack["status"] == ENUMS["ack_status"]["OK"]
    assert of_type(first, "HELLO")[0].fields["reset_cause"] & 0x01  # power-on
    hello2 = of_type(second, "HELLO")[0]
    assert hello2.fields["reset_cause"] & 0x02  # external reset (DTR)
    assert board.summary["avr_resets"] == 1


#: the described DMP images (firmware/src/dmp_descriptions.h): kind -> (image bytes, start, packet)
DMP_KINDS = {"motionapps20": (1929, 0x0300, 42), "emd6": (3062, 0x0400, 28)}


def dmp_build(tmp_path, kind: str, size: int):
    """A made-up image of the described size (the real ones are user-supplied: licence)."""
    rng = np.random.default_rng(size)
    image = tmp_path / f"{kind}.bin"
    image.write_bytes(rng.integers(0, 256, size, dtype=np.uint8).tobytes())
    return build_firmware(tmp_path / f"fw-{kind}", [f"DMP_IMAGE={image}", f"DMP_KIND={kind}"])


@pytest.mark.slow
@pytest.mark.timeout(120)  # two builds' worth of work on a loaded machine
@pytest.mark.parametrize("kind", sorted(DMP_KINDS))
def test_dmp_mode_loads_the_described_image_and_streams_quaternions(
    emu_bin, emu_toolchain, tmp_path, kind
):
    """The loader follows the image's description (start address, FIFO-rate update, ±2000 °/s,
    200 Hz, packet size) and the emulator, told which image it is, confirms the load sequence
    before it lets the DMP run; the model stores and reads back DMP memory but does not execute
    the image: its stub pushes quaternion packets integrated from the truth rate."""
    size, start, packet = DMP_KINDS[kind]
    elf = dmp_build(tmp_path, kind, size)
    stim = tmp_path / "stim.bin"
    write_stimulus(stim, [0.0, 3.0], [[0, 0, 9.80665]] * 2, [[0, 0, 90.0]] * 2, 25.0)
    board = EmulatedBoard(elf, emulator=emu_bin, stimulus=stim, reglog=True, workdir=tmp_path,
                          extra_args=["--dmp-image", kind])  # fmt: skip
    sent = []

    def self_test_once(ser, frames):  # the image needs its ranges: no self-test in DMP mode
        if not sent and of_type(frames, "DMP_QUAT"):
            ser.write(encode_frame("SELF_TEST", 77))
            sent.append(True)

    with board:
        frames = collect(board, max_wall_s=60, on_frames=self_test_once)
    acks = [(a.fields["cmd_seq"], a.fields["status"]) for a in of_type(frames, "ACK")]
    assert acks == [(77, ENUMS["ack_status"]["UNSUPPORTED"])]
    assert not of_type(frames, "SELF_TEST_RESULT")
    s = board.summary
    assert s["spi_violations"] == 0
    assert not s["rules_broken"], "\n".join(s["rules_broken"])
    assert s["dmp_image"] == kind and s["dmp_running"] == 1, s["dmp_problem"]
    assert s["regs"]["USER_CTRL"] & 0xC0 == 0xC0  # DMP_EN | FIFO_EN
    # the image's settings, not the calibration mode's: ±2000 °/s, 200 Hz
    assert (s["regs"]["GYRO_CONFIG"] >> 3) & 3 == 3 and s["regs"]["SMPLRT_DIV"] == 4
    hello = of_type(frames, "HELLO")[0].fields
    assert (hello["gyro_fs_sel"], hello["smplrt_div"], hello["mode"]) == (3, 4, 1)
    writes = [a for a in board.reglog() if a.op == "W"]
    assert len([a for a in writes if a.reg == 0x6F]) == size + 2  # image + FIFO-rate update
    cfg = [a.value for a in writes if a.reg in (0x70, 0x71)]
    assert cfg == [start >> 8, start & 0xFF]
    assert not of_type(frames, "ERROR")
    quats = of_type(frames, "DMP_QUAT")
    assert len(quats) >= 50
    # 90 deg/s about Z: the quaternion turns about Z only
    q = np.array([[f.fields[k] for k in ("q0", "q1", "q2", "q3")] for f in quats]) / 2.0**30
    np.testing.assert_allclose(np.linalg.norm(q, axis=1), 1.0, atol=1e-6)
    assert np.all(q[:, 1:3] == 0)


@pytest.mark.timeout(120)  # one build and one short run on a loaded machine
@pytest.mark.slow
def test_emulator_refuses_to_run_a_dmp_image_loaded_for_another_kind(
    emu_bin, emu_toolchain, tmp_path
):
    """A MotionApps 2.0 build on a part that must run the eMD image: the load sequence does
    not fit (size, start address), so the DMP_LOAD rule names it and no quaternion comes."""
    elf = dmp_build(tmp_path, "motionapps20", DMP_KINDS["motionapps20"][0])
    board = EmulatedBoard(elf, emulator=emu_bin, seconds=2.0, workdir=tmp_path,
                          extra_args=["--dmp-image", "emd6"])  # fmt: skip
    with board:
        frames = collect(board, max_wall_s=60)
    s = board.summary
    assert s["rules"]["DMP_LOAD"] >= 1 and s["dmp_running"] == 0
    assert "emd6: DMP memory 0x0789 never written (image is 3062 bytes)" == s["dmp_problem"]
    assert any(line.startswith("DMP_LOAD (firmware/src/dmp_descriptions.h): ") for line in
               s["rules_broken"])  # fmt: skip
    assert not of_type(frames, "DMP_QUAT")
