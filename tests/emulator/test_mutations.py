"""Mutation suite: realistic single mistakes in ``firmware/src``, each caught by a named rule.

Every mutant is one mistake a developer could make (a wrong SPI mode, a forgotten wait, a
swapped axis...), applied to a copy of the firmware source, built with the real Makefile and run
on the emulated board for :data:`RUN_S` emulated seconds. The run is judged only by *rules*,
never by a recorded capture:

- the MPU-6000 model's and the board's hardware rules (``summary["rules"]``, each with its
  datasheet page: ``firmware/emulator/README.md``, *Hardware rules*);
- six stream rules that hold for any correct firmware, whatever its timing:
  ``CALIBRATION_MODE`` (the chip ends up at ±2 g, ±250 °/s, DLPF 20 Hz, 50 Hz: the calibration
  mode of ``firmware/README.md``), ``STREAMING`` (a healthy chip gives samples),
  ``FRAMES_MATCH_CHIP`` (every IMU_SAMPLE carries exactly the counts of a sample the chip
  produced and the firmware burst-read intact, in order: ``--samplelog``), ``SAMPLE_PERIOD``
  (device time steps equal the chip's sample-clock steps within interrupt latency),
  ``SENSOR_IDENTITY`` (HELLO reports the PRODUCT_ID the chip has: the runs use a rev C5 part,
  0x55, whose accelerometer counts half the LSB/g), ``BUS_FLAG`` (STATUS.flags says
  SPI_LOW_CLOCK exactly when the bus garbled a sensor read) and ``SAMPLE_INSTANT`` (a sample's
  time stamp is the instant the chip made it, within the data-ready latency: the device clock
  starts with the emulated CPU; the DLPF's delay back to the physical instant is checked in
  test_emu_dlpf.py).

A mutant with ``bus="marginal-bus"`` runs on a marginal SPI bus (``--fault marginal-bus``: above
1 MHz every byte read arrives one bit late): the firmware's burst check must drop the garbled
read and carry on at 1 MHz.

Each test asserts that the named rule catches its mutant; the unmutated firmware breaks none.
The score (caught / total) is in docs/boards.md and checked by :func:`test_docs_state_the_score`.
"""

from __future__ import annotations

import re
import shutil
import subprocess
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
from emu_helpers import collect, of_type, sample_counts

from host.bench.emulator import EmulatedBoard
from host.bench.stimulus import write_stimulus

ROOT = Path(__file__).resolve().parents[2]
FIRMWARE = ROOT / "firmware"
RUN_S = 1.5  # emulated: bring-up (~0.25 s) + ~60 samples
TIMESTAMP_TOL_US = 16  # interrupt latency (as in test_emu_firmware)
#: time stamp - the chip's production instant: data-ready latency (~15 µs) minus the device
#: clock's origin (the timer starts a few µs after the emulated CPU)
INSTANT_RANGE_US = (-500, 1000)
PRODUCT_ID = 0x55  # rev C5: not the emulator's default (a hard-coded or unread id shows)
SPI_LOW_CLOCK = 1  # STATUS.flags (protocol/spec.json status_flags)
# a per-test limit with room for a loaded machine: one build (~2 s) + one run (~1 s) normally
MUTANT_TIMEOUT_S = 120

pytestmark = pytest.mark.emulator


@dataclass(frozen=True)
class Mutant:
    name: str
    rule: str  # the rule that must catch it
    edits: tuple[tuple[str, str, str], ...]  # (file under firmware/src, old text, new text)
    bus: str | None = None  # an emulator bus fault to run with


MUTANTS = (
    Mutant("spi_mode_1", "SPI_MODE",
           (("spi.cpp", "_BV(MSTR) | _BV(CPOL) | _BV(CPHA)", "_BV(MSTR) | _BV(CPHA)"),)),
    Mutant("spi_lsb_first", "SPI_BIT_ORDER",
           (("spi.cpp", "_BV(MSTR) | _BV(CPOL)", "_BV(MSTR) | _BV(DORD) | _BV(CPOL)"),)),
    Mutant("config_registers_at_8mhz", "SPI_CLOCK",
           (("mpu6000.cpp", "void write_reg(Register reg, uint8_t value) {\n"
             "    spi::begin(spi::Speed::kRegisters);",
             "void write_reg(Register reg, uint8_t value) {\n"
             "    spi::begin(spi::Speed::kSensor);"),)),
    Mutant("baro_cs_not_driven_high", "BARO_CS",
           (("spi.cpp", "    BOARD_BARO_CS_PORT |= _BV(BOARD_BARO_CS_BIT);\n", ""),)),
    Mutant("no_wait_after_device_reset", "RESET_WAIT",
           (("mpu6000.cpp", "kResetWaitUs = 100000UL", "kResetWaitUs = 1000UL"),)),
    Mutant("signal_path_reset_left_out", "SIGNAL_PATH_RESET",
           (("mpu6000.cpp",
             "write_reg(Register::SIGNAL_PATH_RESET, GYRO_RESET | ACCEL_RESET | TEMP_RESET);",
             ""),)),
    Mutant("no_wait_after_signal_path_reset", "SIGNAL_PATH_WAIT",
           (("mpu6000.cpp", "kSignalPathWaitUs = 100000UL", "kSignalPathWaitUs = 1000UL"),)),
    Mutant("no_gyro_startup_wait", "GYRO_STARTUP",
           (("mpu6000.cpp", "kGyroStartUs = 30000UL", "kGyroStartUs = 1000UL"),)),
    Mutant("i2c_if_dis_never_set", "I2C_IF_DIS",
           (("mpu6000.cpp", "{Register::USER_CTRL, I2C_IF_DIS},", "{Register::USER_CTRL, 0},"),
            ("mpu6000.cpp", "write_reg(Register::USER_CTRL, I2C_IF_DIS);",
             "write_reg(Register::USER_CTRL, 0);"))),
    Mutant("data_ready_on_falling_edge", "DRDY_EDGE",
           (("mpu6000.cpp", "| _BV(ISC61) | _BV(ISC60));", "| _BV(ISC61));"),)),
    Mutant("wrong_accel_full_scale", "CALIBRATION_MODE",
           (("mpu6000.cpp", "kCfgAccel = AFS_SEL_2G;", "kCfgAccel = AFS_SEL_2G | 0x08;"),)),
    Mutant("wrong_gyro_full_scale", "CALIBRATION_MODE",
           (("mpu6000.cpp", "kCfgGyro = FS_SEL_250_DPS;", "kCfgGyro = FS_SEL_250_DPS | 0x18;"),)),
    Mutant("wrong_dlpf_setting", "CALIBRATION_MODE",
           (("mpu6000.cpp", "kCfgDlpf = DLPF_CFG_20HZ;", "kCfgDlpf = DLPF_CFG_20HZ - 1;"),)),
    Mutant("wrong_sample_rate_divider", "CALIBRATION_MODE",
           (("mpu6000.cpp", "kDefaultSmplrtDiv = 19", "kDefaultSmplrtDiv = 9"),)),
    Mutant("wrong_chip_select_pin", "STREAMING",
           (("board.hpp", "#define BOARD_MPU_CS_BIT PB0", "#define BOARD_MPU_CS_BIT PB4"),)),
    Mutant("axes_x_y_swapped", "FRAMES_MATCH_CHIP",
           (("frame.cpp", "be16(raw + 0), be16(raw + 2)", "be16(raw + 2), be16(raw + 0)"),)),
    Mutant("counts_byte_order", "FRAMES_MATCH_CHIP",
           (("frame.cpp", "static_cast<uint16_t>(p[0]) << 8 | p[1]",
             "static_cast<uint16_t>(p[1]) << 8 | p[0]"),)),
    Mutant("t_us_byte_order", "SAMPLE_PERIOD",
           (("mpu6000.cpp", "out->t_us = g_drdy_t_us;",
             "out->t_us = __builtin_bswap32(g_drdy_t_us);"),)),
    Mutant("no_power_on_wait", "POWER_ON",
           (("mpu6000.cpp", "kPowerOnWaitUs = 100000UL", "kPowerOnWaitUs = 0UL"),)),
    Mutant("timestamp_of_previous_data_ready", "SAMPLE_INSTANT",
           (("mpu6000.cpp", "    g_drdy_t_us = t;\n",
             "    static uint32_t s_prev = 0;\n    g_drdy_t_us = s_prev;\n    s_prev = t;\n"),)),
    Mutant("product_id_not_read", "SENSOR_IDENTITY",
           (("mpu6000.cpp", "g_product_id = read_reg(Register::PRODUCT_ID);", ""),)),
    Mutant("product_id_assumed_rev_d8", "SENSOR_IDENTITY",
           (("mpu6000.cpp", "out->product_id = g_product_id;", "out->product_id = 0x58;"),)),
    Mutant("no_burst_check", "FRAMES_MATCH_CHIP",
           (("mpu6000.cpp", "if (!(burst[0] & DATA_RDY_INT) || same) {",
             "if (false && (!(burst[0] & DATA_RDY_INT) || same)) {"),), bus="marginal-bus"),
    Mutant("burst_check_ignores_int_status", "FRAMES_MATCH_CHIP",
           (("mpu6000.cpp", "if (!(burst[0] & DATA_RDY_INT) || same) {", "if (same) {"),),
           bus="marginal-bus"),
    Mutant("no_low_clock_fallback", "STREAMING",
           (("mpu6000.cpp", "        g_burst_speed = spi::Speed::kRegisters;\n", ""),),
           bus="marginal-bus"),
    Mutant("low_clock_flag_not_reported", "BUS_FLAG",
           (("telemetry.cpp", "mpu6000::bus_flags());", "0);"),), bus="marginal-bus"),
)  # fmt: skip


def mutate(dst: Path, mutant: Mutant | None) -> Path:
    """Copy ``firmware/`` (sources and Makefile) to ``dst`` and apply the mutant's edits (each
    old text must occur exactly once, so a refactoring that moves it fails loudly here)."""
    shutil.copytree(FIRMWARE / "src", dst / "src")
    shutil.copy2(FIRMWARE / "Makefile", dst / "Makefile")
    for file, old, new in mutant.edits if mutant else ():
        path = dst / "src" / file
        text = path.read_text()
        assert text.count(old) == 1, f"{mutant.name}: {old!r} not exactly once in {file}"
        path.write_text(text.replace(old, new))
    return dst


def build(src: Path) -> Path:
    r = subprocess.run(["make", "--no-print-directory", "-C", str(src), f"BUILD={src / 'build'}"],
                       capture_output=True, text=True)  # fmt: skip
    assert r.returncode == 0, (r.stdout + r.stderr)[-2000:]
    return src / "build" / "imu_bench.elf"


def stimulus(path: Path) -> Path:
    """At rest with a different value on every axis, every byte of every count different from
    its neighbour's (a swapped axis or byte order shows)."""
    f = np.array([1.1, -2.2, 9.3])  # m/s², chip axes
    w = np.array([11.0, -22.0, 33.0])  # °/s
    write_stimulus(path, [0.0, RUN_S + 1.0], [f, f], [w, w], 31.5)
    return path


def judge(emu_bin: Path, elf: Path, workdir: Path, bus: str | None = None) -> dict[str, str]:
    """Run ``elf`` for RUN_S emulated seconds (on a rev C5 part, with the bus fault ``bus``);
    the broken rules, name -> what happened."""
    workdir.mkdir(parents=True, exist_ok=True)
    board = EmulatedBoard(elf, emulator=emu_bin, stimulus=stimulus(workdir / "stim.bin"),
                          seconds=RUN_S, samplelog=True, workdir=workdir, product_id=PRODUCT_ID,
                          fault=bus)  # fmt: skip
    with board:
        frames = collect(board, max_wall_s=MUTANT_TIMEOUT_S)
    s = board.summary
    assert s is not None and s["product_id"] == PRODUCT_ID
    broken = {line.split(" ", 1)[0]: line for line in s["rules_broken"]}
    hello = of_type(frames, "HELLO")
    if not hello or hello[0].fields["product_id"] != PRODUCT_ID:
        got = [f"{h.fields['product_id']:#04x}" for h in hello]
        broken["SENSOR_IDENTITY"] = f"HELLO product_id {got}, the chip's {PRODUCT_ID:#04x}"
    status = of_type(frames, "STATUS")
    low = bool(status) and bool(status[-1].fields["flags"] & SPI_LOW_CLOCK)
    if status and low != (s["garbled_bytes"] > 0):
        broken["BUS_FLAG"] = (
            f"STATUS flags {status[-1].fields['flags']}, bad_bursts "
            f"{status[-1].fields['bad_bursts']}; the bus garbled {s['garbled_bytes']} bytes"
        )
    regs = s["regs"]
    mode = (regs["ACCEL_CONFIG"] & 0x18, regs["GYRO_CONFIG"] & 0x18, regs["CONFIG"] & 7,
            regs["SMPLRT_DIV"])  # fmt: skip
    if mode != (0, 0, 4, 19):
        broken["CALIBRATION_MODE"] = f"AFS_SEL, FS_SEL, DLPF_CFG, SMPLRT_DIV = {mode}"
    log = board.samplelog()
    read = log[log["read"] == 1]
    got = sample_counts(frames)
    samples = of_type(frames, "IMU_SAMPLE")
    if len(samples) < 0.5 * (RUN_S - 0.3) * 50:
        broken["STREAMING"] = f"{len(samples)} samples in {RUN_S} s from a healthy chip"
    if not samples:
        return broken
    want = np.stack([read[k] for k in ("ax", "ay", "az", "temp", "gx", "gy", "gz")], axis=1)
    if len(got) > len(want) or not np.array_equal(got, want[: len(got)]):
        chip = want[0].tolist() if len(want) else "no sample read intact"
        broken["FRAMES_MATCH_CHIP"] = f"first frame {got[0].tolist()}, chip {chip}"
    t_dev = np.array([f.fields["t_us"] for f in samples], dtype=np.int64)
    t_chip = read["t_us"][: len(samples)]
    if len(t_chip) == len(t_dev) and np.ptp(t_dev - t_chip) > TIMESTAMP_TOL_US:
        broken["SAMPLE_PERIOD"] = f"device time - chip time spreads {np.ptp(t_dev - t_chip)} µs"
    if len(t_chip) == len(t_dev):
        offset = float(np.median(t_dev - t_chip))
        if not INSTANT_RANGE_US[0] <= offset <= INSTANT_RANGE_US[1]:
            broken["SAMPLE_INSTANT"] = f"time stamps {offset:.0f} µs off the chip's sample instants"
    return broken


@pytest.mark.slow
@pytest.mark.timeout(MUTANT_TIMEOUT_S)  # one build and two short runs, even on a busy machine
def test_unmutated_firmware_breaks_no_rule(emu_bin, emu_toolchain, tmp_path):
    elf = build(mutate(tmp_path / "fw", None))
    assert judge(emu_bin, elf, tmp_path / "clean") == {}
    # a marginal bus: the garbled first read is dropped, the rest read intact at 1 MHz
    assert judge(emu_bin, elf, tmp_path / "marginal", bus="marginal-bus") == {}


@pytest.mark.slow
@pytest.mark.timeout(MUTANT_TIMEOUT_S)  # one build and one short run, even on a busy machine
@pytest.mark.parametrize("mutant", MUTANTS, ids=[m.name for m in MUTANTS])
def test_mutant_is_caught_by_its_rule(emu_bin, emu_toolchain, tmp_path, mutant):
    elf = build(mutate(tmp_path / "fw", mutant))
    broken = judge(emu_bin, elf, tmp_path, mutant.bus)
    assert mutant.rule in broken, f"{mutant.name} not caught by {mutant.rule}; broken: {broken}"
    print(f"\n{mutant.name}: {broken[mutant.rule]}")


def test_docs_state_the_score():
    """docs/boards.md reports caught / total; every test above passing means all are caught."""
    text = (ROOT / "docs" / "boards.md").read_text()
    m = re.search(r"mutation score: \*\*(\d+) / (\d+)\*\*", text)
    assert m, "docs/boards.md has no 'mutation score: **N / N**' line"
    assert (int(m.group(1)), int(m.group(2))) == (len(MUTANTS), len(MUTANTS))
