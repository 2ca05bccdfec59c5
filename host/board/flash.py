"""Flashing (``python3 -m host flash``): build the firmware, check its hex, flash it with avrdude
through the board's stk500v2 bootloader, then check that the board says HELLO with what was just
flashed.

    python3 -m host flash                   # /dev/ttyACM0, firmware/build/imu_bench.hex
    python3 -m host flash --port /dev/ttyUSB0 --hex other.hex
    python3 -m host flash --port 'emu://?flash=/tmp/board.flash'  # the emulated board

Steps: ``make -C firmware`` (unless ``--hex``); parse the Intel hex and refuse a corrupt one (bad
record, checksum, no end record) or one that does not fit the application section (256 KiB
flash − 8 KiB bootloader = 253 952 bytes) *before* avrdude touches the board; read the firmware's
identity block (``"IMUB"``, ``firmware/src/telemetry.cpp``) from the hex; run
``avrdude -c wiring -p m2560 -P PORT -b 115200 -D -U flash:w:HEX:i`` (it verifies by reading
back); open the port again (the DTR reset: bootloader ≈ 0.8 s, then the firmware) and decode the
HELLO frame: its version must be the one in the hex and its spec fingerprint this host's
(:data:`host.wire.protocol_gen.SPEC_FINGERPRINT`). Every failure is one line (:class:`UserError`).

The port comes from its transport (:func:`host.transports.flashing.flash_port`): a serial
device as it is; ``emu://?flash=PATH`` serves an emulated board with the bootloader and a
persistent flash file (``host/transports/protocol_emu.py``) whose pseudo-terminal gets the same
avrdude command and HELLO check; the flash file then holds the new firmware for every later
``emu://?flash=PATH``.
"""

from __future__ import annotations

import os
import re
import shutil
import struct
import subprocess
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import serial

from host.bench.build import build_firmware_hex
from host.board.hello import check_spec, wait_for_hello
from host.board.link import Link, LinkLost, LinkTimeout
from host.errors import UserError
from host.transports.flashing import flash_port

DEFAULT_PORT = "/dev/ttyACM0"

FLASH_BYTES = 256 * 1024  # ATmega2560
BOOT_SECTION_BYTES = 8 * 1024  # stk500v2 bootloader, BOOTSZ = 4096 words, at 0x3E000
APP_SECTION_BYTES = FLASH_BYTES - BOOT_SECTION_BYTES  # 253 952 bytes
BOOTLOADER_BAUD = 115200  # what the Mega 2560 stk500v2 bootloader speaks

AVRDUDE = "avrdude"
PROGRAMMER = "wiring"  # stk500v2 over the USB serial port, DTR reset (as the Arduino IDE)
PART = "m2560"
AVRDUDE_TIMEOUT_S = 120.0  # 248 KiB take about a minute at 115200 baud
HELLO_TIMEOUT_S = 6.0  # bootloader ≈ 0.8 s + firmware bring-up ≈ 0.25 s, with margin

IDENTITY_MAGIC = b"IMUB"
IDENTITY = struct.Struct("<4s4BIBIH")  # firmware/src/telemetry.cpp, kIdentity (19 bytes)


# --------------------------------------------------------------------------- Intel hex


@dataclass(frozen=True)
class HexImage:
    """The data of an Intel hex file: ``segments`` maps a start byte address to its bytes
    (contiguous records merged); ``nbytes`` is the number of data bytes, ``end`` one past the
    highest address (bytes)."""

    path: Path
    segments: dict[int, bytes]

    @property
    def nbytes(self) -> int:
        return sum(len(b) for b in self.segments.values())

    @property
    def end(self) -> int:
        return max((a + len(b) for a, b in self.segments.items()), default=0)

    def to_bytes(self, fill: int = 0xFF) -> bytes:
        """The image from address 0 to :attr:`end`, gaps filled with ``fill`` (erased flash)."""
        out = bytearray([fill]) * self.end
        for addr, data in self.segments.items():
            out[addr : addr + len(data)] = data
        return bytes(out)


def _hex_text(p: Path) -> str:
    """The text of hex file ``p``; UserError when it is missing or binary."""
    try:
        return p.read_bytes().decode("ascii")
    except FileNotFoundError:
        raise UserError(f"{p}: no such hex file (build it: make -C firmware)") from None
    except UnicodeDecodeError:
        raise UserError(f"{p}: not an Intel hex file (binary data)") from None


def _hex_record(line: str, where: str) -> bytes:
    """One record's bytes (count, address, type, data, checksum), its form, byte count and
    checksum checked."""
    if not line.startswith(":") or len(line) < 11 or len(line) % 2 == 0:
        raise UserError(f"{where}: not an Intel hex record: corrupt hex")
    try:
        rec = bytes.fromhex(line[1:])
    except ValueError:
        raise UserError(f"{where}: not hexadecimal: corrupt hex") from None
    if len(rec) != rec[0] + 5:
        raise UserError(f"{where}: byte count {rec[0]} does not match the line: corrupt hex")
    if sum(rec) & 0xFF:
        want = (-sum(rec[:-1])) & 0xFF
        raise UserError(f"{where}: checksum 0x{rec[-1]:02X} should be 0x{want:02X}: corrupt hex")
    return rec


def _hex_data(p: Path, text: str) -> list[tuple[int, bytes]]:
    """(address, bytes) of every data record of hex file ``p`` (its ``text``), at the address
    its extended segment or linear address records give, up to the end-of-file record."""
    records: list[tuple[int, bytes]] = []
    base = 0
    seen_eof = False
    for lineno, raw in enumerate(text.splitlines(), 1):
        line = raw.strip()
        if not line:
            continue
        where = f"{p}: line {lineno}"
        if seen_eof:
            raise UserError(f"{where}: data after the end-of-file record: corrupt hex")
        rec = _hex_record(line, where)
        count, addr, rtype, data = rec[0], (rec[1] << 8) | rec[2], rec[3], rec[4:-1]
        if rtype == 0x00:
            if data:
                records.append((base + addr, data))
        elif rtype == 0x01:
            seen_eof = True
        elif rtype == 0x02 and count == 2:  # extended segment address (x16)
            base = int.from_bytes(data, "big") << 4
        elif rtype == 0x04 and count == 2:  # extended linear address (<< 16)
            base = int.from_bytes(data, "big") << 16
        elif rtype not in (0x03, 0x05) or count != 4:  # 03, 05 start address: not flashed
            raise UserError(f"{where}: bad record type 0x{rtype:02X}: corrupt hex")
    if not seen_eof:
        raise UserError(f"{p}: no end-of-file record (truncated?): corrupt hex")
    return records


def _segments(p: Path, records: list[tuple[int, bytes]]) -> dict[int, bytes]:
    """Start address -> bytes of each run of contiguous data; UserError where data overlap."""
    if not records:
        raise UserError(f"{p}: no data in this hex file")
    records = sorted(records)
    segments: dict[int, bytes] = {}
    start, buf = records[0][0], bytearray()
    for addr, data in records:
        if addr < start + len(buf):
            raise UserError(f"{p}: data overlaps at 0x{addr:05X}: corrupt hex")
        if addr > start + len(buf):
            segments[start] = bytes(buf)
            start, buf = addr, bytearray()
        buf += data
    segments[start] = bytes(buf)
    return segments


def parse_ihex(path: str | Path, limit: int = APP_SECTION_BYTES) -> HexImage:
    """Read and check an Intel hex file (record types 00–05) for flashing.

    Raises :class:`UserError` naming the file and line for: a line that is not a record, a
    byte count that does not match, a bad checksum, an unknown record type, overlapping data,
    no end-of-file record, no data at all, or data at or beyond ``limit`` bytes (default: the
    application section, 256 KiB flash − 8 KiB bootloader).
    """
    p = Path(path)
    image = HexImage(p, _segments(p, _hex_data(p, _hex_text(p))))
    if image.end > limit:
        raise UserError(
            f"{p}: the image reaches 0x{image.end:05X} ({image.end} bytes), more than the "
            f"{limit}-byte application section (256 KiB flash − 8 KiB bootloader): too big to flash"
        )
    return image


# --------------------------------------------------------------------------- identity block


@dataclass(frozen=True)
class FirmwareIdentity:
    """What HELLO will report about a build, read from its ``"IMUB"`` identity block."""

    major: int
    minor: int
    patch: int
    protocol_version: int
    spec_fingerprint: int
    mode: int
    baud: int  # UART0, bits/s
    timer_resolution_ns: int

    @property
    def version(self) -> str:
        return f"{self.major}.{self.minor}.{self.patch}"


def find_identity(image: HexImage | bytes) -> FirmwareIdentity | None:
    """The identity block of a firmware image, or None when it has none (not our firmware)."""
    data = image.to_bytes() if isinstance(image, HexImage) else image
    i = data.find(IDENTITY_MAGIC)
    if i < 0 or i + IDENTITY.size > len(data) or data.find(IDENTITY_MAGIC, i + 1) >= 0:
        return None
    _, *fields = IDENTITY.unpack_from(data, i)
    return FirmwareIdentity(*fields)


# --------------------------------------------------------------------------- avrdude


def avrdude_command(
    port: str, hex_path: str | Path, baud: int = BOOTLOADER_BAUD, part: str = PART
) -> list[str]:
    """The avrdude command line (also ``make -C firmware flash`` and ``pio run -t upload``)."""
    return [
        AVRDUDE, "-c", PROGRAMMER, "-p", part, "-P", port, "-b", str(baud), "-D",
        "-U", f"flash:w:{hex_path}:i",
    ]  # fmt: skip


def explain_avrdude_failure(output: str, port: str, part: str = PART) -> str:
    """One line saying what went wrong, from avrdude's output."""
    m = re.search(r"device signature = (0x[0-9a-fA-F]+)", output)
    if m and re.search(r"expected signature|signature.*(mismatch|invalid)", output, re.I):
        sig = m.group(1).lower()
        if sig in ("0x000000", "0xffffff"):
            return (
                f"the board on {port} answered with signature {sig}: no chip behind the "
                "bootloader? Check the board and cable"
            )
        return (
            f"wrong board on {port}: device signature {sig} is not an {part} "
            "(ATmega2560 = 0x1e9801); check the port, or that this is an APM 2.x"
        )
    if re.search(r"verif\w* (error|mismatch)|content mismatch", output, re.I):
        m = re.search(r"first mismatch at byte (0x[0-9a-fA-F]+)", output)
        at = f" at byte {m.group(1)}" if m else ""
        return (
            f"verify failed{at}: the flash of the board on {port} does not hold what was "
            "written; flash again, and if it persists the chip or bootloader is damaged"
        )
    if re.search(r"can(no|')t open (port|device)|ser_open", output, re.I):
        return f"cannot open {port}: check the USB cable and the port name"
    if re.search(r"timeout|not responding|getsync|unable to open programmer", output, re.I):
        return (
            f"no bootloader answered on {port}: the board did not reset into its stk500v2 "
            "bootloader (another program holding the port? wrong port?)"
        )
    lines = [ln.strip() for ln in output.splitlines() if "error" in ln.lower()]
    last = lines[-1] if lines else (output.strip().splitlines() or ["no output"])[-1]
    return f"avrdude failed on {port}: {last}"


def run_avrdude(
    port: str,
    hex_path: str | Path,
    baud: int = BOOTLOADER_BAUD,
    part: str = PART,
    timeout_s: float = AVRDUDE_TIMEOUT_S,
) -> float:
    """Write and verify ``hex_path`` with avrdude; return the time it took (wall seconds).

    Raises :class:`UserError` for a missing avrdude, a port that does not exist, a wrong board
    (signature), no bootloader answering, a verify mismatch or a timeout.
    """
    if shutil.which(AVRDUDE) is None:
        raise UserError("avrdude not found: apt-get install avrdude")
    if port.startswith("/") and not os.path.exists(port):
        # (avrdude 7.1 spins forever with -c wiring on a port it cannot open)
        raise UserError(
            f"no port {port}: is the board plugged in? (python3 -m serial.tools.list_ports)"
        )
    cmd = avrdude_command(port, hex_path, baud, part)
    t0 = time.monotonic()
    try:
        r = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout_s)
    except subprocess.TimeoutExpired:
        raise UserError(f"avrdude did not finish within {timeout_s:.0f} s on {port}") from None
    took = time.monotonic() - t0
    output = r.stdout + r.stderr
    ok = r.returncode == 0 and re.search(r"bytes of flash verified", output) is not None
    if not ok:
        raise UserError(explain_avrdude_failure(output, port, part))
    return took


# --------------------------------------------------------------------------- HELLO


def read_hello(port: str, baud: int, timeout_s: float = HELLO_TIMEOUT_S) -> dict[str, int]:
    """Open ``port`` (a serial device or pty; the open resets the board), decode frames until
    a HELLO arrives and return its fields; UserError after ``timeout_s`` wall seconds."""
    try:
        ser = serial.Serial(port, baud, timeout=0.05)
    except (serial.SerialException, OSError) as exc:
        raise UserError(f"cannot open {port} after flashing: {exc}") from None
    link = Link(ser, stall_s=timeout_s)
    try:
        return wait_for_hello(link, timeout_s, ask_after_s=None)[1].fields
    except LinkLost as exc:
        raise UserError(f"{port} vanished while waiting for HELLO: {exc}") from None
    except LinkTimeout:
        seen = link.stats.frames
    finally:
        ser.close()
    what = f"{seen} other frames" if seen else "no frames"
    raise UserError(
        f"the firmware did not say HELLO within {timeout_s:.0f} s after flashing ({what} at "
        f"{baud} baud): it does not start, or it is not this project's firmware"
    )


def check_hello(hello: dict[str, int], expected: FirmwareIdentity | None) -> str:
    """Compare HELLO with the flashed build; return its version, UserError on a mismatch."""
    version = f"{hello['fw_major']}.{hello['fw_minor']}.{hello['fw_patch']}"
    fp = hello["spec_fingerprint"]
    if expected is not None and version != expected.version:
        raise UserError(
            f"the board says firmware {version} after flashing {expected.version}: "
            "the new firmware is not running"
        )
    check_spec(
        fp,
        who="the firmware",
        remedy="rebuild the firmware (make -C firmware) or update the host",
        protocol_version=hello["protocol_version"],
    )
    return version


# --------------------------------------------------------------------------- the command


@dataclass(frozen=True)
class FlashResult:
    """What :func:`flash` did: the hex, its identity, how long avrdude took (s), HELLO."""

    hex_path: Path
    nbytes: int
    identity: FirmwareIdentity | None
    flash_s: float
    hello_s: float
    hello: dict[str, int]
    emulator_summary: dict[str, Any] | None = None


def prepare_hex(hex_path: str | Path | None = None) -> tuple[Path, HexImage]:
    """Build the firmware if no hex is given, then parse and check the hex (UserError)."""
    path = Path(hex_path) if hex_path else build_firmware_hex()
    image = parse_ihex(path)
    identity = find_identity(image)
    if identity is not None:
        check_spec(
            identity.spec_fingerprint,
            who=str(path),
            remedy="rebuild it (make -C firmware) before flashing",
            protocol_version=identity.protocol_version,
        )
    return path, image


def flash(
    port: str = DEFAULT_PORT,
    hex_path: str | Path | None = None,
    baud: int = BOOTLOADER_BAUD,
    *,
    part: str = PART,
    hello_timeout_s: float = HELLO_TIMEOUT_S,
    log: Callable[[str], None] | None = print,
) -> FlashResult:
    """Build (unless ``hex_path``), check, flash, verify, and check HELLO; see the module doc.

    ``port``: a serial device, or ``emu://?flash=PATH[&...]`` (an emulated board with the
    bootloader, its flash kept in PATH). ``baud``: the bootloader's (115200 on the Mega 2560);
    HELLO is read at the firmware's own baud from its identity block. ``log`` gets progress
    lines (None: quiet).
    """
    say = log or (lambda _msg: None)
    path, image = prepare_hex(hex_path)  # before anything touches the board
    identity = find_identity(image)
    what = f"firmware {identity.version}" if identity else "an image without identity block"
    say(f"flashing {path} ({image.nbytes} bytes, {what}) to {port}")
    app_baud = identity.baud if identity else BOOTLOADER_BAUD
    if shutil.which(AVRDUDE) is None:  # before a transport starts anything
        raise UserError("avrdude not found: apt-get install avrdude")
    with flash_port(port) as target:
        took = run_avrdude(target.device, path, baud, part)
        say(f"written and verified in {took:.2f} s")
        t0 = time.monotonic()
        hello = read_hello(target.device, app_baud, hello_timeout_s)
        hello_s = time.monotonic() - t0
    return _finish(path, image, identity, took, hello_s, hello, target.summary, say)


def _finish(
    path: Path,
    image: HexImage,
    identity: FirmwareIdentity | None,
    took: float,
    hello_s: float,
    hello: dict[str, int],
    summary: dict[str, Any] | None,
    say: Callable[[str], None],
) -> FlashResult:
    version = check_hello(hello, identity)
    say(
        f"HELLO after {hello_s:.2f} s: firmware {version}, spec 0x{hello['spec_fingerprint']:08X}"
        f", {hello['baud']} baud, sensor 0x{hello['who_am_i']:02X} — flash OK in {took:.2f} s"
    )
    return FlashResult(path, image.nbytes, identity, took, hello_s, hello, summary)
