"""The questions answered from the archive (host/archive/checks.py) on a simulated lot with
planted problems — 200 units over 4 benches, 3 sessions each, a reference unit on every
bench, one drifting unit, one biased bench, one unit failing its self-test (on the virtual
board's failing chip, decoded and judged as in a real session): repeat, drift, lot and
check-bench find exactly the planted problems, on SQLite and on PostgreSQL."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from host.archive import checks
from host.archive.store import Archive
from host.errors import UserError
from tests.host.archive.lot_sim import NAMES, simulate_lot


@pytest.fixture
def lot_archive(archive_url: str) -> tuple[Archive, object]:
    # a lot without a chance false alarm: at the family-wise 1 % one lot in a hundred has one
    # (seed 11 does: U0195's A0x, p 2.8e-6 against the limit 4.1e-6); the rate itself is
    # tested on simulated null lots in test_stats.py
    lot = simulate_lot(np.random.default_rng(12))
    a = Archive(archive_url)
    a.add_many(lot.entries)
    return a, lot


@pytest.mark.slow
def test_the_planted_problems_and_only_they_are_found(lot_archive: tuple) -> None:
    a, lot = lot_archive
    with a:
        rep = checks.repeat(a)
        assert {(r.serial, r.bench) for r in rep if r.failed} == {(lot.drifting, "B4")}
        assert {r.name for r in rep if r.failed} == {"A0x"}
        rows, k = checks.drift(a)
        assert {(r.serial, r.name) for r in rows if r.moved} == {(lot.drifting, "A0x")}
        assert 4 < k < 5  # family-wise over 201 units × 12 parameters at 1 %
        lr = checks.lot_report(a)
        assert lr.units == 201
        assert lr.failing == ((lot.failing, "self-test failed"),)
        outcomes = {(s.serial == lot.failing, s.self_test, s.verdict) for s in a.summaries()}
        assert outcomes == {(True, "fail", "fail"), (False, "pass", "pass")}
        assert all(not r.outliers for r in lr.rows)
        assert all(r.summary.within for r in lr.rows)
        benches, _ = checks.check_bench(a, lot.reference)
        assert {(b.bench, b.name) for b in benches if b.flagged} == {(lot.biased_bench, "G0z")}


def test_the_lots_self_tests_take_a_real_sessions_path() -> None:
    """The simulated parts' SELF_TEST_RESULT frames, decoded and judged: a part at its trim
    passes, one axis 20 % low fails and is named; the virtual board's failing chip fails on the
    axes its firmware model gives (accelerometer Y high, gyroscope Z low) every time."""
    from tests.host.archive.lot_sim import (
        decoded_self_test,
        self_test_fields,
        virtual_board_self_tests,
    )

    rng = np.random.default_rng(5)
    healthy = decoded_self_test(self_test_fields(rng, np.zeros(6)))
    assert healthy["self_test"] == "pass" and "self_test_note" not in healthy
    low_gz = decoded_self_test(self_test_fields(rng, np.array([0, 0, 0, 0, 0, -0.2])))
    assert low_gz["self_test"] == "fail" and low_gz["self_test_note"].startswith("gz outside")
    board = virtual_board_self_tests("fail", 3)
    assert [h["self_test"] for h in board] == ["fail"] * 3
    assert all(h["self_test_note"].startswith("ay, gz outside") for h in board)


def test_a_lot_outlier_and_a_tolerance_drift_are_found(archive_url: str) -> None:
    from tests.host.archive.lot_sim import SIGMA, make_entry

    rng = np.random.default_rng(12)
    with Archive(archive_url) as a:
        for i in range(60):
            v = rng.normal(0.0, 0.05, len(NAMES))
            if i == 7:
                v[NAMES.index("A0y")] = 0.6  # 12 spreads out, and beyond the 0.5 datasheet
            a.add(make_entry(f"V{i:02d}", "B1", 0, v, SIGMA, day=0))
            a.add(make_entry(f"V{i:02d}", "B1", 1, v + 0.0001, SIGMA, day=5))
        lr = checks.lot_report(a)
        outl = {(r.name, u) for r in lr.rows for u, _ in r.outliers}
        assert outl == {("A0y", "V07")}
        # every unit moved by 0.0001: within k·σ, beyond a tolerance of 0.00005 on A0x only
        rows, _ = checks.drift(a, tolerances={"A0x": 0.00005})
        assert {r.name for r in rows if r.moved} == {"A0x"}
        assert len({r.serial for r in rows if r.moved}) == 60


def test_trend_and_charts_follow_time(archive_url: str) -> None:
    lot = simulate_lot(np.random.default_rng(13), units=20)
    with Archive(archive_url) as a:
        a.add_many(lot.entries)
        tr = checks.trend(a, lot.drifting, ["A0x"])
        pts = tr["A0x"]
        assert [p.measured_at for p in pts] == sorted(p.measured_at for p in pts)
        assert pts[-1].value - pts[-2].value > 0.05  # the planted 40 σ = 0.08 move
        charts = checks.control_charts(a, serial=lot.reference, names=["G0z"])
        assert [c.bench for c in charts] == list(lot.benches)
        assert all(len(c.values) == 3 for c in charts)
        with pytest.raises(UserError, match="no calibration of this serial"):
            checks.trend(a, "NOPE")
        with pytest.raises(UserError, match="at least two"):
            checks.check_bench(a, lot.drifting)


def test_drift_skips_a_session_without_the_parameter(archive_url: str) -> None:
    """A unit calibrated with another model in between: drift compares the last two sessions
    that determined each parameter."""
    import dataclasses

    from tests.host.archive.lot_sim import SIGMA, make_entry

    v = np.zeros(len(NAMES))
    first = make_entry("W1", "B1", 0, v, SIGMA, day=0)
    middle = make_entry("W1", "B1", 1, v, SIGMA, day=3)
    middle = dataclasses.replace(
        middle, parameters=tuple(p for p in middle.parameters if p.name != "A0x")
    )
    moved = v.copy()
    moved[NAMES.index("A0x")] = 0.1  # 35 σ from the first session
    last = make_entry("W1", "B1", 2, moved, SIGMA, day=6)
    with Archive(archive_url) as a:
        a.add_many([first, middle, last])
        rows, _ = checks.drift(a)
    by = {r.name: r for r in rows}
    assert by["A0x"].moved and by["A0x"].before_at == first.measured_at
    assert by["A0x"].delta == pytest.approx(0.1)
    assert not any(r.moved for r in rows if r.name != "A0x")
    assert by["G0z"].before_at == middle.measured_at


@pytest.mark.slow  # 100 lots archived and checked (~15 s)
def test_false_alarms_at_the_stated_rate_over_null_lots(tmp_path: Path) -> None:
    """100 lots with nothing planted (24 units over 4 benches, 3 sessions each, a reference
    unit on every bench), archived together and checked one lot at a time at a family-wise
    false-alarm rate of 20 % (large enough to count): each check flags at most the stated
    fraction of lots, within three binomial standard deviations (≤ 32 of 100), and not none of
    them (≥ 5: a check that never fires passes the upper bound too). Bonferroni over the units
    × parameters makes each a little conservative (≈ 18 % for independent tests)."""
    n, alpha = 100, 0.2
    rng = np.random.default_rng(2029)
    lots = [
        simulate_lot(rng, units=24, plant=False, lot_name=f"N{j:02d}", prefix=f"N{j:02d}-")
        for j in range(n)
    ]
    flagged = dict.fromkeys(("repeat", "drift", "lot", "check-bench"), 0)
    with Archive(str(tmp_path / "null.sqlite")) as a:
        a.add_many([e for lot in lots for e in lot.entries])
        for j, lot in enumerate(lots):
            name = f"N{j:02d}"
            flagged["repeat"] += any(r.failed for r in checks.repeat(a, lot=name, alpha=alpha))
            rows, _ = checks.drift(a, lot=name, alpha=alpha)
            flagged["drift"] += any(r.moved for r in rows)
            lr = checks.lot_report(a, name, alpha=alpha)
            flagged["lot"] += any(r.outliers for r in lr.rows) or bool(lr.failing)
            benches, _ = checks.check_bench(a, lot.reference, alpha=alpha)
            flagged["check-bench"] += any(b.flagged for b in benches)
    limit = alpha * n + 3 * (n * alpha * (1 - alpha)) ** 0.5
    assert all(5 <= f <= limit for f in flagged.values()), flagged
