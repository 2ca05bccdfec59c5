"""One measurement on device time: the window a board's samples are cut to at the start beep
(on one board, or on several at once: :func:`acquire_all`).

At the beep the host sends PING and the board answers PONG with its ``t_us`` at that moment;
the measurement holds exactly the samples whose device time lies in the window that starts
there (:func:`acquire`). Frames lost on the link, samples the firmware flagged MISSED, a board
that restarts (:class:`BoardReset`), a sensor that stops (:class:`SensorFault`) and the
operator's Esc (:class:`MeasurementAborted`) are told apart. The board it reads from is a
:class:`host.board.driver.Board` (:class:`FrameSource`: reads, the live clock, warnings).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from datetime import datetime
from typing import Protocol

import numpy as np

from host.board.link import Link
from host.errors import UserError
from host.wire import protocol_gen as gen
from host.wire.frames import (
    IMU_SAMPLE,
    SENSOR_ERROR_CODES,
    Frame,
    error_text,
    sample_counts,
    sample_flags,
    sample_t_us,
)
from host.wire.segments import seq_step, seq_went_back, t_us_step, t_us_went_back

#: no IMU sample for this long during a measurement, whatever other frames arrive (STATUS,
#: ERROR), is a stalled board: the measurement stops (:class:`SensorFault`), s
SAMPLE_STALL_S = 5.0
#: how long the start beep waits for the board's PONG (its device time) before cutting the
#: window at the newest sample instead, s
PONG_TIMEOUT_S = 1.0
MISSED = gen.ENUMS["sample_flags"]["MISSED"]


class BoardReset(Exception):
    """The board restarted during a measurement (sequence or device time went back)."""


class MeasurementAborted(Exception):
    """The operator pressed Esc during a measurement."""


class SensorFault(UserError):
    """The board's sensor stopped during a measurement: the board sent a sensor ERROR frame
    (the message carries its reason), or no IMU sample came for ``sample_stall_s`` while the
    board kept talking (STATUS, ERROR). Reconnecting does not help; the sensor needs a look."""


@dataclass
class Acquisition:
    """The samples of one measurement, raw, with its bookkeeping."""

    t_us: np.ndarray  # (N,) int64 µs since the first sample (device clock, unwrapped)
    counts: np.ndarray  # (N, 7) int counts: ax, ay, az, temp, gx, gy, gz
    start_t_us: int  # device t_us (raw, 32-bit) of the first sample
    beep_ns: int  # host monotonic ns of the start beep
    first_ns: int  # host monotonic ns of the read that brought the first sample
    start_time: str  # wall clock of the start beep, ISO
    lost_frames: int  # sequence gaps during the measurement
    missed: int  # samples flagged MISSED by the firmware
    crc_errors: int  # CRC failures the decoder saw during the measurement
    beep_t_us: int = 0  # device t_us (raw, 32-bit) at the start beep: the window's start
    status_flags: int | None = None  # newest STATUS.flags by the window's end (None: no STATUS)

    @property
    def lost(self) -> int:
        return self.lost_frames + self.missed

    @property
    def loss_fraction(self) -> float:
        n = len(self.t_us) + self.lost
        return self.lost / n if n else 0.0


class FrameSource(Protocol):
    """What a measurement reads from: a connected :class:`host.board.driver.Board`."""

    link: Link | None
    sample_stall_s: float
    status_flags: int | None  # newest STATUS.flags since HELLO (None: none yet)

    def read_frames(self) -> list[tuple[int, Frame]]:
        """One read of the port: (host ns of the read, frame) for each frame it completed."""
        ...

    def report_frame(self, f: Frame) -> None:
        """A frame that is no sample (ERROR, HELLO): warn, accept a new HELLO."""
        ...


def acquire(
    board: FrameSource,
    rate_hz: float,
    nonce: int,
    duration_s: float,
    tick: Callable[[float, np.ndarray, int], None] | None = None,
    check_escape: Callable[[], bool] | None = None,
    tick_every_s: float = 0.1,
    enough: Callable[[np.ndarray, float], bool] | None = None,
) -> Acquisition:
    """Record ``duration_s`` seconds of device time from now (the start beep) from ``board``
    (nominal ``rate_hz``, Hz), its PING carrying ``nonce``: :func:`acquire_all` of this one
    board (its exceptions raised as they are).

    The window is cut on device time, not on what a read happens to return: at the beep
    the host sends PING and the board answers PONG with its ``t_us`` at that moment; the
    measurement holds exactly the samples whose device time lies in
    ``[PONG t_us, PONG t_us + duration)`` — samples still in flight from before the beep
    (in the USB/pty buffers, however the reads are chunked and however late the host
    is) are dropped by their time stamp. A board that does not answer within
    :data:`PONG_TIMEOUT_S` gets the window from the newest sample seen at that moment.
    ``tick(elapsed_s, sums_of_counts(7), n)`` is called about every ``tick_every_s``
    (host time); ``check_escape()`` True -> MeasurementAborted. Raises LinkLost /
    LinkTimeout / BoardReset; nothing is kept then. A sensor ERROR frame, or no IMU sample
    for ``sample_stall_s`` (host time) whatever else arrives, raises :class:`SensorFault`:
    the measurement always ends. ``enough(counts (N, 7), elapsed_s)`` True ends the window
    early, after its latest sample; it is asked once a second of device time.
    """
    try:
        return acquire_all([(board, rate_hz, nonce)], duration_s, tick, check_escape,
                           tick_every_s, enough)[0]  # fmt: skip
    except BoardFailed as failed:
        raise failed.error from None


class BoardFailed(Exception):
    """Board ``index`` of :func:`acquire_all` failed with ``error`` (LinkLost, LinkTimeout,
    BoardReset, SensorFault): the measurement of every board is discarded."""

    def __init__(self, index: int, error: Exception) -> None:
        super().__init__(str(error))
        self.index = index
        self.error = error


def acquire_all(
    boards: Sequence[tuple[FrameSource, float, int]],
    duration_s: float,
    tick: Callable[[float, np.ndarray, int], None] | None = None,
    check_escape: Callable[[], bool] | None = None,
    tick_every_s: float = 0.1,
    enough: Callable[[np.ndarray, float], bool] | None = None,
) -> list[Acquisition]:
    """One measurement on several boards at once: each ``(board, rate_hz, nonce)`` gets its
    PING at the one start beep (sent one after the other, within microseconds of host time)
    and its window of ``duration_s`` of its own device time from its PONG, as
    :func:`acquire` says; the boards are read in turn (each read takes what its port holds)
    until every window is over. So the windows start at the same host moment, to within the
    link's latency, and each board's record holds that window's samples. ``tick`` shows the
    first board's window; ``enough`` (one board only) ends it early. A board that fails
    raises :class:`BoardFailed` naming it."""
    beep_ns = time.monotonic_ns()
    start_time = datetime.now().astimezone().isoformat(timespec="milliseconds")
    windows = [_start(k, b, rate, nonce, duration_s, enough) for k, (b, rate, nonce)
               in enumerate(boards)]  # fmt: skip
    crc0 = [_crc(b) for b, _, _ in boards]
    next_tick = time.monotonic()
    done = [False] * len(windows)
    while not all(done):
        for k, w in enumerate(windows):
            if not done[k]:
                done[k] = _step(k, w)
        now = time.monotonic()
        if now >= next_tick:
            next_tick = now + tick_every_s
            if check_escape is not None and check_escape():
                raise MeasurementAborted()
            if tick is not None:
                w = windows[0]
                tick((w.el[-1] if w.el else 0) / 1e6, w.sums, len(w.rows))
    if tick is not None:  # the bar ends where the window ended: at its length, or earlier
        w = windows[0]
        tick(duration_s if w.ended_s is None else w.ended_s, w.sums, len(w.rows))
    return [
        w.acquisition(beep_ns, start_time, _crc(b) - c0, b.status_flags)
        for w, (b, _, _), c0 in zip(windows, boards, crc0, strict=True)
    ]


def _crc(board: FrameSource) -> int:
    assert board.link is not None
    return board.link.decoder.stats.crc_errors


def _start(
    index: int,
    board: FrameSource,
    rate_hz: float,
    nonce: int,
    duration_s: float,
    enough: Callable[[np.ndarray, float], bool] | None,
) -> _Window:
    """Board ``index``'s window, its PING sent now (the start beep)."""
    link = board.link
    assert link is not None
    try:
        link.send("PING", nonce=nonce)
    except UserError as exc:  # LinkLost: named with its board
        raise BoardFailed(index, exc) from None
    w = _Window(board, rate_hz, nonce, duration_s, enough)
    w.last_sample = time.monotonic()
    w.ping_deadline = w.last_sample + PONG_TIMEOUT_S
    return w


def _step(index: int, w: _Window) -> bool:
    """One read of board ``index``'s window; True once it is over."""
    try:
        done = w.read()
        now = time.monotonic()
        if w.t0 is None and now >= w.ping_deadline and w.newest_t is not None:
            done = w.start_after_newest()
        w.check_stall(now, done)
    except (UserError, BoardReset) as exc:  # LinkLost, LinkTimeout, SensorFault, a reset
        raise BoardFailed(index, exc) from None
    return done


class _Window:
    """The state of one measurement while it is read: the window's start on device time
    (``t0``: the PONG's t_us; None until known), the frames held until then, the samples
    taken and the counters."""

    def __init__(
        self,
        board: FrameSource,
        rate_hz: float,
        nonce: int,
        duration_s: float,
        enough: Callable[[np.ndarray, float], bool] | None,
    ) -> None:
        self.board, self.nonce, self.enough = board, nonce, enough
        #: device time at which ``enough`` ended the window, s (None: it did not)
        self.ended_s: float | None = None
        self.duration_us = int(round(duration_s * 1e6))
        self.period_us = 1e6 / rate_hz
        self.every = max(1, round(rate_hz))  # samples in a second: how often ``enough`` is asked
        self.t0: int | None = None  # device t_us of the beep (raw, 32-bit)
        self.newest_t: int | None = None  # newest sample time seen since the beep (fallback t0)
        self.held: list[tuple[int, Frame]] = []  # frames read before t0 was known
        self.t_raw: list[int] = []
        self.el: list[int] = []
        self.rows: list[tuple[int, ...]] = []
        self.sums = np.zeros(7, dtype=np.int64)
        self.first_ns = 0
        self.last_seq = -1
        self.last_rel = -1
        self.lost = 0
        self.missed = 0
        self.last_sample = 0.0  # host monotonic s of the latest read that brought a sample
        self.ping_deadline = 0.0  # host monotonic s: no PONG by then, start after the newest
        self.last_error: Frame | None = None

    def read(self) -> bool:
        """One read of the board; True once the window is over."""
        batch = self.board.read_frames()
        if any(f.type == IMU_SAMPLE for _, f in batch):
            self.last_sample = time.monotonic()
        for arrival_ns, f in batch:
            self.check_frame(f)
            if self.t0 is None:
                if f.name == "PONG" and f.fields["nonce"] == self.nonce:
                    self.t0 = f.fields["t_us"]
                elif f.type == IMU_SAMPLE:
                    self.newest_t = sample_t_us(f.payload)
                self.held.append((arrival_ns, f))
                if self.t0 is not None and self.take_held():
                    return True
                continue
            if self.take(arrival_ns, f):
                return True
        return False

    def check_frame(self, f: Frame) -> None:
        """A new HELLO (the board restarted) or a sensor ERROR end the measurement; other
        ERRORs are kept for the stall message."""
        if f.name == "HELLO":
            raise BoardReset("the board restarted during the measurement")
        if f.name == "ERROR" and f.fields["code"] in SENSOR_ERROR_CODES:
            raise SensorFault(
                f"the board reports {error_text(f)}: its sensor stopped; check the "
                "IMU and its wiring, then power-cycle the board"
            )
        if f.name == "ERROR":
            self.last_error = f

    def start_after_newest(self) -> bool:
        """No PONG (an older firmware?): the window starts after the newest sample; True once
        the window is over."""
        assert self.newest_t is not None
        self.t0 = int(t_us_step(-1, self.newest_t))  # the µs after it, modulo the wrap
        return self.take_held()

    def check_stall(self, now: float, done: bool) -> None:
        if now - self.last_sample > self.board.sample_stall_s and not done:
            raise SensorFault(
                f"no samples from the board for {self.board.sample_stall_s:g} s"
                + (f" (last: {error_text(self.last_error)})" if self.last_error else "")
                + " although it still answers: the sensor has stalled; check the IMU, "
                "then power-cycle the board"
            )

    def take_held(self) -> bool:
        batch, self.held = self.held, []
        return any(self.take(a_ns, g) for a_ns, g in batch)

    def take(self, arrival_ns: int, f: Frame) -> bool:
        """One frame of the window's stream (t0 known); True once the window is over."""
        assert self.t0 is not None
        gap = 0
        if self.last_seq >= 0:
            d = int(seq_step(self.last_seq, f.seq))
            if seq_went_back(d):
                raise BoardReset("the board restarted during the measurement")
            gap = d - 1
        self.last_seq = f.seq
        if f.type != IMU_SAMPLE:
            self.board.report_frame(f)
            if self.rows:
                self.lost += gap
            return False
        t_us = sample_t_us(f.payload)
        rel = int(t_us_step(self.t0, t_us))
        if t_us_went_back(rel):  # sampled before the beep: not part of the measurement
            if self.rows:
                raise BoardReset("the board's clock went back during the measurement")
            return False
        if rel >= self.duration_us:
            return True
        if self.rows:
            if rel < self.last_rel:
                raise BoardReset("the board's clock went back during the measurement")
            self.lost += gap
        else:  # frames lost between the beep and the first sample of the window
            self.first_ns = arrival_ns
            self.lost += min(gap, int(rel // self.period_us))
        return self.keep(f, t_us, rel)

    def keep(self, f: Frame, t_us: int, rel: int) -> bool:
        """A sample of the window; True when ``enough`` ends the window after it."""
        self.last_rel = rel
        counts = sample_counts(f.payload)
        if sample_flags(f.payload) & MISSED:
            self.missed += 1
        self.t_raw.append(t_us)
        self.el.append(rel)
        self.rows.append(counts)
        self.sums[:] += counts
        if self.enough is not None and len(self.rows) % self.every == 0:
            self.ended_s = (rel + self.period_us) / 1e6
            if self.enough(np.asarray(self.rows), self.ended_s):
                return True
            self.ended_s = None
        return False

    def acquisition(
        self, beep_ns: int, start_time: str, crc_errors: int, status_flags: int | None
    ) -> Acquisition:
        """The measurement: the samples on device time from the first, and the counters."""
        first = self.el[0] if self.el else 0
        return Acquisition(
            t_us=np.asarray(self.el, dtype=np.int64) - first,
            counts=np.asarray(self.rows, dtype=np.int64).reshape(-1, 7),
            start_t_us=self.t_raw[0] if self.t_raw else 0,
            beep_ns=beep_ns,
            first_ns=self.first_ns,
            start_time=start_time,
            lost_frames=self.lost,
            missed=self.missed,
            crc_errors=crc_errors,
            beep_t_us=self.t0 if self.t0 is not None else 0,
            status_flags=status_flags,
        )
