"""HELLO (host/board/hello.py): the one wait for a board's HELLO and the one spec check."""

from __future__ import annotations

import time

import pytest

from host.board.hello import SpecMismatch, check_spec, wait_for_hello
from host.board.link import Link, LinkTimeout
from host.wire.frames import encode_frame
from host.wire.protocol_gen import PROTOCOL_VERSION, SPEC_FINGERPRINT
from host.wire.stream import StreamDecoder

HELLO = encode_frame(
    "HELLO", 0, fw_major=0, fw_minor=3, fw_patch=1, protocol_version=PROTOCOL_VERSION,
    spec_fingerprint=SPEC_FINGERPRINT, who_am_i=0x68, product_id=0x58, accel_fs_sel=0,
    gyro_fs_sel=0, dlpf_cfg=4, smplrt_div=19, mode=0, timer_resolution_ns=500, baud=115200,
    reset_cause=1, streaming=1,
)  # fmt: skip
STATUS = encode_frame(
    "STATUS", 1, uptime_ms=5, samples=0, missed=0, dropped=0, crc_errors=0, spi_faults=0,
    fifo_overflows=0, tx_queue_max=0, bad_bursts=0, flags=0,
)  # fmt: skip


class QuietBoard:
    """A port that says ``chatter`` at once and HELLO only when asked with GET_CONFIG."""

    def __init__(self, chatter: bytes = b"") -> None:
        self.out = bytearray(chatter)
        self.commands: list[str] = []
        self._rx = StreamDecoder(sender="host")

    @property
    def in_waiting(self) -> int:
        return len(self.out)

    def read(self, n: int) -> bytes:
        if not self.out:
            time.sleep(0.005)
        data, self.out[:] = bytes(self.out[:n]), self.out[n:]
        return data

    def write(self, data: bytes) -> int:
        for f in self._rx.feed(data):
            self.commands.append(f.name)
            if f.name == "GET_CONFIG":
                self.out += HELLO
        return len(data)

    def close(self) -> None:
        pass


def test_the_spec_check_names_both_specs() -> None:
    check_spec(SPEC_FINGERPRINT, who="the firmware", remedy="x")  # this host's: no error
    with pytest.raises(SpecMismatch) as ei:
        check_spec(0x12345678, who="fw.hex", remedy="rebuild it", protocol_version=7)
    assert str(ei.value) == (
        f"fw.hex speaks protocol 7 (spec 0x12345678), this host protocol {PROTOCOL_VERSION} "
        f"(spec {SPEC_FINGERPRINT:#010x}): rebuild it"
    )


def test_a_silent_board_is_asked_once_and_its_hello_returned() -> None:
    port = QuietBoard(chatter=STATUS)
    _, hello, heard = wait_for_hello(Link(port, stall_s=0.1), 3.0, ask_after_s=0.2)  # type: ignore[arg-type]
    assert hello.fields["fw_minor"] == 3 and heard
    assert port.commands == ["GET_CONFIG"]


def test_not_asking_waits_until_the_time_is_up() -> None:
    port = QuietBoard()
    start = time.monotonic()
    with pytest.raises(LinkTimeout, match=r"no HELLO from the board within 0.5 s \(it sends"):
        wait_for_hello(Link(port, stall_s=0.1), 0.5, ask_after_s=None)  # type: ignore[arg-type]
    assert time.monotonic() - start >= 0.5
    assert port.commands == []  # after flashing, the bootloader must not be spoken to
