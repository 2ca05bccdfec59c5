"""Simulated results in the archive (issue 43 item 6): a sim:// or emu:// session archived with
--archive is flagged (schema v4: a column, set by the migration on the rows archived before
it), kept and listed, and left out of the lot, control and drift statistics, which say how
many they left out."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
from sqlalchemy import create_engine, text

from host.archive import checks, schema, store
from host.archive.entry import Entry
from host.archive.page import page_data, render
from host.archive.store import Archive
from tests.host.archive.lot_sim import NAMES, SIGMA, make_entry
from tests.host.cli.cli_run import run

SIM_JSON = json.dumps({"simulated": True, "provenance": {"simulated": True}}, indent=2)


def _entry(serial: str, session: int, shift: float = 0.0, **kw: object) -> Entry:
    v = np.arange(len(NAMES), dtype=float) * 0.01 + shift
    return make_entry(serial, "B1", session, v, SIGMA, day=session, **kw)  # type: ignore[arg-type]


def _lot(simulated_shift: float) -> list[Entry]:
    """Five real units of lot L1, each calibrated twice the same; and one simulated unit,
    twice, its second session far from its first and its values far from the lot's."""
    real = [_entry(f"U{i}", s, 0.001 * i) for i in range(5) for s in range(2)]
    sim = [
        dataclasses.replace(_entry("DEMO01", s, s * simulated_shift, tag="sim"), simulated=True,
                            result_json=SIM_JSON)
        for s in range(2)
    ]  # fmt: skip
    return real + sim


def test_a_simulated_calibration_is_flagged_kept_and_left_out_of_the_statistics(
    archive_url: str,
) -> None:
    entries = _lot(simulated_shift=50.0)
    with Archive(archive_url) as a:
        a.add_many(entries)
        assert a.entry(entries[-1].result_hash).simulated is True
        assert a.entry(entries[0].result_hash).simulated is False
        assert "DEMO01" in {s.serial for s in a.summaries()}  # kept, and listed
        assert a.simulated_count() == 2 and a.simulated_count(lot="L1") == 2
        assert a.simulated_count(serial="U1") == 0
        rep = checks.lot_report(a, "L1")
        assert rep.units == 5  # the simulated unit is not one of the lot's
        assert not any(s == "DEMO01" for r in rep.rows for s, _ in r.outliers)
        rows, _ = checks.drift(a)
        assert rows and "DEMO01" not in {r.serial for r in rows}
        assert not any(r.moved for r in rows)  # its 50-unit move is not the lot's drift
        charts = checks.control_charts(a)
        assert charts and all("DEMO01" not in c.serials for c in charts)
        # what a user asks of one unit still finds it
        assert len(checks.trend(a, "DEMO01", [NAMES[0]])[NAMES[0]]) == 2
        page = render(page_data(a, lot="L1"))
        assert 'id="simulated"' in page and "2 simulated calibration(s)" in page


def test_the_archive_commands_say_what_they_left_out(tmp_path) -> None:
    db = str(tmp_path / "a.sqlite")
    with Archive(db) as a:
        a.add_many(_lot(simulated_shift=50.0))
    for cmd in (["lot", "L1"], ["drift"], ["control"]):
        rc, out, err = run(["archive", *cmd, "--archive", db])
        assert rc in (0, 1), err
        said = " ".join(out.split())
        assert "left out of these statistics: 2 simulated calibration(s)" in said, cmd
        assert "DEMO01" not in out.replace("archive list shows them", ""), cmd
    with Archive(str(tmp_path / "b.sqlite")) as a:
        a.add_many(_lot(0.0)[:-2])
    rc, out, _ = run(["archive", "lot", "L1", "--archive", str(tmp_path / "b.sqlite")])
    assert "left out" not in out  # nothing simulated: nothing said


def test_an_archive_before_the_flag_is_migrated_and_its_simulated_rows_flagged(
    archive_url: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """An archive of schema v3 (no ``simulated`` column) holding a simulated result and a
    real one: the v4 migration adds the column and flags the simulated row from its result
    file; the statistics then leave it out."""
    engine = create_engine(store.archive_url(archive_url))
    with monkeypatch.context() as m:
        m.setattr(schema, "MIGRATIONS", schema.MIGRATIONS[:3])
        m.setattr(schema, "SCHEMA_VERSION", 3)
        assert schema.migrate(engine.connect) == 3
    real, sim = _entry("U1", 0), _entry("DEMO01", 0, 9.0, tag="sim")
    sim = dataclasses.replace(sim, result_json=SIM_JSON)
    with engine.begin() as conn:  # as the v3 program wrote them: no simulated column
        conn.execute(text("ALTER TABLE calibrations DROP COLUMN simulated"))
        for e in (real, sim):
            row = {k: v for k, v in store._row_of(e).items() if k != "simulated"}
            cid = conn.execute(
                schema.calibrations.insert().returning(schema.calibrations.c.id), row
            ).scalar_one()
            conn.execute(
                schema.parameters.insert(),
                [store._parameter_row(cid, i, p) for i, p in enumerate(e.parameters)],
            )
    engine.dispose()
    with Archive(archive_url) as a:
        assert a.entry(sim.result_hash).simulated and not a.entry(real.result_hash).simulated
        assert a.simulated_count() == 1
        assert checks.lot_report(a).units == 1
