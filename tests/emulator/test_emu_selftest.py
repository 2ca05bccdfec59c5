"""The MPU-6000 self-test (issue 29, item 4) on the real firmware and the emulated chip.

On SELF_TEST the firmware reads the factory trim registers, averages three windows at the
self-test ranges (±8 g, ±250 °/s: off, on, off again), restores the configuration and sends
SELF_TEST_RESULT. The emulated chip answers its self-test bits with a response near its trim (a
healthy part) or, with ``--self-test fail``, accelerometer Y 35 % above and gyroscope Z 45 %
below it; the host's judge (host/wire/selftest.py) must pass the one and catch the other.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import serial
from emu_helpers import collect, of_type, sample_counts

from host.bench.emulator import EmulatedBoard
from host.bench.physics import static_motion
from host.bench.stimulus import write_stimulus
from host.board.driver import Board
from host.wire import protocol_gen as gen
from host.wire import sensor
from host.wire.frames import Frame, encode_frame
from host.wire.selftest import judge

pytestmark = pytest.mark.emulator

ACK = gen.ENUMS["ack_status"]
SELF_TEST = next(t for t, m in gen.MESSAGES.items() if m[0] == "SELF_TEST")
CONFIG_CHANGED = gen.ENUMS["sample_flags"]["CONFIG_CHANGED"]
#: at rest, tilted and turning slowly: a different value on every axis (m/s², °/s, chip axes)
F = np.array([2.1, -3.2, 8.9])
W = np.array([11.0, -22.0, 33.0])
SECONDS = 4.0
NOISE_ACCEL = 0.02  # m/s², white, per sample
NOISE_GYRO = 0.05  # °/s


def _run(tmp_path: Path, **board_kw: object) -> tuple[list[Frame], dict]:
    stim = tmp_path / "stim.bin"
    write_stimulus(stim, [0.0, SECONDS + 1.0], [F, F], [W, W], 30.0)
    board = EmulatedBoard(stimulus=stim, seconds=SECONDS, workdir=tmp_path,
                          noise_accel=NOISE_ACCEL, noise_gyro=NOISE_GYRO, seed=7, **board_kw)  # type: ignore[arg-type]  # fmt: skip

    sent = []

    def on_frames(ser: serial.Serial, frames: list[Frame]) -> bool:
        if not sent and len(of_type(frames, "IMU_SAMPLE")) >= 20:
            # twice in one write: the second arrives while the first runs
            ser.write(encode_frame("SELF_TEST", 40) + encode_frame("SELF_TEST", 41))
            sent.append(True)
        return False

    with board:
        frames = collect(board, max_wall_s=90, on_frames=on_frames)
    assert sent, "the board never streamed 20 samples"
    assert board.summary is not None
    return frames, board.summary


@pytest.mark.timeout(180)  # three short emulator runs on a loaded machine
@pytest.mark.parametrize(
    ("part", "product_id", "outcome", "failed"),
    [("pass", None, "pass", []), ("fail", None, "fail", ["ay", "gz"]), ("pass", 0x55, "pass", [])],
    ids=["healthy", "failing", "healthy_rev_C5"],
)
def test_self_test_passes_a_healthy_part_catches_a_failing_one_and_restores_the_stream(
    emu_bin: Path, fw_elf: Path, tmp_path: Path, part: str, product_id: int | None,
    outcome: str, failed: list[str],
) -> None:  # fmt: skip
    frames, summary = _run(tmp_path, elf=fw_elf, emulator=emu_bin, self_test=part,
                           product_id=product_id)  # fmt: skip
    acks = {f.fields["cmd_seq"]: f.fields["status"] for f in of_type(frames, "ACK")}
    assert acks == {40: ACK["OK"], 41: ACK["BUSY"]}  # one self-test at a time
    (result,) = of_type(frames, "SELF_TEST_RESULT")
    r = result.fields
    assert r["status"] == 0 and r["samples"] == 32
    # the trim registers as the chip holds them
    assert (r["self_test_x"], r["self_test_y"], r["self_test_z"], r["self_test_a"]) == (
        0x4C, 0x4D, 0x6A, 0x56,
    )  # fmt: skip
    # the windows were taken at ±8 g and ±250 °/s: the stimulus at those scales, within 5 σ
    # of a 32-sample mean of the white noise (added after the DLPF) and half a count
    lsb_per_g = sensor.accel_lsb_per_g(2, product_id)
    tol_a = 5 * NOISE_ACCEL * lsb_per_g / sensor.G0 / np.sqrt(32) + 0.5
    tol_g = 5 * NOISE_GYRO * 131.0 / np.sqrt(32) + 0.5
    for w in ("off", "end"):
        got_a = np.array([r[f"a{k}_{w}"] for k in "xyz"])
        got_g = np.array([r[f"g{k}_{w}"] for k in "xyz"])
        np.testing.assert_allclose(got_a, F * lsb_per_g / sensor.G0, atol=tol_a)
        np.testing.assert_allclose(got_g, W * 131.0, atol=tol_g)
    st = judge(r, product_id)
    assert st.outcome == outcome
    assert [a.name for a in st.axes if a.passed is False] == failed
    # configuration restored: the chip's registers and HELLO-worthy state at the end
    regs = summary["regs"]
    assert (regs["SMPLRT_DIV"], regs["CONFIG"], regs["GYRO_CONFIG"], regs["ACCEL_CONFIG"]) == (
        19, 4, 0, 0,
    )  # fmt: skip
    assert summary["rules_broken"] == []
    # the stream pauses for the self-test only, and goes on at ±2 g with CONFIG_CHANGED
    samples = of_type(frames, "IMU_SAMPLE")
    t = np.array([f.fields["t_us"] for f in samples])
    gaps = np.flatnonzero(np.diff(t) > 30_000)
    assert len(gaps) == 1 and 1.2e6 < np.diff(t)[gaps[0]] < 1.45e6
    after = samples[gaps[0] + 1 :]
    assert after[0].fields["flags"] & CONFIG_CHANGED
    assert not any(f.fields["flags"] & CONFIG_CHANGED for f in after[1:])
    counts = sample_counts(after)
    assert len(counts) > 20
    lsb_2g = sensor.accel_lsb_per_g(0, product_id)
    tol = 5 * NOISE_ACCEL * lsb_2g / sensor.G0 / np.sqrt(len(counts)) + 0.5
    np.testing.assert_allclose(counts[:, 0:3].mean(axis=0), F * lsb_2g / sensor.G0, atol=tol)


@pytest.mark.timeout(120)  # one short emulator run
def test_self_test_without_a_streaming_sensor_is_busy(
    emu_bin: Path, fw_elf: Path, tmp_path: Path
) -> None:
    board = EmulatedBoard(fw_elf, emulator=emu_bin, seconds=30.0, fault="absent",
                          workdir=tmp_path)  # fmt: skip

    sent = []

    def on_frames(ser: serial.Serial, frames: list[Frame]) -> bool:
        if of_type(frames, "HELLO") and not sent:
            ser.write(encode_frame("SELF_TEST", 9))
            sent.append(True)
        return bool(of_type(frames, "ACK"))

    with board:
        frames = collect(board, max_wall_s=60, on_frames=on_frames)
    acks = of_type(frames, "ACK")
    assert [(a.fields["cmd_type"], a.fields["status"]) for a in acks] == [(SELF_TEST, ACK["BUSY"])]
    assert not of_type(frames, "SELF_TEST_RESULT")


@pytest.mark.timeout(120)  # one short emulated session
def test_a_unit_moved_during_the_self_test_gets_no_verdict(fw_elf: Path) -> None:
    """The cube tilts by 10° in the middle of the self-test (the simulator's operator is
    manual): the two self-test-off windows differ, so the host gives no verdict (a tilt moves
    the accelerometers as much as the self-test does) and asks for a still repeat."""
    board = Board(f"emu://?operator=manual&seed=3&noise_seed=3&elf={fw_elf}")
    board.connect()
    try:
        port = board.port
        while port.sim_time < 1.0:  # streaming
            board.pump()
        board.link.send("SELF_TEST")
        tilt = np.radians(10.0)
        port.set_motion(static_motion(np.array([0.0, np.sin(tilt), np.cos(tilt)])),
                        port.sim_time + 0.5)  # fmt: skip
        result = None
        while result is None:
            result = next((f for _, f in board.read_frames() if f.name == "SELF_TEST_RESULT"),
                          None)  # fmt: skip
        st = judge(result.fields, board.info.product_id if board.info else None)
        assert result.fields["status"] == 0
        assert st.outcome == "" and "moved" in st.reason and "ay" in st.reason
        assert "self_test" not in st.meta()
    finally:
        board.close()
