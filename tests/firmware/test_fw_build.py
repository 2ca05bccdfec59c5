"""The firmware builds with the required flags, fits, and carries what HELLO will report."""

from __future__ import annotations

import shutil

import pytest
from fwbuild import FIRMWARE, GENERATE, Build, make, spec_fingerprint

REQUIRED_FLAGS = (
    "-mmcu=atmega2560",
    "-DF_CPU=16000000UL",
    "-Os",
    "-Wall",
    "-Wextra",
    "-Werror",
    "-std=gnu++11",
)


@pytest.mark.slow
def test_default_build_fits(default_build: Build) -> None:
    flash, ram = default_build.sizes()
    print(f"\nimu_bench.elf: flash {flash} bytes, RAM {ram} bytes (static; stack on top)")
    # Limits from the issue; the ATmega2560 has 256 KB flash (8 KB boot) and 8 KB SRAM, and
    # the stack needs what static data leaves.
    assert 1000 < flash < 16 * 1024
    assert 100 < ram < 4 * 1024
    assert default_build.elf.stat().st_size > 0
    lines = default_build.hex.read_text().splitlines()
    assert lines[0].startswith(":") and lines[-1] == ":00000001FF"  # Intel HEX, EOF record


def test_compiler_flags(default_build: Build) -> None:
    compile_lines = [
        ln
        for ln in default_build.result.stdout.splitlines()
        if ln.startswith("avr-g++") and " -c " in ln
    ]
    assert len(compile_lines) >= 8, default_build.output  # one per translation unit
    for line in compile_lines:
        for flag in REQUIRED_FLAGS:
            assert f" {flag} " in f" {line} ", f"{flag} missing from: {line}"


def test_warnings_are_errors(avr_toolchain, tmp_path) -> None:
    """-Werror is real: a copy of the sources with one unused variable must not build."""
    src = tmp_path / "firmware"
    shutil.copytree(FIRMWARE / "src", src / "src")
    shutil.copy(FIRMWARE / "Makefile", src / "Makefile")
    main = src / "src" / "main.cpp"
    main.write_text(
        main.read_text() + "\nstatic int unused_helper(int x) { int y = x; return 0; }\n"
    )
    build = make(tmp_path / "out", src=src)
    assert not build.ok
    assert "error" in build.output and "unused" in build.output


def test_identity_defaults(default_build: Build) -> None:
    ident = default_build.identity()
    assert (ident["major"], ident["minor"], ident["patch"]) == (0, 1, 0)
    assert ident["protocol_version"] == GENERATE.load_spec()["protocol_version"]
    # From spec.json itself: a stale protocol_gen.h or a firmware that does not use
    # PROTO_SPEC_FINGERPRINT fails here.
    assert ident["fingerprint"] == spec_fingerprint()
    assert ident["mode"] == 0  # RAW: no DMP image given
    assert ident["baud"] == 115200
    assert ident["timer_resolution_ns"] == 500  # Timer1 at F_CPU/8


def test_fingerprint_bytes_in_flash_image(default_build: Build) -> None:
    """The HELLO fingerprint is in the flashed image, little-endian, as HELLO sends it."""
    fp = spec_fingerprint().to_bytes(4, "little")
    text = default_build.section(".text")
    data = default_build.section(".data")
    assert fp in text + data


@pytest.mark.slow
def test_version_and_baud_overrides(avr_toolchain, tmp_path) -> None:
    build = make(tmp_path / "old", "FW_VERSION=0.9.3", "BAUD=500000")
    assert build.ok, build.output
    ident = build.identity()
    assert (ident["major"], ident["minor"], ident["patch"]) == (0, 9, 3)
    assert ident["baud"] == 500000
    # Changing a variable in the same BUILD directory rebuilds (flags stamp), no stale objects.
    again = make(tmp_path / "old", "FW_VERSION=2.0.1")
    assert again.ok, again.output
    ident = again.identity()
    assert (ident["major"], ident["minor"], ident["patch"], ident["baud"]) == (2, 0, 1, 115200)


@pytest.mark.slow
def test_bad_settings_are_refused(avr_toolchain, tmp_path) -> None:
    # 300 baud needs UBRR 6666 > 4095 with U2X: a static_assert must stop the build.
    assert not make(tmp_path / "slow", "BAUD=300").ok
    # 250000 is exact; 230400 is 3.5 % off at 16 MHz: refused.
    assert make(tmp_path / "b250k", "BAUD=250000").ok
    assert not make(tmp_path / "b230k", "BAUD=230400").ok
    assert not make(tmp_path / "ver", "FW_VERSION=1.2").ok
    assert not make(tmp_path / "ver2", "FW_VERSION=1.2.300").ok


def test_no_build_output_in_source_tree(default_build: Build) -> None:
    src_files = {p.name for p in (FIRMWARE / "src").iterdir()}
    assert not any(
        n.endswith((".o", ".d", ".elf", ".hex")) or n == "dmp_image.h" for n in src_files
    )
