"""The archive's tables (one schema for SQLite and PostgreSQL) and its versioned migrations.

``calibrations`` holds one row per archived result (identity: the result file's SHA-256,
unique), ``parameters`` one row per fitted parameter of it (value and σ; NaN is stored as
NULL), ``record_files`` the hash of every record the result was fitted on. Rows are only ever
inserted: no statement of the archive updates or deletes one (but the v4 migration, which
sets the new ``simulated`` flag once on the rows archived before it). A simulated session
(``simulated``) is kept, and left out of the lot, control and drift statistics.

:data:`MIGRATIONS` is the ordered list of schema versions; ``archive_schema`` records which
were applied. :func:`migrate` applies the missing ones in one transaction per version, under a
lock the other processes wait on (PostgreSQL: an advisory lock; SQLite: ``BEGIN IMMEDIATE``),
so that several processes opening a new archive at once create it once.
"""

from __future__ import annotations

from collections.abc import Callable
from datetime import UTC, datetime

from sqlalchemy import (
    Boolean,
    Column,
    Connection,
    Float,
    ForeignKey,
    Integer,
    MetaData,
    String,
    Table,
    Text,
    UniqueConstraint,
    false,
    inspect,
    select,
    text,
)
from sqlalchemy.exc import IntegrityError

from host.errors import UserError

metadata = MetaData()

schema_versions = Table(
    "archive_schema",
    metadata,
    Column("version", Integer, primary_key=True, autoincrement=False),
    Column("description", Text, nullable=False),
    Column("applied_at", String(32), nullable=False),
)

calibrations = Table(
    "calibrations",
    metadata,
    Column("id", Integer, primary_key=True, autoincrement=True),
    Column("result_hash", String(64), nullable=False),
    Column("serial", String(200), nullable=False),
    Column("bench", String(200), nullable=False),
    Column("operator", String(200), nullable=False),
    Column("lot", String(200), nullable=False),
    Column("firmware", String(200), nullable=False),
    Column("sensor_revision", String(200), nullable=False),
    Column("measured_at", String(32), nullable=False),
    Column("archived_at", String(32), nullable=False),
    Column("temp_min_c", Float),
    Column("temp_mean_c", Float),
    Column("temp_max_c", Float),
    Column("model", Text, nullable=False),
    Column("chi2", Float),
    Column("dof", Integer, nullable=False),
    Column("rms_z", Float),
    Column("p", Float),
    Column("fit_verdict", String(40), nullable=False),
    Column("verdict", String(8), nullable=False),
    Column("self_test", String(8), nullable=False),
    Column("report_hash", String(64), nullable=False),
    Column("records_hash", String(64), nullable=False),
    Column("covariance_kind", String(16), nullable=False),
    Column("covariance", Text, nullable=False),
    Column("result_json", Text, nullable=False),
    #: the records came from a virtual or emulated board (sim://, emu://) or the simulator:
    #: kept, but left out of the lot, control and drift statistics (schema v4)
    Column("simulated", Boolean, nullable=False, server_default=false()),
    UniqueConstraint("result_hash", name="uq_calibrations_result_hash"),
)

parameters = Table(
    "parameters",
    metadata,
    Column("calibration_id", Integer, ForeignKey("calibrations.id"), primary_key=True),
    Column("position", Integer, primary_key=True, autoincrement=False),
    Column("name", String(200), nullable=False),
    Column("term", String(200), nullable=False),
    Column("sensor", String(16), nullable=False),
    Column("axis", String(16), nullable=False),
    Column("unit", String(40), nullable=False),
    Column("value", Float),
    Column("stderr", Float),
    Column("tolerance", Float),
    Column("passed", Boolean),
    Column("dof", Float),
)

record_files = Table(
    "record_files",
    metadata,
    Column("calibration_id", Integer, ForeignKey("calibrations.id"), primary_key=True),
    Column("name", String(200), primary_key=True),
    Column("sha256", String(64), nullable=False),
)


def _v1(conn: Connection) -> None:
    for table in (calibrations, parameters, record_files):
        table.create(conn, checkfirst=True)
    for ddl in (
        "CREATE INDEX ix_calibrations_serial_time ON calibrations (serial, measured_at)",
        "CREATE INDEX ix_calibrations_bench_time ON calibrations (bench, measured_at)",
        "CREATE INDEX ix_calibrations_records ON calibrations (records_hash)",
        "CREATE INDEX ix_parameters_name ON parameters (name, calibration_id)",
    ):
        conn.execute(text(ddl))


def _v2(conn: Connection) -> None:
    """Indexes that answer the lot and trend queries without reading a calibration's row
    (each carries the result file and the covariance, ~90 KB: in SQLite one row read is
    several pages) or a parameter's row; on PostgreSQL the two large columns compressed with
    lz4 where the server has it (a third of pglz's time to archive one)."""
    for ddl in (
        # every column the choice of sessions reads (host.archive.store.Archive.values)
        "CREATE INDEX ix_calibrations_unit_sessions ON calibrations "
        "(serial, measured_at, id, records_hash, bench, lot, self_test, verdict)",
        "DROP INDEX ix_calibrations_serial_time",
        "CREATE INDEX ix_calibrations_records_id ON calibrations (records_hash, id)",
        "DROP INDEX ix_calibrations_records",
        "CREATE INDEX ix_parameters_values ON parameters "
        "(name, calibration_id, position, value, stderr)",
        "DROP INDEX ix_parameters_name",
    ):
        conn.execute(text(ddl))
    if conn.dialect.name == "postgresql":
        lz4 = conn.execute(
            text(
                "SELECT 1 FROM pg_settings WHERE name = 'default_toast_compression' "
                "AND 'lz4' = ANY(enumvals)"
            )
        ).first()
        if lz4 is not None:
            conn.execute(
                text(
                    "ALTER TABLE calibrations ALTER COLUMN result_json SET COMPRESSION lz4, "
                    "ALTER COLUMN covariance SET COMPRESSION lz4"
                )
            )


def _v3(conn: Connection) -> None:
    """The sessions' covering index (v2) with the fit's verdict and RMS z: a PASS on a model
    that does not fit is a conditional PASS, which the lot check names, still from the index
    alone."""
    for ddl in (
        "CREATE INDEX ix_calibrations_unit_verdicts ON calibrations "
        "(serial, measured_at, id, records_hash, bench, lot, self_test, verdict, fit_verdict, "
        "rms_z)",
        "DROP INDEX ix_calibrations_unit_sessions",
    ):
        conn.execute(text(ddl))


def _v4(conn: Connection) -> None:
    """The ``simulated`` flag: a column (an archive created by this program has it from v1's
    table), set once here for the rows archived before it whose result file says
    ``"simulated": true`` (the one statement that ever changes a row, and only this new
    column), and the sessions' covering index with it, so that the statistics leave
    simulated sessions out from the index alone."""
    columns = {col["name"] for col in inspect(conn).get_columns("calibrations")}
    if "simulated" not in columns:
        conn.execute(
            text("ALTER TABLE calibrations ADD COLUMN simulated BOOLEAN NOT NULL DEFAULT FALSE")
        )
    conn.execute(
        text(
            "UPDATE calibrations SET simulated = TRUE "
            "WHERE result_json LIKE '%\"simulated\": true%'"
        )
    )
    for ddl in (
        "CREATE INDEX ix_calibrations_unit_sims ON calibrations "
        "(serial, measured_at, id, records_hash, bench, lot, self_test, verdict, fit_verdict, "
        "rms_z, simulated)",
        "DROP INDEX ix_calibrations_unit_verdicts",
    ):
        conn.execute(text(ddl))


def _v5(conn: Connection) -> None:
    """A parameter's ``dof`` (the degrees of freedom of its σ; null: from the noise model
    alone, and for every row archived before it, whose result files carried none): a column
    (an archive created by this program has it from v1's table), and the values' covering
    index with it, so that the repeat test reads it from the index alone."""
    columns = {col["name"] for col in inspect(conn).get_columns("parameters")}
    if "dof" not in columns:
        conn.execute(text("ALTER TABLE parameters ADD COLUMN dof FLOAT"))
    for ddl in (
        "CREATE INDEX ix_parameters_values_dof ON parameters "
        "(name, calibration_id, position, value, stderr, dof)",
        "DROP INDEX ix_parameters_values",
    ):
        conn.execute(text(ddl))


#: (version, what it does, the change) in order; a new version appends, none is ever edited
MIGRATIONS: tuple[tuple[int, str, Callable[[Connection], None]], ...] = (
    (1, "calibrations, parameters, record_files", _v1),
    (2, "covering indexes for the lot and trend queries; lz4 for the large columns", _v2),
    (3, "the fit's verdict and RMS z in the sessions' covering index", _v3),
    (4, "the simulated flag, set for simulated results, in the sessions' index", _v4),
    (5, "a parameter's dof, in the values' covering index", _v5),
)
SCHEMA_VERSION = MIGRATIONS[-1][0]

#: key of the PostgreSQL advisory lock the migrations take (any constant shared by all)
_LOCK_KEY = 2029


def now_utc() -> str:
    """The current UTC time as the archive writes it (ISO 8601, microseconds, ``Z``)."""
    return datetime.now(UTC).strftime("%Y-%m-%dT%H:%M:%S.%fZ")


def minute_utc(iso: str) -> str:
    """An archived UTC time (ISO text) to the minute: ``2026-01-03 08:12 UTC``."""
    return f"{iso[:10]} {iso[11:16]} UTC" if len(iso) >= 16 else iso


def lock(conn: Connection) -> None:
    """Take the archive's write lock for the rest of the transaction (PostgreSQL: a
    transaction-scoped advisory lock; SQLite's ``BEGIN IMMEDIATE`` already holds it)."""
    if conn.dialect.name == "postgresql":
        conn.execute(text("SELECT pg_advisory_xact_lock(:k)"), {"k": _LOCK_KEY})


def applied_versions(conn: Connection) -> set[int]:
    """The schema versions applied to the archive ``conn`` is connected to."""
    if not conn.dialect.has_table(conn, schema_versions.name):
        return set()
    return {int(v) for v in conn.execute(select(schema_versions.c.version)).scalars()}


def migrate(connect: Callable[[], Connection]) -> int:
    """Bring the archive to :data:`SCHEMA_VERSION`; returns the number of versions applied.
    ``connect`` opens a connection (each version commits on its own). UserError when the
    archive was written by a newer program (a version this one does not know)."""
    done = 0
    for version, description, change in MIGRATIONS:
        with connect() as conn, conn.begin():
            lock(conn)
            schema_versions.create(conn, checkfirst=True)
            have = applied_versions(conn)
            unknown = sorted(v for v in have if v > SCHEMA_VERSION)
            if unknown:
                raise UserError(
                    f"the archive has schema version {unknown[-1]}, newer than this program's "
                    f"{SCHEMA_VERSION}: update imu-bench before using it"
                )
            if version in have:
                continue
            change(conn)
            try:
                conn.execute(
                    schema_versions.insert().values(
                        version=version, description=description, applied_at=now_utc()
                    )
                )
            except IntegrityError:  # another process applied it meanwhile
                continue
            done += 1
    return done
