"""Sensor identity and a sane bus (issue 13, item 4), on the real firmware and the emulated chip.

- The firmware reads PRODUCT_ID and reports it in HELLO; a rev C4/C5 part counts half the
  accelerometer LSB/g, and the host's scale (host/wire/sensor.py) follows the identity.
- Every sensor burst is checked (INT_STATUS data-ready, not 14 equal bytes): on a marginal bus
  (``--fault marginal-bus``: above 1 MHz every byte read arrives one bit late) the garbled read
  is dropped, the next sample is flagged MISSED, the firmware reads at 1 MHz from then on and
  says so in STATUS.flags (the host's side: tests/host/wire/test_sensor_identity.py).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from emu_helpers import collect, of_type, sample_counts

from host.bench.emulator import EmulatedBoard
from host.bench.stimulus import write_stimulus
from host.board.driver import Board
from host.wire import sensor
from host.wire.frames import SPI_LOW_CLOCK, bus_meta

pytestmark = pytest.mark.emulator

INT_STATUS = 0x3A
MISSED = 1  # sample_flags
#: at rest, a different value on every axis (m/s², °/s, chip axes)
F = np.array([1.1, -2.2, 9.3])
W = np.array([11.0, -22.0, 33.0])


def _stimulus(path: Path, seconds: float) -> Path:
    write_stimulus(path, [0.0, seconds + 1.0], [F, F], [W, W], 31.5)
    return path


@pytest.mark.timeout(120)  # two short emulator runs
@pytest.mark.parametrize("product_id", [0x55, 0x5A], ids=["rev_C5", "rev_D10"])
def test_hello_reports_the_chips_revision_and_the_host_scales_by_it(
    emu_bin: Path, fw_elf: Path, tmp_path: Path, product_id: int
) -> None:
    stim = _stimulus(tmp_path / "stim.bin", 1.5)
    board = EmulatedBoard(fw_elf, emulator=emu_bin, stimulus=stim, seconds=1.5,
                          product_id=product_id, workdir=tmp_path)  # fmt: skip
    with board:
        frames = collect(board, max_wall_s=60)
    hello = of_type(frames, "HELLO")[0].fields
    assert hello["product_id"] == product_id
    counts = sample_counts(frames)
    assert len(counts) > 40
    lsb_per_g = 16384.0 / (2.0 if product_id == 0x55 else 1.0)  # C5: half the sensitivity
    np.testing.assert_allclose(counts[:, 0:3].mean(axis=0), F * lsb_per_g / sensor.G0, atol=0.51)
    # the host's scale, from HELLO's identity, gives the physical value back (within 1 LSB)
    a = sensor.accel_mps2(counts[:, 0:3], hello["accel_fs_sel"], hello["product_id"])
    np.testing.assert_allclose(a.mean(axis=0), F, atol=sensor.G0 / lsb_per_g)


@pytest.mark.timeout(120)  # one short emulator run
def test_marginal_bus_drops_the_garbled_read_and_carries_on_at_1_mhz(
    emu_bin: Path, fw_elf: Path, tmp_path: Path
) -> None:
    stim = _stimulus(tmp_path / "stim.bin", 2.5)
    board = EmulatedBoard(fw_elf, emulator=emu_bin, stimulus=stim, seconds=2.5, samplelog=True,
                          reglog=True, fault="marginal-bus", workdir=tmp_path)  # fmt: skip
    with board:
        frames = collect(board, max_wall_s=60)
    s = board.summary
    assert s is not None and s["garbled_bytes"] > 0
    log = board.samplelog()
    garbled = log[log["read"] == 2]
    intact = log[log["read"] == 1]
    assert len(garbled) == 1  # the first read at 8 MHz; then 1 MHz
    samples = of_type(frames, "IMU_SAMPLE")
    got = sample_counts(frames)
    want = np.stack([intact[k] for k in ("ax", "ay", "az", "temp", "gx", "gy", "gz")], axis=1)
    assert len(got) >= 0.8 * 2.2 * 50
    np.testing.assert_array_equal(got, want[: len(got)])  # nothing garbled reached the host
    # the sample after the dropped one says a sample is missing
    t_dev = np.array([f.fields["t_us"] for f in samples], dtype=np.int64)
    first_after = int(np.searchsorted(intact["t_us"], garbled["t_us"][0]))
    assert samples[first_after].fields["flags"] & MISSED
    assert t_dev[first_after] - t_dev[first_after - 1] > 30_000 if first_after else True
    assert not any(f.fields["flags"] & MISSED for f in samples[first_after + 1 :])
    # STATUS tells: the low clock, one bad burst
    status = of_type(frames, "STATUS")[-1].fields
    assert status["flags"] & SPI_LOW_CLOCK and status["bad_bursts"] == 1
    # and it is true: every sensor burst after the bad one is clocked at 1 MHz
    bursts = [a for a in board.reglog() if a.op == "R" and a.reg == INT_STATUS]
    assert bursts[0].spi_hz == 8e6 and all(a.spi_hz <= 1e6 for a in bursts[1:])


@pytest.mark.timeout(120)  # one emulator run through the board driver the dialogue uses
def test_live_board_scales_a_rev_c4_part_and_shows_the_low_clock(tmp_path: Path) -> None:
    warnings: list[str] = []
    board = Board("emu://?stimulus=rest&revision=C4&fault=marginal-bus", warn=warnings.append)
    info = board.connect()
    try:
        assert info.product_id == 0x54 and info.accel_range_g == 4
        assert "rev C4" in info.describe()
        meta = info.meta()
        assert (meta["product_id"], meta["sensor_revision"]) == ("0x54", "C4")
        acq = board.acquire(1.5)
        a, _, _ = board.physical(acq.counts)
    finally:
        assert board.link is not None
        board.link.port.close()
    # at rest, Z up: 1 g on z with half the counts (8192 LSB/g), the host's scale follows
    assert abs(np.median(acq.counts[:, 2]) - 8192) <= 1
    np.testing.assert_allclose(a.mean(axis=0), [0.0, 0.0, sensor.G0], atol=2e-3)
    shown = [w for w in warnings if "marginal" in w]
    assert len(shown) == 1 and "1 MHz" in shown[0], warnings
    # and the records made from it say so in their header (host/dialogue/measurement.py: bus_meta)
    assert acq.status_flags is not None and acq.status_flags & SPI_LOW_CLOCK
    assert bus_meta(acq.status_flags)["sensor_spi_clock"].startswith("1 MHz (SPI_LOW_CLOCK")
