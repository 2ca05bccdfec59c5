"""A simulator of the serial link, for testing the clock mapping against known truth.

It models what stands between the MPU-6000's data-ready pulse and the host's ``read()``:

- the sample clock (the MPU's own oscillator, not exactly 50 Hz) and the AVR's timer, which
  stamps each sample: device µs = AVR clock (skew ±100 ppm plus a slow drift) quantised to
  the timer resolution, plus interrupt latency;
- the UART: a frame is queued a little after data-ready and sent at the baud rate (8N1),
  after any frame still being sent (STATUS frames share the line);
- the USB bridge (ATmega16U2/FTDI): bytes wait until its flush timer fires (≈4.096 ms) or 64
  bytes are buffered, then go in the next 1 ms USB frame;
- the OS: a read returns some jitter later, rarely after a spike of 2–30 ms; bytes that arrive
  meanwhile come back in the same read (chunked arrivals).

The output is an IMUCAP01 capture (``chunks``) and the true host time of each sample's
data-ready event, so a test can measure how well the mapping recovers it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from host.wire.frames import crc16, encode_frame, encode_imu_samples


@dataclass(frozen=True)
class LinkParams:
    """Parameters of the simulated link; defaults are a typical APM 2.6 on a PC."""

    seconds: float = 60.0
    sample_hz: float = 50.0
    sample_clock_error: float = 0.004  # MPU oscillator: +0.4 % fast
    skew_ppm: float = 60.0  # AVR clock rate error
    drift_ppm_per_min: float = 0.5  # slow skew change (temperature)
    device_t0_us: int = 0  # device time at the first sample (near 2**32 to test wrap)
    timer_resolution_us: float = 0.5
    isr_latency_us: tuple[float, float] = (14.0, 30.0)  # uniform range
    processing_us: float = 180.0  # SPI read + framing before the UART starts
    baud: int = 115200
    flush_ms: float = 4.096
    usb_frame_ms: float = 1.0
    os_jitter_us: float = 120.0  # mean of an exponential
    spike_prob: float = 0.004  # per read
    spike_ms: tuple[float, float] = (2.0, 30.0)
    host_t0_ns: int = 5_000_000_000
    status_every_s: float = 1.0
    seq0: int = 0  # first frame's seq (near 65535 to test wrap)
    seed: int = 0


@dataclass(frozen=True)
class LinkCapture:
    """What the host would have recorded, and the truth behind it."""

    chunks: list[tuple[int, bytes]]  # (host ns right after read() returned, bytes)
    true_host_ns: np.ndarray  # (N,) host time of each sample's data-ready event
    device_us: np.ndarray  # (N,) device time stamped (unwrapped)
    params: LinkParams

    def to_imucap(self) -> bytes:
        import struct

        from host.wire.capture import MAGIC

        return MAGIC + b"".join(struct.pack("<QI", t, len(b)) + b for t, b in self.chunks)


def _sample_times(
    p: LinkParams, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(true time of each data-ready s since start, its ISR latency µs, the device time it is
    stamped with µs): the device clock runs at rate 1 + skew(t), the skew drifting linearly,
    read at the timer's resolution."""
    period_s = 1.0 / (p.sample_hz * (1.0 + p.sample_clock_error))
    n = int(p.seconds / period_s)
    t = 0.05 + np.arange(n) * period_s  # true time of data-ready, s since start
    skew = p.skew_ppm * 1e-6
    drift = p.drift_ppm_per_min * 1e-6 / 60.0
    dev_exact = (t + skew * t + 0.5 * drift * t**2) * 1e6
    latency = rng.uniform(*p.isr_latency_us, n)
    res = p.timer_resolution_us
    device_us = p.device_t0_us + np.floor((dev_exact + latency) / res) * res
    return t, latency, device_us


def _frame_events(
    p: LinkParams, t: np.ndarray, latency: np.ndarray, device_us: np.ndarray
) -> list[tuple[float, bytes]]:
    """(time the frame is ready to send s, its bytes) of every IMU sample, and a STATUS frame
    every ``p.status_every_s``."""
    n = t.size
    counts = np.tile([120, -340, 16390, -2400, 37, -55, 12], (n, 1))
    t_wire = (device_us.astype(np.int64)) % (1 << 32)
    imu = encode_imu_samples(0, t_wire, counts)
    events: list[tuple[float, bytes]] = []
    next_status = p.status_every_s
    seq = p.seq0
    for k in range(n):
        ready = t[k] + (latency[k] + p.processing_us) * 1e-6
        frame = bytearray(imu[27 * k : 27 * k + 27])
        frame[4:6] = (seq & 0xFFFF).to_bytes(2, "little")
        seq += 1
        frame[-2:] = crc16(bytes(frame[2:-2])).to_bytes(2, "little")
        events.append((ready, bytes(frame)))
        if t[k] >= next_status:
            st = encode_frame(
                "STATUS", seq & 0xFFFF, uptime_ms=int(t[k] * 1000), samples=k, missed=0, dropped=0,
                crc_errors=0, spi_faults=0, fifo_overflows=0, tx_queue_max=2, bad_bursts=0, flags=0,
            )  # fmt: skip
            seq += 1
            events.append((ready + 1e-4, st))
            next_status += p.status_every_s
    return events


def _uart(events: list[tuple[float, bytes]], baud: int) -> tuple[np.ndarray, bytearray]:
    """The UART: bytes leave one after another; (the time each byte is fully received by the
    bridge s, all the bytes)."""
    byte_s = 10.0 / baud
    byte_times: list[np.ndarray] = []
    payload = bytearray()
    line_free = 0.0
    for ready, frame_bytes in events:
        start = max(ready, line_free)
        byte_times.append(start + byte_s * (1 + np.arange(len(frame_bytes))))
        line_free = start + byte_s * len(frame_bytes)
        payload += frame_bytes
    return np.concatenate(byte_times), payload


def _host_reads(
    p: LinkParams, rng: np.random.Generator, bt: np.ndarray, payload: bytearray
) -> list[tuple[int, bytes]]:
    """(host ns, bytes) of each read: the bridge flushes at timer ticks (random phase), each
    flush goes out at the next USB frame; the OS makes each USB delivery readable after
    jitter, and a read returns everything readable at that moment (spikes delay one read and
    everything behind it)."""
    phase = rng.uniform(0, p.flush_ms * 1e-3)
    flush_at = np.ceil((bt - phase) / (p.flush_ms * 1e-3)) * (p.flush_ms * 1e-3) + phase
    usb = np.ceil(flush_at / (p.usb_frame_ms * 1e-3)) * (p.usb_frame_ms * 1e-3)
    deliveries, idx = np.unique(usb, return_index=True)
    ready_at = deliveries + rng.exponential(p.os_jitter_us * 1e-6, deliveries.size)
    spikes = rng.random(deliveries.size) < p.spike_prob
    ready_at[spikes] += rng.uniform(*p.spike_ms, int(spikes.sum())) * 1e-3
    ready_at = np.maximum.accumulate(ready_at)  # bytes are read in order
    chunks: list[tuple[int, bytes]] = []
    bounds = np.concatenate((idx, [bt.size]))
    i = 0
    while i < deliveries.size:
        j = i
        while j + 1 < deliveries.size and ready_at[j + 1] <= ready_at[i] + 20e-6:
            j += 1  # delivered while the previous read was being served: same read
        data = bytes(payload[bounds[i] : bounds[j + 1]])
        chunks.append((p.host_t0_ns + int(round(ready_at[j] * 1e9)), data))
        i = j + 1
    return chunks


def simulate_link(p: LinkParams) -> LinkCapture:
    """Simulate ``p.seconds`` of streaming; deterministic from ``p.seed``."""
    rng = np.random.default_rng(p.seed)
    t, latency, device_us = _sample_times(p, rng)
    bt, payload = _uart(_frame_events(p, t, latency, device_us), p.baud)
    chunks = _host_reads(p, rng, bt, payload)
    true_host = p.host_t0_ns + t * 1e9
    return LinkCapture(chunks, true_host, device_us, p)
