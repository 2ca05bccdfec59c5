"""``noise`` streams its capture (issue 31): decoded once into a temporary file of samples and
read back in small blocks, with the phases on disk, it gives what the whole capture held in
memory gives (decode_file, the longest segment, the counter unwrapped, recording.analyse), to
rounding — across a reset, a wrap of the device's 32-bit µs counter, a gap and a temperature
drift that is removed. The duration is the samples', not the span across the gap."""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np
import pytest

from host.bench.noise import capture_bytes
from host.cli.noise_source import CaptureSamples, FilePhases
from host.model import allan, recording
from host.timing import clock
from host.wire.bulk import decode_file, full_scale_from_hello, samples_to_physical
from host.wire.capture import MAGIC

RATE = 50.0


def static(rng: np.random.Generator, t_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """White noise at rest (z up) with ax following a temperature that climbs 10 °C."""
    n = t_s.size
    temp = 25.0 + 10.0 * (t_s - t_s[0]) / (t_s[-1] - t_s[0])
    x = rng.normal(0.0, [0.02, 0.02, 0.02, 0.05, 0.05, 0.05], (n, 6))
    x[:, 2] += 9.80665
    x[:, 0] += 0.004 * (temp - 25.0)
    return x, temp


def write_capture(path: Path) -> tuple[int, float]:
    """A first run of 30 s, a reset, then 10 min, a 10-minute gap and 10 min more, whose
    device clock wraps (2^32 µs) in the first part; samples and seconds of the long run."""
    rng = np.random.default_rng(5)
    t_a = np.arange(int(30 * RATE)) / RATE + 100.0
    first = capture_bytes(t_a, *static(rng, t_a))
    t0 = 2**32 / 1e6 - 200.0  # the counter wraps 200 s in
    part = np.arange(int(600 * RATE)) / RATE
    t_b = np.concatenate([part, part + 1200.0]) + t0
    second = capture_bytes(t_b, *static(rng, t_b))
    # the second run's host times after the first's
    shift = int(t_a[-1] * 1e9) + 10**9 - int(t_b[0] * 1e9)
    out, pos = bytearray(first), len(MAGIC)
    while pos < len(second):
        t, n = struct.unpack_from("<QI", second, pos)
        out += struct.pack("<QI", t + shift, n) + second[pos + 12 : pos + 12 + n]
        pos += 12 + n
    path.write_bytes(bytes(out))
    return t_b.size, 1200.0


def in_memory(path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """What ``noise`` read before it streamed: the whole capture's arrays (times s, channels,
    temperature)."""
    result, _ = decode_file(path)
    s = result.samples
    ids, counts = np.unique(s["segment"], return_counts=True)
    s = s[s["segment"] == ids[int(np.argmax(counts))]]
    phys = samples_to_physical(s, *full_scale_from_hello(result.others))
    t = clock.unwrap(np.asarray(s["t_us"], dtype=np.int64), 32).astype(np.float64) / 1e6
    return t, np.column_stack([phys[c] for c in allan.CHANNELS]), phys["temp"]


@pytest.mark.slow
def test_streamed_noise_equals_the_whole_capture_to_rounding(tmp_path: Path) -> None:
    path = tmp_path / "static.cap"
    n, seconds = write_capture(path)
    work = tmp_path / "work"
    work.mkdir()
    samples = CaptureSamples(path, work, block=4099)  # blocks that do not divide anything
    assert samples.size == n and "longest of 2 segments" in samples.note
    t, data, temp = in_memory(path)
    blocks = list(samples.blocks())
    assert np.array_equal(np.concatenate([b[0] for b in blocks]), t)  # the wrap, unwrapped
    assert np.array_equal(np.concatenate([b[1] for b in blocks]), data)
    streamed = recording.analyse_blocks(samples, phases=lambda: FilePhases(work), phase_block=5003)
    whole = recording.analyse(t, data, temp)
    assert streamed.duration_s == pytest.approx(seconds, rel=1e-4)  # not 30 min: 20
    assert streamed.duration_s == pytest.approx(whole.duration_s, rel=1e-12)
    assert streamed.rate_hz == pytest.approx(RATE, rel=1e-4)
    assert any("gaps in the sample times" in w for w in streamed.warnings)
    assert streamed.thermal["ax"].significant and whole.thermal["ax"].significant
    assert streamed.span_c == pytest.approx(whole.span_c, rel=1e-12)
    for name in allan.CHANNELS:
        a, b = streamed.channels[name], whole.channels[name]
        assert a.curve.tau_s.size > 20
        np.testing.assert_allclose(a.curve.adev, b.curve.adev, rtol=1e-9)
        np.testing.assert_allclose(a.coef, b.coef, rtol=1e-6, atol=1e-12 * np.max(b.coef))
        assert streamed.thermal[name].coefficient == pytest.approx(
            whole.thermal[name].coefficient, rel=1e-9, abs=1e-12
        )
    # the drift of ax was taken out: its random walk is not inflated
    assert streamed.channels["ax"].curve.adev[-1] < 3 * streamed.channels["ay"].curve.adev[-1]


def test_the_phase_files_are_removed_with_the_store(tmp_path: Path) -> None:
    store = FilePhases(tmp_path)
    store.append(np.arange(5.0))
    store.append(np.arange(5.0, 9.0))
    assert store.window(3, 7).tolist() == [3.0, 4.0, 5.0, 6.0]
    del store
    assert list(tmp_path.iterdir()) == []


def test_no_room_for_the_temporary_files_is_one_line(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """A full disk where the capture is streamed through: one line naming the place and the
    fix, exit 2, no traceback."""
    from host.__main__ import main

    path = tmp_path / "static.cap"
    write_capture(path)

    def full(self: FilePhases, values: np.ndarray) -> None:
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(FilePhases, "append", full)
    rc = main(["noise", str(path)])
    err = capsys.readouterr().err
    assert rc == 2 and "Traceback" not in err
    assert "No space left on device" in err and "TMPDIR" in err
    assert len([line for line in err.splitlines() if line.startswith("error:")]) == 1
