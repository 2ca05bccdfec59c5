"""Fixtures for the firmware tests (helpers live in fwbuild.py)."""

from __future__ import annotations

import shutil

import pytest
from fwbuild import AVR_TOOLS, Build, make


@pytest.fixture(scope="session")
def avr_toolchain() -> None:
    missing = [t for t in AVR_TOOLS if shutil.which(t) is None]
    if missing:
        pytest.skip(
            f"AVR toolchain not installed (missing {', '.join(missing)}); "
            "apt-get install gcc-avr avr-libc binutils-avr make"
        )


@pytest.fixture(scope="session")
def default_build(avr_toolchain, tmp_path_factory) -> Build:
    build = make(tmp_path_factory.mktemp("fw-default"))
    assert build.ok, build.output
    return build
