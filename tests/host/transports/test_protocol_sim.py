"""The ``sim://`` virtual board (host/transports/protocol_sim.py) on the wire."""

from __future__ import annotations

import time
from typing import cast

import numpy as np
import pytest
import serial

from host.bench.truth import SensorTruth
from host.transports.protocol_sim import Serial as SimSerial
from host.wire import protocol_gen as gen
from host.wire import sensor
from host.wire.frames import BY_NAME, Frame, encode_frame
from host.wire.stream import StreamDecoder

if "host.transports" not in serial.protocol_handler_packages:
    serial.protocol_handler_packages.append("host.transports")

IMU = ("ax", "ay", "az", "temp", "gx", "gy", "gz")


class Board:
    """A sim:// port with a decoder: read frames by simulated seconds."""

    def __init__(self, url: str, timeout: float | None = 1.0) -> None:
        self.port = cast(SimSerial, serial.serial_for_url(url, timeout=timeout))
        self.decoder = StreamDecoder()

    def frames(self, n_bytes: int) -> list[Frame]:
        return self.decoder.feed(self.port.read(n_bytes))

    def seconds(self, s: float) -> list[Frame]:
        """Frames of about ``s`` simulated seconds (max speed)."""
        return self.frames(int(s * 50 * 27))

    def send(self, msg: str, seq: int = 1, **fields: int) -> None:
        self.port.write(encode_frame(msg, seq, **fields))


def samples(frames: list[Frame]) -> np.ndarray:
    return np.array([[f.fields[k] for k in IMU] for f in frames if f.name == "IMU_SAMPLE"])


def sample_times_us(frames: list[Frame]) -> np.ndarray:
    return np.array([f.fields["t_us"] for f in frames if f.name == "IMU_SAMPLE"], dtype=np.int64)


def after_ack(frames: list[Frame], cmd_seq: int) -> list[Frame]:
    """The frames after the ACK of command ``cmd_seq`` (which must be there, status OK)."""
    for i, f in enumerate(frames):
        if f.name == "ACK" and f.fields["cmd_seq"] == cmd_seq:
            assert f.fields["status"] == 0
            return frames[i + 1 :]
    raise AssertionError(f"no ACK of command {cmd_seq}")


def gyro_integral_deg(frames: list[Frame]) -> np.ndarray:
    s = samples(frames)
    t = sample_times_us(frames) / 1e6
    g = sensor.gyro_dps(s[:, 4:7])
    return np.sum(0.5 * (g[1:] + g[:-1]) * np.diff(t)[:, None], axis=0)


def test_hello_first_then_samples_with_consecutive_seq_at_50_hz() -> None:
    b = Board("sim://?seed=1&noise_seed=1&speed=max&sample_clock=0.004&clock_ppm=0")
    fr = b.seconds(3.0)
    assert fr[0].name == "HELLO"
    hello = fr[0].fields
    assert hello["spec_fingerprint"] == gen.SPEC_FINGERPRINT
    assert hello["protocol_version"] == gen.PROTOCOL_VERSION and hello["who_am_i"] == 0x68
    assert (hello["accel_fs_sel"], hello["gyro_fs_sel"], hello["streaming"]) == (0, 0, 1)
    assert fr[0].seq == 0
    assert [f.seq for f in fr] == list(range(len(fr)))  # one counter over all frames
    assert fr[1].name == "IMU_SAMPLE"
    dt = np.diff(sample_times_us(fr))
    assert np.mean(dt) == pytest.approx(20000 / 1.004, abs=2)
    assert np.all(np.abs(dt - 20000 / 1.004) <= 4)  # 4 µs timer
    names = [f.name for f in fr]
    assert names.count("STATUS") in (2, 3)  # once a simulated second
    st = [f for f in fr if f.name == "STATUS"][-1].fields
    assert st["samples"] > 50 and st["missed"] == 0
    assert b.decoder.stats.crc_errors == 0 and b.decoder.stats.lost_frames == 0


def test_same_seeds_same_bytes() -> None:
    a = serial.serial_for_url("sim://?seed=9&noise_seed=9&speed=max", timeout=1).read(5000)
    b = serial.serial_for_url("sim://?seed=9&noise_seed=9&speed=max", timeout=1).read(5000)
    c = serial.serial_for_url("sim://?seed=10&noise_seed=9&speed=max", timeout=1).read(5000)
    d = serial.serial_for_url("sim://?seed=9&speed=max", timeout=1).read(5000)  # fresh noise
    assert a == b and a != c and a != d


def _paced_span_s(url: str, read_s: float) -> tuple[float, float]:
    """Read ``url`` for ``read_s`` of wall time: (device-time span of the samples, wall time).

    The wall time runs from before the port is opened to after the last read, so it bounds
    everything the board could have produced, however late the scheduler ran this process.
    """
    t0 = time.monotonic()
    b = Board(url, timeout=0.05)
    t_read = time.monotonic()
    fr: list[Frame] = []
    while time.monotonic() - t_read < read_s:
        fr += b.frames(4096)
    wall = time.monotonic() - t0
    t_us = [f.fields["t_us"] for f in fr if f.name == "IMU_SAMPLE"]
    assert len(t_us) >= 2
    return (t_us[-1] - t_us[0]) * 1e-6, wall


@pytest.mark.parametrize("speed", [1, 20])
def test_realtime_speed_paces_samples_by_the_wall_clock(speed: int) -> None:
    # Pacing means the board is never ahead of the wall clock (times the speed factor), and
    # does not stall either. Both bounds hold on a loaded machine: the upper one because the
    # wall time covers the whole read, the lower one because a late reader catches up.
    url = (
        "sim://?seed=2&noise_seed=2" if speed == 1 else f"sim://?seed=2&noise_seed=2&speed={speed}"
    )
    span, wall = _paced_span_s(url, 0.3)
    assert span <= speed * (wall + 0.02) + 0.04  # + one sample period of slack either way
    assert span >= speed * 0.3 * 0.5


def test_commands_are_answered() -> None:
    b = Board("sim://?seed=3&noise_seed=3&speed=max")
    b.seconds(0.5)
    b.send("PING", 7, nonce=0xDEADBEEF)
    fr = b.frames(200)
    other = [f for f in fr if f.name != "IMU_SAMPLE"]
    assert [f.name for f in other[:2]] == ["PONG", "ACK"]
    assert other[0].fields["nonce"] == 0xDEADBEEF and 400_000 < other[0].fields["t_us"] < 700_000
    assert other[1].fields == {"cmd_type": 0x81, "cmd_seq": 7, "status": 0}
    b.send("GET_CONFIG", 8)
    b.send("GET_STATUS", 9)
    fr = b.frames(200)
    names = [f.name for f in fr if f.name != "IMU_SAMPLE"]
    assert names[:4] == ["HELLO", "ACK", "STATUS", "ACK"]
    b.send("STOP_STREAM", 10)
    fr = after_ack(b.frames(200), 10)  # samples already on the wire come first
    assert "IMU_SAMPLE" not in {f.name for f in fr}
    fr = b.frames(200)  # max speed, nothing streaming: returns after 2 simulated seconds
    assert [f.name for f in fr] == ["STATUS", "STATUS"]
    b.send("START_STREAM", 11)
    fr = after_ack(b.seconds(0.5), 11)
    assert len(samples(fr)) > 5
    b.send("SET_RATE", 12, smplrt_div=9, dlpf_cfg=3)  # 1 kHz / 10 = 100 Hz
    fr = after_ack(b.seconds(1.0), 12)
    imu = [f for f in fr if f.name == "IMU_SAMPLE"]
    assert imu[0].fields["flags"] & 4 and not imu[1].fields["flags"] & 4  # CONFIG_CHANGED
    assert np.median(np.diff(sample_times_us(fr))) == pytest.approx(10000, rel=0.015)
    b.send("SET_RATE", 13, smplrt_div=0, dlpf_cfg=3)  # 1 kHz: more than the board sends
    b.send("SET_RATE", 14, smplrt_div=9, dlpf_cfg=7)
    b.send("HELLO", 15, **{f.name: 0 for f in BY_NAME["HELLO"].fields})
    answers = [f for f in b.frames(300) if f.name in ("ACK", "ERROR")]
    acks = [f.fields for f in answers if f.name == "ACK"]
    assert [(a["cmd_seq"], a["status"]) for a in acks] == [(13, 1), (14, 1), (15, 2)]
    # as the firmware: an unsupported command also gets ERROR BAD_COMMAND naming its type
    assert answers[-1].name == "ERROR"
    assert answers[-1].fields == {"code": 5, "detail": 0x02, "count": 1}
    bad = bytearray(encode_frame("PING", 16, nonce=1))
    bad[-1] ^= 0xFF
    b.port.write(bytes(bad))
    st = [f for f in b.seconds(1.2) if f.name == "STATUS"]
    assert st and st[-1].fields["crc_errors"] == 1


def test_operator_hints_put_gravity_on_the_asked_axis() -> None:
    b = Board("sim://?seed=4&noise_seed=4&speed=max&truth=ideal&earth_rate=0")
    b.seconds(0.5)
    g_counts = 16384 * 9.8155 / sensor.G0
    for name, axis, sign in (("x_up", 0, 1), ("y_dn", 1, -1), ("z_dn", 2, -1)):
        did = b.port.operator_hint("place", name=name)
        assert did["done"] and did["fault"] is None
        s = samples(b.seconds(1.0))[5:]
        want = np.zeros(3)
        want[axis] = sign * g_counts
        np.testing.assert_allclose(s[:, 0:3].mean(axis=0), want, atol=20)
    assert [h[1] for h in b.port.hints] == ["place", "place", "place"]


def test_operator_turns_when_asked_within_the_window() -> None:
    b = Board("sim://?seed=5&noise_seed=5&speed=max&truth=ideal&earth_rate=0&clock_ppm=0")
    b.seconds(0.3)
    did = b.port.operator_hint("turn", axis="y", direction="cw", turns=2, window_s=12)
    t_hint = did["start_s"] - 1.3
    fr = b.seconds(12.5)
    assert did["up"] == [0.0, 1.0, 0.0] and did["angle_deg"] == pytest.approx(-720.0)
    assert 0.8 <= did["start_s"] - b.port.hints[-1][0] <= 1.3 and did["end_s"] < t_hint + 12.5
    i = gyro_integral_deg(fr)
    assert i[1] == pytest.approx(-720.0, abs=1.0)
    assert abs(i[0]) < 5 and abs(i[2]) < 5
    s = samples(fr)
    assert np.mean(s[-10:, 1]) == pytest.approx(16384 * 9.8155 / sensor.G0, abs=20)  # y up


def test_manual_operator_only_records_hints() -> None:
    b = Board("sim://?seed=5&noise_seed=5&speed=max&truth=ideal&operator=manual")
    b.seconds(0.2)
    did = b.port.operator_hint("place", name="x_up")
    assert did["done"] is False and b.port.hints[-1][1:] == ("place", {"name": "x_up"})
    s = samples(b.seconds(1.0))
    assert np.abs(s[:, 2].mean()) > 16000  # still z up


def test_fault_wrong_face_puts_the_next_axis_up_once() -> None:
    b = Board("sim://?seed=6&noise_seed=6&speed=max&truth=ideal&fault=wrong_face")
    b.seconds(0.2)
    did = b.port.operator_hint("place", name="x_up")
    assert did["fault"] == "wrong_face" and did["up"] == [0.0, 1.0, 0.0]
    s = samples(b.seconds(1.0))[5:]
    assert s[:, 1].mean() > 16000 and abs(s[:, 0].mean()) < 50
    did = b.port.operator_hint("place", name="x_up")  # the repeat is right
    assert did["fault"] is None
    s = samples(b.seconds(1.0))[5:]
    assert s[:, 0].mean() > 16000


def test_fault_too_fast_saturates_and_incomplete_turn_falls_short() -> None:
    b = Board(
        "sim://?seed=7&noise_seed=7&speed=max&truth=ideal&fault=too_fast@1&fault=incomplete_turn@2"
    )
    b.seconds(0.2)
    assert b.port.operator_hint("turn", axis="z", direction="ccw", turns=2)["fault"] == "too_fast"
    s = samples(b.seconds(12.0))
    assert s[:, 6].max() == 32767
    did = b.port.operator_hint("turn", axis="z", direction="ccw", turns=2)
    assert did["fault"] == "incomplete_turn"
    fr = b.seconds(12.0)
    assert gyro_integral_deg(fr)[2] == pytest.approx(0.8 * 720, abs=1.5)
    assert samples(fr)[:, 6].max() < 32767


def test_pull_cable_raises_and_reopening_resets_the_board() -> None:
    b = Board("sim://?seed=8&noise_seed=8&speed=max&fault=pull_cable@2")
    fr = b.seconds(1.5)
    assert fr[0].name == "HELLO" and fr[0].fields["reset_cause"] == 1
    with pytest.raises(serial.SerialException, match="device disconnected"):
        for _ in range(10):
            b.seconds(0.5)
    with pytest.raises(serial.SerialException, match="device disconnected"):
        b.send("PING", nonce=1)
    with pytest.raises(serial.SerialException, match="device disconnected"):
        _ = b.port.in_waiting
    b.port.close()
    b.port.open()
    dec = StreamDecoder()
    fr = dec.feed(b.port.read(6 * 50 * 27))  # beyond the 2 s: stays connected now
    assert fr[0].name == "HELLO" and fr[0].seq == 0 and fr[1].seq == 1
    assert fr[0].fields["reset_cause"] == 1  # powered up afresh
    assert sample_times_us(fr)[0] < 20_000


def test_reopen_resets_seq_and_sends_hello_again_keeping_the_cube_where_it_is() -> None:
    b = Board("sim://?seed=9&noise_seed=9&speed=max&truth=ideal")
    b.seconds(1.0)
    b.port.operator_hint("place", name="y_up")
    last = b.seconds(1.0)[-1].seq
    assert last > 90
    b.port.close()
    with pytest.raises(serial.PortNotOpenError):
        b.port.read(1)
    b.port.open()
    fr = StreamDecoder().feed(b.port.read(2000))
    assert fr[0].name == "HELLO" and fr[0].seq == 0 and fr[0].fields["reset_cause"] == 2
    assert samples(fr)[:, 1].mean() > 16000  # still y up


def test_truth_is_exposed_and_url_errors_are_clear() -> None:
    p = serial.serial_for_url("sim://?seed=3&noise_seed=3&truth=ideal&speed=max")
    assert p.truth == SensorTruth.ideal()  # type: ignore[attr-defined]
    q = serial.serial_for_url("sim://?seed=3&noise_seed=3&speed=max&effects=bias")
    c = q.truth.constants()  # type: ignore[attr-defined]
    assert c["G0x"] != 0 and c["Gxx"] == 0
    with pytest.raises(serial.SerialException, match="unknown option"):
        serial.serial_for_url("sim://?sead=3")
    with pytest.raises(serial.SerialException, match="unknown fault"):
        serial.serial_for_url("sim://?fault=dropped")
    with pytest.raises(serial.SerialException, match="speed"):
        serial.serial_for_url("sim://?speed=0")
