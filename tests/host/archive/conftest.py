"""Fixtures of the archive's tests: an empty archive on each back end (an SQLite file, and a
database in a throwaway PostgreSQL cluster started once for the session)."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.host.archive.pg_cluster import Cluster, cluster, why_no_postgres


@pytest.fixture(scope="session")
def pg_cluster() -> Iterator[Cluster]:
    why = why_no_postgres()
    if why is not None:
        pytest.skip(why)
    with cluster() as c:
        yield c


BACKENDS = ["sqlite", pytest.param("postgresql", marks=pytest.mark.slow)]


@pytest.fixture(params=BACKENDS)
def archive_url(request: pytest.FixtureRequest, tmp_path: Path) -> str:
    """The URL of a new, empty archive on each back end."""
    if request.param == "sqlite":
        return str(tmp_path / "archive.sqlite")
    c: Cluster = request.getfixturevalue("pg_cluster")
    return c.new_database()
