"""Stress and back-pressure: the real firmware at its highest claimed rates, and beyond them.

Claims (firmware/README.md, "Rates"): 1 kHz output (SMPLRT_DIV 0, DLPF 1-6) over a 1 Mbaud
build, and 200 Hz over the default 115200 baud, with no sample lost or duplicated. Above what
the UART can carry, samples are dropped whole and counted in STATUS.dropped: every frame that
does go out is intact and the sequence numbers have no gaps (a dropped sample takes none).
"""

from __future__ import annotations

import numpy as np
import pytest
from emu_helpers import collect, of_type, seq_gaps

from host.bench.build import build_firmware
from host.bench.emulator import EmulatedBoard
from host.bench.stimulus import write_stimulus
from host.wire.frames import Frame, encode_frame

pytestmark = pytest.mark.emulator

JITTER_US = 16  # interrupt latency, as in test_emu_firmware
#: the stimulus (at rest, Z up) is first written up to this emulated time, s: the emulator
#: waits there until the host has sent SET_RATE (after HELLO, ≈ 0.4 s), so the rate changes
#: by this emulated instant however slow the host is (without the gate the emulator ran on
#: while the host answered HELLO: the change landed 0.38–0.64 s in, later under load, and
#: 4.5 s at the new rate need it before 1.5 s)
GATE_S = 1.0


def at_rest(pipe, t: np.ndarray, header: bool) -> None:
    """Stimulus records at rest, Z up, 25 °C (the emulator's default without a stimulus)."""
    n = len(t)
    write_stimulus(pipe, t, np.tile([0.0, 0.0, 9.80665], (n, 1)), np.zeros((n, 3)), 25.0,
                   header=header)  # fmt: skip


def run_at_rate(emu_bin, tmp_path, baud: int, smplrt_div: int, seconds: float) -> list[Frame]:
    """Boot the firmware built for ``baud``, switch it to 1 kHz / (1 + div) at the emulated
    instant :data:`GATE_S`, collect frames until ``seconds``."""
    elf = build_firmware(tmp_path / f"fw{baud}", [f"BAUD={baud}"])
    t = np.arange(0.0, seconds + 0.5, 0.01)
    sent = False

    board = EmulatedBoard(elf, emulator=emu_bin, seconds=seconds, stimulus="pipe",
                          workdir=tmp_path)  # fmt: skip
    with board:
        pipe = board.stimulus_pipe
        assert pipe is not None
        at_rest(pipe, t[t <= GATE_S], header=True)

        def on_frames(ser, frames: list[Frame]) -> None:
            nonlocal sent
            if not sent and of_type(frames, "HELLO"):
                ser.write(encode_frame("SET_RATE", 1, smplrt_div=smplrt_div, dlpf_cfg=1))
                ser.flush()  # in the pty before the emulated time goes on past GATE_S
                sent = True
                at_rest(pipe, t[t > GATE_S], header=False)
                pipe.close()

        frames = collect(board, max_wall_s=120, on_frames=on_frames)
    assert [a.fields["status"] for a in of_type(frames, "ACK")] == [0], "SET_RATE refused"
    assert board.summary is not None and board.summary["stop_reason"] == "seconds reached"
    return frames


def after_rate_change(frames: list[Frame]) -> list[Frame]:
    samples = of_type(frames, "IMU_SAMPLE")
    first = next(i for i, f in enumerate(samples) if f.fields["flags"] & 4)  # CONFIG_CHANGED
    return samples[first:]


@pytest.mark.slow
@pytest.mark.parametrize(("baud", "div"), [(1_000_000, 0), (115_200, 4)])
def test_highest_claimed_rate_loses_and_duplicates_nothing(emu_bin, tmp_path, baud, div):
    period_us = 1000 * (1 + div)
    frames = run_at_rate(emu_bin, tmp_path, baud, div, seconds=6.0)
    samples = after_rate_change(frames)
    t = np.array([f.fields["t_us"] for f in samples], dtype=np.int64)
    # the change by the gate however slow the host (the emulator reads the stimulus at the
    # chip's samples: it stops at the first 50 Hz sample after the gate, ≤ 20 ms past it)
    assert t[0] <= GATE_S * 1e6 + 20_000 + 5 * period_us, t[0]
    assert len(samples) >= 4.5e6 / period_us  # at least 4.5 s of samples at the new rate
    assert not seq_gaps(frames)
    assert np.all(np.abs(np.diff(t) - period_us) <= JITTER_US), (np.diff(t).min(), np.diff(t).max())
    status = of_type(frames, "STATUS")[-1].fields
    assert status["dropped"] == 0 and status["missed"] == 0, status
    assert all(f.fields["flags"] & 1 == 0 for f in samples)  # no MISSED flag either


@pytest.mark.slow
def test_back_pressure_drops_whole_samples_and_counts_them(emu_bin, tmp_path):
    """1 kHz over 115200 baud: the UART carries ~40 % of it."""
    frames = run_at_rate(emu_bin, tmp_path, 115_200, 0, seconds=6.0)
    samples = after_rate_change(frames)
    assert not seq_gaps(frames)  # what was sent is complete and in order (the decoder checked
    # every CRC: a corrupted frame would be missing here and show as a gap)
    t = np.array([f.fields["t_us"] for f in samples], dtype=np.int64)
    steps = np.diff(t) / 1000.0
    assert np.all(np.abs(steps - np.rint(steps)) * 1000 <= JITTER_US)  # on the 1 ms grid
    skipped = int(np.sum(np.rint(steps) - 1))
    assert skipped > len(samples)  # more than half could not be sent
    # every skipped sample is accounted for: between two STATUS frames (which share the UART
    # queue with the samples, so stream order is time order), the samples missing from the
    # stream equal the growth of STATUS.dropped + STATUS.missed
    idx = [i for i, f in enumerate(frames) if f.name == "STATUS"]
    a, b = idx[-3], idx[-1]
    between = [f for f in frames[a:b] if f.name == "IMU_SAMPLE"]
    tb = np.array([f.fields["t_us"] for f in between], dtype=np.int64)
    missing = int(np.sum(np.rint(np.diff(tb) / 1000.0) - 1))
    grew = sum(frames[b].fields[k] - frames[a].fields[k] for k in ("dropped", "missed"))
    assert frames[b].fields["dropped"] > frames[a].fields["dropped"]
    # a sample read just before a STATUS can be queued or dropped just after it: edge effects
    assert abs(missing - grew) <= max(6, grew // 100), (missing, grew)
