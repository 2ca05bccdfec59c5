"""Fixtures for the emulated-board tests (helpers in emu_helpers.py).

Everything here needs simavr + libsimavr-dev + gcc-avr + avr-libc: without them the tests marked
``emulator`` are skipped with the install line.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from host.bench import build
from host.errors import UserError


@pytest.fixture(scope="session")
def emu_toolchain() -> None:
    problem = build.toolchain_problem(need_avr=True)
    if problem:
        pytest.skip(problem)


@pytest.fixture(scope="session")
def emu_bin(emu_toolchain) -> Path:
    return build.build_emulator()


@pytest.fixture(scope="session")
def testapp_elfs(emu_toolchain) -> tuple[Path, Path]:
    return build.build_testapp()


@pytest.fixture(scope="session")
def fw_elf(emu_toolchain, tmp_path_factory) -> Path:
    try:
        return build.build_firmware(tmp_path_factory.mktemp("emu-fw"))
    except UserError as exc:
        pytest.fail(f"the real firmware does not build: {exc}")
