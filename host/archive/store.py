"""The archive store: open by URL, add an entry (idempotent, never an update), read it back.

One code path for both back ends (SQLAlchemy Core): an SQLite file by default — WAL journal,
every transaction ``BEGIN IMMEDIATE`` and a long busy timeout, so several processes on one
machine can write at once — or a PostgreSQL server for many benches
(``postgresql://user@host/db``; the driver is psycopg 3). :func:`archive_url` says which:
``--archive URL`` or a path, else ``$IMU_BENCH_ARCHIVE``, else the user's own file
(:func:`default_file`). The one place the back ends part is how a calibration's parameter
and record rows go in (PostgreSQL: one COPY stream; SQLite: one executemany).
"""

from __future__ import annotations

import json
import math
import os
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from sqlalchemy import (
    Connection,
    Engine,
    Table,
    create_engine,
    event,
    false,
    func,
    make_url,
    select,
    true,
)
from sqlalchemy.dialects.postgresql import insert as pg_insert
from sqlalchemy.dialects.sqlite import insert as sqlite_insert
from sqlalchemy.exc import ArgumentError, DatabaseError, NoSuchModuleError

from host.archive.entry import Entry, Parameter, entry_from_directory
from host.archive.schema import (
    SCHEMA_VERSION,
    applied_versions,
    calibrations,
    migrate,
    now_utc,
    parameters,
    record_files,
)
from host.calib.codec import result_from_json
from host.errors import UserError

ARCHIVE_ENV = "IMU_BENCH_ARCHIVE"
DEFAULT_FILE = "$XDG_DATA_HOME/imu-bench/archive.sqlite"


def default_file() -> Path:
    """The user's own archive: ``$XDG_DATA_HOME/imu-bench/archive.sqlite`` (XDG_DATA_HOME
    defaults to ~/.local/share); its directory is created."""
    base = os.environ.get("XDG_DATA_HOME") or str(Path.home() / ".local" / "share")
    d = Path(base) / "imu-bench"
    d.mkdir(parents=True, exist_ok=True)
    return d / "archive.sqlite"


def archive_url(option: str | None = None) -> str:
    """The SQLAlchemy URL of the archive: ``option`` (a URL, or a path of an SQLite file),
    else $IMU_BENCH_ARCHIVE, else :func:`default_file`. ``postgresql://`` and
    ``postgres://`` use the psycopg 3 driver."""
    if option is not None and not option.strip():  # e.g. --archive "$UNSET": not the default
        raise UserError(
            "--archive '': give an SQLite file or postgresql://user@host/db (or leave "
            f"--archive out: ${ARCHIVE_ENV}, else {DEFAULT_FILE})"
        )
    raw = option or os.environ.get(ARCHIVE_ENV) or str(default_file())
    for scheme in ("postgresql://", "postgres://"):
        if raw.startswith(scheme):
            return "postgresql+psycopg://" + raw[len(scheme) :]
    if "://" in raw:
        return raw
    return f"sqlite:///{Path(raw).expanduser().resolve()}"


def _without_password(url: str) -> str:
    """``url`` for a message: its password as ***, the user's scheme (postgresql://)."""
    try:
        shown = make_url(url).render_as_string(hide_password=True)
    except (ArgumentError, ValueError):  # not a URL (a port that is no number): as typed
        shown = re.sub(r"(://[^:/@]*:)[^@/]*@", r"\1***@", url)
    return shown.replace("postgresql+psycopg://", "postgresql://", 1)


def _sqlite_file(url: str, create: bool) -> None:
    """UserError, naming the fix, when the SQLite file of ``url`` cannot be the archive: a
    directory, not a file, in no directory; with ``create`` False, a file not there (a
    question to an archive that does not exist is not answered from a new empty one)."""
    path = Path(url.split(":///", 1)[1]) if ":///" in url else None
    if path is None or not str(path) or str(path) == ":memory:":
        return
    if path.is_dir():
        raise UserError(
            f"archive {path}: is a directory; give the archive's file, e.g. "
            f"--archive {path / 'archive.sqlite'}"
        )
    if path.exists() and not path.is_file():
        raise UserError(f"archive {path}: not a file; give an SQLite file or postgresql://…")
    if not path.parent.is_dir():
        raise UserError(
            f"archive {path}: no directory {path.parent}; create it or give another --archive"
        )
    if not create and not path.exists():
        raise UserError(
            f"archive {path}: no such file; 'archive add DIR' or calibrate creates it (or "
            "give the archive that holds the calibrations with --archive)"
        )


def _nan(v: Any) -> float:
    return math.nan if v is None else float(v)


def _inf(v: Any) -> float:
    """A stored dof: null (from the noise model alone, or archived before dof) is inf."""
    return math.inf if v is None else float(v)


def _null(v: float) -> float | None:
    return None if v is None or not math.isfinite(v) else float(v)


def _sqlite_setup(engine: Engine) -> None:
    @event.listens_for(engine, "connect")
    def _connect(dbapi_conn: Any, _record: Any) -> None:
        dbapi_conn.isolation_level = None  # the BEGIN below, not the driver's, opens each
        cur = dbapi_conn.cursor()
        cur.execute("PRAGMA busy_timeout = 60000")
        cur.execute("PRAGMA journal_mode = WAL")
        cur.execute("PRAGMA synchronous = NORMAL")
        cur.execute("PRAGMA foreign_keys = ON")
        cur.close()

    @event.listens_for(engine, "begin")
    def _begin(conn: Connection) -> None:
        conn.exec_driver_sql("BEGIN IMMEDIATE")


@dataclass(frozen=True)
class Summary:
    """One archived calibration without its parameters (a line of ``archive list``)."""

    id: int
    serial: str
    bench: str
    operator: str
    lot: str
    measured_at: str
    archived_at: str
    model: str
    verdict: str
    self_test: str
    fit_verdict: str
    rms_z: float
    firmware: str
    sensor_revision: str
    temp_mean_c: float
    records_hash: str
    result_hash: str


@dataclass(frozen=True)
class ValueTable:
    """Parameter values of many calibrations, one row per (calibration, parameter), ordered
    by serial, time, calibration and parameter: ``id`` (calibration), ``serial``, ``bench``,
    ``measured_at`` (UTC ISO text), ``self_test``, ``verdict``, ``fit_verdict`` (the fit's:
    'inadequate' beside a 'pass' is a conditional PASS), ``rms_z`` (the fit's), ``name``,
    ``value``, ``stderr`` (NaN: not determined), ``dof`` (the degrees of freedom of
    ``stderr``; inf: from the noise model alone), all numpy arrays of one length."""

    id: np.ndarray
    serial: np.ndarray
    bench: np.ndarray
    measured_at: np.ndarray
    self_test: np.ndarray
    verdict: np.ndarray
    fit_verdict: np.ndarray
    rms_z: np.ndarray
    name: np.ndarray
    value: np.ndarray
    stderr: np.ndarray
    dof: np.ndarray

    def __len__(self) -> int:
        return int(self.id.shape[0])

    def where(self, mask: np.ndarray) -> ValueTable:
        """The rows where ``mask`` is true."""
        return ValueTable(*(getattr(self, f)[mask] for f in self.__dataclass_fields__))


_SUMMARY_COLUMNS = (
    "id", "serial", "bench", "operator", "lot", "measured_at", "archived_at", "model", "verdict",
    "self_test", "fit_verdict", "rms_z", "firmware", "sensor_revision", "temp_mean_c",
    "records_hash", "result_hash",
)  # fmt: skip


class Archive:
    """An open archive (:func:`archive_url` says where); creates and migrates its schema on
    first use (``create=False``: an SQLite file that is not there is a UserError, for the
    questions that only read). Use as a context manager or call :meth:`close`."""

    def __init__(self, url: str | None = None, *, create: bool = True) -> None:
        self.url = archive_url(url)
        if self.url.split("://", 1)[0].split("+", 1)[0] not in ("sqlite", "postgresql"):
            raise UserError(
                f"archive {_without_password(self.url)}: not an SQLite file nor a "
                "postgresql:// server, the two kinds of database the archive runs on"
            )
        try:
            if self.url.startswith("sqlite"):
                _sqlite_file(self.url, create)
                self.engine = create_engine(self.url)
                _sqlite_setup(self.engine)
            else:
                self.engine = create_engine(self.url)
        except NoSuchModuleError as exc:
            raise UserError(
                f"archive {_without_password(self.url)}: unknown kind of database ({exc})"
            ) from None
        except ModuleNotFoundError as exc:
            raise UserError(
                f"archive {_without_password(self.url)}: the driver is missing ({exc.name}): "
                "pip install 'psycopg[binary]'"
            ) from None
        except ArgumentError as exc:
            raise UserError(f"archive: not a database URL: {url!r} ({exc})") from None
        except ValueError:  # the URL's parser: a port that is no number, an unclosed [
            raise UserError(
                f"archive {_without_password(self.url)}: not a database URL (a port that is "
                "no number, a bracket not closed?); write postgresql://user@host:port/db"
            ) from None
        try:
            with self.engine.connect() as conn:
                current = applied_versions(conn)
            if not current or max(current) != SCHEMA_VERSION:
                migrate(self.engine.connect)
        except DatabaseError as exc:  # cannot connect, or a file that is no database
            self.engine.dispose()
            first = str(exc.orig).strip().splitlines()[0] if exc.orig else str(exc)
            raise UserError(f"archive {self.display_url}: cannot open it ({first})") from None

    @property
    def display_url(self) -> str:
        """The URL without its password (and without the driver's name), for messages."""
        return _without_password(self.engine.url.render_as_string(hide_password=False))

    @property
    def backend(self) -> str:
        """'sqlite' or 'postgresql'."""
        return self.engine.dialect.name

    def close(self) -> None:
        self.engine.dispose()

    def __enter__(self) -> Archive:
        return self

    def __exit__(self, *_exc: object) -> None:
        self.close()

    # ---- writing ---------------------------------------------------------------------------
    def _ids_of(self, conn: Connection, hashes: Sequence[str]) -> dict[str, int]:
        out: dict[str, int] = {}
        c = calibrations.c
        for i in range(0, len(hashes), 500):
            q = select(c.result_hash, c.id).where(c.result_hash.in_(list(hashes[i : i + 500])))
            out.update({str(h): int(k) for h, k in conn.execute(q)})
        return out

    def add(self, entry: Entry) -> tuple[int, bool]:
        """Archive ``entry``; returns (its id, True) — or (the id it already has, False) when
        the same result file was archived before: adding twice is a no-op."""
        return self.add_many([entry])[0]

    def add_many(self, entries: Sequence[Entry]) -> list[tuple[int, bool]]:
        """Archive ``entries`` in one transaction (all or none); per entry (its id, whether
        it was new), as :meth:`add`.

        Three statements per batch, whatever its size: the calibrations (a result already
        there is skipped by its unique hash, not looked up first; a process adding the same
        result at the same moment waits for the other's transaction and then skips it), then
        all their parameters and all their record hashes (:func:`_insert_rows`)."""
        # one row per result, in hash order: concurrent batches take the rows' locks in the
        # same order, so two of them never wait on each other
        unique = sorted({e.result_hash: e for e in reversed(entries)}.items())
        with self.engine.connect() as conn, conn.begin():
            ids: dict[str, int] = {}
            if unique:
                back = conn.execute(_insert_new(conn), [_row_of(e) for _, e in unique])
                ids = {str(h): int(k) for h, k in back}
            new = [(ids[h], e) for h, e in unique if h in ids]
            _insert_rows(
                conn, parameters,
                [_parameter_row(cid, i, p) for cid, e in new for i, p in enumerate(e.parameters)],
            )  # fmt: skip
            _insert_rows(
                conn, record_files,
                [{"calibration_id": cid, "name": n, "sha256": s}
                 for cid, e in new for n, s in e.record_hashes],
            )  # fmt: skip
            have = {**self._ids_of(conn, [h for h, _ in unique if h not in ids]), **ids}
        seen: set[str] = set()
        out = []
        for e in entries:
            h = e.result_hash
            out.append((have[h], h in ids and h not in seen))
            seen.add(h)
        return out

    # ---- reading ---------------------------------------------------------------------------
    def summaries(
        self, serial: str | None = None, bench: str | None = None, lot: str | None = None
    ) -> list[Summary]:
        """Archived calibrations in time order, of one serial/bench/lot when given."""
        c = calibrations.c
        q = select(*(c[n] for n in _SUMMARY_COLUMNS)).order_by(c.measured_at, c.id)
        for col, v in ((c.serial, serial), (c.bench, bench), (c.lot, lot)):
            if v is not None:
                q = q.where(col == v)
        with self.engine.connect() as conn:
            rows = conn.execute(q).all()
        return [
            Summary(**{**r._asdict(), "rms_z": _nan(r.rms_z), "temp_mean_c": _nan(r.temp_mean_c)})
            for r in rows
        ]

    def simulated_count(
        self, serial: str | None = None, bench: str | None = None, lot: str | None = None
    ) -> int:
        """How many archived calibrations (of one serial/bench/lot when given) are of
        simulated records: the statistics leave them out and say how many."""
        c = calibrations.c
        q = select(func.count()).select_from(calibrations).where(c.simulated == true())
        for col, v in ((c.serial, serial), (c.bench, bench), (c.lot, lot)):
            if v is not None:
                q = q.where(col == v)
        with self.engine.connect() as conn:
            return int(conn.execute(q).scalar_one())

    def count(self) -> tuple[int, int]:
        """(calibrations, parameter rows) in the archive."""
        with self.engine.connect() as conn:
            n = conn.execute(select(func.count()).select_from(calibrations)).scalar_one()
            m = conn.execute(select(func.count()).select_from(parameters)).scalar_one()
        return int(n), int(m)

    def result_hashes(self) -> list[str]:
        """The result hash of every archived calibration (one per row, duplicates kept)."""
        with self.engine.connect() as conn:
            return [str(h) for h in conn.execute(select(calibrations.c.result_hash)).scalars()]

    def entry(self, key: int | str) -> Entry:
        """The archived calibration with id ``key`` (int) or whose result hash starts with
        ``key`` (str, ≥ 8 hex digits); UserError when there is none or the prefix is
        ambiguous."""
        c = calibrations.c
        q = select(calibrations)
        if isinstance(key, int):
            q = q.where(c.id == key)
        else:
            if len(key) < 8:
                raise UserError(f"{key!r}: give at least 8 hex digits of the result hash")
            q = q.where(c.result_hash.like(key.lower() + "%"))
        with self.engine.connect() as conn:
            rows = conn.execute(q.limit(2)).all()
            if len(rows) != 1:
                what = "no archived calibration" if not rows else "several calibrations"
                raise UserError(f"{key}: {what} with this id or hash (see 'archive list')")
            r = rows[0]
            ps = conn.execute(
                select(parameters)
                .where(parameters.c.calibration_id == r.id)
                .order_by(parameters.c.position)
            ).all()
            files = conn.execute(
                select(record_files.c.name, record_files.c.sha256)
                .where(record_files.c.calibration_id == r.id)
                .order_by(record_files.c.name)
            ).all()
        params = tuple(
            Parameter(
                p.name, p.term, p.sensor, p.axis, p.unit, _nan(p.value), _nan(p.stderr),
                p.tolerance, p.passed, _inf(p.dof),
            )
            for p in ps
        )  # fmt: skip
        cov = tuple(tuple(_nan(x) for x in row) for row in json.loads(r.covariance))
        return Entry(
            serial=r.serial, measured_at=r.measured_at, model=r.model, parameters=params,
            result_hash=r.result_hash, bench=r.bench, operator=r.operator, lot=r.lot,
            firmware=r.firmware, sensor_revision=r.sensor_revision,
            temp_min_c=_nan(r.temp_min_c), temp_mean_c=_nan(r.temp_mean_c),
            temp_max_c=_nan(r.temp_max_c), covariance=cov, covariance_kind=r.covariance_kind,
            chi2=_nan(r.chi2), dof=int(r.dof), rms_z=_nan(r.rms_z), p=_nan(r.p),
            fit_verdict=r.fit_verdict, verdict=r.verdict, self_test=r.self_test,
            report_hash=r.report_hash, records_hash=r.records_hash,
            record_hashes=tuple((f.name, f.sha256) for f in files), result_json=r.result_json,
            simulated=bool(r.simulated),
        )  # fmt: skip

    def values(
        self,
        names: Sequence[str] | None = None,
        *,
        serial: str | None = None,
        bench: str | None = None,
        lot: str | None = None,
        latest_per_unit: bool = False,
        with_simulated: bool = True,
    ) -> ValueTable:
        """The parameter values of the archived sessions (filtered by ``serial``/``bench``/
        ``lot``, only the parameters ``names`` when given). A session is one set of records:
        when the same records were archived with several results (recomputed), the latest
        archived counts. ``latest_per_unit``: only each serial's latest session;
        ``with_simulated`` False: simulated sessions left out (as if not archived)."""
        c = calibrations.c
        later = calibrations.alias("later")
        # one session per set of records: its latest archived result (no later one with the
        # same records); each condition is answered from an index, no calibration row is read
        sessions = select(
            c.id, c.serial, c.bench, c.measured_at, c.self_test, c.verdict, c.fit_verdict,
            c.rms_z, func.row_number()
            .over(partition_by=c.serial, order_by=(c.measured_at.desc(), c.id.desc()))
            .label("ru"),
        )  # fmt: skip
        newer = select(later.c.id).where(later.c.records_hash == c.records_hash, later.c.id > c.id)
        if not with_simulated:
            sessions = sessions.where(c.simulated == false())
            newer = newer.where(later.c.simulated == false())
        for col, lcol, v in (
            (c.serial, later.c.serial, serial),
            (c.bench, later.c.bench, bench),
            (c.lot, later.c.lot, lot),
        ):
            if v is not None:
                sessions = sessions.where(col == v)
                newer = newer.where(lcol == v)
        chosen = sessions.where(~newer.exists()).subquery()
        p = parameters.c
        final = (
            select(
                chosen.c.id, chosen.c.serial, chosen.c.bench, chosen.c.measured_at,
                chosen.c.self_test, chosen.c.verdict, chosen.c.fit_verdict, chosen.c.rms_z,
                p.name, p.value, p.stderr, p.dof,
            )
            .join(parameters, p.calibration_id == chosen.c.id)
            .where(chosen.c.ru == 1 if latest_per_unit else true())
            .order_by(chosen.c.serial, chosen.c.measured_at, chosen.c.id, p.position)
        )  # fmt: skip
        if names is not None:
            final = final.where(p.name.in_(list(names)))
        with self.engine.connect() as conn:
            rows = conn.execute(final).all()
        return _value_table(rows)

    def shared_records(
        self, *, serial: str | None = None, lot: str | None = None
    ) -> list[tuple[str, str, int, int, str]]:
        """Record files (by SHA-256) archived with two sessions of one unit that are not the
        same set of records: (serial, the later's bench, earlier id, later id, file name)."""
        fa, fb = record_files.alias("fa"), record_files.alias("fb")
        ca, cb = calibrations.alias("ca"), calibrations.alias("cb")
        q = (
            select(ca.c.serial, cb.c.bench, ca.c.id, cb.c.id, fb.c.name)
            .select_from(fa.join(ca, fa.c.calibration_id == ca.c.id))
            .join(fb, fb.c.sha256 == fa.c.sha256)
            .join(cb, cb.c.id == fb.c.calibration_id)
            .where(ca.c.serial == cb.c.serial, ca.c.id < cb.c.id)
            .where(ca.c.records_hash != cb.c.records_hash)
            .order_by(ca.c.serial, cb.c.id, ca.c.id, fb.c.name)
        )
        for col, v in ((ca.c.serial, serial), (ca.c.lot, lot)):
            if v is not None:
                q = q.where(col == v)
        with self.engine.connect() as conn:
            rows = conn.execute(q).all()
        return [(str(r[0]), str(r[1]), int(r[2]), int(r[3]), str(r[4])) for r in rows]


#: what calibrate prints for a simulated session given no --archive
SIMULATED_NOT_ARCHIVED = (
    "not archived: a simulated session goes only into an archive named with --archive URL, "
    "never into the default one"
)


def archive_directory(
    directory: str | os.PathLike[str],
    url: str | None = None,
    *,
    serial: str | None = None,
    records_dir: str | os.PathLike[str] | None = None,
    bench: str | None = None,
    operator: str | None = None,
    lot: str | None = None,
) -> str:
    """Archive the result ``calibrate`` wrote into ``directory`` (what every calibration does
    at its end); returns the line to print. UserError when it cannot. A result of simulated
    records goes only into an archive named by ``url`` (``--archive``): never into the
    default one ($IMU_BENCH_ARCHIVE or the user's own file), beside the real units."""
    e = entry_from_directory(
        directory, serial=serial, records_dir=records_dir, bench=bench, operator=operator,
        lot=lot,
    )  # fmt: skip
    if url is None and result_from_json(e.result_json).simulated:
        return SIMULATED_NOT_ARCHIVED
    with Archive(url) as a:
        cid, added = a.add(e)
        where = a.display_url
    return f"{'archived' if added else 'already archived'} as #{cid} in {where}"


def _value_table(rows: Sequence[Any]) -> ValueTable:
    cols = list(zip(*rows, strict=True)) if rows else [()] * 12

    def obj(i: int) -> np.ndarray:
        a = np.empty(len(cols[i]), dtype=object)
        a[:] = cols[i]
        return a

    def num(i: int) -> np.ndarray:
        return np.array([math.nan if v is None else v for v in cols[i]], dtype=np.float64)

    return ValueTable(
        id=np.array(cols[0], dtype=np.int64), serial=obj(1), bench=obj(2), measured_at=obj(3),
        self_test=obj(4), verdict=obj(5), fit_verdict=obj(6), rms_z=num(7), name=obj(8),
        value=num(9), stderr=num(10), dof=np.array([_inf(v) for v in cols[11]], dtype=np.float64),
    )  # fmt: skip


def _covariance_text(cov: Sequence[Sequence[float]]) -> str:
    """The covariance as JSON (a list of rows; NaN and ±inf as null)."""
    m = np.asarray(cov, dtype=np.float64)
    out = m.astype(object)
    out[~np.isfinite(m)] = None
    return json.dumps(out.tolist())


def _row_of(e: Entry) -> dict[str, Any]:
    return {
        "result_hash": e.result_hash, "serial": e.serial, "bench": e.bench,
        "operator": e.operator, "lot": e.lot, "firmware": e.firmware,
        "sensor_revision": e.sensor_revision, "measured_at": e.measured_at,
        "archived_at": now_utc(), "temp_min_c": _null(e.temp_min_c),
        "temp_mean_c": _null(e.temp_mean_c), "temp_max_c": _null(e.temp_max_c),
        "model": e.model, "chi2": _null(e.chi2), "dof": int(e.dof), "rms_z": _null(e.rms_z),
        "p": _null(e.p), "fit_verdict": e.fit_verdict, "verdict": e.verdict,
        "self_test": e.self_test, "report_hash": e.report_hash, "records_hash": e.records_hash,
        "covariance_kind": e.covariance_kind, "covariance": _covariance_text(e.covariance),
        "result_json": e.result_json, "simulated": e.simulated,
    }  # fmt: skip


def _insert_new(conn: Connection) -> Any:
    """INSERT of calibration rows that skips a result hash already archived (ON CONFLICT DO
    NOTHING: nothing is updated) and returns (result_hash, id) of the rows it inserted."""
    make = pg_insert if conn.dialect.name == "postgresql" else sqlite_insert
    return (
        make(calibrations)
        .on_conflict_do_nothing(index_elements=["result_hash"])
        .returning(calibrations.c.result_hash, calibrations.c.id)
    )


def _insert_rows(conn: Connection, table: Table, rows: list[dict[str, Any]]) -> None:
    """Insert ``rows`` (dicts with the same keys) into ``table`` in this transaction:
    PostgreSQL takes them as one COPY stream (a round trip and a parse per row cost more than
    the rows), SQLite as one executemany in this process."""
    if not rows:
        return
    if conn.dialect.name != "postgresql":
        conn.execute(table.insert(), rows)
        return
    cols = list(rows[0])
    with conn.connection.driver_connection.cursor() as cur:  # type: ignore[union-attr]
        with cur.copy(f"COPY {table.name} ({', '.join(cols)}) FROM STDIN") as copy:
            for r in rows:
                copy.write_row([r[k] for k in cols])


def _parameter_row(cid: int, position: int, p: Parameter) -> dict[str, Any]:
    return {
        "calibration_id": cid, "position": position, "name": p.name, "term": p.term,
        "sensor": p.sensor, "axis": p.axis, "unit": p.unit, "value": _null(p.value),
        "stderr": _null(p.stderr), "tolerance": p.tolerance, "passed": p.passed,
        "dof": _null(p.dof),
    }  # fmt: skip
