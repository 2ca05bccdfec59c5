"""Shared by every test: calibrations archive into a scratch archive of the session (never the
user's own, ``~/.local/share/imu-bench/archive.sqlite``); a test that needs its own archive
says so with ``--archive`` or its own $IMU_BENCH_ARCHIVE."""

from __future__ import annotations

import os
from collections.abc import Iterator

import pytest


@pytest.fixture(autouse=True, scope="session")
def _scratch_archive(tmp_path_factory: pytest.TempPathFactory) -> Iterator[None]:
    before = os.environ.get("IMU_BENCH_ARCHIVE")
    os.environ["IMU_BENCH_ARCHIVE"] = str(tmp_path_factory.mktemp("archive") / "a.sqlite")
    yield
    if before is None:
        os.environ.pop("IMU_BENCH_ARCHIVE", None)
    else:
        os.environ["IMU_BENCH_ARCHIVE"] = before
