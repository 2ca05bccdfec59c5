"""The archive store (host/archive/store.py, schema.py) on SQLite and on a real PostgreSQL:
an entry comes back as it went in, adding twice is a no-op, rows are never updated, the schema
carries its version, and bad URLs get one line."""

from __future__ import annotations

import dataclasses
import math
import re
from pathlib import Path

import numpy as np
import pytest
from sqlalchemy import select, text

from host.archive.entry import Entry
from host.archive.schema import SCHEMA_VERSION, schema_versions
from host.archive.store import ARCHIVE_ENV, Archive, archive_url
from host.errors import UserError
from tests.host.archive.lot_sim import NAMES, SIGMA, make_entry


def _entry(serial: str = "U1", session: int = 0, **kw: object) -> Entry:
    v = np.arange(len(NAMES), dtype=float) * 0.01 + session
    return make_entry(serial, "B1", session, v, SIGMA, **kw)  # type: ignore[arg-type]


def _same(a: Entry, b: Entry) -> bool:
    """Field-wise equality with NaN equal to NaN."""

    def norm(x: object) -> object:
        if isinstance(x, float) and math.isnan(x):
            return "nan"
        if isinstance(x, tuple):
            return tuple(norm(y) for y in x)
        if dataclasses.is_dataclass(x) and not isinstance(x, type):
            return norm(dataclasses.astuple(x))
        return x

    return all(
        norm(getattr(a, f.name)) == norm(getattr(b, f.name)) for f in dataclasses.fields(Entry)
    )


def test_an_entry_comes_back_whole_and_adding_it_twice_is_a_no_op(archive_url: str) -> None:
    e = _entry()
    nan_param = dataclasses.replace(e.parameters[0], value=math.nan, stderr=math.nan)
    e = dataclasses.replace(e, parameters=(nan_param, *e.parameters[1:]), temp_mean_c=31.5)
    with Archive(archive_url) as a:
        cid, added = a.add(e)
        assert added
        assert a.add(e) == (cid, False)
        assert a.count() == (1, len(NAMES))
        back = a.entry(cid)
        assert _same(back, e)
        assert _same(a.entry(e.result_hash[:12]), e)
        assert math.isnan(back.parameters[0].value) and back.temp_mean_c == 31.5


def test_a_sigmas_dof_comes_back_and_null_is_from_the_noise_model(archive_url: str) -> None:
    """A σ read on few dof (a variance component's share) is archived with its dof and the
    values the repeat test reads carry it; one from the noise model alone (inf) as null."""
    e = _entry("U7")
    ps = tuple(dataclasses.replace(p, dof=3.0 + i) if i % 2 else p
               for i, p in enumerate(e.parameters))  # fmt: skip
    e = dataclasses.replace(e, parameters=ps)
    with Archive(archive_url) as a:
        cid, _ = a.add(e)
        assert [p.dof for p in a.entry(cid).parameters] == [p.dof for p in ps]
        v = a.values(serial="U7")
        assert list(v.dof) == [p.dof for p in ps]
        with a.engine.connect() as conn:
            stored = conn.execute(text(f"SELECT dof FROM parameters WHERE calibration_id = {cid} "
                                       "ORDER BY position")).scalars().all()  # fmt: skip
        assert stored[0] is None and stored[1] == 4.0


def test_a_batch_is_added_at_once_and_knows_what_was_there(archive_url: str) -> None:
    a1, a2, a3 = _entry("U1"), _entry("U2"), _entry("U3")
    with Archive(archive_url) as a:
        i2, _ = a.add(a2)
        out = a.add_many([a1, a2, a3, a1])
        assert [added for _, added in out] == [True, False, True, False]
        assert out[1][0] == i2 and out[0][0] == out[3][0]
        assert a.count() == (3, 3 * len(NAMES))
        assert sorted(a.result_hashes()) == sorted(e.result_hash for e in (a1, a2, a3))


def test_rows_are_only_inserted_a_recomputed_session_is_a_new_row(archive_url: str) -> None:
    first = _entry()
    again = dataclasses.replace(first, result_hash="f" * 64, model="base,temperature_bias")
    with Archive(archive_url) as a:
        i1, _ = a.add(first)
        i2, added = a.add(again)
        assert added and i2 != i1
        assert a.entry(i1).model == "base"  # the first is untouched
        # the statistics count the session once: the latest archived result of its records
        v = a.values(["A0x"])
        assert list(v.id) == [i2]


def test_values_filter_and_take_each_units_latest_session(archive_url: str) -> None:
    with Archive(archive_url) as a:
        for serial in ("U1", "U2"):
            for s in range(3):
                a.add(_entry(serial, s, day=s))
        v = a.values(["A0x", "G0z"])
        assert len(v) == 12
        assert list(v.name[:2]) == ["A0x", "G0z"]
        latest = a.values(["A0x"], latest_per_unit=True)
        assert list(latest.serial) == ["U1", "U2"]
        assert list(latest.value) == pytest.approx([2.0, 2.0])  # session 2's A0x
        assert len(a.values(serial="U2")) == 3 * len(NAMES)
        assert [s.serial for s in a.summaries(serial="U1")] == ["U1"] * 3


def test_the_schema_carries_its_version_and_a_newer_archive_is_refused(archive_url: str) -> None:
    with Archive(archive_url) as a:
        with a.engine.connect() as conn:
            versions = conn.execute(select(schema_versions.c.version)).scalars()
            assert sorted(versions) == list(range(1, SCHEMA_VERSION + 1))
        with a.engine.connect() as conn, conn.begin():
            conn.execute(
                schema_versions.insert().values(
                    version=SCHEMA_VERSION + 1, description="future", applied_at="x"
                )
            )
    with pytest.raises(UserError, match="newer than this program"):
        Archive(archive_url)


def test_reopening_does_not_migrate_again(archive_url: str) -> None:
    with Archive(archive_url) as a:
        a.add(_entry())
    with Archive(archive_url) as a:
        assert a.count() == (1, len(NAMES))
        with a.engine.connect() as conn:
            n = conn.execute(text("SELECT count(*) FROM archive_schema")).scalar_one()
        assert n == SCHEMA_VERSION


def _reference_values(entries: list[Entry], latest_per_unit: bool, **where: str) -> list:
    """The rule of Archive.values written out in Python: of the entries matching ``where``,
    per set of records the latest archived (the last added), per unit the latest by
    (time, order added) when asked; (serial, time, name, value) in the store's order."""
    kept = [
        (i, e) for i, e in enumerate(entries) if all(getattr(e, k) == v for k, v in where.items())
    ]
    last = {e.records_hash: i for i, e in kept}
    sessions = [(i, e) for i, e in kept if last[e.records_hash] == i]
    if latest_per_unit:
        best: dict[str, tuple[str, int]] = {}
        for i, e in sessions:
            best[e.serial] = max(best.get(e.serial, ("", -1)), (e.measured_at, i))
        sessions = [(i, e) for i, e in sessions if best[e.serial][1] == i]
    sessions.sort(key=lambda ie: (ie[1].serial, ie[1].measured_at, ie[0]))
    return [(e.serial, e.measured_at, p.name, p.value) for _, e in sessions for p in e.parameters]


@pytest.mark.parametrize("seed", [1, 2])
def test_values_choose_the_sessions_by_the_documented_rule(archive_url: str, seed: int) -> None:
    """Units with several sessions on two benches and two lots, some sessions archived again
    with a new result (recomputed, sometimes under another bench or lot name): every filter,
    with and without latest_per_unit, against the rule written out in Python."""
    rng = np.random.default_rng(seed)
    entries: list[Entry] = []
    for u in range(5):
        for s in range(int(rng.integers(1, 4))):
            bench, lot = f"B{rng.integers(1, 3)}", f"L{rng.integers(1, 3)}"
            e = make_entry(f"U{u}", bench, s, rng.normal(size=len(NAMES)), SIGMA,
                           day=int(rng.integers(0, 3)), lot=lot)  # fmt: skip
            entries.append(e)
            if rng.random() < 0.5:  # recomputed: same records, a new result
                entries.append(dataclasses.replace(
                    e, result_hash=e.result_hash[::-1], bench=f"B{rng.integers(1, 3)}",
                    parameters=tuple(dataclasses.replace(p, value=p.value + 1)
                                     for p in e.parameters),
                ))  # fmt: skip
    with Archive(archive_url) as a:
        for e in entries:
            a.add(e)
        for where in ({}, {"serial": "U1"}, {"bench": "B1"}, {"lot": "L2"}):
            for latest in (False, True):
                v = a.values(latest_per_unit=latest, **where)
                got = list(zip(v.serial, v.measured_at, v.name, v.value, strict=True))
                assert got == _reference_values(entries, latest, **where), (where, latest)


def test_an_archive_of_version_1_is_migrated_and_keeps_its_rows(
    archive_url: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    from sqlalchemy import create_engine, inspect

    from host.archive import schema, store

    entries = [_entry("U1", s, day=s) for s in range(3)] + [_entry("U2", 0)]
    engine = create_engine(store.archive_url(archive_url))
    with monkeypatch.context() as m:
        m.setattr(schema, "MIGRATIONS", schema.MIGRATIONS[:1])
        m.setattr(schema, "SCHEMA_VERSION", 1)
        assert schema.migrate(engine.connect) == 1
    with engine.begin() as conn:  # rows written by the version-1 program (no dof column)
        conn.execute(text("ALTER TABLE parameters DROP COLUMN dof"))
        for e in entries:
            cid = conn.execute(
                schema.calibrations.insert().returning(schema.calibrations.c.id),
                store._row_of(e),
            ).scalar_one()
            conn.execute(
                schema.parameters.insert(),
                [
                    {k: v for k, v in store._parameter_row(cid, i, p).items() if k != "dof"}
                    for i, p in enumerate(e.parameters)
                ],  # fmt: skip
            )
    engine.dispose()
    with Archive(archive_url) as a:
        assert a.count() == (4, 4 * len(NAMES))
        latest = a.values(["A0x"], latest_per_unit=True)
        assert list(latest.serial) == ["U1", "U2"] and list(latest.value) == [2.0, 0.0]
        assert _same(
            a.entry(entries[1].result_hash), dataclasses.replace(entries[1], record_hashes=())
        )
        with a.engine.connect() as conn:
            names = {ix["name"] for ix in inspect(conn).get_indexes("calibrations")}
            assert "ix_calibrations_unit_sims" in names  # v4: with the simulated flag
            pix = {ix["name"] for ix in inspect(conn).get_indexes("parameters")}
            assert "ix_parameters_values_dof" in pix and "ix_parameters_values" not in pix
            assert not names & {"ix_calibrations_serial_time", "ix_calibrations_unit_sessions",
                                "ix_calibrations_unit_verdicts"}  # fmt: skip
            if a.backend == "postgresql":  # the large columns compressed with lz4
                kinds = conn.execute(text(
                    "SELECT attname, attcompression FROM pg_attribute WHERE attrelid = "
                    "'calibrations'::regclass AND attname IN ('result_json', 'covariance')"
                )).all()  # fmt: skip
                assert {k for _, k in kinds} == {"l"}


def test_the_lot_query_reads_only_indexes_with_the_fit_verdict(tmp_path: Path) -> None:
    """The lot check reads each session's fit verdict (a conditional PASS) and still never a
    calibration's row (~90 KB each): SQLite's plan touches the table only through covering
    indexes."""
    from sqlalchemy import event

    with Archive(str(tmp_path / "a.sqlite")) as a:
        a.add_many([_entry("U1", s, day=s) for s in range(3)] + [_entry("U2", 0)])
        said: list[tuple[str, object]] = []
        event.listen(a.engine, "before_cursor_execute",
                     lambda _c, _k, stmt, params, _x, _m: said.append((stmt, params)))  # fmt: skip
        t = a.values(["A0x"], latest_per_unit=True)
        assert list(t.serial) == ["U1", "U2"] and len(t.fit_verdict) == len(t.rms_z) == 2
        stmt, params = said[-1]
        with a.engine.connect() as conn:
            plan = [row[-1] for row in conn.exec_driver_sql("EXPLAIN QUERY PLAN " + stmt, params)]
    touches = [step for step in plan if re.search(r"\b(calibrations|later|parameters)\b", step)]
    assert touches and all("COVERING INDEX" in step for step in touches), plan


def test_an_sqlite_archive_uses_the_wal_journal(tmp_path: Path) -> None:
    with Archive(str(tmp_path / "a.sqlite")) as a:
        with a.engine.connect() as conn:
            assert conn.exec_driver_sql("PRAGMA journal_mode").scalar() == "wal"


def test_the_url_comes_from_the_option_else_the_environment_else_a_file_here(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv(ARCHIVE_ENV, raising=False)
    monkeypatch.setenv("XDG_DATA_HOME", str(tmp_path / "share"))
    own = tmp_path / "share" / "imu-bench" / "archive.sqlite"
    assert archive_url(None) == f"sqlite:///{own}"
    monkeypatch.setenv(ARCHIVE_ENV, "postgresql://qc@db.lab/archive")
    assert archive_url(None) == "postgresql+psycopg://qc@db.lab/archive"
    assert archive_url("x.sqlite") == f"sqlite:///{tmp_path / 'x.sqlite'}"
    assert archive_url("postgres://h/db") == "postgresql+psycopg://h/db"


@pytest.mark.parametrize(
    "url, words",
    [
        ("nosuchdb://x/y", "not an SQLite file nor a postgresql:// server"),
        ("mysql://qc:secret@db/line", "archive mysql://qc:\\*\\*\\*@db/line: not an SQLite"),
        ("/nonexistent/dir/a.sqlite", "no directory /nonexistent/dir; create it or give"),
        # the URL's own parser raised ValueError: a traceback
        ("postgresql://qc:secret@db:notaport/x", "not a database URL .* postgresql://user@host"),
        ("postgresql://qc@[::1/x", "not a database URL"),
        ("/dev/null", "not a file"),
        ("", "--archive '': give an SQLite file or postgresql://"),
    ],
)
def test_a_bad_archive_url_is_one_line(url: str, words: str) -> None:
    with pytest.raises(UserError, match=words) as info:
        Archive(url)
    assert "secret" not in str(info.value) and "\n" not in str(info.value)


def test_a_directory_as_the_archive_names_a_file_in_it(tmp_path: Path) -> None:
    with pytest.raises(UserError, match="is a directory; give the archive's file, e.g.") as e:
        Archive(str(tmp_path))
    assert str(tmp_path / "archive.sqlite") in str(e.value)


def test_only_a_writer_creates_an_archive(tmp_path: Path) -> None:
    """Was: a question to an archive path with a typo made a new empty archive there and
    answered from it ('no unit moved', exit 0)."""
    db = tmp_path / "typo.sqlite"
    with pytest.raises(UserError, match="no such file; 'archive add DIR' or calibrate creates"):
        Archive(str(db), create=False)
    assert not db.exists()
    Archive(str(db)).close()  # a writer creates it
    Archive(str(db), create=False).close()  # then a reader opens it


def test_an_unreachable_server_is_one_line_without_the_password() -> None:
    url = "postgresql://qc:secret@127.0.0.1:1/archive?connect_timeout=2"
    with pytest.raises(UserError, match="cannot open it") as info:
        Archive(url)
    assert "secret" not in str(info.value)
    # the URL as the user gave it, without the driver the program chose
    assert "archive postgresql://qc:***@127.0.0.1:1/archive" in str(info.value)


@pytest.mark.slow  # two sessions of the README's first command on the virtual board
def test_simulated_sessions_stay_out_of_the_default_archive(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """The README's first command, run twice, leaves the user's archive and the one
    $IMU_BENCH_ARCHIVE names as they were (issue 43); named with --archive, it goes in."""
    from host.__main__ import main
    from host.archive.store import archive_directory

    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    monkeypatch.setenv("XDG_DATA_HOME", str(tmp_path / "xdg"))
    env_db = tmp_path / "env.sqlite"
    monkeypatch.setenv("IMU_BENCH_ARCHIVE", str(env_db))
    first = ["calibrate", "--serial", "DEMO01", "--yes", "--warmup", "0", "--static-seconds",
             "5", "--turns", "1"]  # fmt: skip
    for _ in range(2):
        assert main(first) in (0, 1)
        err = " ".join(capsys.readouterr().err.split())
        assert "not archived: a simulated session goes only into an archive named" in err
    assert not env_db.exists() and not (tmp_path / "xdg" / "imu-bench" / "archive.sqlite").exists()
    # the user's own archives, holding a real unit, are left byte for byte as they were
    import hashlib

    own = tmp_path / "xdg" / "imu-bench" / "archive.sqlite"
    own.parent.mkdir(parents=True)
    for db in (env_db, own):
        with Archive(str(db)) as a:
            a.add(_entry("U17"))
    before = {db: hashlib.sha256(db.read_bytes()).hexdigest() for db in (env_db, own)}
    for env in (str(env_db), None):  # $IMU_BENCH_ARCHIVE, then the user's own file
        if env is None:
            monkeypatch.delenv("IMU_BENCH_ARCHIVE")
        assert main(first) in (0, 1)  # a third and fourth run, with the archives there
        assert "not archived: a simulated" in " ".join(capsys.readouterr().err.split())
    assert {db: hashlib.sha256(db.read_bytes()).hexdigest() for db in (env_db, own)} == before
    named = tmp_path / "named.sqlite"
    assert archive_directory(tmp_path / "DEMO01", str(named)).startswith("archived as #1")
    with Archive(str(named)) as a:
        assert [s.serial for s in a.summaries()] == ["DEMO01"]
