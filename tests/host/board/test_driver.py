"""The board driver (host/board/driver.py): the port a calibration opens when none is given,
the HELLO read as a board's description, the live device→host clock a record's header takes."""

from __future__ import annotations

from types import SimpleNamespace
from typing import Any

import pytest

from host.board import driver


def test_default_port() -> None:
    def ports(*items: SimpleNamespace) -> Any:
        return lambda: list(items)

    other = SimpleNamespace(device="/dev/ttyS0", vid=None, description="n/a")
    apm = SimpleNamespace(device="/dev/ttyACM0", vid=0x2341, description="Arduino Mega 2560")
    assert driver.default_port(ports(other, apm))[0] == "/dev/ttyACM0"
    port, note = driver.default_port(ports(other))
    assert port == "sim://" and note is not None
    assert "NO BOARD FOUND (looked at: /dev/ttyS0)" in note and "VIRTUAL board sim://" in note
    assert "no serial ports at all" in (driver.default_port(ports())[1] or "")


def test_gyro_alarm_threshold() -> None:
    fields = dict(fw_major=0, fw_minor=1, fw_patch=0, protocol_version=1, spec_fingerprint=0,
                  who_am_i=0x68, product_id=0x58, accel_fs_sel=0, gyro_fs_sel=0, dlpf_cfg=3,
                  smplrt_div=19, mode=0, timer_resolution_ns=4000, baud=115200, reset_cause=1,
                  streaming=1)  # fmt: skip
    info = driver.BoardInfo.from_hello(fields)
    # 250 °/s − 1 LSB at 131 LSB/(°/s): 32749 counts = 249.992 °/s
    assert info.gyro_alarm_counts == 32749 and info.rate_hz == 50.0


def test_board_live_clock_maps_the_record_start_to_host_time() -> None:
    """The session's live clock (fed every sample as it is read, across a t_us wrap) gives the
    record metadata the device clock's skew and the first sample's host time."""
    from host.bench.linksim import LinkParams, simulate_link
    from host.wire.stream import StreamDecoder

    lc = simulate_link(LinkParams(seconds=30, skew_ppm=80, device_t0_us=2**32 - 5_000_000, seed=9))
    board = driver.Board("unused://")
    dec = StreamDecoder()
    k = 0
    start = None
    for t_ns, chunk in lc.chunks:
        for f in dec.feed(chunk):
            if f.type == 1:
                board._feed_clock(t_ns, f.fields["t_us"])
                if k == 1000:  # a record starting at the 1000th sample, after the wrap
                    start = (f.fields["t_us"], lc.true_host_ns[k])
                k += 1
    assert start is not None and start[0] < 2**31  # the wrap happened before it
    meta = board.clock_meta(start[0])
    assert float(meta["clock_skew_ppm"]) == pytest.approx(-80, abs=5)
    # mapped host time of the record's first sample: its true data-ready time plus the
    # firmware's fixed processing delay (≈0.2 ms), far from the ≈2–6 ms of arrival stamping
    assert 0 < int(meta["clock_host_ns_at_start"]) - start[1] < 600_000
    assert int(meta["clock_points"]) > 1000
