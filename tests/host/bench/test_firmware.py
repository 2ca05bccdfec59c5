"""The virtual firmware (host/bench/firmware.py): host bytes in, device bytes out, as the
firmware behaves on the wire — no port, no wall clock."""

from __future__ import annotations

import numpy as np
import pytest

from host.bench.firmware import RESET_EXTERNAL, VirtualFirmware
from host.bench.options import parse_sim_options
from host.bench.physics import static_motion
from host.wire import protocol_gen as gen
from host.wire.frames import IMU_SAMPLE, crc16, encode_frame
from host.wire.stream import StreamDecoder

ACK = gen.ENUMS["ack_status"]


def firmware(seed: int = 4) -> VirtualFirmware:
    drawn = parse_sim_options({"seed": [str(seed)]}, "max", True).draw()
    return VirtualFirmware(
        drawn.truth, drawn.bench, drawn.environment, np.random.SeedSequence(seed), 0.0,
        static_motion("y_dn"), RESET_EXTERNAL,
    )  # fmt: skip


def frames(fw: VirtualFirmware) -> list:
    out = StreamDecoder().feed(bytes(fw.output))
    fw.output.clear()
    return out


def test_power_up_says_hello_then_streams_with_one_seq_counter() -> None:
    fw = firmware()
    fw.run_until(2.5)
    got = frames(fw)
    assert got[0].name == "HELLO" and got[0].fields["reset_cause"] == RESET_EXTERNAL
    assert [f.seq for f in got] == list(range(len(got)))
    names = [f.name for f in got[1:]]
    assert names.count("STATUS") == 2 and 120 <= names.count("IMU_SAMPLE") <= 130
    imu = [f for f in got if f.type == IMU_SAMPLE]
    assert imu[10].fields["ay"] < -15000  # y down: about −1 g on ±2 g (16384 counts per g)


def test_commands_are_answered_in_any_chunking() -> None:
    fw = firmware()
    fw.run_until(0.3)
    frames(fw)
    cmds = encode_frame("PING", 7, nonce=0xC0FFEE) + encode_frame("STOP_STREAM", 8)
    cmds += encode_frame("SET_RATE", 9, smplrt_div=0, dlpf_cfg=0)  # 8 kHz: refused
    cmds += bytes([0xA5, 0x5A, 0x99, 0, 10, 0, 0x12, 0x34])  # not a valid frame: ignored
    cmds += encode_frame("GET_CONFIG", 11)
    for i in range(0, len(cmds), 3):
        fw.receive(cmds[i : i + 3])
    got = [(f.name, f.fields) for f in frames(fw)]
    pong = got[0][1]
    assert got[0][0] == "PONG" and pong["nonce"] == 0xC0FFEE and pong["t_us"] > 250_000
    acks = [(f["cmd_seq"], f["status"]) for n, f in got if n == "ACK"]
    assert acks == [(7, ACK["OK"]), (8, ACK["OK"]), (9, ACK["BAD_ARGUMENT"]), (11, ACK["OK"])]
    hello = next(f for n, f in got if n == "HELLO")
    assert hello["streaming"] == 0 and hello["smplrt_div"] == 19
    fw.run_until(1.5)
    assert all(f.type != IMU_SAMPLE for f in frames(fw))  # stopped: STATUS only


def test_an_unknown_command_gets_unsupported_and_an_error_frame() -> None:
    fw = firmware()
    frames(fw)
    body = bytes([0x9A, 0, 5, 0])  # type 0x9A (no such command), no payload, seq 5
    fw.receive(gen.SYNC + body + crc16(body).to_bytes(2, "little"))
    ack, err = frames(fw)
    assert (ack.name, ack.fields["cmd_type"], ack.fields["status"]) == (
        "ACK", 0x9A, ACK["UNSUPPORTED"],
    )  # fmt: skip
    assert err.name == "ERROR" and err.fields["detail"] == 0x9A and err.fields["count"] == 1


def test_hello_reports_the_chips_revision_and_counts_follow_it() -> None:
    from host.wire.sensor import PRODUCT_REVISIONS

    drawn = parse_sim_options({"seed": ["4"]}, "max", True).draw()
    for pid in (next(p for p, n in PRODUCT_REVISIONS.items() if n == "C5"), 0x58):
        fw = VirtualFirmware(
            drawn.truth, drawn.bench, drawn.environment, np.random.SeedSequence(4), 0.0,
            static_motion("y_dn"), RESET_EXTERNAL, pid,
        )  # fmt: skip
        fw.run_until(0.5)
        got = frames(fw)
        assert got[0].fields["product_id"] == pid
        ay = np.mean([f.fields["ay"] for f in got if f.type == IMU_SAMPLE])
        # C4/C5 parts count half the LSB per g (host.wire.sensor.accel_lsb_per_g)
        assert ay == pytest.approx(-16384 / (2 if pid != 0x58 else 1), rel=0.1)
