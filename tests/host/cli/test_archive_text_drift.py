"""``archive drift`` says when each calibration was, to the minute (issue 45 item 4): two
calibrations of one day are told apart by their times."""

from __future__ import annotations

from host.archive.checks import DriftRow
from host.cli.archive_text import drift


def _row(before_at: str, after_at: str) -> DriftRow:
    return DriftRow("U17", "A0x", before_at, after_at, 0.1, 0.2, 0.1, 9.0, True)


def test_drift_prints_the_times_of_both_calibrations() -> None:
    rows = [
        _row("2026-01-03T08:12:00.000000Z", "2026-01-03T15:47:30.000000Z"),
        _row("2026-01-03T15:47:30.000000Z", "2026-01-04T09:05:00.000000Z"),
    ]
    text = drift(rows, 4.5, 0.01, width=80)
    assert "U17: 2026-01-03 08:12 UTC -> 2026-01-03 15:47 UTC" in text
    assert "U17: 2026-01-03 15:47 UTC -> 2026-01-04 09:05 UTC" in text  # not merged by day
    assert all(len(ln) <= 80 for ln in text.splitlines())
