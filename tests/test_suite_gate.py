"""The suite is a gate only if no test can hang it: every test runs under a time limit."""

import pytest


def test_every_test_runs_under_a_time_limit(request: pytest.FixtureRequest) -> None:
    # pytest-timeout must be active in this very run, with a finite default from pyproject.toml,
    # so that a broken firmware or a silent port fails one test instead of stalling CI.
    assert request.config.pluginmanager.hasplugin("timeout"), "pytest-timeout is not installed"
    limit = float(request.config.getini("timeout"))
    assert 0 < limit <= 300, f"default per-test limit is {limit} s"
