"""Fixtures for the emulated-board tests (helpers in emu_helpers.py).

Everything here needs simavr + libsimavr-dev + gcc-avr + avr-libc: without them the tests marked
``emulator`` are skipped with the install line.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from host.bench import build
from host.errors import UserError
from tests.emulator import clock_capture


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


def pytest_collection_finish(session: pytest.Session) -> None:
    """Start the sixty-second real-time capture (``clock_capture.py``) as soon as its test is
    collected to run, so that it runs beside the rest of the suite instead of holding a worker
    idle for a minute; its test waits for what is left. Not for ``--collect-only``, nor
    without the toolchain (the test is skipped)."""
    if session.config.option.collectonly:
        return
    if not any(item.nodeid == clock_capture.TEST_ID for item in session.items):
        return
    if build.toolchain_problem(need_avr=True) is None:
        clock_capture.start(clock_capture.run_directory())


@pytest.hookimpl(trylast=True)
def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """The sixty-second test last (after the order tests/conftest.py deals files in): its
    capture runs from the collection on, so by then it is done and the test only checks it;
    dealt first, as a slow file, it would wait out the whole minute."""
    last = [item for item in items if item.nodeid == clock_capture.TEST_ID]
    items[:] = [item for item in items if item.nodeid != clock_capture.TEST_ID] + last
