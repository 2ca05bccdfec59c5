"""A repeat that is an earlier session over again (issue 45 item 3): every value and σ equal
bit for bit, or a record file archived with an earlier session of other records, is named by
:func:`host.archive.checks.identical_repeats` and by ``archive repeat`` (exit 1) — and a
session recomputed from the same records, or a true repeat, is not."""

from __future__ import annotations

import dataclasses

import numpy as np

from host.archive import checks
from host.archive.entry import Entry, records_digest
from host.archive.store import Archive
from tests.host.archive.lot_sim import NAMES, SIGMA, make_entry
from tests.host.cli.cli_run import run


def _sessions(rng: np.random.Generator) -> list[Entry]:
    """Three true repeats of U1 (fresh noise each) and one of U2."""
    truth = rng.normal(0.0, 0.01, len(NAMES))
    return [
        make_entry(s, "B1", i, truth + rng.normal(0.0, SIGMA), SIGMA, day=i)
        for s, n in (("U1", 3), ("U2", 1))
        for i in range(n)
    ]


def _copy_of(e: Entry, session: int) -> Entry:
    """A later session of ``e``'s unit whose values and σ are ``e``'s bit for bit (other
    records: their times differ)."""
    values = np.array([p.value for p in e.parameters])
    later = make_entry(e.serial, e.bench, session, values, SIGMA, day=session, tag="again")
    assert later.records_hash != e.records_hash and later.result_hash != e.result_hash
    return later


def _ids(a: Archive, entries: list[Entry]) -> list[int]:
    return [a.add(e)[0] for e in entries]


def test_a_session_with_every_value_of_an_earlier_one_is_named(archive_url: str) -> None:
    entries = _sessions(np.random.default_rng(3))
    with Archive(archive_url) as a:
        ids = _ids(a, entries)
        assert checks.identical_repeats(a) == []  # true repeats: nothing named
        (copy_id,) = _ids(a, [_copy_of(entries[1], 5)])
        found = checks.identical_repeats(a)
        assert [(r.serial, r.bench, r.earlier, r.later) for r in found] == [
            ("U1", "B1", ids[1], copy_id)
        ]
        assert found[0].what == "every value and σ"
        assert checks.identical_repeats(a, "U2") == []
        pooled = checks.identical_repeats(a, "U1", across_benches=True)
        assert [(r.bench, r.later) for r in pooled] == [("(all)", copy_id)]


def test_one_value_apart_in_the_last_bit_is_a_repeat(archive_url: str) -> None:
    entries = _sessions(np.random.default_rng(4))
    values = np.array([p.value for p in entries[0].parameters])
    values[-1] = np.nextafter(values[-1], np.inf)
    near = make_entry("U1", "B1", 7, values, SIGMA, day=7, tag="near")
    with Archive(archive_url) as a:
        _ids(a, [*entries, near])
        assert checks.identical_repeats(a) == []


def test_a_record_archived_with_an_earlier_session_is_named(archive_url: str) -> None:
    entries = _sessions(np.random.default_rng(5))
    first = entries[0]
    later = entries[2]  # its values are its own; one record is the first session's
    hashes = (*first.record_hashes, ("z_up", "ab" * 32))
    later = dataclasses.replace(later, record_hashes=hashes, records_hash=records_digest(hashes))
    with Archive(archive_url) as a:
        ids = _ids(a, [first, entries[1], later, entries[3]])
        found = checks.identical_repeats(a, "U1")
        assert [(r.earlier, r.later, r.what) for r in found] == [
            (ids[0], ids[2], f"the record {first.record_hashes[0][0]}")
        ]


def test_a_session_recomputed_from_its_records_is_no_copy(archive_url: str) -> None:
    entries = _sessions(np.random.default_rng(6))
    e = entries[0]
    # the same records fitted again with another model: the same session, not a repeat
    again = dataclasses.replace(e, result_hash="cd" * 32, model="base+temperature")
    with Archive(archive_url) as a:
        _ids(a, [*entries, again])
        assert checks.identical_repeats(a) == []


def test_archive_repeat_says_it_and_exits_1(tmp_path) -> None:
    db = str(tmp_path / "a.sqlite")
    entries = _sessions(np.random.default_rng(7))
    with Archive(db) as a:
        _ids(a, entries)
    rc, out, err = run(["archive", "repeat", "U1", "--archive", db])
    assert "IDENTICAL" not in out, out
    with Archive(db) as a:
        first_id = a.add(entries[0])[0]  # the same result again: a no-op, its id
        (copy_id,) = _ids(a, [_copy_of(entries[0], 9)])
    rc, out, err = run(["archive", "repeat", "U1", "--archive", db])
    said = " ".join(out.split())
    assert rc == 1, (out, err)
    assert f"IDENTICAL: U1 #{copy_id} has every value and σ of #{first_id} bit for bit" in said
    assert "repeatability not shown: 1 session(s) repeat an earlier one" in said
    assert "agree within their σ" not in said
