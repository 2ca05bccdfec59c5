"""Device-to-host time mapping: the minimum-delay estimator, live and on its own, and the
counters' unwrap, against a simulated link with known true sample times."""

from __future__ import annotations

import numpy as np
import pytest

from host.bench.linksim import LinkParams, simulate_link
from host.timing import clock
from host.wire import stream
from tests.host.timing.test_timeline import rms_after_offset


def test_unwrap_uses_host_time_for_gaps_longer_than_the_counter() -> None:
    period = 2**32  # µs: one wrap is 71.6 min
    dev = np.array([100, 200, 300 + 2 * period + 50], dtype=np.int64)  # two wraps in the gap
    host = np.array([0, 100_000, (300 + 2 * period + 50 - 100) * 1000], dtype=np.float64)
    assert unwrap_wire(dev, host).tolist() == dev.tolist()
    # without host time the gap is read as less than one wrap
    assert clock.unwrap(dev % 2**32, 32)[-1] == 300 + 50


def unwrap_wire(dev: np.ndarray, host: np.ndarray) -> np.ndarray:
    return clock.unwrap(dev % 2**32, 32, host, 1e-3)


def test_live_estimate_is_usable_early_and_accurate_after_ten_seconds() -> None:
    lc = simulate_link(LinkParams(seconds=40, seed=8))
    dec = stream.StreamDecoder()
    live = clock.LiveClock()
    serial_ns = float(clock.serialisation_ns(27, lc.params.baud))
    mapped = np.full(lc.true_host_ns.size, np.nan)
    k = 0
    first_estimate_at = None
    for t_ns, chunk in lc.chunks:
        for f in dec.feed(chunk):
            if f.type != 1:
                continue
            live.add(lc.device_us[k], t_ns - serial_ns)
            m = live.to_host_ns(lc.device_us[k])
            if m is not None:
                mapped[k] = float(m)
                first_estimate_at = first_estimate_at or k
            k += 1
    t_s = (lc.true_host_ns - lc.true_host_ns[0]) / 1e9
    assert first_estimate_at is not None and t_s[first_estimate_at] < 3.0
    after = t_s > 10
    assert rms_after_offset((mapped - lc.true_host_ns)[after]) < 200_000


def test_min_delay_fit_is_exact_on_noise_free_points_and_ignores_late_ones() -> None:
    x = np.arange(0, 10_000_000, 20_000, dtype=float)  # µs
    y = 7e9 + 999.95 * x  # ns: a clock 50 ppm fast
    late = y + np.where(np.arange(x.size) % 3 == 0, 0.0, 3e6)  # most points 3 ms late
    m = clock.fit_min_delay(x, late)
    assert m.skew_ppm == pytest.approx(-50, abs=1e-6)
    assert np.max(np.abs(m.to_host_ns(x) - y)) < 1.0
