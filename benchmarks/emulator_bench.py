"""Emulator speed and firmware CPU load on the emulated APM 2.6.

    python3 benchmarks/emulator_bench.py [--seconds 60] [--elf FW.elf] [--make-arg BAUD=500000]
                                         [--profile] [--compare-fixed-spi]

Runs the real firmware (built with ``make -C firmware`` unless ``--elf``) as fast as possible
while this script reads the port, and prints: simulated seconds per wall second, the CPU cycles
the firmware spends awake per sample against the 320 000 cycles of a 20 ms period at 16 MHz,
and the latency from the data-ready edge to the end of the sensor burst read. ``--profile``
adds the functions that use the most awake cycles; ``--compare-fixed-spi`` reruns with simavr's
stock 100 us per SPI byte to show what the SPI timing fix changes.
"""

from __future__ import annotations

import argparse
import bisect
import collections
import subprocess
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import serial  # noqa: E402

from host.bench.build import build_emulator, build_firmware  # noqa: E402
from host.bench.emulator import EmulatedBoard  # noqa: E402
from host.errors import UserError  # noqa: E402

PERIOD_CYCLES = 320_000  # 20 ms at 16 MHz


def run(elf: Path, emu: Path, seconds: float, extra: list[str]) -> dict:
    with tempfile.TemporaryDirectory() as tmp:
        with EmulatedBoard(elf, emulator=emu, seconds=seconds, workdir=tmp, extra_args=extra) as b:
            assert b.port
            ser = serial.Serial(b.port, 115200, timeout=0.05)
            nbytes = 0
            while True:
                try:
                    chunk = ser.read(ser.in_waiting or 1)
                except serial.SerialException:
                    break
                nbytes += len(chunk)
                if not chunk and not b.running:
                    break
            ser.close()
        s = dict(b.summary or {})
        s["host_bytes"] = nbytes
        return s


def top_functions(elf: Path, profile_csv: Path, n: int = 12) -> list[tuple[int, str]]:
    nm = subprocess.run(["avr-nm", "-n", "-C", str(elf)], capture_output=True, text=True).stdout
    syms = []
    for line in nm.splitlines():
        p = line.split(None, 2)
        if len(p) == 3 and p[1] in "tTwW":
            syms.append((int(p[0], 16), p[2]))
    addrs = [a for a, _ in syms]
    tot: collections.Counter[str] = collections.Counter()
    for line in profile_csv.read_text().splitlines()[1:]:
        a, c = line.split(",")
        i = bisect.bisect_right(addrs, int(a, 16)) - 1
        tot[syms[i][1] if i >= 0 else "?"] += int(c)
    return [(v, k) for k, v in tot.most_common(n)]


def report(title: str, s: dict) -> None:
    per = s["steady_busy_cycles_per_sample"]
    print(f"== {title}")
    print(
        f"  simulated {s['sim_seconds']:.1f} s in {s['wall_seconds']:.2f} s wall: "
        f"{s['speed']:.1f}x real time"
    )
    print(
        f"  samples produced {s['samples_produced']}, read {s['samples_read']}, "
        f"SPI violations {s['spi_violations']}, bus conflicts {s['bus_conflicts']}"
    )
    print(
        f"  firmware awake {per:,.0f} CPU cycles per sample vs {PERIOD_CYCLES:,} per 20 ms "
        f"period = {100 * per / PERIOD_CYCLES:.2f} % CPU"
    )
    print(
        f"  data-ready edge -> end of the 14-byte burst read: "
        f"{s['drdy_to_read_cycles_mean']:.0f} cycles mean, {s['drdy_to_read_cycles_max']} max"
    )
    print(f"  UART bytes {s['uart_tx_bytes']} sent, {s['host_bytes']} received by the host")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--elf", type=Path)
    ap.add_argument("--make-arg", action="append", default=[], help="e.g. BAUD=500000")
    ap.add_argument("--profile", action="store_true")
    ap.add_argument("--compare-fixed-spi", action="store_true")
    a = ap.parse_args()
    try:
        emu = build_emulator()
        if a.elf:
            elf = a.elf
        else:
            elf = build_firmware(Path(tempfile.mkdtemp(prefix="fw_bench_")), a.make_arg)
    except UserError as exc:
        print(f"emulator_bench: {exc}", file=sys.stderr)
        return 2
    extra: list[str] = []
    prof = Path(tempfile.mkdtemp(prefix="emu_prof_")) / "profile.csv"
    if a.profile:
        extra = ["--profile", str(prof)]
    s = run(elf, emu, a.seconds, extra)
    report(f"{elf.name}, SPI at 8 x divider cycles per byte", s)
    if a.profile and prof.exists():
        print("  awake cycles by function:")
        total = s["busy_cycles"]
        for cycles, name in top_functions(elf, prof):
            per_sample = cycles / max(1, s["samples_read"])
            print(f"    {per_sample:9.0f}/sample {100 * cycles / total:5.1f} % {name}")
    if a.compare_fixed_spi:
        report(
            "same, simavr's stock 100 us per SPI byte",
            run(elf, emu, a.seconds, ["--spi-fixed-timing"]),
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
