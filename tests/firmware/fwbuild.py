"""Helpers for the firmware tests: build with the real Makefile into a temporary directory
and look inside the resulting ELF with binutils-avr."""

from __future__ import annotations

import importlib.util
import re
import struct
import subprocess
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
FIRMWARE = ROOT / "firmware"
AVR_TOOLS = ("make", "avr-g++", "avr-objcopy", "avr-size")

IDENTITY_MAGIC = b"IMUB"
IDENTITY_LEN = 19  # see firmware/src/telemetry.cpp, kIdentity


def _load_generator():
    spec = importlib.util.spec_from_file_location(
        "imu_bench_generate", ROOT / "protocol" / "generate.py"
    )
    assert spec and spec.loader
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


GENERATE = _load_generator()


def spec_fingerprint() -> int:
    """The fingerprint computed from spec.json itself (not from the generated header)."""
    return GENERATE.fingerprint(GENERATE.load_spec())


@dataclass
class Build:
    dir: Path
    result: subprocess.CompletedProcess

    @property
    def elf(self) -> Path:
        return self.dir / "imu_bench.elf"

    @property
    def hex(self) -> Path:
        return self.dir / "imu_bench.hex"

    @property
    def ok(self) -> bool:
        return self.result.returncode == 0

    @property
    def output(self) -> str:
        return self.result.stdout + self.result.stderr

    def sizes(self) -> tuple[int, int]:
        """(flash bytes, RAM bytes) from the avr-size summary the Makefile prints."""
        prog = re.search(r"Program:\s+(\d+) bytes", self.result.stdout)
        data = re.search(r"Data:\s+(\d+) bytes", self.result.stdout)
        assert prog and data, f"no avr-size summary in make output:\n{self.output}"
        return int(prog.group(1)), int(data.group(1))

    def section(self, name: str) -> bytes:
        out = self.dir / f"section{name.replace('.', '_')}.bin"
        subprocess.run(
            ["avr-objcopy", "-O", "binary", "-j", name, str(self.elf), str(out)],
            check=True,
            capture_output=True,
        )
        return out.read_bytes()

    def identity(self) -> dict[str, int]:
        text = self.section(".text")
        assert text.count(IDENTITY_MAGIC) == 1, "identity block missing or ambiguous in .text"
        i = text.index(IDENTITY_MAGIC)
        block = text[i : i + IDENTITY_LEN]
        _, major, minor, patch, proto, fp, mode, baud, res = struct.unpack("<4s4BIBIH", block)
        return dict(
            major=major,
            minor=minor,
            patch=patch,
            protocol_version=proto,
            fingerprint=fp,
            mode=mode,
            baud=baud,
            timer_resolution_ns=res,
        )


def make(build_dir: Path, *args: str, src: Path = FIRMWARE, timeout: float = 300) -> Build:
    """Run the firmware Makefile with BUILD=build_dir and extra VAR=value arguments."""
    result = subprocess.run(
        ["make", "-C", str(src), f"BUILD={build_dir}", *args],
        capture_output=True,
        text=True,
        timeout=timeout,
    )
    return Build(build_dir, result)
