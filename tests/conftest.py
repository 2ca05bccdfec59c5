"""Shared by every test: calibrations archive into a scratch archive of the session (never the
user's own, ``~/.local/share/imu-bench/archive.sqlite``); a test that needs its own archive
says so with ``--archive`` or its own $IMU_BENCH_ARCHIVE.

A test that reads the project's real data beside the clone (``../shared/data/imucal-example``,
named ``REAL`` or ``IMUCAL`` in the test modules) is skipped, with that reason, in a clone
without it: a missing data folder is not a failure of the code.

Where the environment writes no bytecode (``PYTHONDONTWRITEBYTECODE``), the suite keeps its
compiled modules in a cache of its own outside the checkout (:func:`_cache_bytecode`), so that
each worker and each ``python3 -m host`` a test starts does not compile every module again."""

from __future__ import annotations

import functools
import inspect
import os
import re
import sys
import tempfile
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

#: the real sessions shipped beside the project (not in the repository)
SHARED_DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "imucal-example"
#: how a test (or a fixture it uses) names that data
_READS_SHARED = re.compile(r"\b(REAL|IMUCAL)\b|/ \"shared\" /")


def _cache_bytecode() -> None:
    """Where the environment writes no bytecode, write it into a per-user cache outside the
    checkout (``sys.pycache_prefix``; the processes the tests start inherit it): the source
    tree stays as clean as the environment asked, and the modules (pytest's rewritten test
    modules too) are compiled once, not again in each worker and each ``python3 -m host``
    (the collection of the suite took 16 s of CPU per worker compiling, 5 s with the cache;
    ``python3 -m host calibrate --help`` 0.45 s, 0.28 s). A pyc is used only while its source's
    mtime and size match, as in ``__pycache__``; an environment that writes bytecode is left
    alone."""
    if not sys.dont_write_bytecode:
        return
    if not sys.pycache_prefix:
        uid = os.getuid() if hasattr(os, "getuid") else 0
        cache = Path(tempfile.gettempdir()) / f"imu-bench-pycache-{uid}"
        cache.mkdir(mode=0o700, exist_ok=True)
        sys.pycache_prefix = str(cache)
    os.environ["PYTHONPYCACHEPREFIX"] = sys.pycache_prefix
    os.environ.pop("PYTHONDONTWRITEBYTECODE", None)
    sys.dont_write_bytecode = False


@functools.cache
def _file_reads_shared(path: str) -> bool:
    """Whether the file at ``path`` names the shared real data anywhere (a function's source is
    a run of whole lines of its file, so a function of a file that does not cannot)."""
    try:
        return _READS_SHARED.search(Path(path).read_text(encoding="utf-8")) is not None
    except (OSError, UnicodeDecodeError):
        return True  # unknown: the function's own source decides


@functools.cache
def _source_reads_shared(func: Callable[..., object]) -> bool:
    """Whether the source of ``func`` (a test or a fixture) names the shared real data: once per
    function (a parametrized test's items and the fixtures many tests use are the same
    functions), and only in files that name it at all. Read for every item and fixture it was
    7783 sources for the 1708 tests, 3.6-3.8 s of each worker's collection where the data is
    absent."""
    code = getattr(inspect.unwrap(func), "__code__", None)
    if code is not None and not _file_reads_shared(code.co_filename):
        return False
    try:
        return _READS_SHARED.search(inspect.getsource(func)) is not None
    except (OSError, TypeError):
        return False


def _reads_shared(item: pytest.Item) -> bool:
    funcs = [getattr(item, "function", None)]
    info = getattr(item, "_fixtureinfo", None)
    for defs in info.name2fixturedefs.values() if info is not None else ():
        funcs += [d.func for d in defs]
    return any(f is not None and _source_reads_shared(f) for f in funcs)


def pytest_configure(config: pytest.Config) -> None:
    _cache_bytecode()  # before the test modules are collected and imported
    # With two workers (`-n 2 --dist loadfile`) the suite ends when the later worker ends. The
    # scheduler hands out whole files in the order collected, but by default it first sorts them
    # by their number of tests, which sends the few-test, many-second files (one diagnosis loop
    # over ten sessions) last: one worker then runs alone for a minute at the end. Keep the
    # collected order, in which files with slow tests come first (below).
    if getattr(config.option, "loadscopereorder", None) is not None:
        config.option.loadscopereorder = False


def _slow_files_first(items: list[pytest.Item]) -> None:
    """Files holding a slow test first, each file's tests kept together and in their order: the
    long files are dealt out while the other worker still has work, the short ones fill in."""
    slow = {item.path for item in items if item.get_closest_marker("slow") is not None}
    items.sort(key=lambda item: item.path not in slow)  # stable: a file's tests stay together


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    _slow_files_first(items)
    if SHARED_DATA.is_dir():
        return
    skip = pytest.mark.skip(reason=f"needs the project's shared real data {SHARED_DATA} "
                            "(../shared beside the clone), absent here")  # fmt: skip
    for item in items:
        if _reads_shared(item):
            item.add_marker(skip)


@pytest.fixture(autouse=True, scope="session")
def _scratch_archive(tmp_path_factory: pytest.TempPathFactory) -> Iterator[None]:
    before = os.environ.get("IMU_BENCH_ARCHIVE")
    os.environ["IMU_BENCH_ARCHIVE"] = str(tmp_path_factory.mktemp("archive") / "a.sqlite")
    yield
    if before is None:
        os.environ.pop("IMU_BENCH_ARCHIVE", None)
    else:
        os.environ["IMU_BENCH_ARCHIVE"] = before
