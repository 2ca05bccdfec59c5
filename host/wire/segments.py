"""The device counters' rules, in one place: wrap, reset and loss of ``seq`` and ``t_us``.

Every frame carries ``seq``, a 16-bit counter the firmware increments once per frame it sends;
every IMU sample carries ``t_us``, the 32-bit device microsecond clock. Both wrap (2¹⁶ frames,
2³² µs ≈ 71.6 min). Read in arrival order:

- a **reset** (the board restarted, a new *segment* begins) is ``seq`` not moving forward — a
  step of 0 or of half the counter range or more, modulo 2¹⁶ — or an IMU sample's ``t_us``
  going back (a step of 2³¹ µs or more modulo 2³²) against the previous IMU sample of the same
  segment;
- otherwise a ``seq`` step of ``d`` means ``d - 1`` **frames lost** in between; across a reset
  nothing is counted lost.

:class:`SegmentTracker` applies the rules frame by frame (the streaming decoder, a live board),
:func:`segments` to whole arrays (the bulk decoder); a property test keeps the two equal.
Unwrapping a counter into a monotonic one (with host time for gaps longer than a wrap) is
:func:`host.timing.clock.unwrap`.
"""

from __future__ import annotations

import numpy as np

SEQ_BITS = 16
T_US_BITS = 32
SEQ_MOD = 1 << SEQ_BITS
T_US_MOD = 1 << T_US_BITS


def seq_step(prev: int | np.ndarray, seq: int | np.ndarray) -> int | np.ndarray:
    """Frames from ``prev`` to ``seq`` modulo the 16-bit wrap (1 = the next frame)."""
    return (seq - prev) & (SEQ_MOD - 1)


def seq_went_back(step: int | np.ndarray) -> bool | np.ndarray:
    """A ``seq`` step that is no step forward: the device restarted (or repeated a frame)."""
    return (step == 0) | (step >= SEQ_MOD // 2)


def t_us_step(prev: int | np.ndarray, t_us: int | np.ndarray) -> int | np.ndarray:
    """Device µs from ``prev`` to ``t_us`` modulo the 32-bit wrap."""
    return (t_us - prev) & (T_US_MOD - 1)


def t_us_went_back(step: int | np.ndarray) -> bool | np.ndarray:
    """A ``t_us`` step of half the clock's range or more: the device clock went back (restart)."""
    return step >= T_US_MOD // 2


class SegmentTracker:
    """The rules frame by frame: feed every frame's ``seq`` in order, with ``t_us`` for IMU
    samples; each :meth:`update` says whether the frame starts a new segment and how many frames
    were lost just before it."""

    def __init__(self) -> None:
        self.last_seq: int | None = None
        self.last_t_us: int | None = None  # of the last IMU sample in the current segment
        self.resets = 0
        self.lost_frames = 0

    def update(self, seq: int, t_us: int | None = None) -> tuple[bool, int]:
        """One frame (``t_us`` given for an IMU sample) -> (starts a new segment, frames lost)."""
        reset = False
        gap = 0
        if self.last_seq is not None:
            d = int(seq_step(self.last_seq, seq))
            if seq_went_back(d):
                reset = True
                self.last_t_us = None
            else:
                gap = d - 1
        if t_us is not None:
            if self.last_t_us is not None and t_us_went_back(t_us_step(self.last_t_us, t_us)):
                reset = True
            self.last_t_us = t_us
        self.last_seq = seq
        if reset:
            self.resets += 1
            return True, 0
        self.lost_frames += gap
        return False, gap


def segments(
    seq: np.ndarray, imu_idx: np.ndarray, t_us: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The rules over whole arrays (twin of :class:`SegmentTracker`).

    ``seq``: every frame's seq in order; ``imu_idx``: the indices of the IMU samples among them;
    ``t_us``: those samples' device times. Returns per frame: starts a new segment (bool), and
    the frames lost just before it (0 where it starts a segment).
    """
    seq = np.asarray(seq, dtype=np.int64)
    t_us = np.asarray(t_us, dtype=np.int64)
    m = seq.size
    gaps = np.zeros(m, dtype=np.int64)
    if m == 0:
        return np.zeros(m, dtype=bool), gaps
    d = seq_step(seq[:-1], seq[1:])
    reset = np.zeros(m, dtype=bool)  # a seq going back first
    reset[1:] = seq_went_back(d)
    seq_back = bool(reset.any())  # none (the usual case): one sequence, no masks needed
    gaps[1:] = np.where(reset[1:], 0, d - 1) if seq_back else d - 1
    any_reset = seq_back
    if imu_idx.size > 1:
        # an IMU sample's time going back, compared with the previous IMU sample of the same
        # sequence segment (a seq reset forgets the previous time, as the tracker does)
        t_back = np.asarray(t_us_went_back(t_us_step(t_us[:-1], t_us[1:])))
        if seq_back:
            segs = np.cumsum(reset)
            t_back &= segs[imu_idx[1:]] == segs[imu_idx[:-1]]
        if t_back.any():
            reset[imu_idx[1:][t_back]] = True
            any_reset = True
    if any_reset:
        gaps[reset] = 0
    return reset, gaps


def repeated(samples: np.ndarray) -> np.ndarray:
    """Which IMU samples (a structured array with ``seq``, ``t_us``, the counts and ``flags``)
    repeat an earlier one of the same array exactly — the same ``seq``, ``t_us``, every count
    and flags: a capture's read written twice, never a new sample (a reset restarts ``seq``
    and ``t_us``, not the sensor's noise). The first of each is not marked."""
    if samples.size < 2:
        return np.zeros(samples.size, dtype=bool)
    names = [n for n in ("seq", "t_us", "ax", "ay", "az", "temp", "gx", "gy", "gz", "flags")
             if samples.dtype.names and n in samples.dtype.names]  # fmt: skip
    key = np.empty(samples.size, dtype=[(n, samples.dtype[n]) for n in names])
    for n in names:  # (packed: a view of the fields would hold the others' bytes too)
        key[n] = samples[n]
    _, first = np.unique(key.view(np.dtype((np.void, key.dtype.itemsize))), return_index=True)
    out = np.ones(samples.size, dtype=bool)
    out[first] = False
    return out


def repeated_text(n: int) -> str:
    """The line naming ``n`` samples :func:`repeated` found (each was kept once)."""
    return (
        f"{n} sample(s) repeat an earlier one exactly (seq, t_us and every count): a read of "
        "the capture written twice; each is kept once"
    )
