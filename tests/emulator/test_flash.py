"""``python3 -m host flash`` against the emulated board booting like the real one: Debian's
stk500v2 bootloader at 0x3E000, the application in a persistent flash file, avrdude through the
emulator's pty (``emu://?flash=PATH``)."""

from __future__ import annotations

import configparser
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pytest

from host.bench.build import build_firmware, build_firmware_hex
from host.bench.emulator import EmulatedBoard
from host.board import flash as fl
from host.board.link import open_port
from host.errors import UserError
from host.wire.protocol_gen import SPEC_FINGERPRINT
from host.wire.stream import StreamDecoder

pytestmark = pytest.mark.emulator

ROOT = Path(__file__).resolve().parents[2]
BOOTLOADER = Path(
    "/usr/share/arduino/hardware/arduino/avr/bootloaders/stk500v2/stk500boot_v2_mega2560.hex"
)
OLD_VERSION = "0.0.9"


@pytest.fixture(scope="module")
def flash_tools(emu_toolchain) -> None:
    if shutil.which("avrdude") is None:
        pytest.skip("flashing needs avrdude: apt-get install avrdude")
    if not BOOTLOADER.exists():
        pytest.skip("the emulated bootloader needs arduino-core-avr (stk500v2 hex)")


@pytest.fixture(scope="module")
def old_elf(flash_tools, tmp_path_factory) -> Path:
    return build_firmware(tmp_path_factory.mktemp("fw-old"), [f"FW_VERSION={OLD_VERSION}"])


@pytest.fixture(scope="module")
def current_hex(flash_tools) -> Path:
    return build_firmware_hex()  # what `python3 -m host flash` builds and flashes


@pytest.fixture(scope="module")
def old_flash(emu_bin, old_elf, tmp_path_factory) -> Path:
    """A board's flash image: the bootloader and the OLD application."""
    path = tmp_path_factory.mktemp("board") / "old.flash"
    board = EmulatedBoard(old_elf, emulator=emu_bin, flash=path)
    board.start()
    board.stop()
    assert path.stat().st_size == fl.FLASH_BYTES
    return path


@pytest.fixture
def board_flash(old_flash, tmp_path) -> Path:
    """A private copy of the old board, for tests that flash it."""
    path = tmp_path / "board.flash"
    shutil.copyfile(old_flash, path)
    return path


def hello_version(flash_file: Path, timeout_s: float = 10.0) -> str:
    """Power the emulated board up from its flash file, return the version its HELLO reports."""
    port = open_port(f"emu://?flash={flash_file}")
    dec = StreamDecoder()
    deadline = time.monotonic() + timeout_s
    try:
        while time.monotonic() < deadline:
            for f in dec.feed(port.read(port.in_waiting or 1)):
                if f.name == "HELLO":
                    h = f.fields
                    return f"{h['fw_major']}.{h['fw_minor']}.{h['fw_patch']}"
    finally:
        port.close()
    raise AssertionError("no HELLO from the emulated board")


def run_cli(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "host", "flash", *args],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=120,
    )


def assert_one_line_error(r: subprocess.CompletedProcess[str], *words: str) -> str:
    assert r.returncode == 2, r.stdout + r.stderr
    assert "Traceback" not in r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), r.stderr
    for w in words:
        assert w in lines[0], lines[0]
    return lines[0]


# --------------------------------------------------------------------------- the acceptance


@pytest.mark.slow
def test_flash_new_firmware_over_old_then_stream(board_flash, current_hex) -> None:
    new = fl.find_identity(fl.parse_ihex(current_hex))
    assert new is not None and new.version != OLD_VERSION
    assert hello_version(board_flash) == OLD_VERSION

    r = run_cli("--port", f"emu://?flash={board_flash}")
    print(r.stdout)
    assert r.returncode == 0, r.stdout + r.stderr
    assert f"firmware {new.version}, spec 0x{SPEC_FINGERPRINT:08X}" in r.stdout
    assert "written and verified in" in r.stdout and "flash OK in" in r.stdout
    took = float(r.stdout.split("written and verified in ")[1].split(" s")[0])
    assert took < 10.0, "a ~5 KB firmware flashes in about a second"

    # the flash persisted: power the board up again and take two seconds of samples
    port = open_port(f"emu://?flash={board_flash}")
    dec = StreamDecoder()
    hello, samples = None, []
    deadline = time.monotonic() + 20
    try:
        while time.monotonic() < deadline and len(samples) < 101:
            for f in dec.feed(port.read(port.in_waiting or 1)):
                if f.name == "HELLO":
                    hello = f.fields
                elif f.name == "IMU_SAMPLE":
                    samples.append(f)
    finally:
        port.close()
    assert hello is not None
    assert (hello["fw_major"], hello["fw_minor"], hello["fw_patch"]) == (
        new.major, new.minor, new.patch,
    )  # fmt: skip
    assert hello["spec_fingerprint"] == SPEC_FINGERPRINT and hello["who_am_i"] == 0x68
    assert len(samples) >= 101, "two seconds of samples at 50 Hz"
    assert dec.stats.lost_frames == 0 and dec.stats.crc_errors == 0 and dec.stats.resets == 0
    t = [s.fields["t_us"] for s in samples]
    assert all(abs((b - a) - 20_000) <= 50 for a, b in zip(t, t[1:], strict=False)), "no gaps"
    assert all(s.fields["flags"] == 0 for s in samples)
    az = [s.fields["az"] for s in samples]
    assert all(abs(a - 16384) < 1600 for a in az), "at rest, Z up: about +1 g (16384 counts)"


@pytest.mark.parametrize("damage", ["checksum", "oversized"])
@pytest.mark.slow
def test_bad_hex_is_refused_and_the_old_firmware_keeps_running(
    damage, old_flash, current_hex, tmp_path
) -> None:
    before = old_flash.read_bytes()
    bad = tmp_path / f"{damage}.hex"
    lines = current_hex.read_text().splitlines()
    if damage == "checksum":
        i = len(lines) // 2
        lines[i] = lines[i][:-2] + f"{(int(lines[i][-2:], 16) + 1) & 0xFF:02X}"
        bad.write_text("\n".join(lines) + "\n")
        words: tuple[str, ...] = (str(bad), f"line {i + 1}", "checksum", "corrupt hex")
    else:  # the firmware plus 240 KB of padding: into the bootloader's section
        bad.write_text("\n".join(lines[:-1] + padding(0x2000, 0x3E800) + [lines[-1]]) + "\n")
        words = (str(bad), "0x3E800", "application section", "too big")
    t0 = time.monotonic()
    r = run_cli("--port", f"emu://?flash={old_flash}", "--hex", str(bad))
    msg = assert_one_line_error(r, *words)
    print(f"{msg} ({time.monotonic() - t0:.2f} s)")
    assert old_flash.read_bytes() == before
    assert hello_version(old_flash) == OLD_VERSION


def fl_record(addr: int, data: bytes, rtype: int = 0) -> str:
    rec = bytes([len(data), (addr >> 8) & 0xFF, addr & 0xFF, rtype]) + data
    return ":" + (rec + bytes([(-sum(rec)) & 0xFF])).hex().upper()


def padding(start: int, end: int) -> list[str]:
    """Hex records of zeros from ``start`` to ``end`` (bytes), with extended linear addresses."""
    out, page = [], -1
    for a in range(start, end, 32):
        if a >> 16 != page:
            page = a >> 16
            out.append(fl_record(0, page.to_bytes(2, "big"), rtype=4))
        out.append(fl_record(a & 0xFFFF, bytes(32)))
    return out


# --------------------------------------------------------------------------- other failures


@pytest.mark.slow
def test_wrong_board_is_named(board_flash, current_hex) -> None:
    before = board_flash.read_bytes()
    with pytest.raises(UserError, match=r"wrong board on .*signature 0x1e9801 is not an m1280"):
        fl.flash(f"emu://?flash={board_flash}", current_hex, part="m1280", log=None)
    assert board_flash.read_bytes() == before


@pytest.mark.slow
def test_firmware_that_does_not_say_hello(board_flash, tmp_path) -> None:
    src = tmp_path / "mute.c"
    src.write_text("int main(void) { for (;;) {} }\n")
    elf, hexf = tmp_path / "mute.elf", tmp_path / "mute.hex"
    subprocess.run(["avr-gcc", "-mmcu=atmega2560", "-Os", "-o", str(elf), str(src)], check=True)
    subprocess.run(["avr-objcopy", "-O", "ihex", str(elf), str(hexf)], check=True)
    with pytest.raises(UserError, match=r"did not say HELLO within 2 s after flashing"):
        fl.flash(f"emu://?flash={board_flash}", hexf, hello_timeout_s=2.0, log=None)


def test_avrdude_missing_and_no_port(current_hex, monkeypatch) -> None:
    with pytest.raises(UserError, match=r"no port /dev/ttyNOSUCH"):
        fl.flash("/dev/ttyNOSUCH", current_hex, log=None)
    monkeypatch.setattr(fl, "AVRDUDE", "avrdude-not-installed")
    with pytest.raises(UserError, match=r"^avrdude not found: apt-get install avrdude$"):
        fl.flash("/dev/ttyACM0", current_hex, log=None)


def test_emu_flash_needs_a_flash_file(current_hex) -> None:
    with pytest.raises(UserError, match=r"emu://\?flash=PATH"):
        fl.flash("emu://", current_hex, log=None)


def test_avrdude_messages() -> None:
    verify = (
        "avrdude: verifying flash memory against x.hex\n"
        "avrdude error: verification mismatch\n        device 0xff != input 0x0c at addr 0x0000"
        " (error)\navrdude error: verification mismatch\n"
    )
    assert fl.explain_avrdude_failure(verify, "/dev/ttyACM0").startswith("verify failed")
    legacy = "avrdude: verification error, first mismatch at byte 0x0040\n         0xff != 0x0c\n"
    assert "at byte 0x0040" in fl.explain_avrdude_failure(legacy, "P")
    timeout = "avrdude error: timeout communicating with programmer\n"
    assert fl.explain_avrdude_failure(timeout, "P").startswith("no bootloader answered on P")


# --------------------------------------------------------------------------- hex checks


def test_hex_parser(current_hex, tmp_path) -> None:
    image = fl.parse_ihex(current_hex)
    ident = fl.find_identity(image)
    assert ident is not None and ident.spec_fingerprint == SPEC_FINGERPRINT
    assert ident.baud == 115200 and 1000 < image.nbytes < 64 * 1024
    binary = tmp_path / "fw.bin"
    elf = current_hex.with_suffix(".elf")
    subprocess.run(["avr-objcopy", "-O", "binary", "-R", ".eeprom", str(elf), str(binary)],
                   check=True)  # fmt: skip
    assert image.to_bytes() == binary.read_bytes()
    # the bootloader itself sits above the application section (segment records, type 03)
    with pytest.raises(UserError, match="application section"):
        fl.parse_ihex(BOOTLOADER)
    boot = fl.parse_ihex(BOOTLOADER, limit=fl.FLASH_BYTES)
    assert min(boot.segments) == fl.APP_SECTION_BYTES == 0x3E000
    eof = ":00000001FF"
    for lines, why in [
        ([":0400000001020304", eof], "byte count 4 does not match"),
        (["garbage", eof], "line 1: not an Intel hex record"),
        ([fl_record(0, b"\x01\x02")], "no end-of-file record"),
        ([fl_record(0, b"\x01"), fl_record(0, b"\x02"), eof], "overlaps at 0x00000"),
        ([fl_record(0, b"\x01"), fl_record(0, b"\x01", rtype=7), eof], "line 2: bad record"),
        ([eof], "no data"),
        ([eof, fl_record(0, b"\x01")], "after the end-of-file record"),
    ]:
        p = tmp_path / "t.hex"
        p.write_text("\n".join(lines) + "\n")
        with pytest.raises(UserError, match=why):
            fl.parse_ihex(p)
    with pytest.raises(UserError, match="no such hex file"):
        fl.parse_ihex(tmp_path / "missing.hex")


def test_same_avrdude_settings_everywhere() -> None:
    """The Makefile's flash target and platformio.ini's upload: host.board.flash's avrdude line."""
    cmd = fl.avrdude_command("/dev/ttyXX", "HEX")
    assert cmd[1:] == ["-c", "wiring", "-p", "m2560", "-P", "/dev/ttyXX", "-b", "115200", "-D",
                       "-U", "flash:w:HEX:i"]  # fmt: skip
    r = subprocess.run(["make", "-s", "-n", "-C", str(ROOT / "firmware"), "flash",
                        "PORT=/dev/ttyXX"], capture_output=True, text=True)  # fmt: skip
    line = [ln for ln in r.stdout.splitlines() if ln.startswith("avrdude ")][-1]
    assert line.split() == fl.avrdude_command("/dev/ttyXX", "build/imu_bench.hex")
    ini = configparser.ConfigParser()
    ini.read(ROOT / "platformio.ini")
    env = ini["env:apm"]
    assert env["board"] == "megaatmega2560" and env["board_build.mcu"] == "atmega2560"
    assert env["upload_protocol"] == "wiring" and env["upload_speed"] == "115200"
    assert env["upload_flags"].split() == ["-D"]
