"""A pytest plugin that writes each test's CPU time, for ``benchmarks/suite_times.py``.

    python3 -m pytest -p benchmarks.suite_cpu ...      # with SUITE_CPU_OUT=FILE set

Appends one JSON line per test to ``$SUITE_CPU_OUT``: its node id, its CPU time in seconds
(user + system of the pytest process and of the processes it started and waited for, over
setup, call and teardown: a session fixture is charged to the first test that uses it) and its
wall time in seconds. With pytest-xdist every worker appends to the same file. CPU time is what
the test costs whatever the load; the wall time on a shared machine is mostly the load's.
"""

from __future__ import annotations

import json
import os
import resource
import time
from collections.abc import Iterator

import pytest


def cpu_seconds() -> float:
    """User + system CPU time (s) of this process and its waited-for children."""
    me = resource.getrusage(resource.RUSAGE_SELF)
    kids = resource.getrusage(resource.RUSAGE_CHILDREN)
    return me.ru_utime + me.ru_stime + kids.ru_utime + kids.ru_stime


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item: pytest.Item, nextitem: pytest.Item | None) -> Iterator[None]:
    out = os.environ.get("SUITE_CPU_OUT")
    c0, t0 = cpu_seconds(), time.perf_counter()
    yield
    if out:
        line = {"test": item.nodeid, "cpu": cpu_seconds() - c0, "wall": time.perf_counter() - t0}
        with open(out, "a") as f:
            f.write(json.dumps(line) + "\n")
