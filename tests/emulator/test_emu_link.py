"""The emulated board through host.board.link: the committed raw capture
``tests/captures/emu_clean.bin`` is what the real firmware sends (the device clock over a
minute: ``test_emu_clock.py``).

``emu_clean.bin``: 10 s of the raw bytes the real firmware sends through ``emu://`` for the
stimulus of :func:`clean_stimulus` (a different, slowly varying value on every axis). The
emulator is deterministic (cycle-exact AVR, the CPU held until the pty is opened, nothing sent
to the board, a stimulus *file*), so re-recording gives the same samples. Re-write it after a
firmware change with ``python -m tests.emulator.test_emu_link`` (from the checkout).
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pytest
import serial

from host.bench.stimulus import write_stimulus
from host.board.link import open_port
from host.wire.bulk import decode_bulk
from host.wire.frames import IMU_FIELDS

ROOT = Path(__file__).resolve().parents[2]
FIXTURE = ROOT / "tests" / "captures" / "emu_clean.bin"
CLEAN_SECONDS = 10.0


def clean_stimulus(path: Path) -> Path:
    """The stimulus of emu_clean.bin: 100 records/s over 10.5 s; specific force (m/s²) and
    rate (°/s) different on every axis, each slowly varying, die temperature 28.5 °C + 0.2 °C/s."""
    t = np.arange(0.0, CLEAN_SECONDS + 0.5, 0.01)
    two_pi = 2.0 * np.pi
    f = np.column_stack([
        1.234 + 0.5 * np.sin(two_pi * 0.3 * t),
        -2.345 + 0.4 * np.cos(two_pi * 0.2 * t),
        9.123 - 0.3 * np.sin(two_pi * 0.1 * t),
    ])  # fmt: skip
    w = np.column_stack([
        12.5 + 5.0 * np.sin(two_pi * 0.5 * t),
        -23.75 + 3.0 * np.cos(two_pi * 0.7 * t),
        37.125 + 4.0 * np.sin(two_pi * 0.25 * t),
    ])  # fmt: skip
    write_stimulus(path, t, f, w, 28.5 + 0.2 * t)
    return path


def record_clean(stimulus: Path, elf: Path | None = None) -> bytes:
    """Every byte the firmware sends through ``emu://`` for ``stimulus`` in 10 emulated s."""
    url = f"emu://?stimulus={stimulus}&seconds={CLEAN_SECONDS:g}"
    if elf is not None:
        url += f"&elf={elf}"
    port = open_port(url)
    data = bytearray()
    deadline = time.monotonic() + 60.0
    try:
        while time.monotonic() < deadline:
            try:
                chunk = port.read(port.in_waiting or 1)
            except (serial.SerialException, OSError):  # hung up (see emu_helpers.collect)
                break
            data += chunk
            if not chunk and not port.board.running:
                break
    finally:
        port.close()
    return bytes(data)


def _samples(data: bytes) -> np.ndarray:
    r = decode_bulk(data)
    assert r.stats.crc_errors == 0 and r.stats.bytes_discarded == 0
    return r.samples


# --------------------------------------------------------------------------- the fixture


@pytest.mark.emulator
def test_emu_clean_fixture_is_what_the_firmware_sends(
    emu_toolchain: None, fw_elf: Path, tmp_path: Path
) -> None:
    """Re-record emu_clean.bin: the decoded samples (seq, device time, counts) are the same."""
    fixture = FIXTURE.read_bytes()
    assert len(fixture) < 40_000
    want = _samples(fixture)
    got_bytes = record_clean(clean_stimulus(tmp_path / "clean.stim"), fw_elf)
    got = _samples(got_bytes)
    assert got.size == want.size and 0.95 * CLEAN_SECONDS * 50 < got.size <= CLEAN_SECONDS * 50
    for name in ("seq", "t_us", "flags", *IMU_FIELDS):
        np.testing.assert_array_equal(got[name], want[name], err_msg=name)
    # a different value on every axis (a swapped axis shows), and they vary
    first = [int(want[n][0]) for n in IMU_FIELDS]
    assert len(set(first)) == len(first)
    assert all(np.ptp(want[n]) > 0 for n in IMU_FIELDS)
    same = "bit-identical" if got_bytes == fixture else "the same samples, other bytes differ"
    print(f"\nemu_clean.bin: {len(fixture)} bytes, {want.size} samples; re-recorded: {same}")


if __name__ == "__main__":  # re-write the fixture
    import tempfile

    with tempfile.TemporaryDirectory() as d:
        raw = record_clean(clean_stimulus(Path(d) / "clean.stim"))
    FIXTURE.write_bytes(raw)
    print(f"{FIXTURE}: {len(raw)} bytes, {_samples(raw).size} samples")
