"""One measurement cut on device time (host/board/acquisition.py, through
:meth:`host.board.driver.Board.acquire`): the samples whose device time is inside the window,
however late and in whatever pieces the port delivers them."""

from __future__ import annotations

import time
from typing import Any

import numpy as np
import pytest

from host.board import driver
from host.board.link import open_port

LINEAR = "speed=max&effects=linear,noise&earth_rate=0"


class LaggingPort:
    """A port whose bytes reach the host late and in pieces: ``lag`` bytes are always still
    in flight (as in a loaded host's USB/pty buffers) and a read returns at most ``chunk``."""

    def __init__(self, port: Any, lag: int, chunk: int) -> None:
        self._port = port
        self._buf = bytearray()
        self.lag = lag
        self.chunk = chunk

    def __getattr__(self, name: str) -> Any:
        return getattr(self._port, name)

    def _fill(self, size: int) -> None:
        want = self.lag + size - len(self._buf)
        if want > 0:
            self._buf += self._port.read(want)

    @property
    def in_waiting(self) -> int:
        self._fill(self.chunk)
        return max(0, min(self.chunk, len(self._buf) - self.lag))

    def read(self, size: int = 1) -> bytes:
        self._fill(size)
        n = max(0, min(size, self.chunk, len(self._buf) - self.lag))
        data = bytes(self._buf[:n])
        del self._buf[:n]
        return data

    def write(self, data: bytes) -> int:
        return int(self._port.write(data))


@pytest.mark.slow
@pytest.mark.parametrize("chunk", [1, 27, 200, 4096])
def test_measurement_is_cut_on_device_time_not_on_reads(chunk: int) -> None:
    """Samples of the previous pose still in flight at the start beep (20 samples' worth of
    bytes behind, delivered in pieces of ``chunk`` bytes) are not part of the measurement:
    it holds exactly the samples whose device time is inside its window."""
    period_us = 20_000
    board = driver.Board(
        f"sim://?seed=5&noise_seed=5&{LINEAR}",
        port_factory=lambda u: LaggingPort(open_port(u), lag=27 * 20, chunk=chunk),
    )
    try:
        board.connect()
        for _ in range(50):
            board.pump()
        for name, sign in (("x_up", 1), ("z_dn", -1), ("y_up", 1)):
            axis = "xyz".index(name[0])
            board.hint("place", name=name)
            acq = board.acquire(0.5)
            g = acq.counts[:, axis] / 16384.0
            assert np.all(g * sign > 0.9), (name, g[:25])  # every sample in the new pose
            # the window starts at the board's answer to the beep, on its own clock
            assert 0 <= (acq.start_t_us - acq.beep_t_us) & 0xFFFFFFFF < period_us
            assert 0.5e6 - period_us <= acq.t_us[-1] < 0.5e6
            assert acq.lost == 0 and np.all(np.diff(acq.t_us) > 0)
    finally:
        board.close()


def _boards(*urls: str, settle: bool = True) -> list[driver.Board]:
    boards = [driver.Board(u) for u in urls]
    for b in boards:
        b.connect()
    deadline = time.monotonic() + (20.0 if settle else 0.0)
    while any(b.clock.map is None for b in boards) and time.monotonic() < deadline:
        for b in boards:  # read until each live clock has a first estimate
            b.pump()
    return boards


@pytest.mark.slow
def test_several_boards_are_measured_on_one_window_of_host_time() -> None:
    """Two boards read at once from one start beep: each record is its own board's samples
    (the two units differ), of its own device time from its PONG, and the two windows begin
    at the same host moment to within the link's latency (the live clock maps each first
    sample to host time)."""
    boards = _boards(f"sim://?seed=1&{LINEAR[10:]}", f"sim://?seed=2&{LINEAR[10:]}")
    try:
        for b in boards:
            b.hint("place", name="y_up")
        acqs = driver.acquire_boards(boards, 0.6)
        assert len(acqs) == 2 and acqs[0].beep_ns == acqs[1].beep_ns
        starts = []
        for b, acq in zip(boards, acqs, strict=True):
            period_us = 1e6 / b.info.rate_hz  # type: ignore[union-attr]
            assert 0.6e6 - 2 * period_us <= acq.t_us[-1] < 0.6e6
            assert acq.lost == 0 and np.all(np.diff(acq.t_us) > 0)
            assert 0 <= (acq.start_t_us - acq.beep_t_us) & 0xFFFFFFFF < period_us
            assert np.all(acq.counts[:, 1] / 16384.0 > 0.9)  # y up on both
            starts.append(int(b.clock_meta(acq.start_t_us)["clock_host_ns_at_start"]))
        assert abs(starts[0] - starts[1]) < 50e6, starts  # ns: within 50 ms
        assert not np.array_equal(acqs[0].counts[:20], acqs[1].counts[:20])
    finally:
        for b in boards:
            b.close()


def test_a_board_that_vanishes_is_named_by_its_place() -> None:
    """The second of two boards loses its cable during the measurement: BoardFailed names
    board 1 and carries the link's own error; the single-board acquire raises that error
    itself, as it always did."""
    from host.board.acquisition import BoardFailed
    from host.board.link import LinkLost

    plain = LINEAR[10:]  # in real time: the cable goes 1.5 s after the port opened
    boards = _boards(
        f"sim://?seed=1&{plain}", f"sim://?seed=2&{plain}&fault=pull_cable@1.5", settle=False
    )
    try:
        with pytest.raises(BoardFailed) as info:
            driver.acquire_boards(boards, 5.0)
        assert info.value.index == 1 and isinstance(info.value.error, LinkLost)
        with pytest.raises(LinkLost):
            boards[1].acquire(1.0)
    finally:
        for b in boards:
            b.close()
