"""One measurement cut on device time (host/board/acquisition.py, through
:meth:`host.board.driver.Board.acquire`): the samples whose device time is inside the window,
however late and in whatever pieces the port delivers them."""

from __future__ import annotations

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
        f"sim://?seed=5&{LINEAR}",
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
